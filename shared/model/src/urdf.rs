//! Loading an [`ArmModel`] from URDF (via `urdf-rs`).
//!
//! Supported: a single serial chain from the root link with exactly [`NJ`]
//! actuated `revolute`/`continuous` joints (arbitrary origin `xyz`/`rpy` and
//! `axis`) and any number of `fixed` joints anywhere in the chain.
//!
//! * Fixed joints before the first actuated joint are folded into its origin
//!   (links up to there belong to the fixed base and have no dynamic effect).
//! * A link attached by fixed joints after a moving link is rigidly merged into
//!   that moving link: its inertia is added, its collision element is used.
//! * The last link of the chain is the end-effector frame (e.g. a fixed
//!   `tool0`); without trailing fixed joints it is the last moving link.
//!
//! Everything else is rejected with a [`ModelError`] naming the offending
//! joint/link/field.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use nalgebra::{
    Isometry3, Matrix3, Point3, Rotation3, SymmetricEigen, Translation3, UnitQuaternion, Vector3,
};

use crate::model::{ArmModel, JointLimits, LinkCapsule, LinkInertial};
use crate::spatial::SpatialInertia;
use crate::{JVec, NJ};

/// The shipped default arm (`shared/model/urdf/dkrrt_arm.urdf`), embedded at compile time.
pub const DEFAULT_ARM_URDF: &str = include_str!("../urdf/dkrrt_arm.urdf");

/// Why a URDF could not be turned into an [`ArmModel`].
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ModelError {
    /// The file could not be read.
    #[error("cannot read URDF file {path}: {source}")]
    Io {
        /// Path that was read.
        path: PathBuf,
        /// Underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// `urdf-rs` could not parse the XML.
    #[error("URDF parse error: {0}")]
    Parse(String),
    /// Two links share a name.
    #[error("duplicate link name `{link}`")]
    DuplicateLink {
        /// The repeated name.
        link: String,
    },
    /// A joint names a parent or child link that does not exist.
    #[error("joint `{joint}` refers to unknown link `{link}`")]
    UnknownLink {
        /// Joint name.
        joint: String,
        /// The missing link name.
        link: String,
    },
    /// A link is the child of more than one joint.
    #[error("link `{link}` is the child of several joints")]
    MultipleParents {
        /// Link name.
        link: String,
    },
    /// No link is free of a parent joint (the joints form a cycle).
    #[error("URDF has no root link")]
    NoRoot,
    /// More than one link has no parent joint.
    #[error("URDF has several root links: {links:?}")]
    MultipleRoots {
        /// The root link names.
        links: Vec<String>,
    },
    /// A link has more than one child joint.
    #[error("link `{link}` has several child joints {joints:?}; only a serial chain is supported")]
    Branching {
        /// Link name.
        link: String,
        /// Its child joints.
        joints: Vec<String>,
    },
    /// Some links are not reachable from the root along the chain.
    #[error("links not connected to the chain from the root: {links:?}")]
    Disconnected {
        /// Unreached link names.
        links: Vec<String>,
    },
    /// A joint type other than revolute, continuous or fixed (or a mimic joint).
    #[error("joint `{joint}` has unsupported type `{kind}` (only revolute, continuous and fixed)")]
    UnsupportedJoint {
        /// Joint name.
        joint: String,
        /// The URDF type (or `mimic`).
        kind: String,
    },
    /// The chain does not have exactly [`NJ`] actuated joints.
    #[error("the chain has {found} actuated (revolute/continuous) joints, expected {expected}")]
    WrongDof {
        /// Number of actuated joints found.
        found: usize,
        /// Number required ([`NJ`]).
        expected: usize,
    },
    /// A revolute/continuous joint has no `<limit>` element.
    #[error("joint `{joint}` has no <limit> element (lower/upper/velocity/effort are required)")]
    MissingLimit {
        /// Joint name.
        joint: String,
    },
    /// A limit attribute is missing, non-finite or out of range.
    #[error("joint `{joint}`: invalid limit `{field}` = {value}: {reason}")]
    InvalidLimit {
        /// Joint name.
        joint: String,
        /// Attribute name (`lower`, `upper`, `velocity`, `effort`).
        field: &'static str,
        /// The value read.
        value: f64,
        /// What is wrong with it.
        reason: &'static str,
    },
    /// The joint axis is zero or not finite.
    #[error("joint `{joint}`: invalid axis {axis:?} (must be finite and non-zero)")]
    InvalidAxis {
        /// Joint name.
        joint: String,
        /// The axis read.
        axis: [f64; 3],
    },
    /// A link's `<inertial>` is not physically valid.
    #[error("link `{link}`: invalid inertial: {reason}")]
    InvalidInertia {
        /// Link name.
        link: String,
        /// What is wrong.
        reason: String,
    },
    /// A moving body has no inertia about its own joint axis, which would make the
    /// mass matrix singular.
    #[error("link `{link}` has zero inertia about the axis of joint `{joint}` (singular mass matrix)")]
    SingularInertia {
        /// Moving link name.
        link: String,
        /// Its joint.
        joint: String,
    },
    /// A moving body (with its fixed children) has no collision element.
    #[error("link `{link}`: no <collision> element (a cylinder, capsule or sphere is required)")]
    MissingCollision {
        /// Moving link name.
        link: String,
    },
    /// A moving body (with its fixed children) has more than one collision element.
    #[error("link `{link}`: several <collision> elements (also counting fixed children `{other}`); exactly one is supported")]
    MultipleCollisions {
        /// Moving link name.
        link: String,
        /// The link carrying the extra element.
        other: String,
    },
    /// A collision radius/length that is not finite and positive.
    #[error("link `{link}`: invalid collision size (radius {radius}, length {length})")]
    InvalidCollision {
        /// Link name.
        link: String,
        /// Radius read.
        radius: f64,
        /// Length read (0 for a sphere).
        length: f64,
    },
    /// A collision geometry other than cylinder, capsule or sphere.
    #[error("link `{link}`: unsupported collision geometry `{geometry}` (cylinder, capsule or sphere)")]
    UnsupportedCollision {
        /// Link name.
        link: String,
        /// Geometry kind.
        geometry: &'static str,
    },
}

impl ArmModel {
    /// The shipped 6-DoF space manipulator (`urdf/dkrrt_arm.urdf`, embedded).
    ///
    /// Kinematics modelled on the SSRMS joint sequence (shoulder yaw/pitch, elbow
    /// pitch, wrist pitch/yaw/roll, with lateral joint offsets), scaled to the
    /// ETS-VII size class: ~2.9 m reach, 112 kg moving mass. Masses and inertias
    /// are invented (uniform solid cylinders); speed/torque limits are invented
    /// to lie in the range of space harmonic-drive joints (0.12–0.20 rad/s,
    /// 60–200 N m). See the URDF header and the crate README for details.
    pub fn default_arm() -> Self {
        Self::from_urdf_str(DEFAULT_ARM_URDF).expect("the embedded default URDF is valid")
    }

    /// Load from a URDF file on disk.
    pub fn from_urdf_file(path: impl AsRef<Path>) -> Result<Self, ModelError> {
        let path = path.as_ref();
        let s = dkrrt_io::read_text_capped(path, dkrrt_io::limits::URDF)
            .map_err(|e| ModelError::Io { path: path.to_path_buf(), source: e.into() })?;
        Self::from_urdf_str(&s)
    }

    /// Load from URDF XML text. See the [module docs](crate::urdf) for what is supported.
    pub fn from_urdf_str(xml: &str) -> Result<Self, ModelError> {
        let robot = urdf_rs::read_from_string(xml).map_err(|e| ModelError::Parse(e.to_string()))?;
        build(&robot)
    }
}

fn pose_iso(p: &urdf_rs::Pose) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(p.xyz[0], p.xyz[1], p.xyz[2]),
        UnitQuaternion::from_euler_angles(p.rpy[0], p.rpy[1], p.rpy[2]),
    )
}

fn rot_of(iso: &Isometry3<f64>) -> Matrix3<f64> {
    *iso.rotation.to_rotation_matrix().matrix()
}

/// A rotation `Q` with `Q e_z = a` (`a` unit).
fn rot_z_to(a: &Vector3<f64>) -> Matrix3<f64> {
    if a.z > 1.0 - 1e-12 {
        Matrix3::identity()
    } else if a.z < -1.0 + 1e-12 {
        Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0))
    } else {
        *Rotation3::rotation_between(&Vector3::z(), a).expect("non-antiparallel").matrix()
    }
}

/// Validate a URDF `<inertial>` and return it as a spatial inertia in the link frame.
fn link_inertia(link: &urdf_rs::Link) -> Result<SpatialInertia, ModelError> {
    let bad = |reason: String| ModelError::InvalidInertia { link: link.name.clone(), reason };
    let inl = &link.inertial;
    let m = inl.mass.value;
    if !m.is_finite() || m < 0.0 {
        return Err(bad(format!("mass {m} must be finite and >= 0")));
    }
    let t = &inl.inertia;
    let i_in = Matrix3::new(t.ixx, t.ixy, t.ixz, t.ixy, t.iyy, t.iyz, t.ixz, t.iyz, t.izz);
    if i_in.iter().any(|v| !v.is_finite()) {
        return Err(bad("inertia entries must be finite".into()));
    }
    if m == 0.0 {
        if i_in.iter().any(|v| *v != 0.0) {
            return Err(bad("zero mass with non-zero rotational inertia".into()));
        }
        return Ok(SpatialInertia::zero());
    }
    let eig = SymmetricEigen::new(i_in).eigenvalues;
    let scale = eig.amax().max(f64::MIN_POSITIVE);
    let tol = 1e-9 * scale;
    if eig.min() < -tol {
        return Err(bad(format!(
            "rotational inertia is not positive semi-definite (eigenvalues {:?})",
            eig.as_slice()
        )));
    }
    let (a, b, c) = (eig[0], eig[1], eig[2]);
    if a + b < c - tol || a + c < b - tol || b + c < a - tol {
        return Err(bad(format!("principal moments {:?} violate the triangle inequality", eig.as_slice())));
    }
    let r = rot_of(&pose_iso(&inl.origin));
    let c = Vector3::new(inl.origin.xyz[0], inl.origin.xyz[1], inl.origin.xyz[2]);
    Ok(SpatialInertia::from_com(m, &c, &(r * i_in * r.transpose())))
}

/// Collision element of `link` as a capsule in the frame `frame` (pose of `link` in it).
fn link_capsule(
    link: &urdf_rs::Link,
    frame: &Isometry3<f64>,
    idx: usize,
) -> Result<Option<LinkCapsule>, ModelError> {
    if link.collision.len() > 1 {
        return Err(ModelError::MultipleCollisions { link: link.name.clone(), other: link.name.clone() });
    }
    let Some(col) = link.collision.first() else { return Ok(None) };
    let pose = frame * pose_iso(&col.origin);
    let (half, radius) = match &col.geometry {
        urdf_rs::Geometry::Cylinder { radius, length } | urdf_rs::Geometry::Capsule { radius, length } => {
            (0.5 * length, *radius)
        }
        urdf_rs::Geometry::Sphere { radius } => (0.0, *radius),
        urdf_rs::Geometry::Box { .. } => {
            return Err(ModelError::UnsupportedCollision { link: link.name.clone(), geometry: "box" })
        }
        urdf_rs::Geometry::Mesh { .. } => {
            return Err(ModelError::UnsupportedCollision { link: link.name.clone(), geometry: "mesh" })
        }
    };
    if !(radius.is_finite() && radius > 0.0 && half.is_finite() && half >= 0.0) {
        return Err(ModelError::InvalidCollision { link: link.name.clone(), radius, length: 2.0 * half });
    }
    Ok(Some(LinkCapsule {
        link: idx,
        a: pose * Point3::new(0.0, 0.0, -half),
        b: pose * Point3::new(0.0, 0.0, half),
        radius,
    }))
}

fn check_limits(j: &urdf_rs::Joint) -> Result<(f64, f64, f64, f64), ModelError> {
    let l = &j.limit;
    if *l == urdf_rs::JointLimit::default() {
        return Err(ModelError::MissingLimit { joint: j.name.clone() });
    }
    let err = |field, value, reason| ModelError::InvalidLimit { joint: j.name.clone(), field, value, reason };
    let (lo, hi) = if j.joint_type == urdf_rs::JointType::Continuous {
        (f64::NEG_INFINITY, f64::INFINITY)
    } else {
        if !l.lower.is_finite() {
            return Err(err("lower", l.lower, "must be finite for a revolute joint"));
        }
        if !l.upper.is_finite() {
            return Err(err("upper", l.upper, "must be finite for a revolute joint"));
        }
        if l.upper <= l.lower {
            return Err(err("upper", l.upper, "must be greater than `lower`"));
        }
        (l.lower, l.upper)
    };
    if !(l.velocity.is_finite() && l.velocity > 0.0) {
        return Err(err("velocity", l.velocity, "must be finite and > 0"));
    }
    if !(l.effort.is_finite() && l.effort > 0.0) {
        return Err(err("effort", l.effort, "must be finite and > 0"));
    }
    Ok((lo, hi, l.velocity, l.effort))
}

/// Per-moving-body accumulator while walking the chain.
struct BodyAcc {
    inertia: SpatialInertia,
    capsule: Option<LinkCapsule>,
}

fn build(robot: &urdf_rs::Robot) -> Result<ArmModel, ModelError> {
    // --- Topology -------------------------------------------------------------
    let mut link_idx: HashMap<&str, usize> = HashMap::new();
    for (i, l) in robot.links.iter().enumerate() {
        if link_idx.insert(l.name.as_str(), i).is_some() {
            return Err(ModelError::DuplicateLink { link: l.name.clone() });
        }
    }
    let nl = robot.links.len();
    let mut parent_joint: Vec<Option<usize>> = vec![None; nl];
    let mut child_joints: Vec<Vec<usize>> = vec![Vec::new(); nl];
    for (ji, j) in robot.joints.iter().enumerate() {
        let find = |name: &str| {
            link_idx
                .get(name)
                .copied()
                .ok_or_else(|| ModelError::UnknownLink { joint: j.name.clone(), link: name.to_string() })
        };
        let p = find(&j.parent.link)?;
        let c = find(&j.child.link)?;
        if parent_joint[c].replace(ji).is_some() {
            return Err(ModelError::MultipleParents { link: j.child.link.clone() });
        }
        child_joints[p].push(ji);
    }
    let roots: Vec<usize> = (0..nl).filter(|&i| parent_joint[i].is_none()).collect();
    let root = match roots.as_slice() {
        [] => return Err(ModelError::NoRoot),
        [r] => *r,
        _ => {
            return Err(ModelError::MultipleRoots {
                links: roots.iter().map(|&i| robot.links[i].name.clone()).collect(),
            })
        }
    };
    let mut chain = Vec::new();
    let mut visited = vec![false; nl];
    let mut cur = root;
    visited[cur] = true;
    loop {
        match child_joints[cur].as_slice() {
            [] => break,
            [j] => {
                chain.push(*j);
                cur = link_idx[robot.joints[*j].child.link.as_str()];
                visited[cur] = true;
            }
            many => {
                return Err(ModelError::Branching {
                    link: robot.links[cur].name.clone(),
                    joints: many.iter().map(|&j| robot.joints[j].name.clone()).collect(),
                })
            }
        }
    }
    if chain.len() + 1 != nl {
        return Err(ModelError::Disconnected {
            links: (0..nl).filter(|&i| !visited[i]).map(|i| robot.links[i].name.clone()).collect(),
        });
    }

    // --- Joint types ------------------------------------------------------------
    use urdf_rs::JointType as T;
    let mut dof = 0;
    for &ji in &chain {
        let j = &robot.joints[ji];
        match j.joint_type {
            T::Revolute | T::Continuous => {
                if j.mimic.is_some() {
                    return Err(ModelError::UnsupportedJoint { joint: j.name.clone(), kind: "mimic".into() });
                }
                dof += 1;
            }
            T::Fixed => {}
            ref other => {
                return Err(ModelError::UnsupportedJoint {
                    joint: j.name.clone(),
                    kind: format!("{other:?}").to_lowercase(),
                })
            }
        }
    }
    if dof != NJ {
        return Err(ModelError::WrongDof { found: dof, expected: NJ });
    }

    // --- Walk the chain -----------------------------------------------------------
    let mut joint_names: [String; NJ] = Default::default();
    let mut link_names: [String; NJ] = Default::default();
    let mut origins = [Isometry3::identity(); NJ]; // joint origin in previous body's link frame
    let mut axes = [Vector3::z(); NJ];
    let mut lim = JointLimits {
        q_min: JVec::zeros(),
        q_max: JVec::zeros(),
        v_max: JVec::zeros(),
        tau_max: JVec::zeros(),
    };
    let mut bodies: Vec<BodyAcc> = Vec::with_capacity(NJ);
    // Pose of the current link in the frame of the last moving link (or base).
    let mut acc = Isometry3::identity();
    link_inertia(&robot.links[root])?; // validated, but the base does not move
    for &ji in &chain {
        let j = &robot.joints[ji];
        let child = &robot.links[link_idx[j.child.link.as_str()]];
        let origin = pose_iso(&j.origin);
        let inertia = link_inertia(child)?;
        if j.joint_type == T::Fixed {
            acc *= origin;
            let nb = bodies.len();
            if let Some(body) = bodies.last_mut() {
                let (r, p) = (rot_of(&acc), acc.translation.vector);
                body.inertia = body.inertia.add(&inertia.to_parent(&r, &p));
                if let Some(c) = link_capsule(child, &acc, nb - 1)? {
                    if body.capsule.is_some() {
                        return Err(ModelError::MultipleCollisions {
                            link: link_names[nb - 1].clone(),
                            other: child.name.clone(),
                        });
                    }
                    body.capsule = Some(c);
                }
            }
            continue;
        }
        let k = bodies.len();
        let (lo, hi, v, e) = check_limits(j)?;
        lim.q_min[k] = lo;
        lim.q_max[k] = hi;
        lim.v_max[k] = v;
        lim.tau_max[k] = e;
        let a = Vector3::new(j.axis.xyz[0], j.axis.xyz[1], j.axis.xyz[2]);
        let n = a.norm();
        if !(n.is_finite() && n > 1e-9) {
            return Err(ModelError::InvalidAxis { joint: j.name.clone(), axis: j.axis.xyz.0 });
        }
        axes[k] = a / n;
        origins[k] = acc * origin;
        joint_names[k] = j.name.clone();
        link_names[k] = child.name.clone();
        let capsule = link_capsule(child, &Isometry3::identity(), k)?;
        bodies.push(BodyAcc { inertia, capsule });
        acc = Isometry3::identity();
    }
    let ee_link = robot.links[cur].name.clone();

    // --- Precompute internal (axis = z) frames ------------------------------------
    let q_rot: [Matrix3<f64>; NJ] = std::array::from_fn(|k| rot_z_to(&axes[k]));
    let mut rc = [Matrix3::identity(); NJ];
    let mut pc = [Vector3::zeros(); NJ];
    let mut inertia = [SpatialInertia::zero(); NJ];
    let mut to_link = [Matrix3::identity(); NJ];
    let mut inertials = [LinkInertial { mass: 0.0, com: Vector3::zeros(), inertia: Matrix3::zeros() }; NJ];
    let mut capsules = [LinkCapsule { link: 0, a: Point3::origin(), b: Point3::origin(), radius: 0.0 }; NJ];
    for k in 0..NJ {
        let q_prev = if k == 0 { Matrix3::identity() } else { q_rot[k - 1] };
        rc[k] = q_prev.transpose() * rot_of(&origins[k]) * q_rot[k];
        pc[k] = q_prev.transpose() * origins[k].translation.vector;
        to_link[k] = q_rot[k].transpose();
        let body = &bodies[k];
        // Link frame seen from the internal frame: rotation Qᵀ, no translation.
        inertia[k] = body.inertia.to_parent(&q_rot[k].transpose(), &Vector3::zeros());
        if inertia[k].i_o[(2, 2)] <= 1e-12 * (1.0 + inertia[k].m) {
            return Err(ModelError::SingularInertia {
                link: link_names[k].clone(),
                joint: joint_names[k].clone(),
            });
        }
        let li = &body.inertia;
        let com = if li.m > 0.0 { li.h / li.m } else { Vector3::zeros() };
        let cx = crate::spatial::skew(&com);
        inertials[k] = LinkInertial { mass: li.m, com, inertia: li.i_o + cx * cx * li.m };
        capsules[k] =
            body.capsule.ok_or_else(|| ModelError::MissingCollision { link: link_names[k].clone() })?;
    }
    let q_last = q_rot[NJ - 1];
    Ok(ArmModel {
        name: robot.name.clone(),
        joint_names,
        link_names,
        ee_link,
        limits: lim,
        gravity: Vector3::zeros(),
        rc,
        pc,
        inertia,
        to_link,
        ee_rot: q_last.transpose() * rot_of(&acc),
        ee_pos: q_last.transpose() * acc.translation.vector,
        capsules,
        inertials,
    })
}
