//! dkrrt-planner: planning cores and their process shells.
//!
//! * [`goto`]: the joint-space trajectory source (goal → jerk-limited trajectory message).
//! * [`process`]: the `dkrrt goto` process shell.
//! * [`predict`]: the debris predictor core of the `dkrrt predictor` process (models fitted
//!   for the scenario, observation frames in, fixed-size forecasts out).
//! * [`predictor_process`]: the `dkrrt predictor` process shell.
//! * [`replan`]: the scenario's DK-RRT replanning core (`dkrrt_rrt`), for both shells.
//! * [`planner_process`]: the `dkrrt planner` process shell.

pub mod goto;
pub mod planner_process;
pub mod predict;
pub mod predictor_process;
pub mod process;
pub mod record_process;
pub mod replan;
