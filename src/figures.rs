//! The study's figures (the paper's Fig. 2, 3, 4 and a clearance plot), drawn by
//! `dkrrt-figures` from a study's summary and from the trace of one episode.

use std::path::{Path, PathBuf};

use dkrrt_figures::{grouped_bars, path_projections, time_panels, Bar, BarPanel, HLine, Series, TimePanel};
use dkrrt_msg::NJ;

use crate::lockstep::TraceSample;
use crate::study_report::Summary;

/// One episode's trace and what its figures need to know.
#[derive(Debug, Clone)]
pub struct EpisodeTrace {
    pub scene: String,
    pub episode: u64,
    pub method: String,
    pub samples: Vec<TraceSample>,
    /// `(t_s, id, position)` of every debris object, base frame.
    pub debris: Vec<(f64, u32, [f64; 3])>,
    pub v_max: [f64; NJ],
    pub a_max: [f64; NJ],
    pub j_max: [f64; NJ],
    pub margin_m: f64,
}

/// Fig. 3: per scene and method, the completion rate (95 % Wilson whiskers), the execution
/// error and the fitting cost of the method's models.
pub fn fig3(dir: &Path, s: &Summary) -> Result<[PathBuf; 2], String> {
    let fit =
        |m: &str| s.fits.iter().find(|f| f.method == m).map_or(0.0, |f| f.fit_s + f.train_s.unwrap_or(0.0));
    let mut completion = Vec::new();
    let mut exec = Vec::new();
    let mut training = Vec::new();
    for c in &s.cells {
        let bar = |value, interval| Bar { group: c.scene.clone(), series: c.method.clone(), value, interval };
        completion
            .push(bar(100.0 * c.completion, Some((100.0 * c.completion_ci[0], 100.0 * c.completion_ci[1]))));
        exec.push(bar(1e6 * c.execution_error_rad_rms, None));
        training.push(bar(fit(&c.method), None));
    }
    grouped_bars(
        &dir.join("fig3-methods"),
        "Completion, execution error and model fitting time per scene and method",
        &[
            BarPanel {
                title: "Task completion (whiskers: 95 % Wilson interval)".into(),
                y_label: "completed [%]".into(),
                bars: completion,
                y_range: Some((0.0, 100.0)),
            },
            BarPanel {
                title: "Execution error (joint tracking RMS, mean over episodes)".into(),
                y_label: "error [µrad]".into(),
                bars: exec,
                y_range: None,
            },
            BarPanel {
                title: if s.fits.iter().any(|f| f.train_s.is_some()) {
                    "Model training and fitting (deep network trained in this run)".into()
                } else {
                    "Model fitting at start-up (deep network shipped, trained offline by `dkrrt train`)"
                        .into()
                },
                y_label: "time [s]".into(),
                bars: training,
                y_range: None,
            },
        ],
    )
}

fn title(t: &EpisodeTrace) -> String {
    format!("{} episode {} ({})", t.scene, t.episode, t.method)
}

/// Fig. 2: the end effector's desired (red) and real (green) path in three projections, with
/// the true tracks of the debris that come within 1.5 m of it.
pub fn fig2(dir: &Path, t: &EpisodeTrace) -> Result<[PathBuf; 2], String> {
    let real: Vec<[f64; 3]> = t.samples.iter().map(|s| s.ee).collect();
    let desired: Vec<[f64; 3]> = t.samples.iter().filter_map(|s| s.ee_des).collect();
    let mut ids: Vec<u32> = t.debris.iter().map(|d| d.1).collect();
    ids.sort_unstable();
    ids.dedup();
    let near = |p: &[f64; 3]| {
        real.iter().any(|e| (e[0] - p[0]).powi(2) + (e[1] - p[1]).powi(2) + (e[2] - p[2]).powi(2) < 1.5 * 1.5)
    };
    let tracks: Vec<Vec<[f64; 3]>> = ids
        .iter()
        .map(|id| t.debris.iter().filter(|d| d.1 == *id).map(|d| d.2).collect::<Vec<_>>())
        .filter(|tr| tr.iter().any(near))
        .collect();
    path_projections(
        &dir.join("fig2-ee-path"),
        &format!("End-effector path, desired vs real, and nearby debris — {}", title(t)),
        &desired,
        &real,
        &tracks,
    )
}

/// Fig. 4: joint velocity, acceleration and jerk of the motion (the tracker's reference; jerk
/// by differencing its acceleration), each as a fraction of the joint's limit (the limits at ±1).
pub fn fig4(dir: &Path, t: &EpisodeTrace) -> Result<[PathBuf; 2], String> {
    let pick =
        |f: &dyn Fn(&TraceSample) -> Option<[f64; NJ]>, lim: &[f64; NJ], j: usize| -> Vec<(f64, f64)> {
            t.samples.iter().filter_map(|s| f(s).map(|v| (s.t_s, v[j] / lim[j]))).collect()
        };
    let mut jerk: Vec<Vec<(f64, f64)>> = vec![Vec::new(); NJ];
    for w in t.samples.windows(2) {
        if let (Some(a0), Some(a1)) = (w[0].qdd_des, w[1].qdd_des) {
            let dt = w[1].t_s - w[0].t_s;
            for j in 0..NJ {
                jerk[j].push((w[1].t_s, (a1[j] - a0[j]) / dt / t.j_max[j]));
            }
        }
    }
    let series = |pts: &dyn Fn(usize) -> Vec<(f64, f64)>| -> Vec<Series> {
        (0..NJ)
            .map(|j| Series { name: format!("joint {}", j + 1), points: pts(j), color: j, dashed: false })
            .collect()
    };
    let limits = vec![HLine { y: 1.0, name: "limit".into() }, HLine { y: -1.0, name: "limit".into() }];
    time_panels(
        &dir.join("fig4-joint-profiles"),
        &format!("Joint velocity, acceleration and jerk — {}", title(t)),
        &[
            TimePanel {
                title: "velocity / v_max".into(),
                y_label: "fraction of limit".into(),
                series: series(&|j| pick(&|s: &TraceSample| s.qd_des, &t.v_max, j)),
                lines: limits.clone(),
            },
            TimePanel {
                title: "acceleration / a_max".into(),
                y_label: "fraction of limit".into(),
                series: series(&|j| pick(&|s: &TraceSample| s.qdd_des, &t.a_max, j)),
                lines: limits.clone(),
            },
            TimePanel {
                title: "jerk / j_max (differenced acceleration)".into(),
                y_label: "fraction of limit".into(),
                series: series(&|j| jerk[j].clone()),
                lines: limits,
            },
        ],
    )
}

/// The clearance plot: the true smallest arm–debris distance and the planner's predicted
/// clearance of the real configuration (its forecast bound and margin included: it keeps this
/// above 0), with the margin and contact lines.
pub fn clearance(dir: &Path, t: &EpisodeTrace) -> Result<[PathBuf; 2], String> {
    let cap = 2.0;
    let truth: Vec<(f64, f64)> =
        t.samples.iter().filter_map(|s| s.true_distance_m.map(|d| (s.t_s, d.min(cap)))).collect();
    let pred: Vec<(f64, f64)> = t
        .samples
        .iter()
        .filter_map(|s| s.predicted_clearance_m.map(|d| (s.t_s, d.clamp(-cap, cap))))
        .collect();
    time_panels(
        &dir.join("clearance"),
        &format!("Clearance vs time (capped at {cap} m) — {}", title(t)),
        &[TimePanel {
            title: "smallest arm–debris distance".into(),
            y_label: "distance [m]".into(),
            series: vec![
                Series { name: "true distance".into(), points: truth, color: 2, dashed: false },
                Series {
                    name: "predicted clearance (bound + margin included; measured up to 1 m)".into(),
                    points: pred,
                    color: 0,
                    dashed: true,
                },
            ],
            lines: vec![
                HLine { y: t.margin_m, name: format!("planner margin {:.2} m", t.margin_m) },
                HLine { y: 0.0, name: "contact".into() },
            ],
        }],
    )
}

/// Every figure of a study: Fig. 3 from the summary, Fig. 2, Fig. 4 and the clearance plot
/// from the traced episode.
pub fn study_figures(dir: &Path, s: &Summary, t: Option<&EpisodeTrace>) -> Result<Vec<PathBuf>, String> {
    let mut out = Vec::new();
    out.extend(fig3(dir, s)?);
    if let Some(t) = t {
        out.extend(fig2(dir, t)?);
        out.extend(fig4(dir, t)?);
        out.extend(clearance(dir, t)?);
    }
    Ok(out)
}
