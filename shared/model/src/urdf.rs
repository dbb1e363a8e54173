//! Loading an [`ArmModel`] from URDF (via `urdf-rs`).
//!
//! Any URDF whose chosen chain has exactly [`NJ`] actuated `revolute`/`continuous` joints
//! loads, trees included (as Pinocchio does):
//!
//! * **The chain** runs from a base link to a tip link ([`UrdfOptions::base_link`],
//!   [`UrdfOptions::tip_link`]; defaults: the root, and the deepest link of the actuated
//!   chain: the child of the last actuated joint, followed down its fixed joints while they do
//!   not branch). The base frame is the base link's frame; the end-effector frame is the tip's.
//! * **Fixed joints** are merged: every link rigidly attached to a moving body (on the chain or
//!   on a side branch of fixed joints, e.g. `tool0`, a camera) has its inertia lumped onto that
//!   body and its collision geometry added to it. Links before the first actuated joint are the
//!   fixed base. A side branch behind a moving joint is ignored, with a note.
//! * **Collision geometry**: one capsule per moving body. A single cylinder, capsule or sphere
//!   maps exactly (a cylinder to the capsule that encloses it); anything else (boxes, STL/OBJ
//!   meshes on `package://`, `file://` or relative paths, several elements) gets a fitted
//!   capsule enclosing all of it ([`crate::mesh`]). A body without `<collision>` uses its
//!   `<visual>` geometry, or none (a point at its origin), with a note, never a refusal.
//! * Mimic joints and `<transmission>` elements are ignored (a mimic joint on the chain is
//!   driven as an independent joint), with a note.
//!
//! What cannot be modelled is refused with a [`ModelError`] naming the joint/link/field: not
//! exactly [`NJ`] actuated joints on the chain, a prismatic/floating/planar joint on it, a
//! missing `<limit>`, invalid inertia, an unreadable mesh.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use crate::mesh;

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
    /// `base_link` / `tip_link` names no link of the URDF.
    #[error("{field} `{link}` is not a link of the URDF")]
    NoSuchLink {
        /// `robot.base_link` or `robot.tip_link`.
        field: &'static str,
        /// The name given.
        link: String,
    },
    /// The tip link does not lie below the base link.
    #[error("tip link `{tip}` is not below base link `{base}`")]
    TipNotBelowBase {
        /// Base link.
        base: String,
        /// Tip link.
        tip: String,
    },
    /// Several actuated branches are equally deep: the tip must be chosen.
    #[error(
        "several possible tip links {candidates:?} (each after {dof} actuated joints): set robot.tip_link"
    )]
    AmbiguousTip {
        /// The candidate links.
        candidates: Vec<String>,
        /// Actuated joints before each.
        dof: usize,
    },
    /// A mesh of a collision element could not be found or read.
    #[error("link `{link}`: collision mesh {reason}")]
    Mesh {
        /// Link carrying the element.
        link: String,
        /// What went wrong, naming the file.
        reason: String,
    },
}

/// How to load a URDF: the chain, and where its meshes are.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct UrdfOptions {
    /// First link of the chain (its frame is the base frame); `None`: the root link.
    pub base_link: Option<String>,
    /// Last link of the chain (its frame is the end-effector frame); `None`: the deepest link
    /// of the actuated chain (see the [module docs](crate::urdf)).
    pub tip_link: Option<String>,
    /// Directories searched for `package://NAME/...` (each holding package folders, or a
    /// package folder itself), before the `ROS_PACKAGE_PATH` directories.
    pub package_path: Vec<PathBuf>,
    /// Folder relative mesh paths are taken from ([`ArmModel::from_urdf_file_with`] sets it to
    /// the URDF's folder).
    pub urdf_dir: Option<PathBuf>,
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

    /// Load from a URDF file on disk (default chain; meshes relative to the file's folder).
    pub fn from_urdf_file(path: impl AsRef<Path>) -> Result<Self, ModelError> {
        Self::from_urdf_file_with(path, &UrdfOptions::default())
    }

    /// Load from a URDF file on disk with `opts` (`urdf_dir` defaults to the file's folder).
    /// What was ignored or assumed is in [`ArmModel::load_notes`].
    pub fn from_urdf_file_with(path: impl AsRef<Path>, opts: &UrdfOptions) -> Result<Self, ModelError> {
        let path = path.as_ref();
        let s = dkrrt_io::read_text_capped(path, dkrrt_io::limits::URDF)
            .map_err(|e| ModelError::Io { path: path.to_path_buf(), source: e.into() })?;
        let mut o = opts.clone();
        if o.urdf_dir.is_none() {
            o.urdf_dir = path.parent().map(Path::to_path_buf);
        }
        Self::from_urdf_str_with(&s, &o)
    }

    /// Load from URDF XML text. See the [module docs](crate::urdf) for what is supported.
    pub fn from_urdf_str(xml: &str) -> Result<Self, ModelError> {
        Self::from_urdf_str_with(xml, &UrdfOptions::default())
    }

    /// Load from URDF XML text with `opts`.
    pub fn from_urdf_str_with(xml: &str, opts: &UrdfOptions) -> Result<Self, ModelError> {
        let robot = urdf_rs::read_from_string(xml).map_err(|e| ModelError::Parse(e.to_string()))?;
        let mut model = build(&robot, opts)?;
        // The parser drops them: say so (the tracker commands joint torques directly).
        let transmissions = xml.matches("<transmission").count();
        if transmissions > 0 {
            model.notes.push(format!(
                "{transmissions} <transmission> element(s) ignored (joint torques are commanded directly)"
            ));
        }
        Ok(model)
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

/// One collision (or visual) element of a moving body, posed in the body's link frame.
struct Elem<'a> {
    link: &'a str,
    pose: Isometry3<f64>,
    geom: &'a urdf_rs::Geometry,
}

/// Per-moving-body accumulator while walking the chain.
struct BodyAcc<'a> {
    inertia: SpatialInertia,
    collisions: Vec<Elem<'a>>,
    visuals: Vec<Elem<'a>>,
}

/// The points (with radii) an element encloses, in the body frame, appended to `out`.
fn element_points(e: &Elem, opts: &UrdfOptions, out: &mut Vec<(Point3<f64>, f64)>) -> Result<(), ModelError> {
    let bad =
        |radius: f64, length: f64| ModelError::InvalidCollision { link: e.link.to_string(), radius, length };
    match e.geom {
        urdf_rs::Geometry::Cylinder { radius, length } | urdf_rs::Geometry::Capsule { radius, length } => {
            if !(radius.is_finite() && *radius > 0.0 && length.is_finite() && *length >= 0.0) {
                return Err(bad(*radius, *length));
            }
            for z in [-0.5 * length, 0.5 * length] {
                out.push((e.pose * Point3::new(0.0, 0.0, z), *radius));
            }
        }
        urdf_rs::Geometry::Sphere { radius } => {
            if !(radius.is_finite() && *radius > 0.0) {
                return Err(bad(*radius, 0.0));
            }
            out.push((e.pose * Point3::origin(), *radius));
        }
        urdf_rs::Geometry::Box { size } => {
            let h = [0.5 * size[0], 0.5 * size[1], 0.5 * size[2]];
            if !h.iter().all(|x| x.is_finite() && *x >= 0.0) {
                return Err(bad(0.0, size[2]));
            }
            for i in 0..8 {
                let s = |b: usize| if i >> b & 1 == 1 { 1.0 } else { -1.0 };
                out.push((e.pose * Point3::new(s(0) * h[0], s(1) * h[1], s(2) * h[2]), 0.0));
            }
        }
        urdf_rs::Geometry::Mesh { filename, scale } => {
            let err = |reason: String| ModelError::Mesh { link: e.link.to_string(), reason };
            let path = mesh::resolve(filename, opts.urdf_dir.as_deref(), &opts.package_path).map_err(err)?;
            let scale = scale.map_or([1.0; 3], |s| s.0);
            let pts = mesh::load_vertices(&path, scale).map_err(err)?;
            out.extend(pts.iter().map(|p| (e.pose * p, 0.0)));
        }
    }
    Ok(())
}

/// The body's collision capsule: exact for a single cylinder/capsule/sphere, else fitted around
/// all its collision elements (or, without any, its visual ones; or a point), with notes.
fn body_capsule(
    k: usize,
    name: &str,
    body: &BodyAcc,
    opts: &UrdfOptions,
    notes: &mut Vec<String>,
) -> Result<LinkCapsule, ModelError> {
    use urdf_rs::Geometry as G;
    let point = LinkCapsule { link: k, a: Point3::origin(), b: Point3::origin(), radius: 0.0 };
    if let [e] = body.collisions.as_slice() {
        if matches!(e.geom, G::Cylinder { .. } | G::Capsule { .. } | G::Sphere { .. }) {
            let mut pts = Vec::with_capacity(2);
            element_points(e, opts, &mut pts)?;
            let (a, b) = (pts[0].0, pts[pts.len() - 1].0);
            return Ok(LinkCapsule { link: k, a, b, radius: pts[0].1 });
        }
    }
    let mut pts = Vec::new();
    let from_visual = body.collisions.is_empty();
    if from_visual {
        for e in &body.visuals {
            // A visual mesh we cannot read (COLLADA, say) is only a missed fallback.
            if let Err(err) = element_points(e, opts, &mut pts) {
                notes.push(format!(
                    "link `{name}`: visual element skipped for its fitted collision shape ({err})"
                ));
            }
        }
    } else {
        for e in &body.collisions {
            element_points(e, opts, &mut pts)?;
        }
    }
    if pts.is_empty() {
        notes.push(format!(
            "link `{name}` has no usable collision or visual geometry: it is not checked for contact (a point at its origin)"
        ));
        return Ok(point);
    }
    let (a, b, radius) = mesh::fit_capsule(&pts);
    let n = if from_visual { body.visuals.len() } else { body.collisions.len() };
    notes.push(format!(
        "link `{name}`: collision capsule (radius {radius:.3} m, length {:.3} m) fitted around {n} {} element(s)",
        (b - a).norm(),
        if from_visual { "visual (no <collision>)" } else { "collision" }
    ));
    Ok(LinkCapsule { link: k, a, b, radius })
}

fn is_actuated(j: &urdf_rs::Joint) -> bool {
    matches!(j.joint_type, urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous)
}

/// The default tip below `base`: the child of the last actuated joint on the deepest actuated
/// path, followed down its fixed joints while they do not branch.
fn default_tip(
    robot: &urdf_rs::Robot,
    base: usize,
    child_joints: &[Vec<usize>],
    link_idx: &HashMap<&str, usize>,
    notes: &mut Vec<String>,
) -> Result<usize, ModelError> {
    let mut count = vec![None::<usize>; robot.links.len()];
    let mut firsts: Vec<(usize, usize)> = Vec::new(); // (link, actuated joints before it)
    count[base] = Some(0);
    let mut stack = vec![base];
    while let Some(l) = stack.pop() {
        let c = count[l].unwrap_or(0);
        for &j in &child_joints[l] {
            let ch = link_idx[robot.joints[j].child.link.as_str()];
            if count[ch].is_some() {
                continue; // a cycle: never walked twice
            }
            let a = is_actuated(&robot.joints[j]);
            count[ch] = Some(c + a as usize);
            if a {
                firsts.push((ch, c + 1));
            }
            stack.push(ch);
        }
    }
    let dof = firsts.iter().map(|f| f.1).max().unwrap_or(0);
    if dof == 0 {
        return Err(ModelError::WrongDof { found: 0, expected: NJ });
    }
    let deepest: Vec<usize> = firsts.iter().filter(|f| f.1 == dof).map(|f| f.0).collect();
    if deepest.len() > 1 {
        let mut candidates: Vec<String> = deepest.iter().map(|&l| robot.links[l].name.clone()).collect();
        candidates.sort();
        return Err(ModelError::AmbiguousTip { candidates, dof });
    }
    let mut tip = deepest[0];
    for _ in 0..robot.links.len() {
        match child_joints[tip].as_slice() {
            [j] if robot.joints[*j].joint_type == urdf_rs::JointType::Fixed => {
                tip = link_idx[robot.joints[*j].child.link.as_str()];
            }
            [] => break,
            many => {
                let names: Vec<&str> = many.iter().map(|&j| robot.joints[j].child.link.as_str()).collect();
                notes.push(format!(
                    "tip link `{}` (below it: {}; set robot.tip_link to end the chain at one of them)",
                    robot.links[tip].name,
                    names.join(", ")
                ));
                break;
            }
        }
    }
    Ok(tip)
}

fn build(robot: &urdf_rs::Robot, opts: &UrdfOptions) -> Result<ArmModel, ModelError> {
    let mut notes = Vec::new();
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
    let named = |field: &'static str, name: &Option<String>| -> Result<Option<usize>, ModelError> {
        match name {
            None => Ok(None),
            Some(n) => link_idx
                .get(n.as_str())
                .copied()
                .map(Some)
                .ok_or_else(|| ModelError::NoSuchLink { field, link: n.clone() }),
        }
    };
    let base = match named("robot.base_link", &opts.base_link)? {
        Some(b) => b,
        None => {
            let roots: Vec<usize> = (0..nl).filter(|&i| parent_joint[i].is_none()).collect();
            match roots.as_slice() {
                [] => return Err(ModelError::NoRoot),
                [r] => *r,
                _ => {
                    return Err(ModelError::MultipleRoots {
                        links: roots.iter().map(|&i| robot.links[i].name.clone()).collect(),
                    })
                }
            }
        }
    };
    let tip = match named("robot.tip_link", &opts.tip_link)? {
        Some(t) => t,
        None => default_tip(robot, base, &child_joints, &link_idx, &mut notes)?,
    };
    // The chain: the joints from the base down to the tip.
    let mut chain = Vec::new();
    let mut cur = tip;
    while cur != base {
        let Some(j) = parent_joint[cur].filter(|_| chain.len() < nl) else {
            return Err(ModelError::TipNotBelowBase {
                base: robot.links[base].name.clone(),
                tip: robot.links[tip].name.clone(),
            });
        };
        chain.push(j);
        cur = link_idx[robot.joints[j].parent.link.as_str()];
    }
    chain.reverse();

    // --- Joint types ------------------------------------------------------------
    use urdf_rs::JointType as T;
    let mut moving = Vec::with_capacity(NJ);
    for &ji in &chain {
        let j = &robot.joints[ji];
        match j.joint_type {
            T::Revolute | T::Continuous => {
                if let Some(m) = &j.mimic {
                    notes.push(format!(
                        "joint `{}` mimics `{}`: the mimic is ignored, it is driven as an independent joint",
                        j.name, m.joint
                    ));
                }
                moving.push(ji);
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
    if moving.len() != NJ {
        return Err(ModelError::WrongDof { found: moving.len(), expected: NJ });
    }

    // --- The bodies -------------------------------------------------------------
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
    link_inertia(&robot.links[base])?; // validated, but the base does not move
                                       // Fixed joints from the base to the first actuated joint fold into its origin.
    let mut acc = Isometry3::identity();
    for &ji in chain.iter().take_while(|&&ji| ji != moving[0]) {
        acc *= pose_iso(&robot.joints[ji].origin);
    }
    origins[0] = acc * pose_iso(&robot.joints[moving[0]].origin);
    let mut bodies: Vec<BodyAcc> = Vec::with_capacity(NJ);
    let mut ee = None;
    for k in 0..NJ {
        let j = &robot.joints[moving[k]];
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
        joint_names[k] = j.name.clone();
        let child = link_idx[j.child.link.as_str()];
        link_names[k] = robot.links[child].name.clone();
        // Every link rigidly attached to this body, with its pose in the body's link frame.
        let mut body =
            BodyAcc { inertia: SpatialInertia::zero(), collisions: Vec::new(), visuals: Vec::new() };
        let mut stack = vec![(child, Isometry3::identity())];
        let mut walked = 0;
        while let Some((l, pose)) = stack.pop() {
            walked += 1;
            if walked > nl {
                break; // a cycle of fixed joints: every link is walked once at most
            }
            let link = &robot.links[l];
            let (r, p) = (rot_of(&pose), pose.translation.vector);
            body.inertia = body.inertia.add(&link_inertia(link)?.to_parent(&r, &p));
            for c in &link.collision {
                body.collisions.push(Elem {
                    link: &link.name,
                    pose: pose * pose_iso(&c.origin),
                    geom: &c.geometry,
                });
            }
            for c in &link.visual {
                body.visuals.push(Elem {
                    link: &link.name,
                    pose: pose * pose_iso(&c.origin),
                    geom: &c.geometry,
                });
            }
            if l == tip {
                ee = Some(pose);
            }
            for &cj in &child_joints[l] {
                let jj = &robot.joints[cj];
                let to = pose * pose_iso(&jj.origin);
                if jj.joint_type == T::Fixed {
                    stack.push((link_idx[jj.child.link.as_str()], to));
                } else if k + 1 < NJ && cj == moving[k + 1] {
                    origins[k + 1] = to;
                } else {
                    notes.push(format!(
                        "joint `{}` ({:?}) below link `{}` is off the chain: its branch is ignored (its mass is not modelled)",
                        jj.name,
                        jj.joint_type,
                        link.name
                    ));
                }
            }
        }
        bodies.push(body);
    }
    let ee = ee.expect("the tip follows the last actuated joint through fixed joints");
    let ee_link = robot.links[tip].name.clone();

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
        capsules[k] = body_capsule(k, &link_names[k], body, opts, &mut notes)?;
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
        ee_rot: q_last.transpose() * rot_of(&ee),
        ee_pos: q_last.transpose() * ee.translation.vector,
        capsules,
        inertials,
        notes,
    })
}
