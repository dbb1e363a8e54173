//! The prediction state of one debris object and the known nominal dynamics.
//!
//! Layout (`N = 13`), all in the module's LVLH frame (x radial, y along-track, z orbit
//! normal; see `sim/debris/README.md`):
//!
//! | index | content |
//! |-------|---------|
//! | 0..3  | position `p` [m] |
//! | 3..6  | velocity `v` relative to LVLH [m/s] |
//! | 6..10 | attitude quaternion body → LVLH `(w, x, y, z)` |
//! | 10..13| inertial angular velocity in body axes `ω` [rad/s] |
//!
//! Why a quaternion + body rate: the kinematics `q̇ = ½ q ⊗ ω − ½ (n ẑ) ⊗ q` is bilinear in
//! `(q, ω)` and Euler's equations are quadratic in `ω`, so a degree-2 polynomial dictionary on
//! the attitude block contains the exact time derivative of its linear part. A rotation
//! matrix (9 + 3 states) would need the same products with 2.5× more states. Quaternion
//! sign: `q` and `−q` are the same attitude; feed the predictor a sign-continuous sequence
//! ([`align_quaternion`]) and renormalise outputs ([`crate::StateConstraint::UnitQuaternion`]).
//! Translation and attitude are decoupled (no gravity-gradient torque or contact), so two
//! models (6-d translational, 7-d rotational) are much cheaper than one 13-d model.

/// State dimension.
pub const N: usize = 13;
/// Position block.
pub const POS: std::ops::Range<usize> = 0..3;
/// Velocity block.
pub const VEL: std::ops::Range<usize> = 3..6;
/// Quaternion block.
pub const QUAT: std::ops::Range<usize> = 6..10;
/// Body-rate block.
pub const RATE: std::ops::Range<usize> = 10..13;
/// Translational sub-state.
pub const TRANS: std::ops::Range<usize> = 0..6;
/// Rotational sub-state (quaternion + body rate).
pub const ROT: std::ops::Range<usize> = 6..13;

/// Sparse degree-2 dictionary for the 7-d rotational sub-state `(q, ω)`:
/// `[q, ω, 1, q_i ω_j (12), ω_i ω_j (6)]`, `p = 26`. These are exactly the monomials in
/// `q̇` (bilinear in `q, ω`) and `ω̇` (quadratic in `ω`), so the linear part of the attitude
/// dynamics is closed to first order; the 10 `q_i q_j` terms of the full degree-2 dictionary
/// (`p = 36`) are dropped.
pub fn attitude_dictionary() -> crate::Polynomial {
    let mut m = Vec::new();
    for i in 0..4 {
        for j in 4..7 {
            m.push(vec![i, j]);
        }
    }
    for i in 4..7 {
        for j in i..7 {
            m.push(vec![i, j]);
        }
    }
    crate::Polynomial::from_monomials(7, &m)
}

/// Pack a state.
pub fn pack(p: [f64; 3], v: [f64; 3], q: [f64; 4], w: [f64; 3]) -> [f64; N] {
    let mut x = [0.0; N];
    x[POS].copy_from_slice(&p);
    x[VEL].copy_from_slice(&v);
    x[QUAT].copy_from_slice(&q);
    x[RATE].copy_from_slice(&w);
    x
}

/// Flip the sign of `q` if needed so that it is on the same hemisphere as `q_ref`.
pub fn align_quaternion(q: &mut [f64], q_ref: &[f64]) {
    let d: f64 = q[..4].iter().zip(&q_ref[..4]).map(|(a, b)| a * b).sum();
    if d < 0.0 {
        q[..4].iter_mut().for_each(|v| *v = -*v);
    }
}

/// Hamilton product `a ⊗ b`, quaternions as `(w, x, y, z)`.
#[inline]
pub fn quat_mul(a: &[f64], b: &[f64]) -> [f64; 4] {
    [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ]
}

/// Quaternion of a rotation vector `θ` (exponential map).
#[inline]
pub fn quat_exp(theta: [f64; 3]) -> [f64; 4] {
    let a = (theta[0] * theta[0] + theta[1] * theta[1] + theta[2] * theta[2]).sqrt();
    if a < 1e-12 {
        return [1.0, 0.5 * theta[0], 0.5 * theta[1], 0.5 * theta[2]];
    }
    let (s, c) = (0.5 * a).sin_cos();
    let k = s / a;
    [c, k * theta[0], k * theta[1], k * theta[2]]
}

/// Known nominal dynamics for the dual-data generator, circular orbit with mean motion
/// `n`: Clohessy–Wiltshire translation, attitude kinematics in the rotating LVLH frame, and
/// `ω̇ = 0` (inertia unknown: the tumbling dynamics are left to the learned correction).
/// Works on the full 13-state, the 6-d translational (`x.len() == 6`) or 7-d rotational
/// (`x.len() == 7`) sub-state.
pub fn nominal_rhs(n: f64, x: &[f64], dx: &mut [f64]) {
    match x.len() {
        6 => cw_rhs(n, x, dx),
        7 => rot_rhs(n, x, dx),
        N => {
            cw_rhs(n, &x[TRANS], &mut dx[TRANS]);
            rot_rhs(n, &x[ROT], &mut dx[ROT]);
        }
        l => panic!("nominal_rhs: unsupported state length {l}"),
    }
}

fn cw_rhs(n: f64, x: &[f64], dx: &mut [f64]) {
    dx[0] = x[3];
    dx[1] = x[4];
    dx[2] = x[5];
    dx[3] = 3.0 * n * n * x[0] + 2.0 * n * x[4];
    dx[4] = -2.0 * n * x[3];
    dx[5] = -n * n * x[2];
}

fn rot_rhs(n: f64, x: &[f64], dx: &mut [f64]) {
    let q = &x[0..4];
    let w = [0.0, x[4], x[5], x[6]];
    let a = quat_mul(q, &w);
    let b = quat_mul(&[0.0, 0.0, 0.0, n], q);
    for i in 0..4 {
        dx[i] = 0.5 * (a[i] - b[i]);
    }
    dx[4] = 0.0;
    dx[5] = 0.0;
    dx[6] = 0.0;
}
