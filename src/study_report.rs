//! The study's summary: per scene × method the paper's metrics with confidence intervals, and
//! dk-rrt paired against every other method on the same episodes; rendered as JSON
//! (`study.json`) and Markdown (`study.md`).

use dkrrt_stats::{paired_bootstrap, wilson, Z95};
use serde::Serialize;

use crate::study::Row;

/// Figures of one method on one scene.
#[derive(Debug, Clone, Serialize)]
pub struct Cell {
    pub scene: String,
    pub method: String,
    pub episodes: usize,
    /// Episodes that ran (no setup error).
    pub ran: usize,
    pub completed: usize,
    pub completion: f64,
    /// 95 % Wilson interval of the completion rate.
    pub completion_ci: [f64; 2],
    pub collisions: usize,
    pub collision_rate: f64,
    pub collision_ci: [f64; 2],
    /// Execution error (the paper's): joint tracking RMS, mean over episodes, and the largest
    /// max, rad.
    pub execution_error_rad_rms: f64,
    pub execution_error_rad_max: f64,
    /// End-effector path error (desired vs real): RMS mean over episodes, and the largest max, m.
    pub ee_path_error_m_rms: f64,
    pub ee_path_error_m_max: f64,
    /// Medians over the completed episodes.
    pub time_to_goal_s_median: Option<f64>,
    pub path_length_rad_median: Option<f64>,
    /// Planning compute: median over episodes of their p50, largest p99, ms.
    pub plan_ms_p50: f64,
    pub plan_ms_p99: f64,
    pub replans_mean: f64,
    pub fallbacks_keep: u64,
    pub fallbacks_escape: u64,
    pub fallbacks_brake: u64,
    pub fallbacks_dodge: u64,
    /// Smallest true arm–debris distance over the episodes, and smallest predicted clearance, m.
    pub min_distance_m: Option<f64>,
    pub min_predicted_clearance_m: Option<f64>,
    /// Plant seconds per wall second.
    pub lockstep_speed: f64,
}

/// dk-rrt against another method on the same episodes of a scene.
#[derive(Debug, Clone, Serialize)]
pub struct Comparison {
    pub scene: String,
    pub baseline: String,
    pub episodes: u64,
    /// dk-rrt's completion rate minus the baseline's, with a 95 % paired bootstrap interval.
    pub diff: f64,
    pub diff_ci: [f64; 2],
    /// Episodes only dk-rrt / only the baseline completed.
    pub only_dk: u64,
    pub only_baseline: u64,
    /// Exact McNemar p-value.
    pub p_value: f64,
}

/// Fitting cost of a method's models.
#[derive(Debug, Clone, Serialize)]
pub struct FitCost {
    pub method: String,
    pub forecasts: String,
    pub fit_s: f64,
    /// The deep network's training in this study (`--train-deep`), s; `None`: not trained
    /// here (the shipped network, trained offline by `dkrrt train`, or no network).
    pub train_s: Option<f64>,
}

/// The study's summary.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    pub cells: Vec<Cell>,
    pub comparisons: Vec<Comparison>,
    pub fits: Vec<FitCost>,
}

/// Bootstrap resamples of a paired comparison.
pub const BOOTSTRAP_REPS: usize = 10_000;

fn median(mut v: Vec<f64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    Some(if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) })
}

fn min_opt(it: impl Iterator<Item = Option<f64>>) -> Option<f64> {
    it.flatten().fold(None, |a: Option<f64>, b| Some(a.map_or(b, |a| a.min(b))))
}

/// Summarises `rows` per scene × method and pairs dk-rrt with every other method.
pub fn summarize(
    rows: &[Row],
    scenes: &[String],
    methods: &[String],
    fits: Vec<FitCost>,
    seed: u64,
) -> Summary {
    let mut cells = Vec::new();
    let mut comparisons = Vec::new();
    for sc in scenes {
        for m in methods {
            let r: Vec<&Row> = rows.iter().filter(|r| &r.scene == sc && &r.method == m).collect();
            if r.is_empty() {
                continue;
            }
            let ran: Vec<&Row> = r.iter().copied().filter(|x| x.error.is_none()).collect();
            let n = r.len();
            let done = r.iter().filter(|x| x.completed).count();
            let col = r.iter().filter(|x| x.collision).count();
            let nr = ran.len().max(1) as f64;
            let ci = |k: usize| {
                let (lo, hi) = wilson(k as u64, n as u64, Z95);
                [lo, hi]
            };
            let completed: Vec<&&Row> = r.iter().filter(|x| x.completed).collect();
            cells.push(Cell {
                scene: sc.clone(),
                method: m.clone(),
                episodes: n,
                ran: ran.len(),
                completed: done,
                completion: done as f64 / n as f64,
                completion_ci: ci(done),
                collisions: col,
                collision_rate: col as f64 / n as f64,
                collision_ci: ci(col),
                execution_error_rad_rms: ran.iter().map(|x| x.tracking_error_rad_rms).sum::<f64>() / nr,
                execution_error_rad_max: ran.iter().map(|x| x.tracking_error_rad_max).fold(0.0, f64::max),
                ee_path_error_m_rms: ran.iter().map(|x| x.ee_path_error_m_rms).sum::<f64>() / nr,
                ee_path_error_m_max: ran.iter().map(|x| x.ee_path_error_m_max).fold(0.0, f64::max),
                time_to_goal_s_median: median(completed.iter().filter_map(|x| x.time_to_goal_s).collect()),
                path_length_rad_median: median(completed.iter().map(|x| x.path_length_rad).collect()),
                plan_ms_p50: median(ran.iter().map(|x| x.plan_ms.p50).collect()).unwrap_or(0.0),
                plan_ms_p99: ran.iter().map(|x| x.plan_ms.p99).fold(0.0, f64::max),
                replans_mean: ran.iter().map(|x| x.replans as f64).sum::<f64>() / nr,
                fallbacks_keep: ran.iter().map(|x| x.fallbacks_keep).sum(),
                fallbacks_escape: ran.iter().map(|x| x.fallbacks_escape).sum(),
                fallbacks_brake: ran.iter().map(|x| x.fallbacks_brake).sum(),
                fallbacks_dodge: ran.iter().map(|x| x.fallbacks_dodge).sum(),
                min_distance_m: min_opt(ran.iter().map(|x| x.min_distance_m)),
                min_predicted_clearance_m: min_opt(ran.iter().map(|x| x.min_predicted_clearance_m)),
                lockstep_speed: ran.iter().map(|x| x.plant_s).sum::<f64>()
                    / ran.iter().map(|x| x.wall_s).sum::<f64>().max(1e-9),
            });
        }
        if !methods.iter().any(|m| m == "dk-rrt") {
            continue;
        }
        for b in methods.iter().filter(|m| *m != "dk-rrt") {
            // Pairs: the same episode index under both methods.
            let pairs: Vec<(bool, bool)> = rows
                .iter()
                .filter(|x| &x.scene == sc && x.method == "dk-rrt")
                .filter_map(|d| {
                    rows.iter()
                        .find(|x| &x.scene == sc && &x.method == b && x.episode == d.episode)
                        .map(|o| (d.completed, o.completed))
                })
                .collect();
            if pairs.is_empty() {
                continue;
            }
            let p = paired_bootstrap(&pairs, BOOTSTRAP_REPS, seed ^ 0xb007);
            comparisons.push(Comparison {
                scene: sc.clone(),
                baseline: b.clone(),
                episodes: p.n,
                diff: p.diff,
                diff_ci: [p.low, p.high],
                only_dk: p.only_first,
                only_baseline: p.only_second,
                p_value: p.p_value,
            });
        }
    }
    Summary { cells, comparisons, fits }
}

fn pct(x: f64) -> String {
    format!("{:.1} %", 100.0 * x)
}

fn opt(x: Option<f64>, prec: usize) -> String {
    x.map_or("–".into(), |v| format!("{v:.prec$}"))
}

/// The summary as Markdown tables (what `study.md` holds after its header).
pub fn markdown_tables(s: &Summary) -> String {
    let mut o = String::new();
    o.push_str("### Completion, collisions and motion per scene and method\n\n");
    o.push_str("| scene | method | episodes | completed (95 % CI) | collisions (95 % CI) | execution error RMS / max, rad | EE path error RMS / max, m | time to goal, s (median) | path length, rad (median) | plan ms p50 / p99 | replans (mean) | fallbacks keep / escape / dodge / brake | min distance, m | lockstep speed |\n");
    o.push_str("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for c in &s.cells {
        o.push_str(&format!(
            "| {} | {} | {} | **{}** ({:.1}–{:.1} %) | {} ({:.1}–{:.1} %) | {:.2e} / {:.2e} | {:.2e} / {:.2e} | {} | {} | {:.2} / {:.2} | {:.1} | {} / {} / {} / {} | {} | {:.0}× |\n",
            c.scene,
            c.method,
            c.episodes,
            pct(c.completion),
            100.0 * c.completion_ci[0],
            100.0 * c.completion_ci[1],
            c.collisions,
            100.0 * c.collision_ci[0],
            100.0 * c.collision_ci[1],
            c.execution_error_rad_rms,
            c.execution_error_rad_max,
            c.ee_path_error_m_rms,
            c.ee_path_error_m_max,
            opt(c.time_to_goal_s_median, 2),
            opt(c.path_length_rad_median, 2),
            c.plan_ms_p50,
            c.plan_ms_p99,
            c.replans_mean,
            c.fallbacks_keep,
            c.fallbacks_escape,
            c.fallbacks_dodge,
            c.fallbacks_brake,
            opt(c.min_distance_m, 3),
            c.lockstep_speed,
        ));
    }
    if !s.comparisons.is_empty() {
        o.push_str("\n### dk-rrt against each method on the same episodes\n\n");
        o.push_str(
            "Difference of completion rates (dk-rrt − method) with its 95 % paired bootstrap interval (",
        );
        o.push_str(&format!("{BOOTSTRAP_REPS} resamples of the episodes), the discordant episodes and the exact McNemar p-value.\n\n"));
        o.push_str("| scene | method | episodes | dk-rrt − method (95 % CI) | only dk-rrt / only method | McNemar p |\n");
        o.push_str("|---|---|---|---|---|---|\n");
        for c in &s.comparisons {
            o.push_str(&format!(
                "| {} | {} | {} | {:+.1} pts ({:+.1} … {:+.1}) | {} / {} | {} |\n",
                c.scene,
                c.baseline,
                c.episodes,
                100.0 * c.diff,
                100.0 * c.diff_ci[0],
                100.0 * c.diff_ci[1],
                c.only_dk,
                c.only_baseline,
                if c.p_value < 1e-3 { format!("{:.1e}", c.p_value) } else { format!("{:.3}", c.p_value) }
            ));
        }
    }
    o.push_str("\n### Fitting (training) cost of each method's forecast models\n\n");
    o.push_str("| method | forecasts | fit at start-up, s | deep network training, s |\n|---|---|---|---|\n");
    for f in &s.fits {
        let train = match (f.train_s, f.forecasts.starts_with("deep")) {
            (Some(t), _) => format!("{t:.1}"),
            (None, true) => "shipped network (not trained in this run: `--train-deep`)".into(),
            (None, false) => "–".into(),
        };
        o.push_str(&format!("| {} | {} | {:.2} | {} |\n", f.method, f.forecasts, f.fit_s, train));
    }
    o
}

/// Where and how a study ran (for `study.json` and `study.md`).
#[derive(Debug, Clone, Serialize)]
pub struct RunInfo {
    pub command: String,
    pub git_revision: String,
    pub machine: String,
    pub threads: usize,
    pub size: String,
    pub goal: String,
    pub wall_s: f64,
    pub date_utc: String,
}

fn sh(cmd: &str, args: &[&str]) -> Option<String> {
    let out = std::process::Command::new(cmd).args(args).output().ok()?;
    out.status.success().then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

impl RunInfo {
    /// The current command line, the source tree's git revision (`+dirty` with local
    /// changes; `unknown` outside a checkout), the CPU and core count.
    pub fn now(opts: &crate::study::StudyOptions, size: &str, goal: &str, wall_s: f64) -> RunInfo {
        let src = env!("CARGO_MANIFEST_DIR");
        let rev = sh("git", &["-C", src, "rev-parse", "--short=12", "HEAD"]).map_or("unknown".into(), |r| {
            let dirty = sh("git", &["-C", src, "status", "--porcelain", "--untracked-files=no"])
                .is_some_and(|s| !s.is_empty());
            if dirty {
                format!("{r}+dirty")
            } else {
                r
            }
        });
        let cpu = std::fs::read_to_string("/proc/cpuinfo")
            .ok()
            .and_then(|c| {
                c.lines()
                    .find(|l| l.starts_with("model name"))
                    .map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string())
            })
            .unwrap_or_else(|| "unknown CPU".into());
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        RunInfo {
            command: std::env::args().collect::<Vec<_>>().join(" "),
            git_revision: rev,
            machine: format!("{cpu}, {cores} cores, {}", std::env::consts::OS),
            threads: opts.threads,
            size: size.to_string(),
            goal: goal.to_string(),
            wall_s,
            date_utc: sh("date", &["-u", "+%Y-%m-%d %H:%M UTC"]).unwrap_or_default(),
        }
    }
}

/// What every model saw and what was evaluated (the no-leakage split) in a study on the base
/// scenario `b`, as stated in the output.
pub fn split_text(opts: &crate::study::StudyOptions, b: &dkrrt_config::Scenario) -> String {
    format!(
        "Evaluated: threat episodes of {} (indices 0..{}) generated from seed {} (start, goal and the debris' initial states drawn per episode and integrated backwards from their aim points); no model sees any of them before it runs. \
         Forecast models (cv, EDMD, the translation and dual-data parts of dk-rrt): fitted once at start-up on {} runs of generic random scenes (seeds {}.., random objects of every shape, not the named scenes, not an episode). \
         Deep attitude network (dk-rrt): the shipped model, trained by `dkrrt train` on runs of the four named scenes with perturbed initial states and on random tumbling bodies, seeds from 1 000 000: the same kinds of object as the episodes, never an episode's trajectory. \
         During an episode the predictor refines online from that episode's noisy observations only, never from its ground truth; only oracle-rrt reads the true future (an upper bound).",
        opts.scenes.join(", "),
        opts.episodes,
        opts.seed,
        b.predictor.fit_runs,
        b.predictor.fit_seed,
    )
}

/// `study.md`: the header (command, revision, machine, split), the tables and the figures.
pub fn markdown(
    s: &Summary,
    opts: &crate::study::StudyOptions,
    base: &dkrrt_config::Scenario,
    info: &RunInfo,
    figures: &[std::path::PathBuf],
    dir: &std::path::Path,
    traced: Option<&crate::figures::EpisodeTrace>,
) -> String {
    let mut o = String::from("# dkrrt study\n\n");
    o.push_str(&format!(
        "- command: `{}`\n- git revision: `{}`\n- machine: {} ({} worker threads)\n- date: {}\n- size: {} ({} episodes per scene), goals: {}\n- wall time: {:.1} s\n\n",
        info.command, info.git_revision, info.machine, info.threads, info.date_utc, info.size, opts.episodes, info.goal, info.wall_s
    ));
    o.push_str("Completed = the goal reached (every joint within 0.01 rad, or the end effector within 1 cm and 0.02 rad) before the episode's time limit with no contact at any tick. Every method runs the same episodes.\n\n");
    o.push_str(&format!("**Split (no leakage).** {}\n\n", split_text(opts, base)));
    o.push_str(&markdown_tables(s));
    if !figures.is_empty() {
        o.push_str("\n### Figures\n\n");
        if let Some(t) = traced {
            o.push_str(&format!(
                "Fig. 2, Fig. 4 and the clearance plot trace {} episode {} with {} (the completed dk-rrt episode that came closest to the debris).\n\n",
                t.scene, t.episode, t.method
            ));
        }
        for f in figures.iter().filter(|f| f.extension().is_some_and(|e| e == "png")) {
            let rel = f.strip_prefix(dir).unwrap_or(f);
            let name = f.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_default();
            o.push_str(&format!("![{name}]({}) (also as SVG)\n\n", rel.display()));
        }
    }
    o
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(scene: &str, ep: u64, method: &str, completed: bool, collision: bool) -> Row {
        let mut r = Row::empty(scene, ep, method);
        r.completed = completed;
        r.collision = collision;
        r.time_to_goal_s = completed.then_some(10.0 + ep as f64);
        r.tracking_error_rad_rms = 1e-3;
        r.tracking_error_rad_max = 1e-3 * (1 + ep) as f64;
        r.plant_s = 10.0;
        r.wall_s = 0.5;
        r
    }

    #[test]
    fn cells_and_paired_comparisons_on_known_outcomes() {
        // 20 episodes: dk-rrt completes 19; rrt-static completes 10 (all of them also
        // completed by dk-rrt) and collides in 6.
        let mut rows = Vec::new();
        for e in 0..20 {
            rows.push(row("dense", e, "dk-rrt", e != 3, false));
            rows.push(row("dense", e, "rrt-static", e < 10 && e != 3 || e == 12, e >= 14));
        }
        let scenes = vec!["dense".to_string()];
        let methods = vec!["rrt-static".to_string(), "dk-rrt".to_string()];
        let fits = vec![
            FitCost {
                method: "rrt-static".into(),
                forecasts: "latest estimate, held".into(),
                fit_s: 0.0,
                train_s: None,
            },
            FitCost {
                method: "dk-rrt".into(),
                forecasts: "deep-koopman-online".into(),
                fit_s: 0.25,
                train_s: Some(29.4),
            },
        ];
        let s = summarize(&rows, &scenes, &methods, fits, 1);
        assert_eq!(s.cells.len(), 2);
        let dk = s.cells.iter().find(|c| c.method == "dk-rrt").unwrap();
        assert_eq!((dk.episodes, dk.completed, dk.collisions), (20, 19, 0));
        let (lo, hi) = wilson(19, 20, Z95);
        assert_eq!(dk.completion_ci, [lo, hi]);
        assert!(lo < 0.95 && hi > 0.95 && hi < 1.0);
        // Completed times 10 + e for e ≠ 3: the 10th of 19 is 20.
        assert_eq!(dk.time_to_goal_s_median, Some(20.0));
        assert_eq!(dk.execution_error_rad_max, 20e-3);
        assert!((dk.lockstep_speed - 20.0).abs() < 1e-9);
        let rs = s.cells.iter().find(|c| c.method == "rrt-static").unwrap();
        assert_eq!((rs.completed, rs.collisions), (10, 6));
        assert_eq!(s.comparisons.len(), 1);
        let c = &s.comparisons[0];
        assert_eq!((c.baseline.as_str(), c.episodes, c.only_dk, c.only_baseline), ("rrt-static", 20, 9, 0));
        assert!((c.diff - 9.0 / 20.0).abs() < 1e-12);
        assert!(c.diff_ci[0] > 0.0 && c.diff_ci[1] <= 1.0 && c.diff_ci[0] < c.diff && c.diff < c.diff_ci[1]);
        assert!((c.p_value - dkrrt_stats::mcnemar_exact(9, 0)).abs() < 1e-15 && c.p_value < 0.05);
        // The Markdown holds both tables with these numbers.
        let md = markdown_tables(&s);
        assert!(md.contains("| dense | dk-rrt | 20 | **95.0 %**"), "{md}");
        assert!(md.contains("| dense | rrt-static | 20 | +45.0 pts"), "{md}");
        assert!(md.contains("| dk-rrt | deep-koopman-online | 0.25 | 29.4 |"), "{md}");
    }
}
