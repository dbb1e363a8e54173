//! The `dkrrt planner` process shell: the DK-RRT replanning core ([`dkrrt_rrt::Replanner`])
//! wired to the bus and a clock.
//!
//! Inputs: `dkrrt/robot_state` (now = the newest state's plant time, and where the arm is),
//! `dkrrt/torque_command` (the tracker's mode and tracked trajectory), `dkrrt/debris_forecast`,
//! `dkrrt/goal` (a new goal replaces the scenario's). Outputs: `dkrrt/trajectory` (a new plan
//! starts `planner.commit_ms` after the state it was planned from: the tracker splices it in
//! at its `start_ns`) and `dkrrt/plan_status` once per cycle.
//!
//! Cadence: realtime — cycles on absolute CLOCK_MONOTONIC deadlines at `planner.rate_hz`, each
//! with the `planner.deadline_ms` compute deadline; lockstep — one cycle each time the plant
//! clock (state stamps) passes the next cycle boundary (the simulator waits for that cycle's
//! status, so plant time does not run ahead of the planner). Ends with the run or on
//! SIGINT/SIGTERM.

use std::path::Path;

use dkrrt_config::{Mode, Scenario};
use dkrrt_msg::bus::{Bus, HeartbeatTx};
use dkrrt_msg::*;
use dkrrt_rrt::{Replanner, Summary, TrackerView};

use crate::goal_cli::{take_goal, GoalRequest};
use crate::replan::replanner;
use dkrrt_rt::clock::{mono_ns, Pacer};
use dkrrt_rt::signals;

/// What the planner reports at exit (JSON via `--stats`): the loop's summary and the bus.
#[derive(Debug, Clone, serde::Serialize)]
pub struct PlannerReport {
    #[serde(flatten)]
    pub summary: Summary,
    pub forecasts_received: u64,
    /// Messages refused: by the bus's contract checks, forecasts stamped ahead of the plant
    /// clock (`forecasts_ahead`) and those the core refused by the contract
    /// (`forecasts_invalid`).
    pub rejected: u64,
    /// Of `rejected`, per input: `state`, `command`, `forecast`, `goal`, `forecast_ahead`,
    /// `forecast_invalid`.
    pub rejected_by_input: std::collections::BTreeMap<&'static str, u64>,
    /// Why the newest refused message of each input was refused: the service and the
    /// contract's field (`"dkrrt/debris_forecast: tracks.steps.sigma_m[3] = …"`).
    pub rejections: Vec<String>,
    /// End-effector pose goals no IK solution reached (the goal in force was kept).
    pub pose_goals_unreachable: u64,
    pub stopped_by_signal: bool,
}

/// Runs the planner until the end of the run or a signal. `goal` overrides the scenario's.
pub fn run(
    run: &str,
    sc: &Scenario,
    goal: Option<[f64; NJ]>,
    first_traj_id: u64,
    stats_path: Option<&Path>,
    trace: Option<&Path>,
) -> Result<PlannerReport, String> {
    // With `trace`: per cycle, the predicted clearance of the arm's configuration (room
    // allocated up front for the scenario's duration), written as JSON `[[t_s, m], ...]` at exit.
    let cap = if trace.is_some() { (sc.run.duration_s * sc.planner.rate_hz * 2.0) as usize + 16 } else { 0 };
    let mut clearance: Vec<(f64, f64)> = Vec::with_capacity(cap);
    signals::install();
    if sc.forecasts() == dkrrt_config::Forecasts::Oracle {
        return Err("planner: planner.method = \"oracle-rrt\" needs the true future of the debris, which only the in-process lockstep has (`dkrrt eval`, `dkrrt study`)".into());
    }
    let (model, lim, req) = crate::source_setup(sc, goal, "planner")?;
    // The goal in force (a joint goal); a pose goal waits for the first state to be solved.
    let (mut goal, mut pending_pose) = match req {
        GoalRequest::Joint(q) => (Some(q), None),
        GoalRequest::Pose(p, q) => (None, Some((p, q))),
    };
    let mut core = replanner(sc, model);
    core.set_first_traj_id(first_traj_id);
    let mut pose_goals_unreachable = 0u64;
    let bus = Bus::new(run, "planner").map_err(|e| e.to_string())?;
    let mut state_sub = bus.subscriber::<RobotState>().map_err(|e| e.to_string())?;
    let mut state_lock = dkrrt_msg::bus::PublisherLock::default();
    let mut cmd_sub = bus.subscriber::<TorqueCommand>().map_err(|e| e.to_string())?;
    let mut fc_sub = bus.subscriber::<DebrisForecast>().map_err(|e| e.to_string())?;
    let mut goal_sub = bus.subscriber::<Goal>().map_err(|e| e.to_string())?;
    let mut traj_pub = bus.publisher::<Trajectory>(Source::Planner).map_err(|e| e.to_string())?;
    let mut status_pub = bus.publisher::<PlanStatus>(Source::Planner).map_err(|e| e.to_string())?;
    let mut hb = HeartbeatTx::new(&bus, Source::Planner, sc.run.heartbeat_hz).map_err(|e| e.to_string())?;
    let mut state = <RobotState as Zeroed>::zeroed();
    let mut cmd = <TorqueCommand as Zeroed>::zeroed();
    let mut fc = Box::new(<DebrisForecast as Zeroed>::zeroed());
    let mut out = Box::new(<Trajectory as Zeroed>::zeroed());
    let cycle_ns = (1e9 / sc.planner.rate_hz).round() as u64;
    let mut pacer = Pacer::new(cycle_ns, 0, 2_000_000);
    let mut have_state = false;
    let mut forecasts = 0u64;
    let mut clock = mono_ns;
    let lockstep = sc.run.mode == Mode::Lockstep;
    let mut stopped_by_signal = false;
    loop {
        if !lockstep {
            pacer.wait(signals::stop_requested);
        }
        if signals::stop_requested() {
            stopped_by_signal = true;
            break;
        }
        if state_lock.latest(&bus, &mut state_sub, &mut state, &lim).map_err(|e| e.to_string())? {
            have_state = true;
        }
        cmd_sub.latest(&mut cmd, &lim).map_err(|e| e.to_string())?;
        match take_goal(&mut goal_sub, &lim)? {
            Some(GoalRequest::Joint(q)) => {
                goal = Some(q);
                pending_pose = None;
            }
            Some(GoalRequest::Pose(p, q)) => pending_pose = Some((p, q)),
            None => {}
        }
        if let Some((p, q)) = pending_pose.filter(|_| have_state) {
            // Solved against the newest forecast, from where the arm is.
            pending_pose = None;
            let t_now = state.header.stamp_ns as f64 * 1e-9;
            match core.resolve_pose_goal(&p, &q, &state.q, t_now) {
                Some(g) => {
                    eprintln!("planner: pose goal {p:?} {q:?} -> joint goal {g:?}");
                    goal = Some(g);
                }
                None => {
                    pose_goals_unreachable += 1;
                    eprintln!("planner: pose goal {p:?} {q:?} is out of reach; keeping the goal in force");
                }
            }
        }
        let end = have_state && state.header.flags & FLAG_END_OF_RUN != 0;
        // Realtime: every wake is a cycle; lockstep: the core's plant-clock cadence.
        // The plant's controlled stop (FLAG_STOPPING): no new plans, the tracker brakes.
        let stopping = state.header.flags & FLAG_STOPPING != 0;
        let due = have_state && !end && !stopping && (!lockstep || core.cycle_due(state.header.stamp_ns));
        if let (true, Some(goal)) = (due, goal) {
            let new_fc = fc_sub.latest(&mut fc, &lim).map_err(|e| e.to_string())?;
            forecasts += new_fc as u64;
            let view = TrackerView {
                mode: ControllerMode::from_u32(cmd.mode).unwrap_or(ControllerMode::Idle),
                traj_id: cmd.traj_id as u64,
            };
            let d = core.step(
                state.header.stamp_ns,
                &state.q,
                view,
                new_fc.then_some(&*fc),
                &goal,
                &mut clock,
                &mut out,
            );
            if d.publish {
                traj_pub.publish(&mut out).map_err(|e| e.to_string())?;
            }
            let mut st = d.status;
            status_pub.publish(&mut st).map_err(|e| e.to_string())?;
            if clearance.len() < clearance.capacity() {
                let t = state.header.stamp_ns as f64 * 1e-9;
                if let Some(c) = core.predicted_clearance(&state.q, t) {
                    clearance.push((t, c));
                }
            }
        }
        // Late subscribers (a restarted tracker) get the plan from history.
        traj_pub.update_connections().map_err(|e| e.to_string())?;
        hb.maybe_send(
            mono_ns(),
            false,
            state.header.stamp_ns,
            ProcessState::Running,
            core.stats.cycles,
            core.stats.deadline_misses,
            rejected(&[state_sub.rejected, cmd_sub.rejected, fc_sub.rejected, goal_sub.rejected], &core),
            core.stats.fallbacks.brake,
        )
        .map_err(|e| e.to_string())?;
        if end {
            break;
        }
        if lockstep && !due {
            std::hint::spin_loop();
            std::thread::yield_now();
        }
    }
    let _ = hb.maybe_send(
        mono_ns(),
        true,
        state.header.stamp_ns,
        ProcessState::Stopping,
        core.stats.cycles,
        0,
        0,
        0,
    );
    let rep = PlannerReport {
        summary: core.summary(&sc.planner.method),
        forecasts_received: forecasts,
        rejected: rejected(
            &[state_sub.rejected, cmd_sub.rejected, fc_sub.rejected, goal_sub.rejected],
            &core,
        ),
        rejected_by_input: [
            ("state", state_sub.rejected),
            ("command", cmd_sub.rejected),
            ("forecast", fc_sub.rejected),
            ("goal", goal_sub.rejected),
            ("forecast_ahead", core.stats.forecasts_ahead),
            ("forecast_invalid", core.stats.forecasts_invalid),
        ]
        .into_iter()
        .collect(),
        rejections: [state_sub.rejection(), cmd_sub.rejection(), fc_sub.rejection(), goal_sub.rejection()]
            .into_iter()
            .chain([core.summary("").forecast_error])
            .flatten()
            .collect(),
        pose_goals_unreachable,
        stopped_by_signal,
    };
    dkrrt_rt::write_stats("planner", stats_path, &rep)?;
    if let Some(p) = trace {
        std::fs::write(p, serde_json::to_string(&clearance).map_err(|e| e.to_string())?)
            .map_err(|e| format!("planner: --trace {}: {e}", p.display()))?;
    }
    Ok(rep)
}

/// Messages the planner refused: those its subscribers' contract checks rejected (`subs`),
/// forecasts stamped ahead of the plant clock (`forecasts_ahead`) and those its core refused
/// by the contract (`forecasts_invalid`: none that passed the bus).
fn rejected(subs: &[u64], core: &Replanner) -> u64 {
    subs.iter().sum::<u64>() + core.stats.forecasts_ahead + core.stats.forecasts_invalid
}
