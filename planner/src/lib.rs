//! dkrrt-planner: planning cores and their process shells.
//!
//! * [`goto`]: the joint-space trajectory source (goal → jerk-limited trajectory message).
//! * [`process`]: the `dkrrt goto` process shell.
//!
//! The anytime DK-RRT planner will live here too.

pub mod goto;
pub mod process;
