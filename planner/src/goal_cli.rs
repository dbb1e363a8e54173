//! `dkrrt goal`: sends one [`Goal`] (joint positions or an end-effector pose) to the sources
//! of a live run, as a user tool would. The goal is validated against the scenario's arm
//! first (the error names the field); it is published once a source subscribes (up to
//! `wait_s`), and the publisher stays up for a second so the sources read it.

use std::time::{Duration, Instant};

use dkrrt_config::Scenario;
use dkrrt_msg::bus::{Bus, Sub};
use dkrrt_msg::{ContractLimits, Goal, GoalKind, Source, Validate, Zeroed};

/// What to ask for (the scenario's `[goal]` is one too).
pub use dkrrt_config::GoalRequest;

/// Reads every valid goal waiting on `sub` (invalid ones are counted by `sub`); the newest
/// wins. What the trajectory sources (goto, planner) do with `dkrrt/goal` each cycle.
pub fn take_goal(sub: &mut Sub<Goal>, lim: &ContractLimits) -> Result<Option<GoalRequest>, String> {
    let mut last = None;
    sub.for_each(lim, |m| {
        last = Some(match GoalKind::from_u32(m.kind) {
            Some(GoalKind::Pose) => GoalRequest::Pose(m.pose_p, m.pose_q),
            _ => GoalRequest::Joint(m.q),
        })
    })
    .map_err(|e| e.to_string())?;
    Ok(last)
}

/// The message for `req`, checked against the arm of `sc`.
pub fn goal_message(sc: &Scenario, req: GoalRequest, goal_id: u64) -> Result<Goal, String> {
    let model = sc.load_arm().map_err(|e| e.to_string())?;
    let lim = dkrrt_config::arm::contract_limits(&model);
    check_goal(&lim, req, goal_id)
}

/// The message for `req`, checked against the contract limits `lim` (the error names the
/// field).
pub fn check_goal(lim: &ContractLimits, req: GoalRequest, goal_id: u64) -> Result<Goal, String> {
    let mut g = <Goal as Zeroed>::zeroed();
    g.goal_id = goal_id;
    match req {
        GoalRequest::Joint(q) => {
            g.kind = GoalKind::Joint as u32;
            g.q = q;
        }
        GoalRequest::Pose(p, q) => {
            g.kind = GoalKind::Pose as u32;
            g.pose_p = p;
            g.pose_q = q;
        }
    }
    g.validate(lim).map_err(|e| format!("goal rejected: {e}"))?;
    Ok(g)
}

/// Publishes `g` on run `run` once a subscriber is connected (waiting at most `wait_s`).
/// Returns the number of subscribers it went to.
pub fn send(run: &str, mut g: Goal, wait_s: f64) -> Result<usize, String> {
    let bus = Bus::new(run, "goal-cli").map_err(|e| e.to_string())?;
    let mut publ = bus.publisher::<Goal>(Source::User).map_err(|e| e.to_string())?;
    let t0 = Instant::now();
    let mut n = 0;
    while t0.elapsed().as_secs_f64() < wait_s {
        n = bus.subscriber_count::<Goal>().map_err(|e| e.to_string())?;
        if n > 0 {
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    if n == 0 {
        return Err(format!("no goto or planner subscribed to dkrrt/goal of run {run:?} within {wait_s} s"));
    }
    publ.update_connections().map_err(|e| e.to_string())?;
    publ.publish(&mut g).map_err(|e| e.to_string())?;
    // Keep the sample alive until the sources have polled it (they do every cycle).
    std::thread::sleep(Duration::from_secs(1));
    Ok(n)
}
