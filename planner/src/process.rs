//! The `dkrrt goto` process shell: waits for the robot state, plans a
//! jerk-limited trajectory to the goal and publishes it; replans when a new
//! [`Goal`] arrives on `dkrrt/goal` (from the reference it is on, so the
//! motion stays continuous). If the tracker ends up holding short of the
//! goal (a safe hold after stale state or an invalid trajectory) while the
//! robot state flows again, it re-issues the goal from where the arm rests.
//! Ends with the run.

use std::path::Path;

use dkrrt_config::Scenario;
use dkrrt_msg::bus::{Bus, HeartbeatTx};
use dkrrt_msg::*;
use dkrrt_otg::Limits;
use dkrrt_rt::clock::mono_ns;
use dkrrt_rt::signals;

use crate::goal_cli::{take_goal, GoalRequest};
use crate::goto::Goto;
pub use crate::goto::GOAL_TOLERANCE_RAD;

#[derive(Debug, Clone, serde::Serialize)]
pub struct GotoReport {
    pub trajectories: u64,
    pub last_duration_s: f64,
    pub goals_received: u64,
    /// Goals re-issued after the tracker stopped short of them (safe hold).
    pub replans_after_hold: u64,
    pub goals_rejected: u64,
    /// End-effector pose goals no IK solution reached.
    pub pose_goals_unreachable: u64,
    pub states_rejected: u64,
    pub plan_errors: Vec<String>,
}

/// Runs the trajectory source. `goal` overrides the scenario's goal.
pub fn run(
    run: &str,
    sc: &Scenario,
    goal: Option<[f64; NJ]>,
    stats_path: Option<&Path>,
) -> Result<GotoReport, String> {
    signals::install();
    let (model, lim, req) = crate::source_setup(sc, goal, "goto")?;
    // A pose goal is solved from the first state; nothing is planned before.
    let (first_goal, mut pending_pose) = match req {
        GoalRequest::Joint(q) => (Some(q), None),
        GoalRequest::Pose(p, q) => (None, Some((p, q))),
    };
    let mut goal_known = first_goal.is_some();
    let bus = Bus::new(run, "goto").map_err(|e| e.to_string())?;
    let mut state_sub = bus.subscriber::<RobotState>().map_err(|e| e.to_string())?;
    let mut state_lock = dkrrt_msg::bus::PublisherLock::default();
    let mut goal_sub = bus.subscriber::<Goal>().map_err(|e| e.to_string())?;
    let mut cmd_sub = bus.subscriber::<TorqueCommand>().map_err(|e| e.to_string())?;
    let mut cmd = <TorqueCommand as Zeroed>::zeroed();
    let mut last_seq = 0u64;
    let mut traj_pub = bus.publisher::<Trajectory>(Source::TrajectorySource).map_err(|e| e.to_string())?;
    let mut hb =
        HeartbeatTx::new(&bus, Source::TrajectorySource, sc.run.heartbeat_hz).map_err(|e| e.to_string())?;
    let limits = Limits { v_max: sc.motion.v_max, a_max: sc.motion.a_max, j_max: sc.motion.j_max };
    let period_s = sc.period_ns() as f64 * 1e-9;

    let mut state = <RobotState as Zeroed>::zeroed();
    let mut traj = Box::new(<Trajectory as Zeroed>::zeroed());
    let mut have_state = false;
    let mut core = Goto::new(limits, period_s, first_goal.unwrap_or([0.0; NJ]));
    let mut rep = GotoReport {
        trajectories: 0,
        last_duration_s: 0.0,
        goals_received: 0,
        replans_after_hold: 0,
        goals_rejected: 0,
        pose_goals_unreachable: 0,
        states_rejected: 0,
        plan_errors: Vec::new(),
    };
    while !signals::stop_requested() {
        if state_lock.latest(&bus, &mut state_sub, &mut state, &lim).map_err(|e| e.to_string())? {
            have_state = true;
        }
        match take_goal(&mut goal_sub, &lim)? {
            Some(GoalRequest::Joint(q)) => {
                core.set_goal(q);
                goal_known = true;
                pending_pose = None;
            }
            Some(GoalRequest::Pose(p, q)) => pending_pose = Some((p, q)),
            None => {}
        }
        if let Some((p, q)) = pending_pose.filter(|_| have_state) {
            pending_pose = None;
            if core.set_pose_goal(&model, &p, &q, &state.q) {
                goal_known = true;
            } else {
                rep.pose_goals_unreachable += 1;
                eprintln!("goto: pose goal {p:?} {q:?} is out of reach; keeping the goal in force");
            }
        }
        rep.goals_received = goal_sub.received;
        rep.goals_rejected = goal_sub.rejected;
        rep.states_rejected = state_sub.rejected;
        let fresh = have_state && state.header.seq > last_seq;
        last_seq = state.header.seq;
        let have_cmd = cmd_sub.latest(&mut cmd, &lim).map_err(|e| e.to_string())?;
        // The plant's controlled stop (FLAG_STOPPING): nothing new is planned.
        if have_state && goal_known && state.header.flags & FLAG_STOPPING == 0 {
            // The tracker holds: its newest command is a hold for a recent state.
            let holding = fresh
                && have_cmd
                && cmd.mode == ControllerMode::Hold as u32
                && cmd.state_seq + 5 >= state.header.seq;
            let reissues = core.reissues;
            match core.step(state.header.stamp_ns, &state.q, holding, &mut traj) {
                Some(Ok(d)) => {
                    if core.reissues > reissues {
                        eprintln!("goto: tracker held short of the goal; re-issued it");
                    }
                    traj_pub.publish(&mut traj).map_err(|e| e.to_string())?;
                    rep.trajectories += 1;
                    rep.last_duration_s = d;
                    eprintln!("goto: trajectory {} to {:?}: {d:.3} s", core.traj_id, core.goal());
                }
                Some(Err(e)) => {
                    eprintln!("goto: cannot plan to {:?}: {e}", core.goal());
                    rep.plan_errors.push(e.to_string());
                }
                None => {}
            }
            rep.replans_after_hold = core.reissues;
        }
        if have_state && state.header.flags & FLAG_END_OF_RUN != 0 {
            break;
        }
        // Late subscribers (a restarted tracker) get the trajectory from history.
        traj_pub.update_connections().map_err(|e| e.to_string())?;
        hb.maybe_send(
            mono_ns(),
            false,
            state.header.stamp_ns,
            ProcessState::Running,
            rep.trajectories,
            0,
            state_sub.rejected + goal_sub.rejected,
            0,
        )
        .map_err(|e| e.to_string())?;
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    let _ = hb.maybe_send(
        mono_ns(),
        true,
        state.header.stamp_ns,
        ProcessState::Stopping,
        rep.trajectories,
        0,
        0,
        0,
    );
    dkrrt_rt::write_stats("goto", stats_path, &rep)?;
    Ok(rep)
}
