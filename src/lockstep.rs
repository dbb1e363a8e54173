//! In-process lockstep evaluation: the same sim, tracker, predictor and planner cores as the
//! processes, wired directly (no IPC, no clock), with the same timing contract. Deterministic:
//! the same scenario gives the same numbers.
//!
//! The trajectory source is the scenario's `planner.method`: `straight` (the goto core: one
//! jerk-limited line to the goal, planned from the first state) or `dk-rrt` (the replanning
//! core, one cycle every `1/planner.rate_hz` of plant time with `planner.iterations` of work).
//! A plan computed from the state at plant time `t` starts at `t + planner.commit_ms`, as in
//! real time, so lockstep results carry the real-time latency.

use dkrrt_config::arm::contract_limits;
use dkrrt_config::{GoalRequest, Scenario};
use dkrrt_model::ArmModel;
use dkrrt_msg::{ContractLimits, ControllerMode, DebrisForecast, DebrisObservation, Trajectory, Zeroed, NJ};
use dkrrt_otg::Limits;
use dkrrt_planner::goto::Goto;
use dkrrt_planner::predict::{fit_models, ObsCounters, PredictorCore};
use dkrrt_planner::replan::replanner;
use dkrrt_predictor::{GateStats, Models};
use dkrrt_rrt::{Replanner, Summary, TrackerView};
use dkrrt_sim::core::SimCore;
use dkrrt_sim::debris::DebrisStats;
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
    /// Planner figures, `null` for the straight method.
    pub planner: Option<Summary>,
}

/// What the in-process predictor did.
#[derive(Debug, Clone, serde::Serialize)]
pub struct PredictorFigures {
    pub method: String,
    pub forecasts: u64,
    pub tracks: u32,
    pub observations: ObsCounters,
    pub gate: GateStats,
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
    rate_hz: f64,
}

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
}

fn mono_ns() -> u64 {
    dkrrt_rt::clock::mono_ns()
}

impl Lockstep {
    /// Builds the cores for `sc` (an `[episode]` must already be resolved). The predictor's
    /// models are fitted as the scenario says (`predictor.fit`).
    pub fn new(sc: &Scenario) -> Result<Lockstep, String> {
        let models = if sc.has_debris() { Some(fit_models(sc)?) } else { None };
        Self::with_models(sc, models)
    }

    /// As [`Lockstep::new`], with the predictor's models given (fitted once for many episodes).
    pub fn with_models(sc: &Scenario, models: Option<Models>) -> Result<Lockstep, String> {
        let model = sc.load_arm().map_err(|e| e.to_string())?;
        let predictor = match (sc.has_debris(), models) {
            (true, Some(m)) => Some(PredictorLoop {
                core: PredictorCore::new(m, sc),
                forecast: Box::new(<DebrisForecast as Zeroed>::zeroed()),
                forecasts: 0,
                tracks: 0,
                fresh: false,
                lim: contract_limits(&model),
                rate_hz: sc.predictor.rate_hz,
            }),
            (true, None) => {
                return Err("lockstep: a scenario with debris needs the predictor's models".into())
            }
            _ => None,
        };
        let sim = SimCore::new(sc, model.clone())?;
        let tracker = Tracker::new(model.clone(), TrackerConfig::from_scenario(sc));
        let req = sc.goal.request().ok_or("lockstep: the scenario gives no goal")?;
        let pose_goal = match req {
            GoalRequest::Pose(p, q) => Some((p, q)),
            GoalRequest::Joint(_) => None,
        };
        let unreachable = |p: &[f64; 3]| format!("lockstep: the pose goal at {p:?} is out of reach");
        // A pose goal is solved from the initial configuration, as the sources solve it at
        // their first state.
        let (source, goal) = if sc.planner.method == "dk-rrt" {
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
            frame: Box::new(<DebrisObservation as Zeroed>::zeroed()),
            source,
            goal,
            pose_goal,
            model,
            goal_tol: 0.01,
            goal_reached_s: None,
            started: false,
            clock: mono_ns,
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
                let fc = self
                    .predictor
                    .as_mut()
                    .and_then(|p| std::mem::take(&mut p.fresh).then_some(&*p.forecast));
                let mut clock = self.clock;
                let d = core.step(stamp, &m.q, view, fc, &self.goal, &mut clock, out);
                if d.publish {
                    if let Some(e) = self.tracker.set_trajectory(out) {
                        push(&mut self.events, e);
                    }
                }
            }
        }
        let out = self.tracker.tick(deliver_state.then_some((m.tick, stamp, &m.q, &m.qd)));
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
        let pred = &mut self.predictor;
        let _ = self.sim.step::<()>(&mut self.frame, |f| {
            if let Some(p) = pred.as_mut() {
                let n = p.core.observe_then_forecast(f, &p.lim, p.rate_hz, &mut p.forecast);
                if n > 0 {
                    p.forecasts += 1;
                    p.tracks = n as u32;
                    p.fresh = true;
                }
            }
            Ok(())
        });
        let q: [f64; NJ] = self.sim.plant.true_state().0.into();
        if self.goal_reached_s.is_none() && self.at_goal(&q) {
            self.goal_reached_s = Some(self.sim.plant.tick() as f64 * self.period_ns as f64 * 1e-9);
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
        EvalReport {
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
            predictor: self.predictor.as_ref().map(|d| PredictorFigures {
                method: sc.predictor.method.clone(),
                forecasts: d.forecasts,
                tracks: d.tracks,
                observations: d.core.counters,
                gate: *d.core.gate(),
            }),
            planner,
        }
    }
}

fn push(events: &mut Vec<ModeEvent>, e: ModeEvent) {
    if events.len() < events.capacity() {
        events.push(e);
    }
}

/// Runs the scenario's duration in lockstep, in process.
pub fn run(sc: &Scenario) -> Result<EvalReport, String> {
    let mut ls = Lockstep::new(sc)?;
    for _ in 0..sc.ticks() {
        ls.tick(true);
    }
    Ok(ls.report(sc))
}
