//! Error values returned by the generator. Every invalid input yields one of
//! these; the generator never panics and never returns a wrong trajectory.

/// Why a trajectory could not be calculated.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum OtgError {
    /// A velocity, acceleration or jerk limit is zero, negative, NaN or infinite.
    #[error("joint {joint}: limit `{which}` = {value} must be finite and > 0")]
    InvalidLimit { joint: usize, which: &'static str, value: f64 },
    /// A current or target state entry is NaN or infinite.
    #[error("joint {joint}: {which} = {value} is not a finite number")]
    NonFiniteState { joint: usize, which: &'static str, value: f64 },
    /// The target velocity is beyond the velocity limit.
    #[error("joint {joint}: target velocity {value} exceeds the velocity limit {limit}")]
    TargetVelocityBeyondLimit { joint: usize, value: f64, limit: f64 },
    /// The target acceleration is beyond the acceleration limit.
    #[error("joint {joint}: target acceleration {value} exceeds the acceleration limit {limit}")]
    TargetAccelerationBeyondLimit { joint: usize, value: f64, limit: f64 },
    /// The target acceleration cannot be reached without violating the velocity
    /// limit (arriving with acceleration `a` at velocity `v` requires a velocity
    /// of `v ∓ a²/(2 j_max)` shortly before).
    #[error("joint {joint}: target acceleration {acceleration} at velocity {velocity} is unreachable within the velocity limit")]
    UnreachableTargetAcceleration { joint: usize, velocity: f64, acceleration: f64 },
    /// An option is invalid (negative/NaN minimum duration or period).
    #[error("invalid option `{which}` = {value}")]
    InvalidOption { which: &'static str, value: f64 },
    /// The trajectory would need more segments than [`crate::MAX_SEGMENTS`]
    /// (e.g. too many waypoints, see [`crate::MAX_WAYPOINTS`]).
    #[error("too many waypoints: {given} > {max}")]
    TooManyWaypoints { given: usize, max: usize },
    /// The numerical solver found no valid profile (should not happen for valid
    /// input; reported instead of returning a wrong trajectory).
    #[error("joint {joint}: no valid profile found (numerical failure)")]
    NoSolution { joint: usize },
    /// The requested duration exceeds the numeric range the generator supports.
    #[error("joint {joint}: resulting duration {duration} s is too long")]
    DurationTooLong { joint: usize, duration: f64 },
}
