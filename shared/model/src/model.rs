//! The [`ArmModel`] type: immutable, precomputed model data plus accessors.
//!
//! The algorithms live in [`crate::kinematics`], [`crate::dynamics`] and
//! [`crate::ik`]; loading lives in [`crate::urdf`].

use nalgebra::{Isometry3, Matrix3, Point3, Vector3};

use crate::spatial::SpatialInertia;
use crate::{JVec, NJ};

/// Per-joint limits, read from the URDF `<limit>` element.
///
/// Continuous joints have `q_min = −∞`, `q_max = +∞`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointLimits {
    /// Lower position limit (rad) (URDF `lower`).
    pub q_min: JVec,
    /// Upper position limit (rad) (URDF `upper`).
    pub q_max: JVec,
    /// Speed limit, symmetric (rad/s) (URDF `velocity`).
    pub v_max: JVec,
    /// Torque limit, symmetric (N m) (URDF `effort`).
    pub tau_max: JVec,
}

impl JointLimits {
    /// `true` if every `q[i]` lies in `[q_min[i], q_max[i]]`.
    pub fn contains(&self, q: &JVec) -> bool {
        (0..NJ).all(|i| q[i] >= self.q_min[i] && q[i] <= self.q_max[i])
    }

    /// Component-wise clamp of `q` into the position limits.
    pub fn clamp(&self, q: &JVec) -> JVec {
        JVec::from_fn(|i, _| q[i].clamp(self.q_min[i], self.q_max[i]))
    }
}

/// A collision capsule rigidly attached to one moving link: the set of points
/// within `radius` of the segment `a`–`b`.
///
/// `a` and `b` are expressed in the URDF frame of link `link` (the child link of
/// actuated joint `link`), i.e. the frame returned by
/// [`ArmModel::link_poses`]`[link]`. A URDF `<cylinder>` is converted to the
/// capsule with the same axis segment and radius (which encloses it; the
/// hemispherical caps add up to `radius` at each end), a `<capsule>` maps
/// exactly, and a `<sphere>` becomes a capsule with `a == b`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkCapsule {
    /// Index of the moving link (0 = child of the first actuated joint).
    pub link: usize,
    /// First segment endpoint in the link frame (m).
    pub a: Point3<f64>,
    /// Second segment endpoint in the link frame (m).
    pub b: Point3<f64>,
    /// Radius (m).
    pub radius: f64,
}

impl LinkCapsule {
    /// Segment endpoints in the base frame, given the pose of the link.
    pub fn world_segment(&self, link_pose: &Isometry3<f64>) -> (Point3<f64>, Point3<f64>) {
        (link_pose * self.a, link_pose * self.b)
    }
}

/// Inertial parameters of one moving body (the URDF link plus every link rigidly
/// attached to it by fixed joints), expressed in that link's URDF frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkInertial {
    /// Mass (kg).
    pub mass: f64,
    /// Centre of mass in the link frame (m).
    pub com: Vector3<f64>,
    /// Rotational inertia about the centre of mass, link-frame axes (kg m²).
    pub inertia: Matrix3<f64>,
}

/// A 6-DoF serial manipulator with a fixed base: kinematics, dynamics and IK.
///
/// Build it with [`ArmModel::default_arm`], [`ArmModel::from_urdf_str`] or
/// [`ArmModel::from_urdf_file`]. All kinematic/dynamic queries take `&self`,
/// work on fixed-size nalgebra types and never allocate.
///
/// **Frames.** Everything is expressed in the *base frame*: the frame of the URDF
/// root link. `link_poses()[i]` is the URDF frame of the child link of the
/// `i`-th actuated joint; [`ArmModel::fk`] is the end-effector frame, the last
/// link of the chain (after any trailing fixed joints, e.g. `tool0`).
///
/// **Internally** each moving body uses a frame rotated (by a constant
/// rotation) so that its joint axis is `+z`; this keeps every motion subspace
/// `S = (e_z, 0)` and makes the algorithms cheap. Public results are converted
/// back to URDF frames.
#[derive(Debug, Clone)]
pub struct ArmModel {
    pub(crate) name: String,
    pub(crate) joint_names: [String; NJ],
    pub(crate) link_names: [String; NJ],
    pub(crate) ee_link: String,
    pub(crate) limits: JointLimits,
    pub(crate) gravity: Vector3<f64>,
    /// Rotation of body `i`'s internal frame in its parent's internal frame at `q_i = 0`.
    pub(crate) rc: [Matrix3<f64>; NJ],
    /// Origin of body `i`'s internal frame in its parent's internal frame.
    pub(crate) pc: [Vector3<f64>; NJ],
    /// Spatial inertia of body `i` in its internal frame (fixed children merged).
    pub(crate) inertia: [SpatialInertia; NJ],
    /// Rotation taking internal-frame coordinates to URDF link-frame coordinates
    /// (`R_link = R_internal * to_link`).
    pub(crate) to_link: [Matrix3<f64>; NJ],
    /// End-effector frame relative to the internal frame of the last body.
    pub(crate) ee_rot: Matrix3<f64>,
    pub(crate) ee_pos: Vector3<f64>,
    pub(crate) capsules: [LinkCapsule; NJ],
    pub(crate) inertials: [LinkInertial; NJ],
    /// What loading ignored or assumed (branches off the chain, fitted collision shapes, …).
    pub(crate) notes: Vec<String>,
}

impl ArmModel {
    /// Robot name (URDF `<robot name=...>`).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Names of the actuated joints, base to tip.
    pub fn joint_names(&self) -> &[String; NJ] {
        &self.joint_names
    }

    /// Names of the moving links (child of each actuated joint), base to tip.
    pub fn link_names(&self) -> &[String; NJ] {
        &self.link_names
    }

    /// Name of the URDF link whose frame is the end-effector frame.
    pub fn ee_link_name(&self) -> &str {
        &self.ee_link
    }

    /// Joint position, velocity and torque limits.
    pub fn limits(&self) -> &JointLimits {
        &self.limits
    }

    /// Gravity acceleration in the base frame (m/s²) (default zero: free fall / orbit).
    pub fn gravity(&self) -> &Vector3<f64> {
        &self.gravity
    }

    /// Set the gravity acceleration vector in the base frame (m/s²), e.g.
    /// `Vector3::new(0.0, 0.0, -9.81)` for a ground test bed.
    pub fn set_gravity(&mut self, g: Vector3<f64>) {
        self.gravity = g;
    }

    /// One collision capsule per moving link, in link frames (see [`LinkCapsule`]).
    pub fn collision_capsules(&self) -> &[LinkCapsule; NJ] {
        &self.capsules
    }

    /// Inertial parameters of each moving body (fixed children merged), in link frames.
    pub fn link_inertials(&self) -> &[LinkInertial; NJ] {
        &self.inertials
    }

    /// What loading the URDF ignored or assumed, one sentence each (side branches behind a
    /// moving joint, mimic joints, collision capsules fitted around boxes/meshes/visuals, the
    /// tip chosen where fixed frames branch). Empty for the shipped arm.
    pub fn load_notes(&self) -> &[String] {
        &self.notes
    }

    /// Total mass of the moving bodies (kg).
    pub fn total_mass(&self) -> f64 {
        self.inertials.iter().map(|l| l.mass).sum()
    }
}
