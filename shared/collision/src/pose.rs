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
    (lerp3(pa, pb, f), slerp(qa, qb, f.clamp(0.0, 1.0)))
}

/// `pa + f·(pb − pa)`.
#[inline]
fn lerp3(pa: &[f64; 3], pb: &[f64; 3], f: f64) -> [f64; 3] {
    [pa[0] + f * (pb[0] - pa[0]), pa[1] + f * (pb[1] - pa[1]), pa[2] + f * (pb[2] - pa[2])]
}

/// The motion from (`pa`, `qa`) to (`pb`, `qb`) continued to the fraction `f ≥ 1` of that
/// interval (1: at `b`; 2: one interval past it): position linear, attitude on the same
/// great circle at the same rate (the slerp with `f` unclamped). How the planner reads a
/// forecast past its last step, and how `dkrrt predict-eval` checks that reading.
pub fn continue_pose(
    pa: &[f64; 3],
    qa: &[f64; 4],
    pb: &[f64; 3],
    qb: &[f64; 4],
    f: f64,
) -> ([f64; 3], [f64; 4]) {
    (lerp3(pa, pb, f), slerp(qa, qb, f.max(0.0)))
}

/// `q`, or `q` turned by a half turn about a body axis, whichever is nearest to `prev`: for a
/// shape that is its own half turns (a box or a capsule centred on its body origin: see
/// [`self_half_turns`]) the same shape, and the slerp from `prev` no longer sweeps it end over
/// end through half a turn it did not make (a reported flip).
pub fn nearest_half_turn(prev: &[f64; 4], q: &[f64; 4]) -> [f64; 4] {
    let dot = |a: &[f64; 4]| (a[0] * prev[0] + a[1] * prev[1] + a[2] * prev[2] + a[3] * prev[3]).abs();
    let mut best = (dot(q), *q);
    for h in [[0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]] {
        let c = quat_mul(q, &h);
        if dot(&c) > best.0 + 1e-12 {
            best = (dot(&c), c);
        }
    }
    best.1
}

/// The attitude reached from `prev` by the shortest turn that takes its body z axis onto `q`'s
/// (or onto its opposite, whichever is nearer): for a shape that depends on its z axis alone
/// (a capsule or a disc centred on its body origin) the same shape as `q`, without `q`'s spin
/// about the axis (which a forecast may not know and the shape does not show), so reading
/// the steps in between, or past the last, moves the axis on the great circle between them.
pub fn axis_swing(prev: &[f64; 4], q: &[f64; 4]) -> [f64; 4] {
    let z = [0.0, 0.0, 1.0];
    let za = quat_rotate(prev, &z);
    let mut zb = quat_rotate(q, &z);
    if za[0] * zb[0] + za[1] * zb[1] + za[2] * zb[2] < 0.0 {
        zb = zb.map(|x| -x);
    }
    let c = [za[1] * zb[2] - za[2] * zb[1], za[2] * zb[0] - za[0] * zb[2], za[0] * zb[1] - za[1] * zb[0]];
    let s = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
    if s < 1e-15 {
        return *prev;
    }
    let th = s.atan2(za[0] * zb[0] + za[1] * zb[1] + za[2] * zb[2]);
    let (hs, hc) = ((0.5 * th).sin() / s, (0.5 * th).cos());
    let r = [hc, hs * c[0], hs * c[1], hs * c[2]];
    let mut out = quat_mul(&r, prev);
    let n = (out[0] * out[0] + out[1] * out[1] + out[2] * out[2] + out[3] * out[3]).sqrt();
    out.iter_mut().for_each(|x| *x /= n);
    out
}

/// `q` as the attitude of `shape` nearest to `prev` among those that show the same shape: for
/// a shape that depends on its z axis alone ([`crate::bounds::AttitudeChannel::Axis`]: a
/// capsule or a disc centred on its body origin) [`axis_swing`]; for another that is its own
/// half turns (a box, [`self_half_turns`]) [`nearest_half_turn`]; else `q`. What the planner
/// reads a forecast's steps as, and what `dkrrt predict-eval` checks.
pub fn same_shape_nearest(shape: &dkrrt_msg::DebrisShape, prev: &[f64; 4], q: &[f64; 4]) -> [f64; 4] {
    use crate::bounds::{attitude_channel, AttitudeChannel};
    if attitude_channel(shape) == AttitudeChannel::Axis {
        axis_swing(prev, q)
    } else if self_half_turns(shape) {
        nearest_half_turn(prev, q)
    } else {
        *q
    }
}

/// Whether `shape` is its own half turns about its body axes (a box or a capsule with no
/// offset), so [`nearest_half_turn`] may pick among its attitudes.
pub fn self_half_turns(shape: &dkrrt_msg::DebrisShape) -> bool {
    use dkrrt_msg::ShapeKind;
    matches!(ShapeKind::from_u32(shape.kind), Some(ShapeKind::Box | ShapeKind::Capsule))
        && shape.offset == [0.0; 3]
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
        // Nearly parallel, continued past `b` (`f > 1`): the normalised lerp would fall behind
        // the constant rate (by 1 % of the turn at f = 11), so the weights of the great circle,
        // with the small angle from its stable form 2·atan2(|a − b|, |a + b|).
        None if f > 1.0 => {
            let (mut dm, mut dp) = (0.0, 0.0);
            for i in 0..4 {
                dm += (a[i] - s * b[i]) * (a[i] - s * b[i]);
                dp += (a[i] + s * b[i]) * (a[i] + s * b[i]);
            }
            let th = 2.0 * dm.sqrt().atan2(dp.sqrt());
            if th > 1e-12 {
                let st = th.sin();
                (((1.0 - f) * th).sin() / st, (f * th).sin() / st)
            } else {
                (1.0 - f, f)
            }
        }
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
