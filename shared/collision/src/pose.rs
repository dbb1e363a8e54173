//! Pose helpers shared by the predictor (forecasts on a common grid) and the planner (poses
//! between forecast steps): one interpolation, so both read the same motion into a forecast.
//! Quaternions are (w, x, y, z).

/// Rotates `v` by the unit quaternion `q`.
#[inline]
pub fn quat_rotate(q: &[f64; 4], v: &[f64; 3]) -> [f64; 3] {
    let (w, x, y, z) = (q[0], q[1], q[2], q[3]);
    // t = 2 (q_vec × v); v' = v + w t + q_vec × t
    let t = [2.0 * (y * v[2] - z * v[1]), 2.0 * (z * v[0] - x * v[2]), 2.0 * (x * v[1] - y * v[0])];
    [
        v[0] + w * t[0] + (y * t[2] - z * t[1]),
        v[1] + w * t[1] + (z * t[0] - x * t[2]),
        v[2] + w * t[2] + (x * t[1] - y * t[0]),
    ]
}

/// The product `a ⊗ b` (the rotation `b`, then `a`).
#[inline]
pub fn quat_mul(a: &[f64; 4], b: &[f64; 4]) -> [f64; 4] {
    [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ]
}

/// The rotation matrix (rows) of the quaternion `q` (normalised first).
pub fn rotation_matrix(q: &[f64; 4]) -> [[f64; 3]; 3] {
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    let (w, x, y, z) = (q[0] / n, q[1] / n, q[2] / n, q[3] / n);
    [
        [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)],
        [2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)],
        [2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)],
    ]
}

/// Rotation angle between two unit quaternions, rad (in [0, π]).
#[inline]
pub fn quat_angle(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    let d = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]).abs().min(1.0);
    2.0 * d.acos()
}

/// The pose a fraction `f` of the way from (`pa`, `qa`) to (`pb`, `qb`): position linear
/// (extrapolated for `f > 1`), attitude by slerp on the shorter arc (`f` clamped to [0, 1]).
/// The motion between two poses is then at constant linear and angular speed.
pub fn interpolate_pose(
    pa: &[f64; 3],
    qa: &[f64; 4],
    pb: &[f64; 3],
    qb: &[f64; 4],
    f: f64,
) -> ([f64; 3], [f64; 4]) {
    let p = [pa[0] + f * (pb[0] - pa[0]), pa[1] + f * (pb[1] - pa[1]), pa[2] + f * (pb[2] - pa[2])];
    (p, slerp(qa, qb, f.clamp(0.0, 1.0)))
}

/// Spherical linear interpolation of unit quaternions on the shorter arc.
pub fn slerp(a: &[f64; 4], b: &[f64; 4], f: f64) -> [f64; 4] {
    slerp_on(a, b, &SlerpArc::between(a, b), f)
}

/// What [`slerp`] needs of a pair of quaternions besides the fraction: computed once for a
/// pair read at many fractions (the planner's forecast intervals), the same numbers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlerpArc {
    /// −1 when the shorter arc runs to `−b`.
    sign: f64,
    /// The angle between them and its sine; `None` when nearly parallel (normalised lerp).
    angle: Option<(f64, f64)>,
}

impl SlerpArc {
    /// The shorter arc from `a` to `b`.
    #[inline]
    pub fn between(a: &[f64; 4], b: &[f64; 4]) -> SlerpArc {
        let mut d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
        let sign = if d < 0.0 {
            d = -d;
            -1.0
        } else {
            1.0
        };
        let angle = if d > 0.9995 {
            None
        } else {
            let th = d.min(1.0).acos();
            Some((th, th.sin()))
        };
        SlerpArc { sign, angle }
    }
}

/// [`slerp`] with the pair's [`SlerpArc`] given.
#[inline]
pub fn slerp_on(a: &[f64; 4], b: &[f64; 4], arc: &SlerpArc, f: f64) -> [f64; 4] {
    let s = arc.sign;
    let (wa, wb) = match arc.angle {
        None => (1.0 - f, f), // nearly parallel: normalised lerp
        Some((th, st)) => (((1.0 - f) * th).sin() / st, (f * th).sin() / st),
    };
    let mut q = [0.0; 4];
    for i in 0..4 {
        q[i] = wa * a[i] + wb * s * b[i];
    }
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    if n > 0.0 {
        q.iter_mut().for_each(|x| *x /= n);
    }
    q
}
