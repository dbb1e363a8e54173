//! The replanning loop as a core: one [`Replanner::step`] per planning cycle, called the same
//! way by the `dkrrt planner` process and by the in-process lockstep.
//!
//! Each cycle:
//! 1. the newest forecast becomes the world in time;
//! 2. the active plan is checked from now to the look-ahead's end; it is kept while it stays
//!    valid (and reaches the goal);
//! 3. otherwise (or when the goal changed, or the active plan is only an escape) the planner
//!    plans from the **exact state (p, v, a) of the active plan at the commit time**
//!    `now + commit_s` (≥ the deadline + transport), so the tracker splices the new plan in at
//!    its `start_ns` without a jump; with no active plan, from rest where the arm is;
//! 4. the plan, as the message the tracker will follow, is checked once more before it is
//!    published; a plan that fails is never published;
//! 5. no valid plan: keep the active one if it is still valid from the commit time, else the
//!    best escape (a safe haven), else a brake to rest from the commit state. Each is counted.
//!
//! A plan whose predicted conflict lies beyond the reaction time is kept (newer forecasts
//! often clear it) only while an escape from it is known: see [`Replanner::hold_conflicting`].

use dkrrt_model::{ArmModel, NJ};
use dkrrt_msg::bus::Topic;
use dkrrt_msg::{
    ContractLimits, ControllerMode, DebrisForecast, Fallback, PlanStatus, Trajectory, Validate,
    ValidationError, Zeroed,
};
use dkrrt_otg::{KinState, Limits, Options};
use dkrrt_rt::hist::{LatencyHist, Percentiles};
use serde::Serialize;

use crate::build::Builder;
use crate::rrt::{PlanStats, Planner, PlannerConfig, Reach, Request};
use crate::world::WorldInTime;

/// Replanning settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReplanConfig {
    /// Cycle period, s.
    pub cycle_s: f64,
    /// Compute deadline per cycle, s (counted when missed).
    pub deadline_s: f64,
    /// A new plan starts this long after the cycle's "now", s (≥ deadline + transport).
    pub commit_s: f64,
    /// Obstacles are inflated by σ + this margin, m.
    pub margin_m: f64,
    /// While moving, a predicted conflict of the active plan further ahead than this is not
    /// yet acted on by leaving the plan (a better one is still sought every cycle), s.
    pub move_react_s: f64,
    /// Planner iterations per cycle (the work budget lockstep runs use).
    pub iterations: u32,
    /// With debris expected, wait this long (plant time) for a first forecast before moving
    /// (default: infinite, until one comes: the predictor publishes empty forecasts when the
    /// sky is empty, so a predictor that never speaks leaves the arm at rest).
    pub forecast_wait_s: f64,
    /// Goal tolerance (every joint), rad.
    pub goal_tol_rad: f64,
    /// Stop planning at the compute deadline (real time). Off in lockstep runs: the work is
    /// exactly `iterations` per cycle, whatever the machine's speed (deterministic).
    pub enforce_deadline: bool,
    /// At rest at the end of the active plan, react to predicted conflicts this close only, s.
    pub rest_react_s: f64,
    /// While moving on a plan to the goal whose conflict lies beyond `move_react_s`, do not
    /// trade it for a clean plan that arrives later (long-horizon bounds are wide; replacing
    /// it every cycle by one just past the look-ahead makes the arrival recede).
    pub keep_earlier_arrival: bool,
    /// Anytime across cycles: while a clean plan to the goal is kept, still search for an
    /// earlier arrival (forecasts tighten as objects come near and pass) and take one that
    /// arrives at least this much earlier, s. Negative: off (keep the clean plan).
    pub improve_gain_s: f64,
    /// That search runs every this many cycles (1: every cycle).
    pub improve_every: u32,
}

impl Default for ReplanConfig {
    fn default() -> Self {
        ReplanConfig {
            cycle_s: 0.1,
            deadline_s: 0.05,
            commit_s: 0.06,
            margin_m: 0.05,
            move_react_s: 3.0,
            iterations: 300,
            forecast_wait_s: f64::INFINITY,
            goal_tol_rad: 0.01,
            enforce_deadline: true,
            rest_react_s: 3.0,
            keep_earlier_arrival: true,
            improve_gain_s: 0.1,
            improve_every: 2,
        }
    }
}

/// The replanning cadence on the plant clock: a cycle is due at the first stamp at or past
/// the next multiple of the period.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CycleClock {
    period_ns: u64,
    /// The plant time at or after which the next cycle is due, ns (0 before the first).
    pub next_ns: u64,
}

impl CycleClock {
    pub fn new(cycle_s: f64) -> Self {
        CycleClock { period_ns: ((cycle_s * 1e9).round() as u64).max(1), next_ns: 0 }
    }

    /// True (and the next cycle scheduled) when `stamp_ns` has reached the next cycle.
    pub fn due(&mut self, stamp_ns: u64) -> bool {
        if stamp_ns < self.next_ns {
            return false;
        }
        self.next_ns = stamp_ns - stamp_ns % self.period_ns + self.period_ns;
        true
    }
}

/// What the tracker is doing (from its commands, or the in-process tracker).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackerView {
    pub mode: ControllerMode,
    /// Id of the trajectory it tracks (0: none).
    pub traj_id: u64,
}

/// Fallback counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Fallbacks {
    pub keep: u64,
    pub escape: u64,
    pub brake: u64,
    /// Best-effort motions away from a predicted conflict when nothing clean was found
    /// ([`crate::Planner::dodge`]; published with the escape status).
    pub dodge: u64,
}

/// Running figures of the loop.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct ReplanStats {
    pub cycles: u64,
    /// Trajectories published (first plan included).
    pub replans: u64,
    pub plans_rejected_by_final_check: u64,
    pub deadline_misses: u64,
    pub fallbacks: Fallbacks,
    /// Smallest predicted clearance of the active plan seen over the run, m.
    pub min_predicted_clearance_m: Option<f64>,
    /// Compute time of the cycles that planned, and of the first plan, ms.
    pub first_plan_ms: Option<f64>,
    pub planner_iterations: u64,
    /// Plant time the goal was first reached, s.
    pub goal_reached_s: Option<f64>,
    /// Cycles that did not plan because no forecast had come yet (debris expected).
    pub cycles_waiting_for_forecast: u64,
    /// Forecasts refused as stamped ahead of the cycle's plant time by more than
    /// [`FORECAST_LEAD_S`] ([`Replanner::step`]).
    pub forecasts_ahead: u64,
    /// Forecasts refused by the message contract ([`Replanner::set_contract`]): the lockstep's
    /// counterpart of the bus's check (which the process's forecasts pass before they get here).
    pub forecasts_invalid: u64,
}

/// A forecast starts at its newest observation, which is never after the plant time it is
/// read at; one stamped more than this ahead of a cycle (a bad clock, a corrupted message)
/// would be read backwards from its first step, its objects placed where they were long
/// before: [`Replanner::step`] refuses it, counts it and keeps the forecast it had, s.
pub const FORECAST_LEAD_S: f64 = 1.0;

/// What the replanning loop did over a run (the `planner` section of reports, the same for
/// the process and the lockstep).
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    pub method: String,
    pub cycles: u64,
    /// Trajectories published.
    pub replans: u64,
    /// Compute time of the cycles that ran the planner, ms.
    pub plan_ms: Percentiles,
    pub first_plan_ms: Option<f64>,
    /// Cycles whose compute time exceeded the deadline.
    pub deadline_misses: u64,
    pub fallbacks: Fallbacks,
    pub min_predicted_clearance_m: Option<f64>,
    /// Predicted clearances are measured up to this (the checker's cap), m: a
    /// `min_predicted_clearance_m` equal to it means this much or more.
    pub clearance_measured_up_to_m: f64,
    pub plans_rejected_by_final_check: u64,
    /// Plant time the arm was first at the goal (every joint within the tolerance), s.
    pub goal_reached_s: Option<f64>,
    /// Cycles that did not plan because no forecast had come yet.
    pub cycles_waiting_for_forecast: u64,
    /// Forecasts refused as stamped more than [`FORECAST_LEAD_S`] ahead of the cycle.
    pub forecasts_ahead: u64,
    /// Forecasts refused by the message contract, and why the newest of them was.
    pub forecasts_invalid: u64,
    pub forecast_error: Option<String>,
    pub iterations: u64,
    /// Configurations the planner checked over the run (searches, plan checks, dodges): its
    /// work, whatever the machine's speed.
    pub configs_checked: u64,
}

/// What one cycle decided.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Decision {
    /// `out` holds a new trajectory to publish.
    pub publish: bool,
    pub status: PlanStatus,
}

/// The replanning core.
pub struct Replanner {
    pub cfg: ReplanConfig,
    pub planner: Planner,
    pub world: WorldInTime,
    /// The arm (for pose goals).
    model: ArmModel,
    current: Box<Trajectory>,
    current_reach: Option<Reach>,
    /// A clean alternative to a conflicting active plan, branching off it at the next
    /// cycle's commit time (see [`Replanner::hold_conflicting`]); id 0: none.
    backup: Box<Trajectory>,
    backup_reach: Reach,
    /// The active plan's id when the backup was made.
    backup_of: u64,
    goal: Option<[f64; NJ]>,
    have_forecast: bool,
    has_debris: bool,
    next_id: u64,
    plan_hist: LatencyHist,
    pub stats: ReplanStats,
    pub last_plan: PlanStats,
    status: PlanStatus,
    /// Cycles to skip before the next attempt at the goal, and planning attempts in a row that
    /// did not reach it.
    backoff: u32,
    misses: u32,
    clock: CycleClock,
    /// Print one line per cycle to stderr (`DKRRT_PLAN_DEBUG` set at construction).
    pub debug: bool,
    /// The message contract forecasts are checked against (`None`: not checked).
    contract: Option<ContractLimits>,
    /// Why the newest refused forecast was refused.
    forecast_error: Option<ValidationError>,
}

impl Replanner {
    /// `has_debris`: forecasts are expected (wait for one before the first motion).
    pub fn new(
        model: ArmModel,
        limits: Limits<NJ>,
        pcfg: PlannerConfig,
        cfg: ReplanConfig,
        has_debris: bool,
    ) -> Self {
        Replanner {
            planner: Planner::new(model.clone(), limits, pcfg),
            model,
            world: WorldInTime::new(cfg.margin_m),
            current: Box::new(<Trajectory as Zeroed>::zeroed()),
            current_reach: None,
            backup: Box::new(<Trajectory as Zeroed>::zeroed()),
            backup_reach: Reach::Escape,
            backup_of: 0,
            goal: None,
            have_forecast: false,
            has_debris,
            next_id: 1,
            plan_hist: LatencyHist::new(),
            stats: ReplanStats::default(),
            last_plan: PlanStats::default(),
            status: <PlanStatus as Zeroed>::zeroed(),
            debug: std::env::var_os("DKRRT_PLAN_DEBUG").is_some(),
            backoff: 0,
            misses: 0,
            clock: CycleClock::new(cfg.cycle_s),
            cfg,
            contract: None,
            forecast_error: None,
        }
    }

    /// Checks every forecast against the message contract before it is read, as the bus
    /// checks each message it delivers: one that breaks it (a NaN attitude, a position out of
    /// range…) is refused, counted (`forecasts_invalid`) and the last one kept. In process
    /// (the lockstep) nothing else checks them.
    pub fn set_contract(&mut self, lim: ContractLimits) {
        self.contract = Some(lim);
    }

    /// Plan compute times (cycles that ran the planner), ms.
    pub fn plan_ms(&self) -> Percentiles {
        let p = self.plan_hist.percentiles_us();
        Percentiles {
            p50: p.p50 / 1e3,
            p99: p.p99 / 1e3,
            p999: p.p999 / 1e3,
            max: p.max / 1e3,
            mean: p.mean / 1e3,
            count: p.count,
        }
    }

    /// The cycle cadence on the plant clock, shared by both shells: true (and the next cycle
    /// scheduled) when `stamp_ns` has reached the next multiple of the cycle period.
    pub fn cycle_due(&mut self, stamp_ns: u64) -> bool {
        self.clock.due(stamp_ns)
    }

    /// The plant time at or after which the next cycle is due, ns (0 before the first).
    pub fn next_cycle_ns(&self) -> u64 {
        self.clock.next_ns
    }

    /// The cycle cadence (a copy follows the same cycles when given the same stamps).
    pub fn cycle_clock(&self) -> CycleClock {
        self.clock
    }

    /// Numbers this planner's trajectories from `first` on (a restarted planner process starts
    /// past its predecessors' ids, so the tracker never takes a new plan for an old one).
    pub fn set_first_traj_id(&mut self, first: u64) {
        self.next_id = first.max(1);
    }

    /// The run so far, for reports.
    pub fn summary(&self, method: &str) -> Summary {
        let s = &self.stats;
        Summary {
            method: method.to_string(),
            cycles: s.cycles,
            replans: s.replans,
            plan_ms: self.plan_ms(),
            first_plan_ms: s.first_plan_ms,
            deadline_misses: s.deadline_misses,
            fallbacks: s.fallbacks,
            min_predicted_clearance_m: s.min_predicted_clearance_m,
            clearance_measured_up_to_m: self.planner.checker.cap,
            plans_rejected_by_final_check: s.plans_rejected_by_final_check,
            goal_reached_s: s.goal_reached_s,
            cycles_waiting_for_forecast: s.cycles_waiting_for_forecast,
            forecasts_ahead: s.forecasts_ahead,
            forecasts_invalid: s.forecasts_invalid,
            forecast_error: self.forecast_error.map(|e| format!("{}: {e}", DebrisForecast::SERVICE)),
            iterations: s.planner_iterations,
            configs_checked: self.planner.checker.configs_checked,
        }
    }

    /// The active plan (id 0: none).
    pub fn current(&self) -> &Trajectory {
        &self.current
    }

    /// Clearance of configuration `q` at plant time `t_s` against the newest forecast,
    /// inflated as the planner inflates it (forecast bound + margin), m: what the planner
    /// keeps positive. `None` before the first forecast.
    pub fn predicted_clearance(&mut self, q: &[f64; NJ], t_s: f64) -> Option<f64> {
        self.have_forecast
            .then(|| self.planner.checker.clearance_at(&self.world, q, t_s, 0.0, f64::NEG_INFINITY))
    }

    /// One planning cycle at plant time `now_ns`. `forecast`: the newest forecast, if a new
    /// one arrived (`None` keeps the last; one stamped more than [`FORECAST_LEAD_S`] after
    /// `now_ns` is refused and counted, and the last is kept too). `clock()` reads a monotonic clock in ns (for the
    /// compute time and the deadline; the lockstep passes a real clock too, the budget is
    /// `cfg.iterations` either way). Writes a new trajectory into `out` when `publish`.
    #[allow(clippy::too_many_arguments)]
    pub fn step(
        &mut self,
        now_ns: u64,
        q_meas: &[f64; NJ],
        tracker: TrackerView,
        forecast: Option<&DebrisForecast>,
        goal: &[f64; NJ],
        clock: &mut dyn FnMut() -> u64,
        out: &mut Trajectory,
    ) -> Decision {
        let c_start = clock();
        let cc0 = self.planner.checker.configs_checked;
        self.stats.cycles += 1;
        if let Some(f) = forecast {
            let broken = self.contract.as_ref().and_then(|lim| f.validate(lim).err());
            if f.t0_ns as f64 * 1e-9 > now_ns as f64 * 1e-9 + FORECAST_LEAD_S {
                self.stats.forecasts_ahead += 1;
            } else if let Some(e) = broken {
                self.stats.forecasts_invalid += 1;
                self.forecast_error = Some(e);
            } else {
                self.world.load_forecast(f);
                self.have_forecast = true;
            }
        }
        let t_now = now_ns as f64 * 1e-9;
        let goal_changed = self.goal.is_none_or(|g| g != *goal);
        self.goal = Some(*goal);
        let at_goal = (0..NJ).all(|i| (q_meas[i] - goal[i]).abs() <= self.cfg.goal_tol_rad);
        if at_goal && self.stats.goal_reached_s.is_none() {
            self.stats.goal_reached_s = Some(t_now);
        }
        let mut st = <PlanStatus as Zeroed>::zeroed();
        st.cycle = self.stats.cycles;
        st.goal_reached = self.stats.goal_reached_s.is_some() as u32;
        st.active_traj_id = self.current.traj_id;
        st.min_predicted_clearance_m = f64::INFINITY;
        let mut publish = false;
        let waiting = self.has_debris && !self.have_forecast && t_now < self.cfg.forecast_wait_s;
        self.stats.cycles_waiting_for_forecast += waiting as u64;
        let braking = tracker.mode == ControllerMode::Brake;
        if !waiting && !braking {
            publish = self.cycle(t_now, q_meas, tracker, goal_changed, clock, c_start, &mut st, out);
        }
        let dt = clock().saturating_sub(c_start);
        st.plan_time_us = dt / 1000;
        if dt as f64 * 1e-9 > self.cfg.deadline_s {
            self.stats.deadline_misses += 1;
            st.deadline_missed = 1;
        }
        st.replans = self.stats.replans;
        st.header.stamp_ns = now_ns;
        if st.min_predicted_clearance_m.is_finite() {
            let m = &mut self.stats.min_predicted_clearance_m;
            *m = Some(m.map_or(st.min_predicted_clearance_m, |x| x.min(st.min_predicted_clearance_m)));
        } else {
            st.min_predicted_clearance_m = self.planner.checker.cap;
        }
        self.status = st;
        if self.debug {
            eprintln!(
                "plan t={t_now:.2} cycle_configs={} tracks={} mode={:?} cur={} publish={publish} fallback={} it={} nodes={} edges={} configs={} first={:?} clear={:.3} {:.1} ms reach={:?} ends={:.2}",
                self.planner.checker.configs_checked - cc0,
                self.world.len(),
                tracker.mode,
                self.current.traj_id,
                st.fallback,
                st.iterations,
                self.last_plan.nodes,
                self.last_plan.edges_checked,
                self.last_plan.configs_checked,
                self.last_plan.first_solution_iter,
                st.min_predicted_clearance_m,
                dt as f64 * 1e-6,
                self.current_reach,
                self.current.start_ns as f64 * 1e-9 + self.current.duration_s
            );
        }
        if self.debug && self.stats.cycles % 20 == 3 {
            for dt in [0.0, 1.0, 3.0, 6.0, 9.0] {
                let t = t_now + dt;
                let c = self.planner.checker.clearance_at(&self.world, q_meas, t, 0.0, f64::NEG_INFINITY);
                let n = self.planner.checker.nearest_at(&self.world, q_meas, t);
                eprintln!("  rest clearance at +{dt}: {c:.3} nearest {n:?}");
            }
            if self.current.traj_id != 0 {
                let near: Vec<String> = [0.5, 1.0, 2.0, 3.0, 4.0, 5.0]
                    .iter()
                    .map(|dt| {
                        let t = t_now + dt;
                        let q = self.current.sample(self.current.time_of((t * 1e9) as u64)).p;
                        let n = self.planner.checker.nearest_at(&self.world, &q, t);
                        n.map_or(String::new(), |(id, c)| format!("+{dt}: #{id} {c:.2}"))
                    })
                    .collect();
                eprintln!("  plan nearest: {near:?}");
            }
            if let Some(g) = self.goal {
                let gc: Vec<String> = [0.0, 1.0, 2.0, 3.0, 4.0, 6.0]
                    .iter()
                    .map(|dt| {
                        let n = self.planner.checker.nearest_at(&self.world, &g, t_now + dt);
                        n.map_or("-".into(), |(id, c)| format!("{c:.2}#{id}"))
                    })
                    .collect();
                eprintln!("  goal clearance (nearest) at +0,1,2,3,4,6: {gc:?}");
            }
            for i in 0..self.world.len() {
                let (p, _, s, _, sph) = self.world.pose_at(i, t_now + 6.0);
                let (p0, _, s0, _, _) = self.world.pose_at(i, t_now);
                let sg: Vec<String> = [1.0, 2.0, 3.0, 4.0]
                    .iter()
                    .map(|d| {
                        let (_, _, s, sp, sph) = self.world.pose_at(i, t_now + d);
                        format!("{s:.2}/{sp:.2}{}", if sph { "S" } else { "" })
                    })
                    .collect();
                eprintln!(
                    "  track {} kind {} sigma/pos +1..4: {:?}",
                    self.world.id(i),
                    self.world.shape(i).kind,
                    sg
                );
                eprintln!(
                    "  track {} now {:?} σ {:.3} | +6 s {:?} σ {:.3} sphere {}",
                    self.world.id(i),
                    p0.map(|x| (x * 100.0).round() / 100.0),
                    s0,
                    p.map(|x| (x * 100.0).round() / 100.0),
                    s,
                    sph
                );
            }
        }
        Decision { publish, status: st }
    }

    /// The last cycle's status.
    pub fn status(&self) -> &PlanStatus {
        &self.status
    }

    #[allow(clippy::too_many_arguments)]
    fn cycle(
        &mut self,
        t_now: f64,
        q_meas: &[f64; NJ],
        tracker: TrackerView,
        goal_changed: bool,
        clock: &mut dyn FnMut() -> u64,
        c_start: u64,
        st: &mut PlanStatus,
        out: &mut Trajectory,
    ) -> bool {
        let t_end = t_now + self.planner.cfg.lookahead_s;
        let cur_id = self.current.traj_id;
        let following = cur_id != 0 && tracker.traj_id == cur_id;
        let cur_done = cur_id != 0 && self.current.time_of((t_now * 1e9) as u64) >= self.current.duration_s;
        // Is the active plan still valid from now on?
        let (cur_valid, cur_clean) =
            if cur_id != 0 && (following || cur_done || tracker.mode == ControllerMode::Track) {
                let c = check_message_at(&mut self.planner, &self.world, &self.current, t_now, t_end);
                st.min_predicted_clearance_m = c.min_clearance;
                // A predicted conflict further ahead than the reaction time is not acted on by
                // leaving the plan: newer forecasts (smaller bounds) decide, rather than leaving
                // a motion that is clear for now for one found in a hurry. At rest at the end of
                // the plan that is `rest_react_s`; while moving `move_react_s`.
                let react = if cur_done { self.cfg.rest_react_s } else { self.cfg.move_react_s };
                (c.ok || c.t_fail > t_now + react, c.ok)
            } else {
                (false, false)
            };
        let reaches_goal = self.current_reach == Some(Reach::Goal);
        // Such a plan is kept only while an escape from it is known.
        if cur_valid && !cur_clean && !goal_changed && (following || cur_done) {
            return self.hold_conflicting(t_now, reaches_goal, cur_done, clock, c_start, st, out);
        }
        let kept = cur_valid && cur_clean && reaches_goal && !goal_changed;
        // A clean plan to the goal is kept; while it still moves (or waits) towards the goal,
        // the search goes on for an earlier arrival (the cross-cycle anytime improvement).
        let improving = kept
            && !cur_done
            && following
            && self.cfg.improve_gain_s >= 0.0
            && self.stats.cycles.is_multiple_of(self.cfg.improve_every.max(1) as u64);
        if kept && !improving {
            return false;
        }
        // While a valid plan (an escape, or the rest) is kept and the goal is out of reach,
        // retry the goal every few cycles only (backing off to `MAX_BACKOFF` cycles).
        if self.backoff > 0 && !goal_changed && !improving && (cur_valid || cur_id == 0) {
            self.backoff -= 1;
            if cur_valid {
                self.stats.fallbacks.keep += 1;
                st.fallback = Fallback::Keep as u32;
            }
            return false;
        }
        // The start of a new plan.
        let t_c = t_now + self.cfg.commit_s;
        let c_ns = (t_c * 1e9).round() as u64;
        let start = if following && !cur_done {
            let s = self.current.sample(self.current.time_of(c_ns));
            KinState { p: s.p, v: s.v, a: s.a }
        } else if cur_done && tracker.mode == ControllerMode::Hold {
            KinState::rest(self.current.sample(self.current.duration_s).p)
        } else if tracker.mode == ControllerMode::Track {
            // Tracking something that is not our active plan (it has not taken over yet).
            return false;
        } else {
            KinState::rest(*q_meas)
        };
        let id = self.next_id;
        // Improving: only a plan arriving clearly earlier than the kept one is wanted.
        let cur_arrival = self.current.start_ns as f64 * 1e-9 + self.current.duration_s;
        let before = if improving { cur_arrival - self.cfg.improve_gain_s } else { f64::INFINITY };
        let plan = self.search(&start, t_c, before, clock, c_start, !improving, st, out);
        if let Some(p) = plan {
            // The message the tracker will follow, checked once more before it goes out.
            let look = self.planner.cfg.lookahead_s;
            let (ok, clear) = check_message(&mut self.planner, &self.world, out, t_c, t_c + look);
            let better = !cur_clean || !reaches_goal || goal_changed || p.reach == Reach::Goal;
            // Improving a kept clean plan: only a clean plan to the goal that arrives clearly
            // earlier replaces it.
            let gains = !improving || (p.reach == Reach::Goal && p.arrival < before);
            if ok && better && gains && !(cur_valid && p.reach == Reach::Escape) {
                self.accept(out, p.reach);
                st.fallback = if p.reach == Reach::Escape {
                    self.stats.fallbacks.escape += 1;
                    Fallback::Escape as u32
                } else {
                    Fallback::None as u32
                };
                st.active_traj_id = id;
                st.min_predicted_clearance_m = clear;
                return true;
            }
            if !ok {
                self.stats.plans_rejected_by_final_check += 1;
            }
        }
        if improving {
            return false; // the clean plan stays: no fallback
        }
        if cur_valid {
            self.stats.fallbacks.keep += 1;
            st.fallback = Fallback::Keep as u32;
            return false;
        }
        // The escape known from the last cycle (it starts at this cycle's commit time).
        if self.take_backup(t_now, st, out) {
            return true;
        }
        // Nothing clean is known: the motion with the most predicted clearance, if it beats
        // staying (the brake, or the rest) clearly.
        let req = Request { start, t0: t_c, goal: *goal_for(self.goal.as_ref()) };
        let deadline = self.deadline_ns(c_start);
        if let Some(p) = self.planner.dodge(&req, &self.world, id, || clock() < deadline, out) {
            self.accept(out, Reach::Escape);
            st.min_predicted_clearance_m = p.min_clearance;
            self.stats.fallbacks.dodge += 1;
            st.fallback = Fallback::Escape as u32;
            st.active_traj_id = id;
            return true;
        }
        // Brake to rest from the commit state.
        self.stats.fallbacks.brake += 1;
        st.fallback = Fallback::Brake as u32;
        let moving = start.v.iter().chain(start.a.iter()).any(|x| x.abs() > 1e-12);
        if !moving || !self.brake_into(&start, id, c_ns, out) {
            return false; // at rest: hold (the tracker holds without a new plan)
        }
        self.accept(out, Reach::Escape);
        st.active_traj_id = id;
        true
    }

    /// The active plan (moving, or resting at its end) has a predicted conflict beyond the
    /// reaction time. Newer forecasts, with tighter bounds, often clear such a conflict, so the
    /// plan is not left for a worse one yet, but only while an escape from it is known: else
    /// the conflict can come within the reaction time where no escape is left (a plan followed
    /// into a trap). Every cycle works from the plan's state at the *next* cycle's commit time
    /// `t_b`: the brake to rest from there is tried, and a search runs (unless backing off with
    /// the brake clean). A clean plan to the goal arriving no later than the active one is
    /// published (the tracker splices it in at `t_b`); any other clean plan (an escape, a later
    /// arrival, the brake) becomes the *backup*. When this cycle finds nothing clean, the
    /// backup of the last cycle, which starts at this cycle's commit time, is published.
    #[allow(clippy::too_many_arguments)]
    fn hold_conflicting(
        &mut self,
        t_now: f64,
        reaches_goal: bool,
        cur_done: bool,
        clock: &mut dyn FnMut() -> u64,
        c_start: u64,
        st: &mut PlanStatus,
        out: &mut Trajectory,
    ) -> bool {
        let look = self.planner.cfg.lookahead_s;
        let t_b = t_now + self.cfg.commit_s + self.cfg.cycle_s;
        let b_ns = (t_b * 1e9).round() as u64;
        let id = self.next_id;
        let s = self.current.sample(self.current.time_of(b_ns));
        let start = if cur_done { KinState::rest(s.p) } else { KinState { p: s.p, v: s.v, a: s.a } };
        let moving = start.v.iter().chain(start.a.iter()).any(|x| x.abs() > 1e-12);
        let mut known = false;
        if moving && self.brake_into(&start, id, b_ns, out) {
            known = check_message(&mut self.planner, &self.world, out, t_b, t_b + look).0;
            if known {
                self.set_backup(out, Reach::Escape);
            }
        }
        if !(known && self.backoff > 0) {
            let plan = self.search(&start, t_b, f64::INFINITY, clock, c_start, true, st, out);
            if let Some(p) = plan {
                let (ok, clear) = check_message(&mut self.planner, &self.world, out, t_b, t_b + look);
                let cur_arrival = self.current.start_ns as f64 * 1e-9 + self.current.duration_s;
                let no_later = p.reach == Reach::Goal
                    && (!reaches_goal || !self.cfg.keep_earlier_arrival || p.arrival <= cur_arrival + 1e-3);
                if ok && no_later {
                    self.accept(out, p.reach);
                    st.fallback = Fallback::None as u32;
                    st.active_traj_id = id;
                    st.min_predicted_clearance_m = clear;
                    return true;
                }
                if ok {
                    self.set_backup(out, p.reach);
                    known = true;
                } else {
                    self.stats.plans_rejected_by_final_check += 1;
                }
            }
        } else {
            self.backoff -= 1;
        }
        if !known && self.take_backup(t_now, st, out) {
            return true;
        }
        self.stats.fallbacks.keep += 1;
        st.fallback = Fallback::Keep as u32;
        false
    }

    /// Runs the planner from `start` at plant time `t0` into `out`, with the cycle's budget
    /// and deadline, and books it (`count_miss`: a plan short of the goal grows the backoff).
    /// `before` finite: only a plan to the goal arriving before it is sought
    /// ([`Planner::plan_to_beat`]).
    #[allow(clippy::too_many_arguments)]
    fn search(
        &mut self,
        start: &KinState<NJ>,
        t0: f64,
        before: f64,
        clock: &mut dyn FnMut() -> u64,
        c_start: u64,
        count_miss: bool,
        st: &mut PlanStatus,
        out: &mut Trajectory,
    ) -> Option<crate::rrt::Plan> {
        let req = Request { start: *start, t0, goal: *goal_for(self.goal.as_ref()) };
        let deadline = self.deadline_ns(c_start);
        self.planner.debug = self.debug && self.stats.cycles % 20 == 3;
        let keep_going = || clock() < deadline;
        let plan = self.planner.plan_to_beat(
            &req,
            &self.world,
            before,
            self.cfg.iterations,
            keep_going,
            self.next_id,
            out,
        );
        self.last_plan = self.planner.stats;
        self.stats.planner_iterations += self.planner.stats.iterations as u64;
        st.iterations = self.planner.stats.iterations;
        let took = clock().saturating_sub(c_start);
        self.plan_hist.record_ns(took);
        if self.stats.first_plan_ms.is_none() && plan.is_some() {
            self.stats.first_plan_ms = Some(took as f64 * 1e-6);
        }
        if count_miss {
            self.misses =
                if plan.is_some_and(|p| p.reach == Reach::Goal) { 0 } else { (self.misses + 1).min(8) };
            self.backoff = (1u32 << self.misses.min(3)) - 1; // 0, 1, 3, 7 cycles
        }
        plan
    }

    /// The clock reading by which a cycle started at `c_start` must be done (never, in
    /// lockstep: its work is the iteration budget).
    fn deadline_ns(&self, c_start: u64) -> u64 {
        if self.cfg.enforce_deadline {
            c_start + (self.cfg.deadline_s * 1e9) as u64
        } else {
            u64::MAX
        }
    }

    /// Writes into `out` the brake to rest from the moving state `start` at `start_ns`.
    fn brake_into(&self, start: &KinState<NJ>, id: u64, start_ns: u64, out: &mut Trajectory) -> bool {
        let lim = *self.planner.limits();
        let Ok(br) = dkrrt_otg::Trajectory::calculate_velocity(
            start,
            &[0.0; NJ],
            &[0.0; NJ],
            &lim,
            &Options::default(),
        ) else {
            return false;
        };
        let mut b = Builder::new(out, id, start_ns);
        if b.otg(&br).is_err() {
            return false;
        }
        b.finish();
        true
    }

    /// Remembers a clean alternative to the active plan (see [`Self::hold_conflicting`]).
    fn set_backup(&mut self, tr: &Trajectory, reach: Reach) {
        *self.backup = *tr;
        self.backup_reach = reach;
        self.backup_of = self.current.traj_id;
    }

    /// Publishes the backup if it branches off the active plan, still starts at least about
    /// the commit lead ahead (`commit_s` less half its slack over the deadline) and is still
    /// clean against the newest forecast.
    fn take_backup(&mut self, t_now: f64, st: &mut PlanStatus, out: &mut Trajectory) -> bool {
        let start = self.backup.start_ns as f64 * 1e-9;
        let lead = self.cfg.commit_s - 0.5 * (self.cfg.commit_s - self.cfg.deadline_s).max(0.0);
        if self.backup.traj_id == 0 || self.backup_of != self.current.traj_id || start < t_now + lead {
            return false;
        }
        let look = self.planner.cfg.lookahead_s;
        let (ok, clear) = check_message(&mut self.planner, &self.world, &self.backup, start, start + look);
        if !ok {
            return false;
        }
        *out = *self.backup;
        out.traj_id = self.next_id;
        st.active_traj_id = self.next_id;
        st.min_predicted_clearance_m = clear;
        self.stats.fallbacks.escape += 1;
        st.fallback = Fallback::Escape as u32;
        self.accept(out, self.backup_reach);
        true
    }

    fn accept(&mut self, out: &Trajectory, reach: Reach) {
        *self.current = *out;
        self.backup.traj_id = 0;
        self.current_reach = Some(reach);
        self.next_id += 1;
        self.stats.replans += 1;
    }
}

impl Replanner {
    /// A joint goal for the end-effector pose `p`, `q` ([`crate::goal`]): IK from the arm's
    /// configuration `q_now`, the goal in force and seeded restarts; the solution nearest to
    /// `q_now` among those clear of the current forecast at rest from `t_now` over the
    /// look-ahead (checked every 0.25 s), else the clearest. `None`: unreachable.
    pub fn resolve_pose_goal(
        &mut self,
        p: &[f64; 3],
        q: &[f64; 4],
        q_now: &[f64; NJ],
        t_now: f64,
    ) -> Option<[f64; NJ]> {
        let mut seeds = vec![*q_now];
        if let Some(g) = self.goal {
            seeds.push(g);
        }
        let sols = crate::goal::ik_solutions(&self.model, p, q, &seeds);
        let look = self.planner.cfg.lookahead_s;
        let (checker, world) = (&mut self.planner.checker, &self.world);
        crate::goal::choose(&sols, q_now, |c| {
            let mut m = f64::INFINITY;
            let mut t = t_now;
            while t <= t_now + look + 1e-9 {
                m = m.min(checker.clearance_at(world, c, t, 0.0, f64::NEG_INFINITY));
                t += 0.25;
            }
            m
        })
    }
}

fn goal_for(g: Option<&[f64; NJ]>) -> &[f64; NJ] {
    g.unwrap_or(&[0.0; NJ])
}

/// A message trajectory checked against the world over [t0, t1] (the final rest included):
/// (valid, min clearance).
pub fn check_message(
    planner: &mut Planner,
    world: &WorldInTime,
    tr: &Trajectory,
    t0: f64,
    t1: f64,
) -> (bool, f64) {
    let c = check_message_at(planner, world, tr, t0, t1);
    (c.ok, c.min_clearance)
}

/// As [`check_message`], with the first failing time.
pub fn check_message_at(
    planner: &mut Planner,
    world: &WorldInTime,
    tr: &Trajectory,
    t0: f64,
    t1: f64,
) -> crate::Check {
    let start = tr.start_ns as f64 * 1e-9;
    // A message that starts inside the inflated obstacles must leave them (the relief).
    let s0 = tr.sample(t0 - start);
    planner.relieve(world, &KinState { p: s0.p, v: s0.v, a: s0.a }, t0);
    // The motion in pieces of at most `MESSAGE_PIECE_S`, each checked with the speed its
    // joints actually reach in it, then the rest at its end (the arm still).
    let end = start + tr.duration_s.max(0.0);
    let mut c = crate::Check { ok: true, min_clearance: planner.checker.cap, t_fail: f64::NAN, samples: 0 };
    let mut a = t0;
    while c.ok && a < t1.min(end) {
        let b = (a + MESSAGE_PIECE_S).min(t1.min(end));
        let peaks = message_speed_peaks(tr, a - start, b - start);
        c = merge(
            c,
            planner.checker.check_joint_motion(world, a, b, t1, Some(&peaks), |t| tr.sample(t - start).p),
        );
        a = b;
    }
    if c.ok && t1 >= a {
        let q = tr.sample(a - start).p;
        c = merge(c, planner.checker.check_motion(world, a, t1, t1, None, |_| q));
    }
    planner.checker.end_relief();
    c
}

/// A message's motion is checked in pieces this long at most, s.
const MESSAGE_PIECE_S: f64 = 0.5;

/// Two checks of consecutive stretches as one.
fn merge(a: crate::Check, b: crate::Check) -> crate::Check {
    crate::Check {
        ok: a.ok && b.ok,
        min_clearance: a.min_clearance.min(b.min_clearance),
        t_fail: if a.ok { b.t_fail } else { a.t_fail },
        samples: a.samples + b.samples,
    }
}

/// Each joint's largest speed over trajectory times `[a, b]` of a message (after its end the
/// arm holds its last position).
pub fn message_speed_peaks(tr: &Trajectory, a: f64, b: f64) -> [f64; NJ] {
    let (a, b) = (a.max(0.0), b.min(tr.duration_s));
    let mut out = [0.0; NJ];
    if !(b > a) {
        return out;
    }
    for (j, m) in out.iter_mut().enumerate() {
        let n = (tr.n_seg[j] as usize).clamp(1, dkrrt_msg::MAX_SEGMENTS);
        let segs = &tr.seg[j][..n];
        for (k, sg) in segs.iter().enumerate() {
            let t_next = segs.get(k + 1).map_or(tr.duration_s, |s| s.t0);
            let (lo, hi) = (sg.t0.max(a), t_next.min(b));
            if hi < lo {
                continue;
            }
            let d = lo - sg.t0;
            let (v, acc) = (sg.v + d * (sg.a + d * sg.j / 2.0), sg.a + d * sg.j);
            *m = m.max(dkrrt_otg::speed_peak(v, acc, sg.j, hi - lo));
        }
    }
    out
}
