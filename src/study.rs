//! `dkrrt study`: threat episodes run in lockstep, one row per (scene, episode, method).
//!
//! Every method runs the same episodes (same generated start, goal and debris). The predictor
//! never sees an episode before it runs: its models are fitted once, on generic random scenes
//! (`predictor.fit = "generic"`), plus the shipped deep model; during the episode it refines
//! online from the observations only. Episodes run in parallel on the available cores; each
//! row is appended to the JSON-lines file `<json>.rows` as it finishes (an interrupted study
//! keeps them), and the JSON file gets all rows at the end.

use std::io::Write;
use std::path::Path;
use std::sync::Mutex;

use dkrrt_config::{EpisodeCfg, Forecasts, Scenario, PLANNER_METHODS};
use dkrrt_predictor::Models;
use serde::Serialize;

use crate::lockstep::Lockstep;

/// Plan compute time summary, ms.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct PlanMs {
    pub p50: f64,
    pub p99: f64,
    pub max: f64,
}

/// One episode of one method.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    pub scene: String,
    pub episode: u64,
    pub method: String,
    /// Goal reached (every joint within 0.01 rad) before the time limit, no contact at any tick.
    pub completed: bool,
    pub collision: bool,
    pub time_to_goal_s: Option<f64>,
    pub min_distance_m: Option<f64>,
    pub replans: u64,
    /// Execution error: the joint tracking error (measured vs reference), RMS and max, rad.
    pub tracking_error_rad_rms: f64,
    pub tracking_error_rad_max: f64,
    /// End-effector path error, desired vs real, RMS and max, m.
    pub ee_path_error_m_rms: f64,
    pub ee_path_error_m_max: f64,
    /// Joint-space length of the real motion, rad.
    pub path_length_rad: f64,
    /// The planner's smallest predicted clearance of its active plans, m.
    pub min_predicted_clearance_m: Option<f64>,
    pub plan_ms: PlanMs,
    pub first_plan_ms: Option<f64>,
    pub fallbacks_keep: u64,
    pub fallbacks_escape: u64,
    pub fallbacks_brake: u64,
    pub fallbacks_dodge: u64,
    pub deadline_misses: u64,
    pub safe_holds: u64,
    pub straight_duration_s: f64,
    pub time_limit_s: f64,
    /// Plant seconds simulated and the wall time they took (lockstep only), and the wall time
    /// of generating the episode.
    pub plant_s: f64,
    pub wall_s: f64,
    pub episode_gen_s: f64,
    /// Planner cycles that read an older forecast than the process set would have (the
    /// lockstep builds only the forecasts the planner reads: `PredictorFigures::stale_reads`).
    pub stale_forecast_reads: u64,
    /// Configurations the planner checked (its work, the same on any machine).
    pub planner_configs: u64,
    /// Forecasts the planner refused (by the message contract, or stamped ahead of the plant
    /// clock), and why the newest was: in the process set each is a rejected message that
    /// fails the run's verdict.
    pub forecasts_refused: u64,
    pub forecast_error: Option<String>,
    pub error: Option<String>,
}

impl Row {
    /// A row with nothing measured yet (not completed, no collision, no figures).
    pub fn empty(scene: &str, index: u64, method: &str) -> Row {
        Row {
            scene: scene.to_string(),
            episode: index,
            method: method.to_string(),
            completed: false,
            collision: false,
            time_to_goal_s: None,
            min_distance_m: None,
            replans: 0,
            tracking_error_rad_rms: 0.0,
            tracking_error_rad_max: 0.0,
            ee_path_error_m_rms: 0.0,
            ee_path_error_m_max: 0.0,
            path_length_rad: 0.0,
            min_predicted_clearance_m: None,
            plan_ms: PlanMs::default(),
            first_plan_ms: None,
            fallbacks_keep: 0,
            fallbacks_escape: 0,
            fallbacks_brake: 0,
            fallbacks_dodge: 0,
            deadline_misses: 0,
            safe_holds: 0,
            straight_duration_s: 0.0,
            time_limit_s: 0.0,
            plant_s: 0.0,
            wall_s: 0.0,
            episode_gen_s: 0.0,
            stale_forecast_reads: 0,
            planner_configs: 0,
            forecasts_refused: 0,
            forecast_error: None,
            error: None,
        }
    }
}

/// The study's options.
#[derive(Debug, Clone)]
pub struct StudyOptions {
    pub scenes: Vec<String>,
    pub episodes: u64,
    pub methods: Vec<String>,
    pub seed: u64,
    pub threads: usize,
    /// Episodes' goals as end-effector poses (`[episode] pose_goal`), else joint goals.
    pub pose_goals: bool,
    /// Train the deep attitude network first (as `dkrrt train` does, timed) and plan dk-rrt
    /// on it, instead of the shipped one.
    pub train_deep: bool,
    /// The scenario file the episodes are built on (its camera, limits, predictor and
    /// planner settings; its `[episode]` is replaced by each generated one); `None`: the
    /// embedded default.
    pub scenario: Option<String>,
}

/// The base scenario of every episode: the embedded default, with the predictor fitted on
/// generic scenes and real-time options off (lockstep).
pub fn base_scenario() -> Scenario {
    as_study_base(Scenario::default_scenario())
}

/// The base scenario of the study's episodes: [`StudyOptions::scenario`] or the embedded
/// default, made a study base as [`base_scenario`] is.
pub fn base_scenario_of(opts: &StudyOptions) -> Result<Scenario, String> {
    match &opts.scenario {
        None => Ok(base_scenario()),
        Some(path) => {
            let sc = Scenario::load(path).map_err(|e| format!("--scenario: {e}"))?;
            Ok(as_study_base(sc))
        }
    }
}

fn as_study_base(mut sc: Scenario) -> Scenario {
    sc.predictor.fit = "generic".into();
    sc.run.mode = dkrrt_config::Mode::Lockstep;
    sc.episode = None;
    sc
}

/// A scene file a study can build episodes on: an absolute path (the episodes' scenarios
/// resolve relative paths against their own directory; `dkrrt study` makes a command-line
/// path absolute) that loads as a scene.
fn scene_file_ok(s: &str) -> bool {
    std::path::Path::new(s).is_absolute()
        && dkrrt_config::is_scene_path(s)
        && dkrrt_debris::Scene::from_file(s).is_ok()
}

/// The scenario of one episode (generated: start, goal, debris), with its episode.
pub fn episode_scenario(
    base: &Scenario,
    scene: &str,
    index: u64,
    seed: u64,
    pose_goal: bool,
) -> Result<(Scenario, dkrrt_episodes::Episode), String> {
    let mut sc = base.clone();
    sc.episode = Some(EpisodeCfg {
        scene: scene.to_string(),
        index,
        seed,
        duration_s: None,
        pose_goal,
        max_straight_s: None,
    });
    let ep = dkrrt_episodes::resolve(&mut sc)?.ok_or("no episode")?;
    Ok((sc, ep))
}

/// Runs one episode of one method to its end (goal, contact or time limit). `episode`: the
/// generated episode (or why it could not be). `ahead`: step the debris side on a second
/// thread where the run allows it ([`Lockstep::run_ahead`]; the same run).
pub fn run_episode(
    episode: &Result<(Scenario, dkrrt_episodes::Episode), String>,
    scene: &str,
    index: u64,
    method: &str,
    models: Option<&Models>,
    ahead: bool,
) -> Row {
    let t_wall = std::time::Instant::now();
    let mut row = Row::empty(scene, index, method);
    let res = (|| -> Result<(), String> {
        let (sc, ep) = episode.as_ref().map_err(|e| e.clone())?;
        let mut sc = sc.clone();
        set_method(&mut sc, method);
        row.straight_duration_s = ep.straight_duration_s;
        row.time_limit_s = ep.time_limit_s;
        let mut ls = Lockstep::with_models(&sc, models.cloned())?;
        if ahead {
            ls.run_ahead(&sc)?;
        }
        let ticks = (ep.time_limit_s * sc.run.control_hz).round() as u64;
        for _ in 0..ticks {
            ls.tick(true);
            if ls.collided() || ls.goal_reached_s.is_some() {
                break;
            }
        }
        let r = ls.report(&sc);
        row.collision = ls.collided();
        row.time_to_goal_s = ls.goal_reached_s;
        row.completed = !row.collision && ls.goal_reached_s.is_some_and(|t| t <= ep.time_limit_s);
        row.min_distance_m = r.debris.and_then(|d| d.min_distance_m);
        row.safe_holds = r.safe_hold_entries;
        row.tracking_error_rad_rms = r.tracking_error_rad_rms;
        row.tracking_error_rad_max = r.tracking_error_rad_max;
        row.ee_path_error_m_rms = r.motion.ee_path_error_m_rms;
        row.ee_path_error_m_max = r.motion.ee_path_error_m_max;
        row.path_length_rad = r.motion.path_length_rad;
        row.plant_s = r.ticks as f64 * sc.period_ns() as f64 * 1e-9;
        row.stale_forecast_reads = r.predictor.as_ref().map_or(0, |p| p.stale_reads);
        if let Some(p) = r.planner {
            row.replans = p.replans;
            row.plan_ms = PlanMs { p50: p.plan_ms.p50, p99: p.plan_ms.p99, max: p.plan_ms.max };
            row.first_plan_ms = p.first_plan_ms;
            row.fallbacks_keep = p.fallbacks.keep;
            row.fallbacks_escape = p.fallbacks.escape;
            row.fallbacks_brake = p.fallbacks.brake;
            row.fallbacks_dodge = p.fallbacks.dodge;
            row.deadline_misses = p.deadline_misses;
            row.min_predicted_clearance_m = p.min_predicted_clearance_m;
            row.planner_configs = p.configs_checked;
            row.forecasts_refused = p.forecasts_ahead + p.forecasts_invalid;
            row.forecast_error = p.forecast_error;
        }
        Ok(())
    })();
    row.error = res.err();
    row.wall_s = t_wall.elapsed().as_secs_f64();
    row
}

/// One method's forecast model, fitted once for the whole study, and what it cost.
pub struct MethodFit {
    pub planner_method: String,
    /// The predictor method it forecasts with (`none`, `truth`, or a predictor method).
    pub predictor_method: String,
    pub models: Option<Models>,
    /// Seconds to fit the method's models at start-up (on generic scenes, never an evaluated
    /// episode): the EDMD / dual-data regressions, and for the deep method the fit of the
    /// translation model around the shipped attitude network (whose own training is `dkrrt
    /// train`'s, not repeated here).
    pub fit_s: f64,
    /// Whether the method plans on the model's forecasts (else the fit serves only the
    /// predictor's filtering, and its cost is not the method's).
    pub forecasts_with_model: bool,
    /// Seconds the deep network's training took in this study (`--train-deep`), for the
    /// methods that use it.
    pub train_s: Option<f64>,
}

/// What each method's models cost, for the summary.
pub fn fit_costs(fits: &[MethodFit]) -> Vec<crate::study_report::FitCost> {
    fits.iter()
        .map(|f| crate::study_report::FitCost {
            method: f.planner_method.clone(),
            forecasts: f.predictor_method.clone(),
            fit_s: if f.forecasts_with_model { f.fit_s } else { 0.0 },
            train_s: f.train_s,
        })
        .collect()
}

/// Fits every method's models once (methods on the same predictor method share the fit and
/// its time).
pub fn fit_methods(
    base: &Scenario,
    methods: &[String],
    trained: Option<(&dkrrt_predictor::training::TrainedModels, f64)>,
) -> Result<Vec<MethodFit>, String> {
    let mut out: Vec<MethodFit> = Vec::new();
    for m in methods {
        let mut sc = base.clone();
        set_method(&mut sc, m);
        // What the method forecasts with, and the predictor models its run needs (the
        // straight method plans on nothing but keeps the default predictor running, for the
        // report; rrt-static uses the predictor's filtered poses only).
        let (label, fit_method) = match sc.forecasts() {
            Forecasts::None => ("none".to_string(), Some(base.predictor_method().to_string())),
            Forecasts::Oracle => ("truth".to_string(), None),
            Forecasts::Static => {
                ("latest estimate, held".to_string(), Some(sc.predictor_method().to_string()))
            }
            Forecasts::Predictor => {
                (sc.predictor_method().to_string(), Some(sc.predictor_method().to_string()))
            }
        };
        let uses_model = matches!(sc.forecasts(), Forecasts::Predictor);
        let (models, fit_s) = match fit_method {
            None => (None, 0.0),
            Some(fm) => {
                let shared = out.iter().find(|f| f.models.as_ref().is_some_and(|x| x.method.name() == fm));
                match shared {
                    Some(f) => (f.models.clone(), f.fit_s),
                    None => {
                        let mut fs = base.clone();
                        fs.predictor.method = fm;
                        fs.planner.method = "dk-rrt".into();
                        let t = std::time::Instant::now();
                        let models = dkrrt_planner::predict::fit_models_with(&fs, trained.map(|t| t.0))?;
                        (Some(models), t.elapsed().as_secs_f64())
                    }
                }
            }
        };
        let deep = models.as_ref().is_some_and(|m| m.method.deep());
        out.push(MethodFit {
            planner_method: m.clone(),
            predictor_method: label,
            models,
            fit_s,
            forecasts_with_model: uses_model,
            train_s: trained.filter(|_| uses_model && deep).map(|t| t.1),
        });
    }
    Ok(out)
}

/// The camera variant of dk-rrt (issue #15): the same planner and predictor, the predictor
/// seeing the debris through the sim's depth camera (`predictor.input = "depth"`, the
/// scenario's `[camera]`) instead of the pose sensor. Not in the default method list.
pub const DK_RRT_DEPTH: &str = "dk-rrt-depth";
/// [`DK_RRT_DEPTH`] with the learned front end (the shipped visual features f_θ read each
/// object's axes and class, `predictor.front_end = "learned"`). Not in the default list.
pub const DK_RRT_VISUAL: &str = "dk-rrt-visual";

/// Sets the scenario of a study method: a planning method, [`DK_RRT_DEPTH`] or
/// [`DK_RRT_VISUAL`].
pub fn set_method(sc: &mut Scenario, method: &str) {
    if method == DK_RRT_DEPTH || method == DK_RRT_VISUAL {
        sc.planner.method = "dk-rrt".into();
        sc.predictor.input = "depth".into();
        if method == DK_RRT_VISUAL {
            sc.predictor.front_end = "learned".into();
        }
    } else {
        sc.planner.method = method.to_string();
    }
}

/// Refuses a list that names an item twice (`flag` names the option): a scene or method
/// given twice would run and count its episodes twice.
pub fn no_repeats(flag: &str, items: &[String]) -> Result<(), String> {
    for (i, a) in items.iter().enumerate() {
        if items[..i].contains(a) {
            return Err(format!("{flag}: {a:?} is given twice"));
        }
    }
    Ok(())
}

/// Runs the study; rows stream to `rows_path` (JSON lines) as they finish.
pub fn run(
    opts: &StudyOptions,
    rows_path: Option<&Path>,
    progress: bool,
) -> Result<(Vec<Row>, Vec<MethodFit>), String> {
    if opts.episodes == 0 {
        return Err("--episodes 0: a study needs at least one episode per scene".into());
    }
    if opts.threads == 0 {
        return Err("--threads 0: a study needs at least one worker thread".into());
    }
    no_repeats("--scenes", &opts.scenes)?;
    no_repeats("--methods", &opts.methods)?;
    for s in &opts.scenes {
        if !dkrrt_debris::SCENE_NAMES.contains(&s.as_str()) && !scene_file_ok(s) {
            return Err(format!(
                "--scenes: unknown scene {s:?} ({}, or a scene file: an absolute path ending in .toml)",
                dkrrt_debris::SCENE_NAMES.join(", ")
            ));
        }
    }
    for m in &opts.methods {
        if !PLANNER_METHODS.contains(&m.as_str()) && m != DK_RRT_DEPTH && m != DK_RRT_VISUAL {
            return Err(format!(
                "--methods: unknown method {m:?} ({}, {DK_RRT_DEPTH}, {DK_RRT_VISUAL})",
                PLANNER_METHODS.join(", ")
            ));
        }
    }
    let base = base_scenario_of(opts)?;
    let trained = if opts.train_deep {
        // As `dkrrt train` with its defaults: the same data, the same network.
        let t = std::time::Instant::now();
        eprintln!("study: training the deep attitude network (dkrrt train's defaults)...");
        let m = dkrrt_predictor::training::train_models(
            &dkrrt_predictor::training::TrainOptions::default(),
            &mut |_| {},
        )
        .map_err(|e| format!("--train-deep: {e}"))?;
        let s = t.elapsed().as_secs_f64();
        eprintln!("study: trained in {s:.1} s");
        Some((m, s))
    } else {
        None
    };
    let fits = fit_methods(&base, &opts.methods, trained.as_ref().map(|(m, s)| (m, *s)))?;
    let models_of = |m: &str| fits.iter().find(|f| f.planner_method == m).and_then(|f| f.models.as_ref());
    // One job per episode: it is generated once and run with every method.
    let mut jobs = Vec::new();
    for s in &opts.scenes {
        for e in 0..opts.episodes {
            jobs.push((s.clone(), e));
        }
    }
    let sink = match rows_path {
        Some(p) => Some(std::fs::File::create(p).map_err(|e| format!("{}: {e}", p.display()))?),
        None => None,
    };
    let total = jobs.len() * opts.methods.len();
    let state = Mutex::new((0usize, Vec::with_capacity(total), sink));
    let next = Mutex::new(0usize);
    let threads = opts.threads.max(1).min(jobs.len().max(1));
    // A core left free by the episode workers steps each episode's debris side ahead.
    let ahead = threads < std::thread::available_parallelism().map_or(1, |n| n.get());
    // A bar with the ETA on a terminal; the per-episode lines above it (or alone, in a log).
    let bar =
        if progress { indicatif::ProgressBar::new(total as u64) } else { indicatif::ProgressBar::hidden() };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "study [{bar:30}] {pos}/{len} episode runs, {elapsed} elapsed, ETA {eta}  {msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    let t0 = std::time::Instant::now();
    std::thread::scope(|s| {
        for _ in 0..threads {
            s.spawn(|| loop {
                let i = {
                    let mut n = next.lock().unwrap();
                    let i = *n;
                    *n += 1;
                    i
                };
                let Some((scene, e)) = jobs.get(i) else { break };
                let t_gen = std::time::Instant::now();
                let episode = episode_scenario(&base, scene, *e, opts.seed, opts.pose_goals);
                let gen_s = t_gen.elapsed().as_secs_f64();
                for m in &opts.methods {
                    let mut row = run_episode(&episode, scene, *e, m, models_of(m), ahead);
                    row.episode_gen_s = gen_s;
                    let mut st = state.lock().unwrap();
                    st.0 += 1;
                    if let Some(f) = st.2.as_mut() {
                        let _ = writeln!(f, "{}", serde_json::to_string(&row).unwrap_or_default());
                    }
                    if progress {
                        let el = t0.elapsed().as_secs_f64();
                        let eta = el / st.0 as f64 * (total - st.0) as f64;
                        let line = format!(
                            "study: [{}/{total}] {} #{} {}: {}{} ({:.1} s plant in {:.2} s; ETA {:.0} s)",
                            st.0,
                            row.scene,
                            row.episode,
                            row.method,
                            if row.completed {
                                "completed"
                            } else if row.collision {
                                "COLLISION"
                            } else {
                                "not completed"
                            },
                            row.error.as_deref().map(|e| format!(" error: {e}")).unwrap_or_default(),
                            row.plant_s,
                            row.wall_s,
                            eta
                        );
                        if bar.is_hidden() {
                            eprintln!("{line}");
                        } else {
                            bar.println(line);
                        }
                        bar.set_message(format!("{} #{} {}", row.scene, row.episode, row.method));
                        bar.inc(1);
                    }
                    st.1.push(row);
                }
            });
        }
    });
    bar.finish_and_clear();
    let mut rows = state.into_inner().map_err(|e| e.to_string())?.1;
    rows.sort_by(|a, b| {
        (a.scene.as_str(), a.episode, a.method.as_str()).cmp(&(
            b.scene.as_str(),
            b.episode,
            b.method.as_str(),
        ))
    });
    Ok((rows, fits))
}

/// The per-scene table.
pub fn table(rows: &[Row], scenes: &[String], methods: &[String]) -> String {
    let mut s = String::from(
        "scene          method    episodes  completed  collisions  time-to-goal s (median)  plan ms, worst episode p50 / p99 / max  replans (mean)  lockstep speed\n",
    );
    for sc in scenes {
        for m in methods {
            let r: Vec<&Row> = rows.iter().filter(|r| &r.scene == sc && &r.method == m).collect();
            if r.is_empty() {
                continue;
            }
            let n = r.len();
            let done = r.iter().filter(|x| x.completed).count();
            let col = r.iter().filter(|x| x.collision).count();
            let mut tg: Vec<f64> =
                r.iter().filter_map(|x| x.time_to_goal_s.filter(|_| x.completed)).collect();
            tg.sort_by(f64::total_cmp);
            let med = tg.get(tg.len() / 2).copied();
            let p50 = r.iter().map(|x| x.plan_ms.p50).fold(0.0, f64::max);
            let p99 = r.iter().map(|x| x.plan_ms.p99).fold(0.0, f64::max);
            let mx = r.iter().map(|x| x.plan_ms.max).fold(0.0, f64::max);
            let replans = r.iter().map(|x| x.replans as f64).sum::<f64>() / n as f64;
            let speed =
                r.iter().map(|x| x.plant_s).sum::<f64>() / r.iter().map(|x| x.wall_s).sum::<f64>().max(1e-9);
            s.push_str(&format!(
                "{sc:<14} {m:<9} {n:>8}  {:>8.1}%  {:>6} ({:>3.0}%)  {:>23}  {:>21.2} / {:>6.2} / {:>6.2}  {:>14.1}  {:>10.0}x\n",
                100.0 * done as f64 / n as f64,
                col,
                100.0 * col as f64 / n as f64,
                med.map_or("-".into(), |v| format!("{v:.2}")),
                p50,
                p99,
                mx,
                replans,
                speed
            ));
        }
    }
    s
}

/// Re-runs one episode of one method with a trace (for the figures): the same episode and
/// models as in the study, so the same outcome.
pub fn trace_episode(
    opts: &StudyOptions,
    fits: &[MethodFit],
    scene: &str,
    index: u64,
    method: &str,
) -> Result<crate::figures::EpisodeTrace, String> {
    let base = base_scenario_of(opts)?;
    let fit =
        fits.iter().find(|f| f.planner_method == method).ok_or_else(|| format!("no fit for {method}"))?;
    let (sc, ep) = episode_scenario(&base, scene, index, opts.seed, opts.pose_goals)?;
    let mut sc = sc;
    set_method(&mut sc, method);
    let mut ls = Lockstep::with_models(&sc, fit.models.clone())?;
    ls.keep_trace(ep.time_limit_s + 1.0);
    let ticks = (ep.time_limit_s * sc.run.control_hz).round() as u64;
    for _ in 0..ticks {
        ls.tick(true);
        if ls.collided()
            || ls.goal_reached_s.is_some_and(|t| ls.sim.plant.tick() as f64 / sc.run.control_hz > t + 1.0)
        {
            break;
        }
    }
    Ok(crate::figures::EpisodeTrace {
        scene: scene.to_string(),
        episode: index,
        method: method.to_string(),
        samples: ls.trace.take().unwrap_or_default(),
        debris: std::mem::take(&mut ls.debris_trace),
        v_max: sc.motion.v_max,
        a_max: sc.motion.a_max,
        j_max: sc.motion.j_max,
        margin_m: sc.planner.margin_m,
    })
}
