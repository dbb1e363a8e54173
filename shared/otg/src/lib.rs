//! # dkrrt-otg — time-optimal, jerk-limited online trajectory generation
//!
//! An in-house Ruckig-class generator: from any current kinematic state
//! (position, velocity, acceleration) of `N` joints to a target state, it
//! computes the time-optimal motion under per-joint velocity, acceleration and
//! jerk limits, with all joints finishing together. It is allocation-free
//! (const-generic joint count, fixed-size storage) and never panics on bad
//! input: invalid input yields an [`OtgError`].
//!
//! Each joint's motion is a sequence of constant-jerk [`Segment`]s (at most
//! [`MAX_SEGMENTS`]), so a trajectory can be sent as a fixed-size message and
//! re-evaluated exactly anywhere.
//!
//! ```
//! use dkrrt_otg::{KinState, Limits, Options, Trajectory};
//!
//! let limits = Limits { v_max: [1.0, 2.0], a_max: [2.0, 2.0], j_max: [10.0, 10.0] };
//! let current = KinState { p: [0.0, 0.0], v: [0.0, 0.0], a: [0.0, 0.0] };
//! let target = KinState { p: [1.0, -0.5], v: [0.0, 0.0], a: [0.0, 0.0] };
//! let traj = Trajectory::calculate(&current, &target, &limits, &Options::default()).unwrap();
//!
//! // Offline use: sample anywhere (time is clamped to [0, duration]).
//! let mid = traj.at(0.5 * traj.duration());
//! assert!(mid.v[0] > 0.0);
//! let end = traj.at(traj.duration());
//! assert!((end.p[0] - 1.0).abs() < 1e-8 && (end.p[1] + 0.5).abs() < 1e-8);
//!
//! // Safe hold: brake to rest from any state (velocity interface).
//! let moving = KinState { p: [0.3, 0.1], v: [0.8, -1.5], a: [1.0, 0.5] };
//! let stop = Trajectory::calculate_velocity(&moving, &[0.0; 2], &[0.0; 2], &limits, &Options::default()).unwrap();
//! let rest = stop.at(stop.duration());
//! assert!(rest.v.iter().all(|v| v.abs() < 1e-8));
//!
//! // Segments for a fixed-size message.
//! for s in traj.joint_segments(0) {
//!     assert!(s.t1 >= s.t0);
//! }
//! ```
#![forbid(unsafe_code)]
// `!(x >= y)` is deliberate: it is also true for NaN. Index loops mirror the math.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]

mod brake;
mod error;
mod online;
mod poly;
mod profile;
mod step1;
mod step2;
mod sync;
mod trajectory;
mod velocity;
mod waypoints;

pub use error::OtgError;
pub use online::{Otg, Output, Status};
pub use trajectory::{speed_peak, turning_points, Extrema, Sample, Segment, Trajectory};

/// Most intermediate waypoints a single waypoint trajectory may have.
pub const MAX_WAYPOINTS: usize = 8;

/// Most constant-jerk segments per joint in any [`Trajectory`]: a braking
/// pre-trajectory (2) plus 7 phases for each of up to `MAX_WAYPOINTS + 1` sections.
pub const MAX_SEGMENTS: usize = 2 + 7 * (MAX_WAYPOINTS + 1);

/// Per-joint kinematic limits (symmetric: `|v| <= v_max`, `|a| <= a_max`,
/// `|jerk| <= j_max`). All must be finite and strictly positive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits<const N: usize> {
    pub v_max: [f64; N],
    pub a_max: [f64; N],
    pub j_max: [f64; N],
}

/// Kinematic state of `N` joints.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KinState<const N: usize> {
    pub p: [f64; N],
    pub v: [f64; N],
    pub a: [f64; N],
}

impl<const N: usize> KinState<N> {
    /// All joints at rest at position `p`.
    pub fn rest(p: [f64; N]) -> Self {
        KinState { p, v: [0.0; N], a: [0.0; N] }
    }
}

impl<const N: usize> Default for KinState<N> {
    fn default() -> Self {
        Self::rest([0.0; N])
    }
}

/// How the joints are synchronized.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Sync {
    /// All joints finish at the same (earliest feasible) time.
    #[default]
    Time,
    /// Like `Time`, and additionally the motion is a straight line in joint
    /// space whenever that is possible (falls back to `Time` otherwise).
    Phase,
    /// Every joint moves time-optimally on its own; the trajectory's duration is
    /// that of the slowest joint and faster joints hold their target afterwards.
    None,
}

/// Calculation options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options<const N: usize> {
    /// Joint synchronization (default [`Sync::Time`]).
    pub sync: Sync,
    /// The trajectory lasts at least this long (seconds).
    pub min_duration: Option<f64>,
    /// If set, the duration is rounded up to a whole number of these periods
    /// (seconds), e.g. the 1 ms control period.
    pub period: Option<f64>,
    /// Per-joint enable. A disabled joint keeps its current acceleration (zero
    /// jerk) from its current state and does not influence the duration.
    pub enabled: [bool; N],
}

impl<const N: usize> Default for Options<N> {
    fn default() -> Self {
        Options { sync: Sync::Time, min_duration: None, period: None, enabled: [true; N] }
    }
}
