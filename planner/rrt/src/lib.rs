//! dkrrt-rrt: the anytime DK-RRT planner core, with no IPC.
//!
//! * [`world`]: the debris world in time (forecast tracks → inflated obstacles at any `t`).
//! * [`check`]: configuration / motion / rest checks with a sampling density that lets nothing
//!   slip between two samples (the argument is in the module docs).
//! * [`rrt`]: the space-time RRT (rest-to-rest jerk-limited edges with waits, goal time free,
//!   first solution fast, then improved while the budget lasts; escape when the goal is out
//!   of reach).
//! * [`build`]: a plan as the fixed-size trajectory message the tracker follows.
//! * [`problem`]: a planning problem as a JSON file and its solution (`dkrrt plan`).
//! * [`replan`]: the replanning loop's step function (keep / replan / splice / fallbacks).
//!
//! Preallocated: after construction, a planning cycle allocates nothing (counting-allocator
//! test). Deterministic for a given seed and iteration budget.

pub mod build;
pub mod check;
pub mod connect;
pub mod goal;
pub mod problem;
pub mod replan;
pub mod rrt;
pub mod world;

pub use check::{Check, Checker};
pub use replan::{
    check_message, message_speed_peaks, CycleClock, Decision, Fallbacks, ReplanConfig, ReplanStats,
    Replanner, Summary, TrackerView,
};
pub use rrt::{
    Plan, PlanStats, Planner, PlannerConfig, Reach, Request, DODGE_AREA_FRACTION, DODGE_DT, DODGE_GAIN_M,
    DODGE_TIME_GAIN_S,
};
pub use world::{After, Gaps, TimedPose, WorldError, WorldInTime};
