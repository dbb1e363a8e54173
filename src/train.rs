//! `dkrrt train` and `dkrrt predict-eval`: thin command wrappers around the predictor
//! library's training (`dkrrt_predictor::training`) and accuracy study (`dkrrt_predictor::eval`).

use std::io::Write;
use std::path::{Path, PathBuf};

use dkrrt_deep::Progress;
use dkrrt_predictor::eval::{markdown_table, run_study_views, StudyConfig, View};
use dkrrt_predictor::recorded::{read_observations, train_from_observations};
use dkrrt_predictor::training::{train_models, TrainOptions, TrainedModels};
use dkrrt_predictor::Method;

/// The training progress bar on stderr (deep and visual training).
pub fn progress_bar(p: &Progress) {
    let width = 30;
    let done = (p.epoch * width / p.epochs.max(1)).min(width);
    let eta = if p.epoch > 0 { p.elapsed_s / p.epoch as f64 * (p.epochs - p.epoch) as f64 } else { 0.0 };
    eprint!(
        "\r  [{}{}] epoch {:>3}/{}  train {:.3e}  valid {:.3e}  {:>5.1} s (eta {:.0} s)",
        "#".repeat(done),
        ".".repeat(width - done),
        p.epoch,
        p.epochs,
        p.train_loss,
        p.valid_loss,
        p.elapsed_s,
        eta
    );
    let _ = std::io::stderr().flush();
}

/// Trains the deep attitude model, prints its validation error per horizon, saves it.
/// With `recorded = Some((files, scenario))` the data are those recorded observation files
/// (the scenario gives the sensor noise for the pose filter and the orbit's mean motion).
pub fn train(
    out: &Path,
    quick: bool,
    epochs: Option<usize>,
    json: Option<&Path>,
    recorded: Option<(Vec<PathBuf>, dkrrt_config::Scenario)>,
) -> Result<TrainedModels, String> {
    let mut opts = if quick { TrainOptions::tiny() } else { TrainOptions::default() };
    if let Some(e) = epochs {
        if e == 0 {
            return Err("--epochs must be >= 1".into());
        }
        opts.deep.epochs = e;
    }
    check_outputs(out, json)?;
    let t = std::time::Instant::now();
    let m = match recorded {
        Some((files, sc)) => train_recorded(&files, &sc, &opts)?,
        None => train_simulated(&opts)?,
    };
    report_and_save(&m, out, json, t.elapsed().as_secs_f64())?;
    Ok(m)
}

/// The model file and the report are written after training: paths that cannot take them
/// are refused before it starts (nothing is learnt late).
pub fn check_outputs(out: &Path, json: Option<&Path>) -> Result<(), String> {
    crate::launch::check_writable(out).map_err(|e| format!("--out {}: {e}", out.display()))?;
    if let Some(j) = json {
        crate::launch::check_writable(j).map_err(|e| format!("--json {}: {e}", j.display()))?;
    }
    Ok(())
}

/// Data from the recorded files; `origin:line` errors for bad lines.
fn train_recorded(
    files: &[PathBuf],
    sc: &dkrrt_config::Scenario,
    opts: &TrainOptions,
) -> Result<TrainedModels, String> {
    let mut recs = Vec::new();
    for f in files {
        let bytes = dkrrt_io::read_capped(f, dkrrt_io::limits::JSON)
            .map_err(|e| format!("--observations {}: {e}", f.display()))?;
        let obs = read_observations(std::io::BufReader::new(&bytes[..]), &f.display().to_string())?;
        eprintln!("dkrrt train: {} observations from {}", obs.len(), f.display());
        recs.push(obs);
    }
    let frame_rate = if sc.has_debris() {
        dkrrt_debris::DebrisWorld::new(&sc.load_debris_scene().map_err(|e| e.to_string())?)
            .map_err(|e| e.to_string())?
            .orbit()
            .mean_motion()
    } else {
        dkrrt_predictor::filter::FilterConfig::default().frame_rate
    };
    eprintln!(
        "dkrrt train: recorded observations, pose filter with the scenario's sensor noise, mean motion {frame_rate:.4e} rad/s; \
         MLP {}x{} -> {} extra observables, {}-step loss",
        opts.deep.layers, opts.deep.hidden, opts.deep.extra, opts.deep.horizon
    );
    let cfg = dkrrt_planner::predict::predictor_config(sc);
    let m = train_from_observations(&recs, frame_rate, &cfg, opts, &mut progress_bar)?;
    eprintln!();
    Ok(m)
}

fn train_simulated(opts: &TrainOptions) -> Result<TrainedModels, String> {
    eprintln!(
        "dkrrt train: {} scenes x {} runs + {} random scenes x {} bodies, {} s each; MLP {}x{} -> {} extra observables, \
         {}-step loss, K re-solved every {} epochs",
        opts.scenes.len(),
        opts.runs_per_scene,
        opts.random_runs,
        opts.random_bodies,
        opts.duration,
        opts.deep.layers,
        opts.deep.hidden,
        opts.deep.extra,
        opts.deep.horizon,
        opts.deep.resolve_every
    );
    let m = train_models(opts, &mut progress_bar).map_err(|e| format!("training failed: {e}"))?;
    eprintln!();
    Ok(m)
}

/// Prints the training report and the validation table, saves the model (and re-reads it).
fn report_and_save(m: &TrainedModels, out: &Path, json: Option<&Path>, secs: f64) -> Result<(), String> {
    if let Some(r) = &m.report {
        println!(
            "trained in {secs:.1} s ({} epochs, best {}, {} training / {} validation windows)",
            r.epochs, r.best_epoch, r.train_windows, r.valid_windows
        );
    }
    if m.validation.is_empty() {
        println!("validation: no held-out data long enough for the longest horizon");
    }
    println!("validation (held-out runs or the last quarter of recorded tracks; attitude error median):");
    println!("| horizon [s] | deep [rad] | constant body rate [rad] | RMSE (q, w) | n |");
    println!("|---|---|---|---|---|");
    for v in &m.validation {
        println!(
            "| {} | {:.4} | {:.4} | {:.4} | {} |",
            v.horizon_s, v.att_err_rad, v.cv_att_err_rad, v.rmse, v.n
        );
    }
    m.save(out).map_err(|e| format!("write {}: {e}", out.display()))?;
    let size = std::fs::metadata(out).map(|m| m.len()).unwrap_or(0);
    println!("saved {} ({size} bytes)", out.display());
    // Read it back: what we wrote is what a predictor will load.
    TrainedModels::load(out).map_err(|e| format!("re-reading {}: {e}", out.display()))?;
    if let Some(j) = json {
        let v = serde_json::json!({
            "seconds": secs,
            "validation": m.validation,
            "model": out.display().to_string(),
        });
        std::fs::write(j, serde_json::to_string_pretty(&v).unwrap())
            .map_err(|e| format!("write {}: {e}", j.display()))?;
    }
    Ok(())
}

/// Runs the accuracy study, prints the table, writes the JSON rows.
pub fn predict_eval(
    size: &str,
    model: Option<&str>,
    scenes: Option<Vec<String>>,
    methods: Option<Vec<String>>,
    seed: u64,
    json: Option<&Path>,
    visual_model: Option<&str>,
) -> Result<(), String> {
    let mut cfg = match size {
        "small" => StudyConfig::small(),
        "full" => StudyConfig::full(),
        _ => StudyConfig::medium(),
    };
    // The study's runs use seeds `seed .. seed + 10 000 · scenes + 1 000 + runs`; the deep
    // model's training data start at 1 000 000: keep them disjoint.
    if seed > 900_000 {
        return Err(format!(
            "--seed {seed}: must be at most 900000 (the deep model's training runs use seeds from 1000000)"
        ));
    }
    cfg.seed = seed;
    // The rows are written at the end: a path that cannot take them is refused first.
    if let Some(j) = json {
        crate::launch::check_writable(j).map_err(|e| format!("--json {}: {e}", j.display()))?;
    }
    if let Some(s) = scenes {
        crate::study::no_repeats("--scenes", &s)?;
        for name in &s {
            dkrrt_debris::Scene::named(name).map_err(|e| format!("--scenes: {e}"))?;
        }
        cfg.scenes = s;
    }
    if let Some(ms) = methods {
        crate::study::no_repeats("--methods", &ms)?;
        cfg.methods = ms
            .iter()
            .map(|n| {
                Method::from_name(n).ok_or_else(|| {
                    let all: Vec<&str> = Method::ALL.iter().map(|m| m.name()).collect();
                    format!("--methods: unknown method {n:?} (one of {})", all.join(", "))
                })
            })
            .collect::<Result<_, _>>()?;
    }
    let deep = if cfg.methods.iter().any(|m| m.deep()) {
        Some(match model {
            Some("train") => train_models(&cfg.deep_train, &mut progress_bar).map_err(|e| e.to_string())?,
            Some(p) => TrainedModels::load(Path::new(p)).map_err(|e| format!("--model {p}: {e}"))?,
            None => {
                let mut sc = dkrrt_config::Scenario::default_scenario();
                sc.predictor.model.clear();
                dkrrt_planner::predict::load_trained(&sc)?
            }
        })
    } else {
        None
    };
    let t = std::time::Instant::now();
    // The depth camera's view of the same held-out runs, for the planner's predictor (issue
    // #15): the cube rig of the default camera through the classical front end, and through
    // the front end whose attitudes the learned visual features f_θ read (when the shipped
    // visual model is there).
    let camera = dkrrt_config::Scenario::default_scenario().camera;
    let rig = crate::depth_view::cube_rig(&camera);
    let classical = || dkrrt_depthpose::perception::DepthPerception::default();
    let rec = |sc: &dkrrt_debris::Scene, seed: u64, dur: f64, dt: f64| {
        crate::depth_view::record_depth(sc, seed, dur, dt, &rig, &classical)
    };
    let visual = match visual_model {
        Some("none") => None,
        Some(p) => Some(dkrrt_visual::file::load(Path::new(p)).map_err(|e| format!("--visual-model {e}"))?),
        None => Some(dkrrt_planner::predict::embedded_visual()?),
    };
    // The learned front end exists only with a visual model.
    let rec_visual = visual.as_ref().map(|net| {
        let learned = move || dkrrt_planner::predict::learned_perception(net.clone());
        let rig = &rig;
        move |sc: &dkrrt_debris::Scene, seed: u64, dur: f64, dt: f64| {
            crate::depth_view::record_depth(sc, seed, dur, dt, rig, &learned)
        }
    });
    let mut depth_pred = cfg.predictor;
    dkrrt_planner::predict::for_depth(&mut depth_pred, &camera);
    let mut views: Vec<View> = Vec::new();
    for &method in cfg.methods.iter().filter(|m| **m == Method::DeepKoopmanOnline) {
        views.push(View { name: "depth", method, predictor: depth_pred, record: &rec });
        if let Some(r) = &rec_visual {
            views.push(View { name: "visual", method, predictor: depth_pred, record: r });
        }
    }
    let rows = run_study_views(&cfg, deep.as_ref(), &views).map_err(|e| e.to_string())?;
    println!("{}", markdown_table(&rows));
    println!(
        "{} scenes x {} methods, {} training + {} held-out runs of {} s per scene, seed {}, {:.1} s",
        cfg.scenes.len(),
        cfg.methods.len(),
        cfg.train_runs,
        cfg.test_runs,
        cfg.duration,
        cfg.seed,
        t.elapsed().as_secs_f64()
    );
    if rows.iter().any(|r| r.method == Method::DeepKoopmanOnline.name()) {
        println!("\n{}", dkrrt_predictor::eval::calibration_text(&rows, Method::DeepKoopmanOnline.name()));
    }
    let cmp = dkrrt_predictor::eval::deep_vs_edmd(&rows, 2.0);
    if !cmp.is_empty() {
        println!("\n{}", dkrrt_predictor::eval::deep_vs_edmd_text(&cmp));
    }
    if let Some(j) = json {
        std::fs::write(j, serde_json::to_string_pretty(&rows).unwrap())
            .map_err(|e| format!("write {}: {e}", j.display()))?;
        println!("rows: {}", j.display());
    }
    Ok(())
}
