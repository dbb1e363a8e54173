//! In-process lockstep evaluation: the same plant, tracker and trajectory
//! cores as the processes, wired directly (no IPC, no clock), with the same
//! timing contract. Deterministic: the same scenario gives the same numbers.

use dkrrt_config::arm::contract_limits;
use dkrrt_config::Scenario;
use dkrrt_msg::{ContractLimits, DebrisForecast, DebrisObservation, Trajectory, Zeroed, NJ};
use dkrrt_otg::{KinState, Limits};
use dkrrt_planner::goto::plan;
use dkrrt_planner::predict::{fit_models, ObsCounters, PredictorCore};
use dkrrt_predictor::GateStats;
use dkrrt_sim::debris::{DebrisSide, DebrisStats};
use dkrrt_sim::plant::{Plant, PlantConfig, PlantStats};
use dkrrt_tracker::ctrl::{ModeEvent, Tracker, TrackerConfig};

/// Result of an in-process run.
#[derive(Debug, Clone, serde::Serialize)]
pub struct EvalReport {
    pub ticks: u64,
    pub trajectory_duration_s: f64,
    pub tracking_error_rad_rms: f64,
    pub tracking_error_rad_max: f64,
    pub final_error_rad: f64,
    pub safe_hold_entries: u64,
    pub events: Vec<ModeEvent>,
    pub plant: PlantStats,
    pub final_q: [f64; NJ],
    /// Debris side (closest approach, contacts), `null` without debris.
    pub debris: Option<DebrisStats>,
    /// Predictor figures, `null` without debris.
    pub predictor: Option<PredictorFigures>,
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

/// The debris side and the predictor, wired in process.
pub struct DebrisLoop {
    pub side: DebrisSide,
    pub core: PredictorCore,
    pub frame: Box<DebrisObservation>,
    pub forecast: Box<DebrisForecast>,
    pub forecasts: u64,
    pub tracks: u32,
    lim: ContractLimits,
    rate_hz: f64,
}

/// The wired cores, stepped one tick at a time.
pub struct Lockstep {
    pub plant: Plant,
    pub tracker: Tracker,
    pub period_ns: u64,
    pub events: Vec<ModeEvent>,
    pub traj: Box<Trajectory>,
    pub traj_duration: f64,
    pub debris: Option<DebrisLoop>,
    dt_s: f64,
}

impl Lockstep {
    /// Builds the cores for `sc` and plans the trajectory to its goal from the
    /// initial state, starting at plant time 0.
    pub fn new(sc: &Scenario) -> Result<Lockstep, String> {
        let model = sc.load_arm().map_err(|e| e.to_string())?;
        let debris = if sc.has_debris() {
            Some(DebrisLoop {
                side: DebrisSide::new(sc)?,
                core: PredictorCore::new(fit_models(sc)?, sc),
                frame: Box::new(<DebrisObservation as Zeroed>::zeroed()),
                forecast: Box::new(<DebrisForecast as Zeroed>::zeroed()),
                forecasts: 0,
                tracks: 0,
                lim: contract_limits(&model),
                rate_hz: sc.predictor.rate_hz,
            })
        } else {
            None
        };
        let plant = Plant::new(model.clone(), PlantConfig::from_scenario(sc), &sc.sim.initial_q);
        let mut debris = debris;
        if let Some(d) = debris.as_mut() {
            d.side.check(plant.model(), &plant.true_state().0);
        }
        let tracker = Tracker::new(model, TrackerConfig::from_scenario(sc));
        let mut traj = Box::new(<Trajectory as Zeroed>::zeroed());
        let limits = Limits { v_max: sc.motion.v_max, a_max: sc.motion.a_max, j_max: sc.motion.j_max };
        let d = plan(
            &KinState::rest(sc.sim.initial_q),
            &sc.goal.q,
            &limits,
            sc.period_ns() as f64 * 1e-9,
            1,
            0,
            &mut traj,
        )
        .map_err(|e| e.to_string())?;
        Ok(Lockstep {
            plant,
            tracker,
            period_ns: sc.period_ns(),
            events: Vec::with_capacity(64),
            traj,
            traj_duration: d,
            debris,
            dt_s: sc.period_ns() as f64 * 1e-9,
        })
    }

    /// One tick: measure, control, apply, step. `deliver_state = false`
    /// simulates a lost state message.
    pub fn tick(&mut self, deliver_state: bool) {
        let m = self.plant.measured();
        let stamp = m.tick * self.period_ns;
        let out = self.tracker.tick(deliver_state.then_some((m.tick, stamp, &m.q, &m.qd)));
        if let Some(e) = out.event {
            if self.events.len() < self.events.capacity() {
                self.events.push(e);
            }
        }
        if deliver_state {
            self.plant.offer_command(out.state_seq, &out.tau);
        }
        self.plant.step();
        if let Some(d) = self.debris.as_mut() {
            // As in the processes: the world advances with the plant, contacts are checked on
            // the true arm state, observations go to the predictor, forecasts on the plant clock.
            d.side.step(self.dt_s);
            d.side.check(self.plant.model(), &self.plant.true_state().0);
            let (core, lim, rate_hz, fc) = (&mut d.core, &d.lim, d.rate_hz, &mut d.forecast);
            let (forecasts, tracks) = (&mut d.forecasts, &mut d.tracks);
            let _ = d.side.drain_observations::<()>(&mut d.frame, |f| {
                let n = core.observe_then_forecast(f, lim, rate_hz, fc);
                if n > 0 {
                    *forecasts += 1;
                    *tracks = n as u32;
                }
                Ok(())
            });
        }
    }
}

/// Runs the scenario's duration in lockstep, in process.
pub fn run(sc: &Scenario) -> Result<EvalReport, String> {
    let mut ls = Lockstep::new(sc)?;
    let total = sc.ticks();
    // The first state arrives before the trajectory (as in the process set).
    ls.tick(true);
    if let Some(e) = ls.tracker.set_trajectory(&ls.traj) {
        ls.events.push(e);
    }
    for _ in 1..total {
        ls.tick(true);
    }
    let (q, _) = ls.plant.true_state();
    let goal = sc.goal.q;
    let final_error_rad = (0..NJ).map(|i| (goal[i] - q[i]).abs()).fold(0.0, f64::max);
    let st = ls.tracker.stats;
    Ok(EvalReport {
        ticks: total,
        trajectory_duration_s: ls.traj_duration,
        tracking_error_rad_rms: st.track.rms(),
        tracking_error_rad_max: st.track.max_abs,
        final_error_rad,
        safe_hold_entries: st.safe_hold_entries,
        events: ls.events.clone(),
        plant: ls.plant.stats,
        final_q: q.into(),
        debris: ls.debris.as_ref().map(|d| d.side.stats),
        predictor: ls.debris.as_ref().map(|d| PredictorFigures {
            method: sc.predictor.method.clone(),
            forecasts: d.forecasts,
            tracks: d.tracks,
            observations: d.core.counters,
            gate: *d.core.gate(),
        }),
    })
}
