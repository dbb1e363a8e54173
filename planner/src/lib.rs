//! dkrrt-planner: planning cores and their process shells.
//!
//! * [`goto`]: the joint-space trajectory source (goal → jerk-limited trajectory message).
//! * [`process`]: the `dkrrt goto` process shell.
//! * [`predict`]: the debris predictor core of the `dkrrt predictor` process (models fitted
//!   for the scenario, observation frames in, fixed-size forecasts out).
//! * [`predictor_process`]: the `dkrrt predictor` process shell.
//! * [`replan`]: the scenario's DK-RRT replanning core (`dkrrt_rrt`), for both shells.
//! * [`planner_process`]: the `dkrrt planner` process shell.

pub mod goal_cli;
pub mod goto;
pub mod planner_process;
pub mod predict;
pub mod predictor_process;
pub mod process;
pub mod record_process;
pub mod replan;

/// The arm model of `sc`, its contract limits, and the goal (`goal`, a joint goal, else the
/// scenario's joint or end-effector pose goal), checked against them the way a `dkrrt/goal`
/// message is: what a trajectory source (`dkrrt goto`, `dkrrt planner`) starts from. Errors
/// name `who`.
pub fn source_setup(
    sc: &dkrrt_config::Scenario,
    goal: Option<[f64; dkrrt_msg::NJ]>,
    who: &str,
) -> Result<(dkrrt_model::ArmModel, dkrrt_msg::ContractLimits, goal_cli::GoalRequest), String> {
    let model = sc.load_arm().map_err(|e| e.to_string())?;
    let lim = dkrrt_config::arm::contract_limits(&model);
    let req = match goal {
        Some(q) => goal_cli::GoalRequest::Joint(q),
        None => sc.goal.request().ok_or_else(|| format!("{who}: the scenario gives no goal"))?,
    };
    goal_cli::check_goal(&lim, req, 0).map_err(|e| format!("{who}: {e}"))?;
    Ok((model, lim, req))
}
