//! dkrrt-planner: planning cores and their process shells.
//!
//! * [`goto`]: the joint-space trajectory source (goal → jerk-limited trajectory message).
//! * [`process`]: the `dkrrt goto` process shell.
//! * [`predict`]: the debris predictor core of the `dkrrt predictor` process (models fitted
//!   for the scenario, observation frames in, fixed-size forecasts out).
//! * [`predictor_process`]: the `dkrrt predictor` process shell.
//!
//! The anytime DK-RRT planner will live here too.

pub mod goto;
pub mod predict;
pub mod predictor_process;
pub mod process;
pub mod record_process;
