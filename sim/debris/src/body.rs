//! Rigid-body description of a debris object: shape, mass, inertia, state and the
//! torque-free attitude dynamics.

use nalgebra::{Matrix3, Quaternion, UnitQuaternion, Vector3};
use parry3d_f64::math::Vector as PVec;
use parry3d_f64::shape::SharedShape;
use serde::{Deserialize, Serialize};

/// Geometric shape of a debris object, in its body frame (centred on the centre of mass).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum ShapeSpec {
    /// Solid sphere.
    Sphere {
        /// Radius [m].
        radius: f64,
    },
    /// Solid box.
    Box {
        /// Half extents along body x, y, z [m].
        #[serde(deserialize_with = "dkrrt_io::exact::array")]
        half_extents: [f64; 3],
    },
    /// Rod: capsule along body z.
    Rod {
        /// Half length of the axis segment [m].
        half_length: f64,
        /// Radius [m].
        radius: f64,
    },
    /// Thin rectangular panel in the body x–y plane.
    Panel {
        /// Half extents along body x and y [m].
        #[serde(deserialize_with = "dkrrt_io::exact::array")]
        half_extents: [f64; 2],
        /// Full thickness along body z [m].
        thickness: f64,
    },
    /// Convex fragment: convex hull of the points (re-centred on its centre of mass).
    Convex {
        /// Hull points in the body frame [m].
        #[serde(deserialize_with = "dkrrt_io::exact::arrays")]
        points: Vec<[f64; 3]>,
    },
}

/// Shape, mass and inertia of a debris object, built once (allocates) and shared cheaply.
#[derive(Clone)]
pub struct BodyProps {
    /// parry3d shape in the body frame (origin = centre of mass).
    pub shape: SharedShape,
    /// Mass [kg].
    pub mass: f64,
    /// Inertia tensor about the centre of mass, body frame [kg m²].
    pub inertia: Matrix3<f64>,
    /// Inverse inertia tensor.
    pub inv_inertia: Matrix3<f64>,
    /// Radius of a sphere centred at the body origin enclosing the shape [m].
    pub bounding_radius: f64,
}

impl std::fmt::Debug for BodyProps {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BodyProps")
            .field("mass", &self.mass)
            .field("inertia", &self.inertia)
            .field("bounding_radius", &self.bounding_radius)
            .finish()
    }
}

/// Why a shape/mass specification is invalid.
#[derive(Debug, Clone, PartialEq)]
pub struct PropsError {
    /// Field (relative to the debris entry), e.g. `shape.radius`.
    pub field: String,
    /// What is wrong.
    pub reason: String,
}

fn perr(field: &str, reason: impl Into<String>) -> PropsError {
    PropsError { field: field.to_string(), reason: reason.into() }
}

fn pos(name: &str, v: f64) -> Result<(), PropsError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(perr(name, format!("must be finite and > 0 (got {v})")))
    }
}

/// The largest dimension of a debris shape (a half extent, radius or hull point's distance), m:
/// beyond it the shape's volume overflows or it is no object near an arm.
pub const MAX_SIZE_M: f64 = 100.0;

/// A dimension of a shape: finite, > 0 and at most [`MAX_SIZE_M`].
fn size(name: &str, v: f64) -> Result<(), PropsError> {
    pos(name, v)?;
    if v > MAX_SIZE_M {
        return Err(perr(name, format!("must be at most {MAX_SIZE_M} m (got {v})")));
    }
    Ok(())
}

impl BodyProps {
    /// Build from a shape and a mass. The inertia is that of the shape with uniform density
    /// unless `principal_inertia` (body-axis diagonal, kg m²) is given.
    pub fn new(spec: &ShapeSpec, mass: f64, principal_inertia: Option<[f64; 3]>) -> Result<Self, PropsError> {
        pos("mass", mass)?;
        let shape = match spec {
            ShapeSpec::Sphere { radius } => {
                size("shape.radius", *radius)?;
                SharedShape::ball(*radius)
            }
            ShapeSpec::Box { half_extents: h } => {
                for (i, v) in h.iter().enumerate() {
                    size(&format!("shape.half_extents[{i}]"), *v)?;
                }
                SharedShape::cuboid(h[0], h[1], h[2])
            }
            ShapeSpec::Rod { half_length, radius } => {
                size("shape.half_length", *half_length)?;
                size("shape.radius", *radius)?;
                SharedShape::capsule_z(*half_length, *radius)
            }
            ShapeSpec::Panel { half_extents: h, thickness } => {
                size("shape.half_extents[0]", h[0])?;
                size("shape.half_extents[1]", h[1])?;
                size("shape.thickness", *thickness)?;
                SharedShape::cuboid(h[0], h[1], 0.5 * thickness)
            }
            ShapeSpec::Convex { points } => {
                if points.len() < 4 {
                    return Err(perr("shape.points", "a convex fragment needs at least 4 points"));
                }
                for (i, p) in points.iter().enumerate() {
                    let r = p.iter().map(|x| x * x).sum::<f64>().sqrt();
                    if !(r.is_finite() && r <= MAX_SIZE_M) {
                        return Err(perr(
                            &format!("shape.points[{i}]"),
                            format!("must be finite, within {MAX_SIZE_M} m"),
                        ));
                    }
                }
                let pts: Vec<PVec> = points.iter().map(|p| PVec::new(p[0], p[1], p[2])).collect();
                let hull = SharedShape::convex_hull(&pts)
                    .ok_or_else(|| perr("shape.points", "degenerate convex hull"))?;
                let com = hull.mass_properties(1.0).local_com;
                let pts: Vec<PVec> = pts.iter().map(|p| *p - com).collect();
                SharedShape::convex_hull(&pts)
                    .ok_or_else(|| perr("shape.points", "degenerate convex hull"))?
            }
        };
        let mp = shape.mass_properties(1.0);
        let volume = mp.mass();
        pos("shape volume", volume)?;
        let inertia = match principal_inertia {
            Some(d) => {
                for (i, v) in d.iter().enumerate() {
                    pos(&format!("inertia[{i}]"), *v)?;
                }
                if d[0] + d[1] < d[2] || d[1] + d[2] < d[0] || d[0] + d[2] < d[1] {
                    return Err(perr("inertia", "principal moments violate the triangle inequality"));
                }
                Matrix3::from_diagonal(&Vector3::from(d))
            }
            None => {
                let m = mp.reconstruct_inertia_matrix().to_cols_array();
                Matrix3::from_column_slice(&m) * (mass / volume)
            }
        };
        let inv_inertia = inertia.try_inverse().ok_or_else(|| perr("inertia", "singular inertia tensor"))?;
        let bs = shape.compute_local_bounding_sphere();
        let bounding_radius = bs.center.length() + bs.radius;
        Ok(BodyProps { shape, mass, inertia, inv_inertia, bounding_radius })
    }
}

/// Full rigid-body state of a debris object.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidState {
    /// Position of the centre of mass in LVLH [m].
    pub p: Vector3<f64>,
    /// Velocity relative to the LVLH frame, in LVLH [m/s].
    pub v: Vector3<f64>,
    /// Attitude: rotation body → LVLH.
    pub q: UnitQuaternion<f64>,
    /// Inertial angular velocity, body frame [rad/s].
    pub w: Vector3<f64>,
}

impl Default for RigidState {
    fn default() -> Self {
        RigidState {
            p: Vector3::zeros(),
            v: Vector3::zeros(),
            q: UnitQuaternion::identity(),
            w: Vector3::zeros(),
        }
    }
}

/// Euler's torque-free equation: `ω̇ = I⁻¹ (−ω × Iω)`.
#[inline]
pub fn euler_rhs(inertia: &Matrix3<f64>, inv_inertia: &Matrix3<f64>, w: &Vector3<f64>) -> Vector3<f64> {
    inv_inertia * (-w.cross(&(inertia * w)))
}

/// Quaternion kinematics of body → LVLH attitude with inertial body rate `w` and LVLH frame
/// rate `frame_rate` about LVLH z: `q̇ = ½ q ⊗ (0, ω_b) − ½ (0, ν̇ ẑ) ⊗ q`.
#[inline]
pub fn quat_rhs(q: &Quaternion<f64>, w: &Vector3<f64>, frame_rate: f64) -> Quaternion<f64> {
    let wb = Quaternion::new(0.0, w.x, w.y, w.z);
    let wf = Quaternion::new(0.0, 0.0, 0.0, frame_rate);
    (q * wb - wf * q) * 0.5
}

/// One RK4 step of the torque-free attitude dynamics (quaternion renormalised afterwards).
/// The frame rate is taken as constant over the step (exact for circular orbits).
pub fn attitude_rk4(
    props: &BodyProps,
    q: &mut UnitQuaternion<f64>,
    w: &mut Vector3<f64>,
    frame_rate: [f64; 3],
    h: f64,
) {
    let (i, ii) = (&props.inertia, &props.inv_inertia);
    // A body in its principal axes (every shape but a convex piece's): Euler's equation on the
    // diagonals alone, the same values as the full products (their other terms are exact zeros).
    let diag = |m: &Matrix3<f64>| (0..3).all(|r| (0..3).all(|c| r == c || m[(r, c)] == 0.0));
    let principal = diag(i) && diag(ii);
    let (di, dii) = (i.diagonal(), ii.diagonal());
    #[inline(always)]
    fn principal_rhs(di: &Vector3<f64>, dii: &Vector3<f64>, w: &Vector3<f64>) -> Vector3<f64> {
        let c = -w.cross(&di.component_mul(w));
        dii.component_mul(&c)
    }
    let rhs = |w: &Vector3<f64>| {
        if principal {
            principal_rhs(&di, &dii, w)
        } else {
            euler_rhs(i, ii, w)
        }
    };
    let q0 = *q.quaternion();
    let w0 = *w;
    let kq1 = quat_rhs(&q0, &w0, frame_rate[0]);
    let kw1 = rhs(&w0);
    let q2 = q0 + kq1 * (0.5 * h);
    let w2 = w0 + kw1 * (0.5 * h);
    let kq2 = quat_rhs(&q2, &w2, frame_rate[1]);
    let kw2 = rhs(&w2);
    let q3 = q0 + kq2 * (0.5 * h);
    let w3 = w0 + kw2 * (0.5 * h);
    let kq3 = quat_rhs(&q3, &w3, frame_rate[1]);
    let kw3 = rhs(&w3);
    let q4 = q0 + kq3 * h;
    let w4 = w0 + kw3 * h;
    let kq4 = quat_rhs(&q4, &w4, frame_rate[2]);
    let kw4 = rhs(&w4);
    let qn = q0 + (kq1 + kq2 * 2.0 + kq3 * 2.0 + kq4) * (h / 6.0);
    *w = w0 + (kw1 + kw2 * 2.0 + kw3 * 2.0 + kw4) * (h / 6.0);
    *q = UnitQuaternion::new_normalize(qn);
}

/// Rotational kinetic energy `½ ωᵀ I ω` [J].
pub fn rotational_energy(props: &BodyProps, w: &Vector3<f64>) -> f64 {
    0.5 * w.dot(&(props.inertia * w))
}
