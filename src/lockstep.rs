//! In-process lockstep evaluation: the same sim, tracker, predictor and planner cores as the
//! processes, wired directly (no IPC, no clock), with the same timing contract. Deterministic:
//! the same scenario gives the same numbers.
//!
//! The trajectory source is the scenario's `planner.method`: `straight` (the goto core: one
//! jerk-limited line to the goal, planned from the first state) or one of the replanning
//! methods (the replanning core, one cycle every `1/planner.rate_hz` of plant time with
//! `planner.iterations` of work) on the forecasts the method names
//! ([`dkrrt_config::Forecasts`]): the predictor's (`cv-rrt`, `edmd-rrt`, `dk-rrt`), the
//! latest estimates held still (`rrt-static`), or the true future (`oracle-rrt`, from a
//! [`TruthTable`] recorded at start-up, on the predictor's schedule).
//! A plan computed from the state at plant time `t` starts at `t + planner.commit_ms`, as in
//! real time, so lockstep results carry the real-time latency.

use dkrrt_config::arm::contract_limits;
use dkrrt_config::{Forecasts, GoalRequest, Scenario};
use dkrrt_model::ArmModel;
use dkrrt_msg::{ContractLimits, ControllerMode, DebrisForecast, DebrisObservation, Trajectory, Zeroed, NJ};
use dkrrt_otg::Limits;
use dkrrt_planner::goto::Goto;
use dkrrt_planner::predict::{fit_models, Cadence, ObsCounters, PredictorCore};
use dkrrt_planner::replan::replanner;
use dkrrt_predictor::{GateStats, Models};
use dkrrt_rrt::{Replanner, Summary, TrackerView};
use dkrrt_sim::core::SimCore;
use dkrrt_sim::debris::DebrisStats;
use dkrrt_sim::oracle::TruthTable;
use dkrrt_sim::plant::PlantStats;
use dkrrt_tracker::ctrl::{ModeEvent, Tracker, TrackerConfig};

/// Result of an in-process run.
#[derive(Debug, Clone, serde::Serialize)]
pub struct EvalReport {
    pub method: String,
    pub ticks: u64,
    pub trajectory_duration_s: f64,
    pub tracking_error_rad_rms: f64,
    pub tracking_error_rad_max: f64,
    pub final_error_rad: f64,
    pub safe_hold_entries: u64,
    /// Plant time the arm was first within the goal tolerance (every joint), s.
    pub goal_reached_s: Option<f64>,
    pub events: Vec<ModeEvent>,
    pub plant: PlantStats,
    pub final_q: [f64; NJ],
    /// Debris side (closest approach, contacts), `null` without debris.
    pub debris: Option<DebrisStats>,
    /// Predictor figures, `null` without debris.
    pub predictor: Option<PredictorFigures>,
    /// The depth camera's frames (`null` when off).
    pub camera: Option<dkrrt_sim::camera::CameraStats>,
    /// Planner figures, `null` for the straight method.
    pub planner: Option<Summary>,
    /// Path figures of the real motion.
    pub motion: MotionFigures,
    /// Whether the run did what was asked: every check below passed.
    pub ok: bool,
    /// The checks of a process-set run ([`crate::verdict`]) that apply in process: the goal,
    /// no collision, the joint limits, no safe hold or brake.
    pub checks: Vec<crate::verdict::Check>,
}

/// The in-process checks of a run ([`crate::verdict::checks`] on the report's figures; the
/// checks about processes and messages have nothing to check without them).
fn in_process_checks(sc: &Scenario, r: &EvalReport) -> Vec<crate::verdict::Check> {
    use serde_json::{json, to_value, Value};
    let sim = json!({ "plant": r.plant, "debris": r.debris });
    let tr = json!({ "final_error_rad": r.final_error_rad, "safe_hold_entries": r.safe_hold_entries });
    let plan = to_value(&r.planner).unwrap_or(Value::Null);
    let end = crate::verdict::Ending::default();
    let all = crate::verdict::checks(sc, &end, &sim, &tr, &Value::Null, &plan, &Value::Null);
    const IN_PROCESS: [&str; 4] = ["goal_reached", "no_collision", "joint_limits", "safe_holds"];
    all.into_iter().filter(|c| IN_PROCESS.contains(&c.name)).collect()
}

/// Ticks between end-effector samples (path error, traces): 10 ms at 1 kHz.
pub const SAMPLE_TICKS: u64 = 10;

/// Path figures of a run: the end effector's desired (the tracker's reference) vs real path,
/// sampled every [`SAMPLE_TICKS`] ticks (the paper's Fig. 2 error), and the joint-space path
/// length of the real motion (every tick).
#[derive(Debug, Clone, Copy, Default, serde::Serialize)]
pub struct MotionFigures {
    /// RMS and max distance between the desired and the real end-effector position, m.
    pub ee_path_error_m_rms: f64,
    pub ee_path_error_m_max: f64,
    /// Σ ‖q_{k+1} − q_k‖ over the run, rad.
    pub path_length_rad: f64,
    #[serde(skip)]
    ee_sum_sq: f64,
    #[serde(skip)]
    ee_n: u64,
}

/// One sample of a run's trace (every [`SAMPLE_TICKS`] ticks; for the figures).
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct TraceSample {
    pub t_s: f64,
    /// True joint positions and velocities.
    pub q: [f64; NJ],
    pub qd: [f64; NJ],
    /// The tracker's reference: positions, velocities, accelerations (none while idle).
    pub q_des: Option<[f64; NJ]>,
    pub qd_des: Option<[f64; NJ]>,
    pub qdd_des: Option<[f64; NJ]>,
    /// Real and desired end-effector positions, m (base frame).
    pub ee: [f64; 3],
    pub ee_des: Option<[f64; 3]>,
    /// True smallest arm–debris separation, m.
    pub true_distance_m: Option<f64>,
    /// The planner's predicted clearance of the real configuration (forecast bound and margin
    /// included), m.
    pub predicted_clearance_m: Option<f64>,
}

/// What the in-process predictor did.
#[derive(Debug, Clone, serde::Serialize)]
pub struct PredictorFigures {
    pub method: String,
    pub forecasts: u64,
    pub tracks: u32,
    pub observations: ObsCounters,
    pub gate: GateStats,
    /// Of `forecasts`, those nobody was going to read (a newer one came before the planner's
    /// next cycle, or no planner reads them): only their calibration was done.
    pub deferred: u64,
    /// Planner cycles that read an older forecast than the process set would have (the
    /// newest one had been deferred and no newer one came): 0 unless the input stalled.
    pub stale_reads: u64,
}

/// The predictor, wired in process.
pub struct PredictorLoop {
    pub core: PredictorCore,
    pub forecast: Box<DebrisForecast>,
    pub forecasts: u64,
    pub tracks: u32,
    /// A forecast newer than the planner's last cycle.
    pub fresh: bool,
    lim: ContractLimits,
    pub(crate) rate_hz: f64,
    /// Due forecasts that nobody was going to read: only their calibration was done
    /// ([`PredictorCore::observe_then_forecast_if`]).
    pub deferred: u64,
    /// Planner cycles whose latest due forecast had been deferred (the planner read an older
    /// one than the process set would have): 0 unless the input stalled longer than
    /// `read_window_ns`.
    pub stale_reads: u64,
    /// Defer the forecasts nobody reads (the default; `false`: build every one, as the
    /// predictor process does).
    pub lazy: bool,
    pub(crate) latest_deferred: bool,
    /// A due forecast is written when the planner's next cycle is at most this far ahead:
    /// the longest gap between due forecasts of the pose sensor (the slower of its and the
    /// forecast rate, plus its latency jitter), so a later one comes before the cycle unless
    /// the input stalls (then `stale_reads` counts it); through the depth camera, always.
    read_window_ns: u64,
}

impl PredictorLoop {
    /// Whether a forecast due now (`now_ns`) could be the one the planner reads at its next
    /// cycle (`None`: no planner reads forecasts).
    fn read(&self, now_ns: u64, next_cycle_ns: Option<u64>) -> bool {
        !self.lazy || next_cycle_ns.is_some_and(|c| c.saturating_sub(now_ns) <= self.read_window_ns)
    }

    /// Feeds one observation frame arriving at plant time `now_ns` (the planner's next cycle at
    /// `next_cycle_ns`): the forecast is written only if a cycle may read it
    /// ([`PredictorLoop::read`]), and the loop's figures counted. The one frame step of the
    /// serial lockstep and of the thread running ahead ([`crate::ahead`]).
    pub(crate) fn feed(&mut self, f: &DebrisObservation, now_ns: u64, next_cycle_ns: Option<u64>) -> Cadence {
        let read = self.read(now_ns, next_cycle_ns);
        let c = self.core.observe_then_forecast_if(f, &self.lim, self.rate_hz, &mut self.forecast, read);
        self.count(c);
        c
    }

    fn count(&mut self, c: Cadence) {
        match c {
            Cadence::Written(n) => {
                (self.forecasts, self.tracks, self.fresh, self.latest_deferred) =
                    (self.forecasts + 1, n as u32, true, false);
            }
            Cadence::CalibrationOnly(n) => {
                (self.forecasts, self.tracks, self.deferred, self.latest_deferred) =
                    (self.forecasts + 1, n as u32, self.deferred + 1, true);
            }
            _ => {}
        }
    }
}

/// The sim's depth camera, in process; with `predictor.input = "depth"` its frames reach the
/// predictor through the classical front end (`dkrrt_depthpose::perception`).
pub struct CameraLoop {
    pub side: dkrrt_sim::camera::CameraSide,
    renderers: Vec<dkrrt_sim::camera::Renderer>,
    snap: Box<dkrrt_sim::camera::Snapshot>,
    /// The predictor reads the camera, not the pose sensor.
    feeds_predictor: bool,
}

/// The true future, published on the predictor's plant-clock schedule (`oracle-rrt`).
pub struct OracleLoop {
    pub table: TruthTable,
    pub forecast: Box<DebrisForecast>,
    pub forecasts: u64,
    pub fresh: bool,
    rate_hz: f64,
    steps: usize,
    dt_s: f64,
    next_due_s: f64,
}

/// Seconds between the oracle's kept true poses (interpolated between).
pub const ORACLE_SAMPLE_S: f64 = 0.01;

/// A pose goal is reached with the end effector this close, m.
pub const EE_TOL_M: f64 = 0.01;
/// ... and this close in attitude, rad.
pub const EE_TOL_RAD: f64 = 0.02;

/// Position (m) and attitude (rad) error of the end effector at `q` from the pose `p`, `r`
/// (w, x, y, z).
pub fn ee_error(model: &ArmModel, q: &[f64; NJ], p: &[f64; 3], r: &[f64; 4]) -> (f64, f64) {
    let t = dkrrt_rrt::goal::target(p, r);
    let x = model.fk(&dkrrt_model::JVec::from_row_slice(q));
    ((x.translation.vector - t.translation.vector).norm(), x.rotation.angle_to(&t.rotation))
}

/// The trajectory source.
pub enum TrajSource {
    /// One jerk-limited line to the goal.
    Straight { core: Box<Goto>, traj: Box<Trajectory>, duration: f64 },
    /// The DK-RRT replanning loop.
    Planner { core: Box<Replanner>, out: Box<Trajectory> },
}

/// The wired cores, stepped one tick at a time.
pub struct Lockstep {
    pub sim: SimCore,
    pub tracker: Tracker,
    pub period_ns: u64,
    pub events: Vec<ModeEvent>,
    pub predictor: Option<PredictorLoop>,
    pub oracle: Option<OracleLoop>,
    /// The depth camera (`[camera] enabled` or `predictor.input = "depth"`).
    pub camera: Option<CameraLoop>,
    frame: Box<DebrisObservation>,
    pub source: TrajSource,
    /// The joint goal (a pose goal's IK solution).
    pub goal: [f64; NJ],
    /// The end-effector pose goal (position m, attitude (w, x, y, z)), if the scenario gave one.
    pub pose_goal: Option<([f64; 3], [f64; 4])>,
    model: ArmModel,
    goal_tol: f64,
    pub goal_reached_s: Option<f64>,
    started: bool,
    clock: fn() -> u64,
    motion: MotionFigures,
    prev_q: Option<[f64; NJ]>,
    /// The run's trace, if asked for ([`Lockstep::keep_trace`]).
    pub trace: Option<Vec<TraceSample>>,
    /// With the trace: every debris object's true position (base frame) per sample,
    /// `(t_s, id, p)`.
    pub debris_trace: Vec<(f64, u32, [f64; 3])>,
    /// The debris side and the predictor stepped ahead on a second thread
    /// ([`Lockstep::run_ahead`]).
    ahead: Option<crate::ahead::Ahead>,
}

fn mono_ns() -> u64 {
    dkrrt_rt::clock::mono_ns()
}

impl Lockstep {
    /// Builds the cores for `sc` (an `[episode]` must already be resolved). The predictor's
    /// models are fitted as the scenario says (`predictor.fit`).
    pub fn new(sc: &Scenario) -> Result<Lockstep, String> {
        let models =
            if sc.has_debris() && sc.forecasts() != Forecasts::Oracle { Some(fit_models(sc)?) } else { None };
        Self::with_models(sc, models)
    }

    /// As [`Lockstep::new`], with the predictor's models given (fitted once for many episodes).
    pub fn with_models(sc: &Scenario, models: Option<Models>) -> Result<Lockstep, String> {
        let model = sc.load_arm().map_err(|e| e.to_string())?;
        let oracle_wanted = sc.forecasts() == Forecasts::Oracle;
        if oracle_wanted && !sc.has_debris() {
            return Err("lockstep: oracle-rrt needs debris (debris.scene is empty)".into());
        }
        let predictor = match (sc.has_debris() && !oracle_wanted, models) {
            (false, _) => None,
            (true, Some(m)) => Some(PredictorLoop {
                core: PredictorCore::for_scenario(m, sc)?,
                forecast: Box::new(<DebrisForecast as Zeroed>::zeroed()),
                forecasts: 0,
                tracks: 0,
                fresh: false,
                lim: contract_limits(&model),
                rate_hz: sc.predictor.rate_hz,
                deferred: 0,
                stale_reads: 0,
                lazy: true,
                latest_deferred: false,
                read_window_ns: read_window_ns(sc),
            }),
            (true, None) => {
                return Err("lockstep: a scenario with debris needs the predictor's models".into())
            }
        };
        let sim = SimCore::new(sc, model.clone())?;
        let camera = if sc.camera_on() {
            Some(CameraLoop {
                side: dkrrt_sim::camera::CameraSide::new(&sc.camera)?,
                renderers: dkrrt_sim::camera::Renderer::rig(&sc.camera, sc.debris.base_lvlh)?,
                snap: Box::default(),
                feeds_predictor: sc.depth_input(),
            })
        } else {
            None
        };
        let oracle = match (&sim.debris, oracle_wanted) {
            (Some(d), true) => {
                let dt = sc.period_ns() as f64 * 1e-9;
                let horizon = sc.predictor.horizon_steps as f64 * sc.predictor.dt_s;
                let ticks = sc.ticks() + (horizon / dt).ceil() as u64;
                let every = ((ORACLE_SAMPLE_S / dt).round() as u64).max(1);
                Some(OracleLoop {
                    table: d.truth_table(dt, ticks, every),
                    forecast: Box::new(<DebrisForecast as Zeroed>::zeroed()),
                    forecasts: 0,
                    fresh: false,
                    rate_hz: sc.predictor.rate_hz,
                    steps: sc.predictor.horizon_steps as usize,
                    dt_s: sc.predictor.dt_s,
                    next_due_s: 0.0,
                })
            }
            _ => None,
        };
        let tracker = Tracker::new(model.clone(), TrackerConfig::from_scenario(sc));
        let req = sc.goal.request().ok_or("lockstep: the scenario gives no goal")?;
        let pose_goal = match req {
            GoalRequest::Pose(p, q) => Some((p, q)),
            GoalRequest::Joint(_) => None,
        };
        let unreachable = |p: &[f64; 3]| format!("lockstep: the pose goal at {p:?} is out of reach");
        // A pose goal is solved from the initial configuration, as the sources solve it at
        // their first state.
        let (source, goal) = if sc.replans() {
            // In process, the work per cycle is the iteration budget, never the wall clock.
            let mut core = Box::new(replanner(sc, model.clone()));
            core.cfg.enforce_deadline = false;
            let goal = match req {
                GoalRequest::Joint(q) => q,
                GoalRequest::Pose(p, q) => {
                    core.resolve_pose_goal(&p, &q, &sc.sim.initial_q, 0.0).ok_or_else(|| unreachable(&p))?
                }
            };
            (TrajSource::Planner { core, out: Box::new(<Trajectory as Zeroed>::zeroed()) }, goal)
        } else {
            let mut traj = Box::new(<Trajectory as Zeroed>::zeroed());
            let limits = Limits { v_max: sc.motion.v_max, a_max: sc.motion.a_max, j_max: sc.motion.j_max };
            // The same core as `dkrrt goto`: planned from the initial state, published at the
            // first tick; re-issued when the tracker holds short of the goal.
            let period = sc.period_ns() as f64 * 1e-9;
            let mut core = match req {
                GoalRequest::Joint(q) => Box::new(Goto::new(limits, period, q)),
                GoalRequest::Pose(p, q) => {
                    let mut core = Box::new(Goto::new(limits, period, sc.sim.initial_q));
                    if !core.set_pose_goal(&model, &p, &q, &sc.sim.initial_q) {
                        return Err(unreachable(&p));
                    }
                    core
                }
            };
            let goal = *core.goal();
            let d = core
                .step(0, &sc.sim.initial_q, false, &mut traj)
                .expect("a new source plans at its first step")
                .map_err(|e| e.to_string())?;
            (TrajSource::Straight { core, traj, duration: d }, goal)
        };
        Ok(Lockstep {
            sim,
            tracker,
            period_ns: sc.period_ns(),
            events: Vec::with_capacity(256),
            predictor,
            oracle,
            camera,
            frame: Box::new(<DebrisObservation as Zeroed>::zeroed()),
            source,
            goal,
            pose_goal,
            model,
            goal_tol: 0.01,
            goal_reached_s: None,
            started: false,
            clock: mono_ns,
            motion: MotionFigures::default(),
            prev_q: None,
            trace: None,
            debris_trace: Vec::new(),
            ahead: None,
        })
    }

    /// One tick: measure, (plan), control, apply, step. `deliver_state = false` simulates a lost
    /// state message.
    pub fn tick(&mut self, deliver_state: bool) {
        let m = self.sim.plant.measured();
        let stamp = m.tick * self.period_ns;
        if let TrajSource::Straight { core, traj, .. } = &mut self.source {
            if deliver_state && self.started {
                let holding = self.tracker.mode() == ControllerMode::Hold;
                if let Some(Ok(_)) = core.step(stamp, &m.q, holding, traj) {
                    if let Some(e) = self.tracker.set_trajectory(traj) {
                        push(&mut self.events, e);
                    }
                }
            }
        }
        if let TrajSource::Planner { core, out } = &mut self.source {
            if deliver_state && core.cycle_due(stamp) {
                let view = TrackerView { mode: self.tracker.mode(), traj_id: self.tracker.active_traj_id() };
                let fc = match (&mut self.predictor, &mut self.oracle, &mut self.ahead) {
                    (Some(p), _, _) => {
                        p.stale_reads += p.latest_deferred as u64;
                        std::mem::take(&mut p.fresh).then_some(&*p.forecast)
                    }
                    (None, Some(o), _) => std::mem::take(&mut o.fresh).then_some(&*o.forecast),
                    (None, None, Some(a)) if a.predictor.is_some() || a.fresh => {
                        a.stale_reads += a.latest_deferred as u64;
                        std::mem::take(&mut a.fresh).then_some(&*a.forecast)
                    }
                    _ => None,
                };
                let mut clock = self.clock;
                let d = core.step(stamp, &m.q, view, fc, &self.goal, &mut clock, out);
                if d.publish {
                    if let Some(e) = self.tracker.set_trajectory(out) {
                        push(&mut self.events, e);
                    }
                }
            }
        }
        let out = self.tracker.tick(deliver_state.then_some((m.tick, stamp, &m.q, &m.qd, m.brake_engaged)));
        if let Some(e) = out.event {
            push(&mut self.events, e);
        }
        // The straight source publishes once the first state is known (as `dkrrt goto`).
        if !self.started {
            self.started = true;
            if let TrajSource::Straight { traj, .. } = &self.source {
                if let Some(e) = self.tracker.set_trajectory(traj) {
                    push(&mut self.events, e);
                }
            }
        }
        if deliver_state {
            self.sim.plant.offer_command(out.state_seq, &out.tau);
        }
        // Forecasts the planner will not read (a newer one comes before its next cycle, or no
        // planner reads them) are not built: the lockstep's speed, the same run.
        let next_cycle = match &self.source {
            TrajSource::Planner { core, .. } => Some(core.next_cycle_ns()),
            TrajSource::Straight { .. } => None,
        };
        let now_ns = stamp + self.period_ns;
        if let Some(a) = self.ahead.as_mut() {
            assert!(deliver_state, "lockstep: a run ahead needs every state delivered");
            let w = a.next_tick();
            self.sim.step_against(&w.obstacles, w.t);
            if let Some(d) = self.sim.debris.as_mut() {
                (d.stats.observations, d.stats.observation_frames, d.stats.events_fired) =
                    (w.observations, w.observation_frames, w.events_fired);
            }
        } else {
            let pred = &mut self.predictor;
            let poses = !self.camera.as_ref().is_some_and(|c| c.feeds_predictor);
            let _ = self.sim.step::<()>(&mut self.frame, |f| {
                if let Some(p) = pred.as_mut().filter(|_| poses) {
                    p.feed(f, now_ns, next_cycle);
                }
                Ok(())
            });
        }
        if let (Some(c), Some(side)) = (self.camera.as_mut(), self.sim.debris.as_mut()) {
            let q: [f64; NJ] = self.sim.plant.true_state().0.into();
            let pred = &mut self.predictor;
            let CameraLoop { side: cam, renderers, snap, feeds_predictor } = c;
            let _ = cam.tick::<()>(side, &q, snap, renderers, |img| {
                let Some(p) = pred.as_mut().filter(|_| *feeds_predictor) else { return Ok(()) };
                let read = p.read(now_ns, next_cycle);
                let c = p.core.observe_depth_then_forecast_if(img, &p.lim, p.rate_hz, &mut p.forecast, read);
                p.count(c);
                Ok(())
            });
        }
        if let Some(o) = self.oracle.as_mut() {
            // The predictor's plant-clock schedule, on the truth.
            let t = self.sim.plant.tick() as f64 * self.period_ns as f64 * 1e-9;
            if t + 1e-9 >= o.next_due_s {
                o.next_due_s = dkrrt_planner::predict::next_forecast_due(t + 1e-9, o.rate_hz);
                // Every one, empty too: the truth's forecast of an empty sky is empty.
                o.table.forecast_into(t, o.steps, o.dt_s, &mut o.forecast);
                o.forecasts += 1;
                o.fresh = true;
            }
        }
        let q: [f64; NJ] = self.sim.plant.true_state().0.into();
        self.account_motion(&q);
        if self.goal_reached_s.is_none() && self.at_goal(&q) {
            self.goal_reached_s = Some(self.sim.plant.tick() as f64 * self.period_ns as f64 * 1e-9);
        }
    }

    /// Runs the debris world, its sensor and the predictor on a second thread, ahead of the
    /// plant, tracker and planner ([`crate::ahead`]): the same run, tick for tick, in less wall
    /// time where a core is free. Only at the start of a run on the pose sensor, without a
    /// camera, the oracle or a trace, and with every state delivered afterwards (`tick(true)`);
    /// returns whether it was done. The debris world of `sim.debris` then stays at its start
    /// (its contact figures and counters are kept up to date; its objects are not moved).
    pub fn run_ahead(&mut self, sc: &Scenario) -> Result<bool, String> {
        if self.sim.plant.tick() != 0
            || self.started
            || self.ahead.is_some()
            || self.camera.is_some()
            || self.oracle.is_some()
            || self.trace.is_some()
            || self.sim.debris.is_none()
        {
            return Ok(false);
        }
        let side = dkrrt_sim::debris::DebrisSide::new(sc, &self.model)?;
        let cadence = match &self.source {
            TrajSource::Planner { core, .. } => Some(core.cycle_clock()),
            TrajSource::Straight { .. } => None,
        };
        self.ahead = Some(crate::ahead::Ahead::start(side, self.predictor.take(), cadence, self.period_ns)?);
        Ok(true)
    }

    /// The thread running ahead's allocations so far (`None`: not running ahead).
    pub fn ahead_allocs(&self) -> Option<u64> {
        self.ahead.as_ref().map(|a| a.thread_allocs)
    }

    /// Keeps a trace of the run from now on (every [`SAMPLE_TICKS`] ticks; allocates its room
    /// for `seconds` of plant time at once).
    pub fn keep_trace(&mut self, seconds: f64) {
        let n = (seconds * 1e9 / (self.period_ns * SAMPLE_TICKS) as f64).ceil() as usize + 1;
        self.trace = Some(Vec::with_capacity(n));
        let objects = self.sim.debris.as_ref().map_or(0, |d| d.stats.objects);
        self.debris_trace = Vec::with_capacity(n * (objects + 2));
    }

    /// Path length every tick; end-effector path error (and the trace) every
    /// [`SAMPLE_TICKS`] ticks.
    fn account_motion(&mut self, q: &[f64; NJ]) {
        if let Some(p) = self.prev_q {
            self.motion.path_length_rad += (0..NJ).map(|i| (q[i] - p[i]).powi(2)).sum::<f64>().sqrt();
        }
        self.prev_q = Some(*q);
        let tick = self.sim.plant.tick();
        if !tick.is_multiple_of(SAMPLE_TICKS) {
            return;
        }
        let ns = tick * self.period_ns;
        let ee_of = |m: &ArmModel, q: &[f64; NJ]| {
            let x = m.fk(&dkrrt_model::JVec::from_row_slice(q)).translation.vector;
            [x[0], x[1], x[2]]
        };
        let ee = ee_of(&self.model, q);
        let des = self.tracker.desired(ns);
        let q_des = des.map(|d| d.0);
        let ee_des = q_des.map(|qd| ee_of(&self.model, &qd));
        if let Some(d) = ee_des {
            let e = ((ee[0] - d[0]).powi(2) + (ee[1] - d[1]).powi(2) + (ee[2] - d[2]).powi(2)).sqrt();
            let m = &mut self.motion;
            m.ee_sum_sq += e * e;
            m.ee_n += 1;
            m.ee_path_error_m_rms = (m.ee_sum_sq / m.ee_n as f64).sqrt();
            m.ee_path_error_m_max = m.ee_path_error_m_max.max(e);
        }
        if self.trace.as_ref().is_some_and(|t| t.len() < t.capacity()) {
            let t_s = ns as f64 * 1e-9;
            let predicted = match &mut self.source {
                TrajSource::Planner { core, .. } => core.predicted_clearance(q, t_s),
                TrajSource::Straight { .. } => None,
            };
            let sample = TraceSample {
                t_s,
                q: *q,
                qd: self.sim.plant.true_state().1.into(),
                q_des,
                qd_des: des.map(|d| d.1),
                qdd_des: des.map(|d| d.2),
                ee,
                ee_des,
                true_distance_m: self.sim.debris.as_ref().map(|d| d.distance_now_m).filter(|d| d.is_finite()),
                predicted_clearance_m: predicted,
            };
            if let Some(t) = self.trace.as_mut() {
                t.push(sample);
            }
            if let Some(d) = self.sim.debris.as_ref() {
                let out = &mut self.debris_trace;
                d.positions(|id, p| {
                    if out.len() < out.capacity() {
                        out.push((t_s, id, p));
                    }
                });
            }
        }
    }

    /// The goal is reached at `q`: every joint within 0.01 rad of the joint goal, or (a pose
    /// goal) the end effector within [`EE_TOL_M`] and [`EE_TOL_RAD`] of the pose.
    pub fn at_goal(&self, q: &[f64; NJ]) -> bool {
        if (0..NJ).all(|i| (q[i] - self.goal[i]).abs() <= self.goal_tol) {
            return true;
        }
        let Some((p, r)) = &self.pose_goal else { return false };
        let (dp, da) = ee_error(&self.model, q, p, r);
        dp <= EE_TOL_M && da <= EE_TOL_RAD
    }

    /// A contact happened.
    pub fn collided(&self) -> bool {
        self.sim.debris.as_ref().is_some_and(|d| d.stats.collided())
    }

    /// The report of the run so far.
    pub fn report(&self, sc: &Scenario) -> EvalReport {
        let (q, _) = self.sim.plant.true_state();
        let goal = self.goal;
        let final_error_rad = (0..NJ).map(|i| (goal[i] - q[i]).abs()).fold(0.0, f64::max);
        let st = self.tracker.stats;
        let (duration, planner) = match &self.source {
            TrajSource::Straight { duration, .. } => (*duration, None),
            TrajSource::Planner { core, .. } => {
                (core.current().duration_s, Some(core.summary(&sc.planner.method)))
            }
        };
        let mut r = EvalReport {
            method: sc.planner.method.clone(),
            ticks: self.sim.plant.tick(),
            trajectory_duration_s: duration,
            tracking_error_rad_rms: st.track.rms(),
            tracking_error_rad_max: st.track.max_abs,
            final_error_rad,
            safe_hold_entries: st.safe_hold_entries,
            goal_reached_s: self.goal_reached_s,
            events: self.events.clone(),
            plant: self.sim.plant.stats,
            final_q: q.into(),
            debris: self.sim.debris.as_ref().map(|d| d.stats),
            camera: self.camera.as_ref().map(|c| c.side.stats),
            predictor: match (&self.predictor, &self.oracle) {
                (None, None) if self.ahead.as_ref().is_some_and(|a| a.predictor.is_some()) => {
                    let a = self.ahead.as_ref().expect("ahead");
                    let p = a.predictor.unwrap_or_default();
                    Some(PredictorFigures {
                        method: sc.predictor_method().to_string(),
                        forecasts: p.forecasts,
                        tracks: p.tracks,
                        observations: p.counters,
                        gate: p.gate,
                        deferred: p.deferred,
                        stale_reads: a.stale_reads,
                    })
                }
                (Some(d), _) => Some(PredictorFigures {
                    method: sc.predictor_method().to_string(),
                    forecasts: d.forecasts,
                    tracks: d.tracks,
                    observations: d.core.counters,
                    gate: *d.core.gate(),
                    deferred: d.deferred,
                    stale_reads: d.stale_reads,
                }),
                (None, Some(o)) => Some(PredictorFigures {
                    method: "truth".into(),
                    forecasts: o.forecasts,
                    tracks: o.forecast.count,
                    observations: ObsCounters::default(),
                    gate: GateStats::default(),
                    deferred: 0,
                    stale_reads: 0,
                }),
                (None, None) => None,
            },
            planner,
            motion: self.motion,
            ok: false,
            checks: Vec::new(),
        };
        r.checks = in_process_checks(sc, &r);
        r.ok = r.checks.iter().all(|c| c.ok);
        r
    }
}

/// [`PredictorLoop::read_window_ns`] of a scenario: the predictor's input (the pose sensor,
/// with its latency jitter, or the depth camera) and forecast rates.
fn read_window_ns(sc: &Scenario) -> u64 {
    if sc.depth_input() {
        // A camera frame may hold no whole view of any object (then nothing is observed and
        // no forecast is due) for several frames in a row: every forecast is built.
        return u64::MAX;
    }
    // Every sensor frame carries every object (losing all of them is rare): one frame, and
    // the spread of its latency.
    let window_s =
        (1.0 / sc.debris.sensor_rate_hz).max(1.0 / sc.predictor.rate_hz) + sc.debris.latency_jitter_s;
    (window_s * 1e9).ceil() as u64 + sc.period_ns()
}

fn push(events: &mut Vec<ModeEvent>, e: ModeEvent) {
    if events.len() < events.capacity() {
        events.push(e);
    }
}

/// Runs the scenario's duration in lockstep, in process.
pub fn run(sc: &Scenario) -> Result<EvalReport, String> {
    let mut ls = Lockstep::new(sc)?;
    if std::thread::available_parallelism().map_or(1, |n| n.get()) > 1 {
        ls.run_ahead(sc)?;
    }
    for _ in 0..sc.ticks() {
        ls.tick(true);
    }
    Ok(ls.report(sc))
}
