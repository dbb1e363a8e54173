//! The payload types. Every type is `#[repr(C)]`, `Copy`, pointer-free and
//! `ZeroCopySend`, so it can live in iceoryx2 shared memory. Sizes and
//! alignments are checked at compile time at the bottom of this file; a change
//! of layout must bump the `type_name` version so old and new processes refuse
//! to connect instead of misreading each other.

use iceoryx2::prelude::ZeroCopySend;

/// Number of actuated joints of the arm.
pub const NJ: usize = 6;
/// Piecewise-constant-jerk segments per joint a trajectory message can carry.
pub const MAX_SEGMENTS: usize = 72;
/// Debris objects an observation or forecast message can carry.
pub const MAX_DEBRIS: usize = 32;
/// Forecast steps per debris object.
pub const FORECAST_STEPS: usize = 40;

/// Common header of every payload.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
pub struct Header {
    /// Per-publisher sequence number, starting at 0, +1 per message.
    pub seq: u64,
    /// Plant-clock time in ns (the simulator's or driver's time of the data).
    pub stamp_ns: u64,
    /// CLOCK_MONOTONIC time in ns at which the message was published
    /// (for latency measurement across processes on one machine).
    pub mono_ns: u64,
    /// Who published it: a [`Source`] value.
    pub source: u32,
    /// Bit flags; meaning per message type (see the `FLAG_*` constants).
    pub flags: u32,
}

impl Header {
    pub const fn new(source: Source) -> Self {
        Header { seq: 0, stamp_ns: 0, mono_ns: 0, source: source as u32, flags: 0 }
    }
}

/// Publisher identities carried in [`Header::source`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum Source {
    Sim = 1,
    Tracker = 2,
    TrajectorySource = 3,
    Planner = 4,
    Predictor = 5,
    Launcher = 6,
    /// A real arm driver taking the simulator's place.
    Driver = 7,
    /// A user tool (`dkrrt goal`).
    User = 8,
}

impl Source {
    pub fn from_u32(v: u32) -> Option<Source> {
        Some(match v {
            1 => Source::Sim,
            2 => Source::Tracker,
            3 => Source::TrajectorySource,
            4 => Source::Planner,
            5 => Source::Predictor,
            6 => Source::Launcher,
            7 => Source::Driver,
            8 => Source::User,
            _ => return None,
        })
    }
    pub fn name(self) -> &'static str {
        match self {
            Source::Sim => "sim",
            Source::Tracker => "tracker",
            Source::TrajectorySource => "goto",
            Source::Planner => "planner",
            Source::Predictor => "predictor",
            Source::Launcher => "launcher",
            Source::Driver => "driver",
            Source::User => "user",
        }
    }
}

/// [`RobotState`] flag: the plant ends the run after this state; consumers finish cleanly.
pub const FLAG_END_OF_RUN: u32 = 1;
/// [`RobotState`] flag: the plant's own watchdog has engaged the joint brakes
/// (no valid torque command for too long).
pub const FLAG_BRAKE_ENGAGED: u32 = 2;
/// [`RobotState`] flag: the plant is ending the run (a stop request, or its duration is
/// over with the arm moving): the tracker brakes to rest within the motion limits and holds,
/// trajectory sources stop planning; the plant ends the run (`FLAG_END_OF_RUN`) once the arm
/// is at rest.
pub const FLAG_STOPPING: u32 = 4;

/// Measured joint state of the arm, published by the plant (sim or driver) every tick (1 kHz).
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("dkrrt::RobotState/1")]
pub struct RobotState {
    pub header: Header,
    /// Joint positions, rad.
    pub q: [f64; NJ],
    /// Joint velocities, rad/s.
    pub qd: [f64; NJ],
    /// Torque actually applied over the last tick (after saturation), N·m.
    pub tau: [f64; NJ],
}

/// Controller mode carried by a [`TorqueCommand`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum ControllerMode {
    /// No trajectory yet: holding the first measured position.
    Idle = 0,
    /// Tracking the active trajectory.
    Track = 1,
    /// Safe hold, phase 1: decelerating to rest within the limits.
    Brake = 2,
    /// Safe hold, phase 2 (or trajectory finished): holding position.
    Hold = 3,
}

impl ControllerMode {
    pub fn from_u32(v: u32) -> Option<Self> {
        Some(match v {
            0 => ControllerMode::Idle,
            1 => ControllerMode::Track,
            2 => ControllerMode::Brake,
            3 => ControllerMode::Hold,
            _ => return None,
        })
    }
}

/// Joint torque command, published by the tracker once per received state (1 kHz).
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("dkrrt::TorqueCommand/2")]
pub struct TorqueCommand {
    pub header: Header,
    /// Commanded joint torques, N·m.
    pub tau: [f64; NJ],
    /// The reference joint positions (rad) and velocities (rad/s) for the tick this command
    /// acts in (its state's tick + 1): the setpoints of an arm that takes position/velocity
    /// commands instead of torques (`tracker.command = "servo"`); the measured position and
    /// zero velocity while the tracker has no reference (idle).
    pub q_set: [f64; NJ],
    pub qd_set: [f64; NJ],
    /// `header.seq` of the [`RobotState`] this command answers.
    pub state_seq: u64,
    /// A [`ControllerMode`] value.
    pub mode: u32,
    /// Id of the trajectory being tracked (0: none).
    pub traj_id: u32,
}

/// One segment of constant jerk for one joint. It starts at `t0` (s, relative
/// to the trajectory start) in state (`p`, `v`, `a`) and lasts until the next
/// segment's `t0` (or the trajectory's duration for the last one).
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
pub struct JerkSegment {
    pub t0: f64,
    pub p: f64,
    pub v: f64,
    pub a: f64,
    pub j: f64,
}

/// A joint trajectory as per-joint piecewise-constant-jerk segments: what the
/// tracker samples each tick. Published on change by the trajectory source or planner.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("dkrrt::Trajectory/1")]
pub struct Trajectory {
    pub header: Header,
    /// Unique non-zero id per trajectory from one publisher.
    pub traj_id: u64,
    /// Plant-clock time (ns) at which trajectory time 0 happens.
    pub start_ns: u64,
    /// Duration in seconds; after it the final state is held.
    pub duration_s: f64,
    /// Segments used per joint (1..=MAX_SEGMENTS).
    pub n_seg: [u32; NJ],
    pub seg: [[JerkSegment; MAX_SEGMENTS]; NJ],
}

/// Goal for the trajectory source / planner: joint positions, or an end-effector pose
/// ([`GoalKind`]).
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("dkrrt::Goal/2")]
pub struct Goal {
    pub header: Header,
    pub goal_id: u64,
    /// [`GoalKind`].
    pub kind: u32,
    pub _pad: u32,
    /// Target joint positions, rad (`GoalKind::Joint`).
    pub q: [f64; NJ],
    /// Target end-effector position in the base frame, m (`GoalKind::Pose`).
    pub pose_p: [f64; 3],
    /// Target end-effector attitude in the base frame, (w, x, y, z), unit (`GoalKind::Pose`).
    pub pose_q: [f64; 4],
}

/// What a [`Goal`] asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum GoalKind {
    /// The joint positions `q`.
    Joint = 0,
    /// The end-effector pose `pose_p`, `pose_q` (the source solves IK).
    Pose = 1,
}

impl GoalKind {
    pub fn from_u32(v: u32) -> Option<Self> {
        match v {
            0 => Some(GoalKind::Joint),
            1 => Some(GoalKind::Pose),
            _ => None,
        }
    }
}

/// Life-cycle state reported in a [`Heartbeat`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum ProcessState {
    Starting = 0,
    Running = 1,
    SafeHold = 2,
    Stopping = 3,
    Fault = 4,
}

impl ProcessState {
    pub fn from_u32(v: u32) -> Option<Self> {
        Some(match v {
            0 => ProcessState::Starting,
            1 => ProcessState::Running,
            2 => ProcessState::SafeHold,
            3 => ProcessState::Stopping,
            4 => ProcessState::Fault,
            _ => return None,
        })
    }
}

/// Health and liveness of one process, published at 10 Hz by every process.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("dkrrt::Heartbeat/1")]
pub struct Heartbeat {
    pub header: Header,
    /// A [`ProcessState`] value.
    pub state: u32,
    pub _reserved: u32,
    /// Loop iterations so far.
    pub ticks: u64,
    /// Deadlines missed so far.
    pub deadline_misses: u64,
    /// Incoming messages rejected by validation so far.
    pub rejected: u64,
    /// Times the process entered a safe state so far.
    pub safe_hold_entries: u64,
}

/// [`DebrisObs`] flag: `v` and `w` hold measured velocities.
pub const DEBRIS_HAS_VELOCITY: u32 = 1;

/// [`DebrisObs`] flag: the pose comes from a partial view (an object cut by the image border
/// or hidden in part): `p` is good only to about the object's size; `q` is measured only for
/// a rod (its axis from the visible part), else it is the last attitude seen whole.
pub const DEBRIS_PARTIAL: u32 = 2;

/// [`DebrisObs`] flag: this view shows the object larger than every earlier one (a rod seen
/// end-on at first, then broadside): the earlier reports showed it in part, so their centres
/// were off; restart the object's position and velocity estimate from this one.
pub const DEBRIS_RESTART: u32 = 4;

/// [`DebrisObs`] flag: `q` measures only the body z axis (a rod's axis or a disc's normal,
/// which a depth view shows):
/// its spin about that axis is arbitrary (a front end's bookkeeping, not a measurement), and
/// so is its sign. The predictor takes the axis only and keeps its own spin.
pub const DEBRIS_AXIS_ONLY: u32 = 8;

/// [`DebrisShape::kind`] values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum ShapeKind {
    /// Nothing known but the bounding radius: the shape is the bounding sphere.
    Unknown = 0,
    /// Sphere: `dims[0]` = radius.
    Sphere = 1,
    /// Capsule (rod) along the body z axis: `dims[0]` = half length of the axis, `dims[1]` = radius.
    Capsule = 2,
    /// Box (also panels, and convex pieces as their body-frame box): `dims` = half extents.
    Box = 3,
    /// Disc: a flat cylinder about the body z axis, `dims[0]` = radius, `dims[1]` = half
    /// thickness. What a panel sweeps as it turns in its own plane: a depth front end that sees
    /// a square panel's normal but not its in-plane attitude reports it so (with
    /// [`DEBRIS_AXIS_ONLY`]); its spin about z and a half turn end over end leave it unchanged.
    Disc = 4,
}

impl ShapeKind {
    pub fn from_u32(v: u32) -> Option<Self> {
        Some(match v {
            0 => ShapeKind::Unknown,
            1 => ShapeKind::Sphere,
            2 => ShapeKind::Capsule,
            3 => ShapeKind::Box,
            4 => ShapeKind::Disc,
            _ => return None,
        })
    }
}

/// A debris object's shape as a perception driver would estimate it, in the body frame of the
/// pose it travels with: a primitive centred at `offset` (body axes), its axes along the body's.
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
pub struct DebrisShape {
    /// A [`ShapeKind`] value.
    pub kind: u32,
    pub _reserved: u32,
    /// Dimensions per kind (see [`ShapeKind`]), m.
    pub dims: [f64; 3],
    /// Centre of the primitive in the body frame, m.
    pub offset: [f64; 3],
}

impl DebrisShape {
    pub const fn sphere(radius: f64) -> Self {
        DebrisShape {
            kind: ShapeKind::Sphere as u32,
            _reserved: 0,
            dims: [radius, 0.0, 0.0],
            offset: [0.0; 3],
        }
    }
    pub const fn capsule(half_length: f64, radius: f64) -> Self {
        DebrisShape {
            kind: ShapeKind::Capsule as u32,
            _reserved: 0,
            dims: [half_length, radius, 0.0],
            offset: [0.0; 3],
        }
    }
    pub const fn cuboid(half_extents: [f64; 3], offset: [f64; 3]) -> Self {
        DebrisShape { kind: ShapeKind::Box as u32, _reserved: 0, dims: half_extents, offset }
    }
    pub const fn disc(radius: f64, half_thickness: f64) -> Self {
        DebrisShape {
            kind: ShapeKind::Disc as u32,
            _reserved: 0,
            dims: [radius, half_thickness, 0.0],
            offset: [0.0; 3],
        }
    }
    /// The largest distance from the body origin of a surface point that moves under a rotation
    /// about the origin, m: an attitude error θ moves the surface by at most θ times it (a
    /// centred sphere does not move). `Unknown`: the bounding radius.
    pub fn rotation_lever(&self, bounding_radius: f64) -> f64 {
        let o = (self.offset[0].powi(2) + self.offset[1].powi(2) + self.offset[2].powi(2)).sqrt();
        let d = &self.dims;
        match ShapeKind::from_u32(self.kind) {
            Some(ShapeKind::Sphere) => o,
            Some(ShapeKind::Capsule) => o + d[0],
            Some(ShapeKind::Box) => o + (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt(),
            Some(ShapeKind::Disc) => o + d[0].hypot(d[1]),
            _ => bounding_radius,
        }
    }

    /// Radius of a sphere about the body origin enclosing the shape, m (0 for `Unknown`).
    pub fn bounding_radius(&self) -> f64 {
        let o = (self.offset[0].powi(2) + self.offset[1].powi(2) + self.offset[2].powi(2)).sqrt();
        let d = &self.dims;
        o + match ShapeKind::from_u32(self.kind) {
            Some(ShapeKind::Sphere) => d[0],
            Some(ShapeKind::Capsule) => d[0] + d[1],
            Some(ShapeKind::Box) => (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt(),
            Some(ShapeKind::Disc) => d[0].hypot(d[1]),
            _ => 0.0,
        }
    }
}

/// One observed debris object.
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
pub struct DebrisObs {
    pub id: u32,
    pub flags: u32,
    /// Plant-clock time of the measurement, ns (observations may arrive late).
    pub t_meas_ns: u64,
    /// Position in the arm base frame, m.
    pub p: [f64; 3],
    /// Attitude quaternion (w, x, y, z), unit norm.
    pub q: [f64; 4],
    /// Linear velocity, m/s (valid with [`DEBRIS_HAS_VELOCITY`]).
    pub v: [f64; 3],
    /// Angular velocity in the body frame, rad/s (valid with [`DEBRIS_HAS_VELOCITY`]).
    pub w: [f64; 3],
    /// Radius of a sphere around the body origin enclosing its shape, m.
    pub bounding_radius: f64,
    /// The estimated shape (kind `Unknown`: only the bounding sphere is known).
    pub shape: DebrisShape,
}

/// Debris observations of one sensor frame (30–100 Hz).
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("dkrrt::DebrisObservation/2")]
pub struct DebrisObservation {
    pub header: Header,
    pub count: u32,
    pub _reserved: u32,
    pub items: [DebrisObs; MAX_DEBRIS],
}

/// One predicted pose with its uncertainty.
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
pub struct ForecastStep {
    pub p: [f64; 3],
    /// (w, x, y, z), unit norm.
    pub q: [f64; 4],
    /// Error bound of the shape's surface at this horizon, m: the position bound plus what the
    /// attitude bound moves the surface by (inflate the shape by it).
    pub sigma_m: f64,
    /// The position (centre) error bound alone, m: the bounding sphere inflated by it is also
    /// a valid bound, tighter when the attitude is poorly known.
    pub sigma_pos_m: f64,
}

/// The forecast of one debris object.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
pub struct ForecastTrack {
    pub id: u32,
    pub _reserved: u32,
    pub bounding_radius: f64,
    /// The track's shape (from the observations), in the frame of the forecast poses.
    pub shape: DebrisShape,
    pub steps: [ForecastStep; FORECAST_STEPS],
}

/// Time-indexed debris forecast (≥ 50 Hz): step `k` of every track is the
/// prediction for plant time `t0_ns + (k + 1) · dt_s`.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("dkrrt::DebrisForecast/2")]
pub struct DebrisForecast {
    pub header: Header,
    pub count: u32,
    /// Steps used per track (1..=FORECAST_STEPS).
    pub steps: u32,
    pub dt_s: f64,
    pub t0_ns: u64,
    pub tracks: [ForecastTrack; MAX_DEBRIS],
}

/// [`PlanStatus::fallback`] values: what the replanning loop did when it found no new valid plan.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum Fallback {
    /// A valid plan is active (new or kept because it stays valid).
    None = 0,
    /// No new plan was found; the current one is still valid and kept.
    Keep = 1,
    /// The best escape (a safe haven short of the goal) was published.
    Escape = 2,
    /// Nothing valid: a brake to rest was published (or the arm is held at rest).
    Brake = 3,
}

impl Fallback {
    pub fn from_u32(v: u32) -> Option<Self> {
        Some(match v {
            0 => Fallback::None,
            1 => Fallback::Keep,
            2 => Fallback::Escape,
            3 => Fallback::Brake,
            _ => return None,
        })
    }
}

/// The replanning loop's state, published once per planning cycle (10–20 Hz).
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("dkrrt::PlanStatus/1")]
pub struct PlanStatus {
    pub header: Header,
    pub cycle: u64,
    /// Compute time of this cycle, µs.
    pub plan_time_us: u64,
    /// Planner iterations this cycle.
    pub iterations: u32,
    /// A [`Fallback`] value.
    pub fallback: u32,
    /// Trajectories published so far.
    pub replans: u64,
    /// Id of the plan the tracker should be following (0: none).
    pub active_traj_id: u64,
    /// Smallest predicted clearance of the active plan over the look-ahead, m.
    pub min_predicted_clearance_m: f64,
    /// 1 once the arm is at the goal.
    pub goal_reached: u32,
    /// 1 if this cycle's compute time exceeded the deadline.
    pub deadline_missed: u32,
}

/// The predictor's progress through the observation stream: published after every batch of
/// frames it has consumed (and the forecasts they made due are out). The lockstep sim waits on
/// it before a planner cycle, so the process set plans on the same forecasts as the in-process
/// lockstep; tools read it to see how far behind the sensor the predictor is.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("dkrrt::PredictorProgress/1")]
pub struct PredictorProgress {
    /// `stamp_ns`: plant time of the newest frame consumed.
    pub header: Header,
    /// `header.seq` of the newest observation frame consumed.
    pub frame_seq: u64,
    /// Frames consumed so far.
    pub frames: u64,
    /// Forecasts published so far.
    pub forecasts: u64,
}

/// Width of the largest depth image ([`DepthImage`]), pixels.
pub const DEPTH_WIDTH: usize = 128;
/// Height of the largest depth image, pixels.
pub const DEPTH_HEIGHT: usize = 96;
/// Pixels of the largest depth image.
pub const DEPTH_PIXELS: usize = DEPTH_WIDTH * DEPTH_HEIGHT;
/// Objects one depth image can label (instances `1..=DEPTH_MAX_INSTANCES`).
pub const DEPTH_MAX_INSTANCES: usize = 254;
/// Instance of a pixel with no return.
pub const DEPTH_BACKGROUND: u8 = 0;
/// Instance of the arm's own pixels.
pub const DEPTH_ARM: u8 = 255;
/// Farthest depth a `u16` in millimetres holds, m.
pub const DEPTH_MAX_M: f64 = 65.535;

/// One depth camera frame with its segmentation: what a depth sensor and a segmentation
/// front end deliver (`dkrrt/depth_image`). Pinhole camera, pixel (`u`, `v`) (row-major,
/// index `v · width + u`, centre at image coordinates (`u + 0.5`, `v + 0.5`)) looks along
/// `((u + 0.5 − cx) / focal_px, (v + 0.5 − cy) / focal_px, 1)` in camera axes (x right,
/// y down, z the optical axis).
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("dkrrt::DepthImage/1")]
pub struct DepthImage {
    /// `stamp_ns`: the capture time (plant clock).
    pub header: Header,
    /// Image size, pixels (≤ [`DEPTH_WIDTH`] × [`DEPTH_HEIGHT`]; the first `width · height`
    /// entries of `depth_mm` and `instance` are the image).
    pub width: u32,
    pub height: u32,
    /// Focal length and principal point, pixels.
    pub focal_px: f64,
    pub cx: f64,
    pub cy: f64,
    /// Optical centre in the arm's base frame, m.
    pub position_m: [f64; 3],
    /// Camera-to-base rotation (w, x, y, z), unit norm.
    pub orientation: [f64; 4],
    /// The sensor's range: returns outside it are none, m.
    pub range_min_m: f64,
    pub range_max_m: f64,
    /// Instances labelled in this frame (≤ [`DEPTH_MAX_INSTANCES`]).
    pub n_instances: u32,
    pub _reserved: u32,
    /// Debris id of instance `k` at index `k − 1`.
    pub ids: [u32; DEPTH_MAX_INSTANCES],
    /// Depth along the optical axis, mm; 0: no return (none, out of range, or dropped).
    pub depth_mm: [u16; DEPTH_PIXELS],
    /// Instance per pixel: [`DEPTH_BACKGROUND`], [`DEPTH_ARM`], or `1..=n_instances`.
    pub instance: [u8; DEPTH_PIXELS],
}

/// All-zero value of a payload (every payload is plain numbers, so all-zero
/// bytes are a valid value). Large payloads are built in place from this.
pub trait Zeroed: Sized + Copy {
    fn zeroed() -> Self {
        // SAFETY: implemented only for the repr(C) payloads of this module,
        // whose fields are all integers and floats (valid for all-zero bytes).
        unsafe { core::mem::zeroed() }
    }
}
impl Zeroed for RobotState {}
impl Zeroed for TorqueCommand {}
impl Zeroed for Trajectory {}
impl Zeroed for Goal {}
impl Zeroed for Heartbeat {}
impl Zeroed for DebrisObservation {}
impl Zeroed for DebrisForecast {}
impl Zeroed for PlanStatus {}
impl Zeroed for PredictorProgress {}
impl Zeroed for DepthImage {}

// Compile-time layout checks: a failing assert here means the wire layout changed.
const _: () = {
    use core::mem::{align_of, size_of};
    assert!(size_of::<Header>() == 32 && align_of::<Header>() == 8);
    assert!(size_of::<RobotState>() == 32 + 3 * 8 * NJ);
    assert!(size_of::<TorqueCommand>() == 32 + 3 * 8 * NJ + 16);
    assert!(size_of::<JerkSegment>() == 40);
    assert!(size_of::<Trajectory>() == 32 + 24 + 4 * NJ + 40 * MAX_SEGMENTS * NJ);
    assert!(size_of::<Goal>() == 32 + 8 + 8 + 8 * NJ + 24 + 32);
    assert!(size_of::<Heartbeat>() == 32 + 8 + 32);
    assert!(size_of::<DebrisShape>() == 56);
    assert!(size_of::<DebrisObs>() == 128 + 56);
    assert!(size_of::<DebrisObservation>() == 32 + 8 + 184 * MAX_DEBRIS);
    assert!(size_of::<ForecastStep>() == 72);
    assert!(size_of::<ForecastTrack>() == 16 + 56 + 72 * FORECAST_STEPS);
    assert!(size_of::<DebrisForecast>() == 32 + 24 + (72 + 72 * FORECAST_STEPS) * MAX_DEBRIS);
    assert!(size_of::<PlanStatus>() == 32 + 8 * 5 + 4 * 4);
    assert!(size_of::<PredictorProgress>() == 32 + 3 * 8);
    assert!(
        size_of::<DepthImage>()
            == 32 + 8 + 3 * 8 + 24 + 32 + 16 + 8 + 4 * DEPTH_MAX_INSTANCES + 3 * DEPTH_PIXELS
    );
    assert!(align_of::<RobotState>() == 8 && align_of::<TorqueCommand>() == 8);
    assert!(align_of::<Trajectory>() == 8 && align_of::<DebrisForecast>() == 8);
};
