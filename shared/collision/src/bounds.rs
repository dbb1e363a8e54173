//! How a forecast's uncertainty becomes an inflated shape, and how far a true shape lies
//! outside a predicted one. One place for the rules the predictor publishes with, the
//! planner reads with and `dkrrt predict-eval` checks with.
//!
//! * A forecast step carries `sigma_pos_m` (bound on the body origin's position error) and
//!   `sigma_m` = `sigma_pos_m` + θ · lever, where θ bounds the attitude error that matters
//!   for the shape ([`attitude_channel`]) and the lever is the farthest shape point from the
//!   body origin ([`DebrisShape::rotation_lever`]): a rotation by θ moves a point at distance
//!   ℓ by `2ℓ sin(θ/2) ≤ θℓ`.
//! * The planner takes the object to lie both in the predicted shape inflated by `sigma_m`
//!   (+ margin) and in the bounding sphere inflated by `sigma_pos_m` (+ margin), and measures
//!   the arm's distance to it as the larger of its distances to the two
//!   ([`crate::Obstacle::with_ball`]).
//! * [`surface_excess`] is the smallest inflation of the predicted shape that contains the
//!   true one: the forecast is *contained* when it is ≤ the inflation used, for both
//!   containers.

use crate::pose::quat_rotate;
use dkrrt_msg::{DebrisShape, ShapeKind};

/// Which attitude error a shape's inflation needs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AttitudeChannel {
    /// No attitude dependence (a sphere about the body origin, or an unknown shape that is
    /// its bounding sphere).
    None,
    /// Only the line of the body z axis (a capsule or a disc about z centred on the body
    /// origin): its spin about the axis and a half turn end over end leave the shape unchanged.
    Axis,
    /// The full attitude.
    Full,
}

/// The attitude error `shape` needs (see [`AttitudeChannel`]).
pub fn attitude_channel(shape: &DebrisShape) -> AttitudeChannel {
    let o = &shape.offset;
    match ShapeKind::from_u32(shape.kind) {
        Some(ShapeKind::Sphere) if o.iter().all(|v| *v == 0.0) => AttitudeChannel::None,
        Some(ShapeKind::Capsule | ShapeKind::Disc) if o.iter().all(|v| *v == 0.0) => AttitudeChannel::Axis,
        Some(ShapeKind::Unknown) | None => AttitudeChannel::None,
        _ => AttitudeChannel::Full,
    }
}

/// Attitude bounds above this are not used (rad): past it the bounding sphere is tighter for
/// every shape.
pub const MAX_ATTITUDE_BOUND: f64 = 2.0;

/// `sigma_m` of a forecast step: the position bound plus the attitude bound of the shape's
/// channel (`att_full` or `att_axis`, rad) times its lever.
pub fn surface_sigma(
    shape: &DebrisShape,
    bounding_radius: f64,
    pos: f64,
    att_full: f64,
    att_axis: f64,
) -> f64 {
    let th = match attitude_channel(shape) {
        AttitudeChannel::None => 0.0,
        AttitudeChannel::Axis => att_axis,
        AttitudeChannel::Full => att_full,
    };
    pos + th.min(MAX_ATTITUDE_BOUND) * shape.rotation_lever(bounding_radius)
}

/// Whether the bounding sphere (radius + `sigma_pos`) is the smaller of a track's two
/// containers (its lever + `sigma` ≥ its radius + `sigma_pos`, with lever ≈ radius): the bound
/// `dkrrt predict-eval` reports, the tighter one.
pub fn sphere_is_tighter(sigma: f64, sigma_pos: f64, lever: f64) -> bool {
    sigma - sigma_pos >= lever
}

/// How fast a forecast's bound keeps growing past its last step, m/s: the larger of its mean
/// rate since the forecast's start (`last` over `span`, the time from the start, where the
/// bound is about 0, to the last step) and its rate over the last interval (from `prev`,
/// `interval` before), and never below 0. The planner grows each bound at this rate past the
/// horizon (`sigma_pos_m` for the bounding ball, `sigma_m` for the shape, at least the
/// ball's), and `dkrrt predict-eval` checks that reading.
pub fn growth_rate(last: f64, prev: f64, interval: f64, span: f64) -> f64 {
    let mut rate = if span > 0.0 { last / span } else { 0.0 };
    if interval > 0.0 {
        rate = rate.max((last - prev) / interval);
    }
    rate.max(0.0)
}

/// The smallest `s` such that the true shape (pose `p_true`, `q_true`) lies inside the
/// predicted one (`p_pred`, `q_pred`) inflated by `s`, m: for a sphere the centre distance,
/// for a capsule the larger distance of the true axis's end points to the predicted axis
/// segment, for a box the largest distance of a true corner to the predicted box (all exact:
/// the inflated predicted shape is convex and the true shape is the hull of those points,
/// swept by the same radius). Unknown shapes: the centre distance (bounding spheres).
pub fn surface_excess(
    shape: &DebrisShape,
    p_pred: &[f64; 3],
    q_pred: &[f64; 4],
    p_true: &[f64; 3],
    q_true: &[f64; 4],
) -> f64 {
    // An unknown shape's radius cancels (the centre distance).
    shape_excess(shape, 0.0, p_pred, q_pred, shape, 0.0, p_true, q_true)
}

/// The smallest `s` such that the true shape `truth` (pose `p_true`, `q_true`) lies inside
/// the predicted shape `pred` (another descriptor: e.g. what a perception front end
/// estimated; pose `p_pred`, `q_pred`) inflated by `s`, m (0 when it lies inside as it is).
/// Each shape is a core swept by a ball (a sphere: its centre and radius; a capsule: its
/// axis segment and radius; a box: itself and 0; unknown: the body origin and its bounding
/// radius). The distance to the inflated predicted shape is convex, so its largest value
/// over the true shape is at a ball around an extreme point of the true core (centre, axis
/// ends, corners): from a point or a segment, that ball's farthest point lies its radius
/// beyond the point's own distance; from a box, the same for a point outside, and for a
/// point inside the radius less the point's depth below the nearest face; a disc is a solid
/// too. Exact, but for a true disc, whose extreme points are its two rim circles: they are
/// taken at [`RIM_POINTS`] points each, so the result may lie below the exact value by as
/// much as the rim strays from that polygon (`r (1 − cos(π/n))`: 0.008 % of its radius).
/// With `pred == truth` it is [`surface_excess`].
#[allow(clippy::too_many_arguments)]
pub fn shape_excess(
    pred: &DebrisShape,
    pred_radius: f64,
    p_pred: &[f64; 3],
    q_pred: &[f64; 4],
    truth: &DebrisShape,
    true_radius: f64,
    p_true: &[f64; 3],
    q_true: &[f64; 4],
) -> f64 {
    let core = Core::of(pred, pred_radius, p_pred, q_pred);
    let at = |local: &[f64; 3]| posed(truth, p_true, q_true, local);
    let t = &truth.dims;
    let mut worst = f64::NEG_INFINITY;
    let mut point = |x: [f64; 3], r: f64| worst = worst.max(core.excess(&x, r));
    match ShapeKind::from_u32(truth.kind) {
        Some(ShapeKind::Sphere) => point(at(&[0.0; 3]), t[0]),
        Some(ShapeKind::Capsule) => {
            point(at(&[0.0, 0.0, -t[0]]), t[1]);
            point(at(&[0.0, 0.0, t[0]]), t[1]);
        }
        Some(ShapeKind::Box) => {
            for c in 0..8 {
                let s = |i: usize| if c >> i & 1 == 1 { t[i] } else { -t[i] };
                point(at(&[s(0), s(1), s(2)]), 0.0);
            }
        }
        Some(ShapeKind::Disc) => {
            let n = RIM_POINTS;
            for k in 0..n {
                let (sin, cos) = (std::f64::consts::TAU * k as f64 / n as f64).sin_cos();
                for z in [-t[1], t[1]] {
                    point(at(&[t[0] * cos, t[0] * sin, z]), 0.0);
                }
            }
        }
        _ => point(*p_true, true_radius),
    }
    worst.max(0.0)
}

/// Points taken on each rim circle of a true disc ([`shape_excess`]).
pub const RIM_POINTS: usize = 256;

/// [`shape_excess`] for a true body given by the points whose hull it is (body frame, e.g. a
/// convex fragment's vertices about its centre of mass, which its descriptor only bounds by
/// its box): the smallest `s` such that every point, posed at `p_true`, `q_true`, lies in the
/// predicted shape inflated by `s` (exact: the inflated shape is convex), m (0 inside).
pub fn points_excess(
    pred: &DebrisShape,
    pred_radius: f64,
    p_pred: &[f64; 3],
    q_pred: &[f64; 4],
    points: &[[f64; 3]],
    p_true: &[f64; 3],
    q_true: &[f64; 4],
) -> f64 {
    let core = Core::of(pred, pred_radius, p_pred, q_pred);
    let mut worst = 0.0f64;
    for x in points {
        let r = quat_rotate(q_true, x);
        worst = worst.max(core.excess(&[p_true[0] + r[0], p_true[1] + r[1], p_true[2] + r[2]], 0.0));
    }
    worst
}

/// A body-frame point `local` of `sh` (its offset added), posed at `p`, `q`.
fn posed(sh: &DebrisShape, p: &[f64; 3], q: &[f64; 4], local: &[f64; 3]) -> [f64; 3] {
    let l = [local[0] + sh.offset[0], local[1] + sh.offset[1], local[2] + sh.offset[2]];
    let r = quat_rotate(q, &l);
    [p[0] + r[0], p[1] + r[1], p[2] + r[2]]
}

/// A predicted shape as a core swept by a ball ([`shape_excess`]).
enum Core {
    /// Centre and radius (a sphere, or an unknown shape's bounding sphere).
    Point([f64; 3], f64),
    /// Axis ends and radius (a capsule).
    Segment([f64; 3], [f64; 3], f64),
    /// Centre, world → body rotation and half extents (a box).
    Solid([f64; 3], [f64; 4], [f64; 3]),
    /// Centre, world → body rotation, radius and half thickness (a disc about body z).
    Disc([f64; 3], [f64; 4], f64, f64),
}

impl Core {
    /// The predicted shape `pred` (bounding radius `pred_radius`: an unknown shape's sphere)
    /// posed at `p_pred`, `q_pred`.
    fn of(pred: &DebrisShape, pred_radius: f64, p_pred: &[f64; 3], q_pred: &[f64; 4]) -> Core {
        let at = |local: &[f64; 3]| posed(pred, p_pred, q_pred, local);
        let inv = [q_pred[0], -q_pred[1], -q_pred[2], -q_pred[3]];
        let d = &pred.dims;
        match ShapeKind::from_u32(pred.kind) {
            Some(ShapeKind::Sphere) => Core::Point(at(&[0.0; 3]), d[0]),
            Some(ShapeKind::Capsule) => Core::Segment(at(&[0.0, 0.0, -d[0]]), at(&[0.0, 0.0, d[0]]), d[1]),
            Some(ShapeKind::Box) => Core::Solid(at(&[0.0; 3]), inv, *d),
            Some(ShapeKind::Disc) => Core::Disc(at(&[0.0; 3]), inv, d[0], d[1]),
            _ => Core::Point(*p_pred, pred_radius),
        }
    }

    /// How far the ball (`x`, `r`) reaches beyond this shape: its farthest point's distance to
    /// the core less the core's radius. From a point or a segment the farthest point lies `r`
    /// beyond `x`'s own distance; from a box too for `x` outside, and for `x` inside `r` less
    /// its depth below the nearest face.
    fn excess(&self, x: &[f64; 3], r: f64) -> f64 {
        match self {
            Core::Point(c, rc) => crate::dist(c, x) + r - rc,
            Core::Segment(a, b, rc) => crate::seg_point(a, b, x) + r - rc,
            Core::Solid(o, qc, h) => {
                let l = quat_rotate(qc, &[x[0] - o[0], x[1] - o[1], x[2] - o[2]]);
                let out = (0..3).map(|i| (l[i].abs() - h[i]).max(0.0).powi(2)).sum::<f64>().sqrt();
                if out > 0.0 {
                    out + r
                } else {
                    r - (0..3).map(|i| h[i] - l[i].abs()).fold(f64::INFINITY, f64::min)
                }
            }
            Core::Disc(o, qc, rd, hd) => {
                let l = quat_rotate(qc, &[x[0] - o[0], x[1] - o[1], x[2] - o[2]]);
                let (rho, z) = (l[0].hypot(l[1]), l[2].abs());
                let out = (rho - rd).max(0.0).hypot((z - hd).max(0.0));
                if out > 0.0 {
                    out + r
                } else {
                    r - (rd - rho).min(hd - z)
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shape(kind: ShapeKind, dims: [f64; 3], offset: [f64; 3]) -> DebrisShape {
        DebrisShape { kind: kind as u32, dims, offset, ..Default::default() }
    }

    #[test]
    fn channels() {
        assert_eq!(
            attitude_channel(&shape(ShapeKind::Sphere, [0.3, 0.0, 0.0], [0.0; 3])),
            AttitudeChannel::None
        );
        assert_eq!(
            attitude_channel(&shape(ShapeKind::Sphere, [0.3, 0.0, 0.0], [0.1, 0.0, 0.0])),
            AttitudeChannel::Full
        );
        assert_eq!(
            attitude_channel(&shape(ShapeKind::Capsule, [1.0, 0.05, 0.0], [0.0; 3])),
            AttitudeChannel::Axis
        );
        assert_eq!(
            attitude_channel(&shape(ShapeKind::Capsule, [1.0, 0.05, 0.0], [0.0, 0.0, 0.3])),
            AttitudeChannel::Full
        );
        assert_eq!(
            attitude_channel(&shape(ShapeKind::Capsule, [1.0, 0.05, 0.0], [0.2, 0.0, 0.0])),
            AttitudeChannel::Full
        );
        assert_eq!(
            attitude_channel(&shape(ShapeKind::Box, [1.0, 0.5, 0.1], [0.0; 3])),
            AttitudeChannel::Full
        );
        assert_eq!(
            attitude_channel(&shape(ShapeKind::Disc, [0.7, 0.01, 0.0], [0.0; 3])),
            AttitudeChannel::Axis
        );
        let rod = shape(ShapeKind::Capsule, [1.0, 0.05, 0.0], [0.0; 3]);
        assert!((surface_sigma(&rod, 1.05, 0.1, 0.9, 0.2) - 0.3).abs() < 1e-12);
        let b = shape(ShapeKind::Box, [1.0, 0.0, 0.0], [0.0; 3]);
        assert!((surface_sigma(&b, 1.0, 0.1, 5.0, 0.0) - 2.1).abs() < 1e-12, "attitude bound capped");
    }

    #[test]
    fn excess_of_known_errors() {
        let id = [1.0, 0.0, 0.0, 0.0];
        let p0 = [0.0; 3];
        // Rod of half length 1 turned by θ about x: its ends move by 2 sin(θ/2) off the old
        // axis's ends, and their distance to the old segment is sin θ.
        let rod = shape(ShapeKind::Capsule, [1.0, 0.05, 0.0], [0.0; 3]);
        let th: f64 = 0.3;
        let q = [(th / 2.0).cos(), (th / 2.0).sin(), 0.0, 0.0];
        assert!((surface_excess(&rod, &p0, &id, &p0, &q) - th.sin()).abs() < 1e-12);
        // Spin about its own axis: nothing moves.
        let spin = [(0.7f64).cos(), 0.0, 0.0, (0.7f64).sin()];
        assert!(surface_excess(&rod, &p0, &id, &p0, &spin) < 1e-12);
        // Upside down: the same line.
        assert!(surface_excess(&rod, &p0, &id, &p0, &[0.0, 1.0, 0.0, 0.0]) < 1e-12);
        // Shift along the axis by 0.2: one end 0.2 past the old end.
        assert!((surface_excess(&rod, &p0, &id, &[0.0, 0.0, 0.2], &id) - 0.2).abs() < 1e-12);
        // Box: turned by 90° about z, a 2×1 footprint sticks out by 0.5 along y.
        let b = shape(ShapeKind::Box, [1.0, 0.5, 0.1], [0.0; 3]);
        let s = std::f64::consts::FRAC_1_SQRT_2;
        assert!((surface_excess(&b, &p0, &id, &p0, &[s, 0.0, 0.0, s]) - 0.5).abs() < 1e-9);
        assert!((surface_excess(&b, &p0, &id, &[0.3, 0.0, 0.0], &id) - 0.3).abs() < 1e-12);
        // Disc of radius 1: turned by θ about y, its rim's lowest point lies sin θ below its
        // plane (a thin disc); spun about its axis or upside down, nothing moves.
        let disc = shape(ShapeKind::Disc, [1.0, 1e-9, 0.0], [0.0; 3]);
        let qy = [(th / 2.0).cos(), 0.0, (th / 2.0).sin(), 0.0];
        let e = surface_excess(&disc, &p0, &id, &p0, &qy);
        assert!((e - th.sin()).abs() < 1e-6, "{e}");
        assert!(surface_excess(&disc, &p0, &id, &p0, &spin) < 1e-9);
        assert!(surface_excess(&disc, &p0, &id, &p0, &[0.0, 1.0, 0.0, 0.0]) < 1e-9);
        // Sphere: centre distance.
        let sp = shape(ShapeKind::Sphere, [0.4, 0.0, 0.0], [0.0; 3]);
        assert!((surface_excess(&sp, &p0, &id, &[0.0, 0.3, 0.4], &spin) - 0.5).abs() < 1e-12);
    }

    #[test]
    fn excess_between_two_shapes() {
        let id = [1.0, 0.0, 0.0, 0.0];
        let p0 = [0.0; 3];
        let rod = shape(ShapeKind::Capsule, [0.2, 0.05, 0.0], [0.0; 3]);
        let ball = |r: f64| shape(ShapeKind::Sphere, [r, 0.0, 0.0], [0.0; 3]);
        // A ball of 0.3 around a rod reaching 0.25 from the centre holds it; one of 0.2 misses
        // its ends by 0.05.
        assert_eq!(shape_excess(&ball(0.3), 0.3, &p0, &id, &rod, 0.25, &p0, &id), 0.0);
        assert!((shape_excess(&ball(0.2), 0.2, &p0, &id, &rod, 0.25, &p0, &id) - 0.05).abs() < 1e-12);
        // A unit cube's corners lie √3/2 out: a ball of 0.5 misses them by √3/2 − 0.5.
        let cube = shape(ShapeKind::Box, [0.5, 0.5, 0.5], [0.0; 3]);
        let e = shape_excess(&ball(0.5), 0.5, &p0, &id, &cube, 0.866, &p0, &id);
        assert!((e - (0.75f64.sqrt() - 0.5)).abs() < 1e-12, "{e}");
        // A ball inside a box estimated 0.1 too thin along x, shifted 0.1 along x.
        let slab = shape(ShapeKind::Box, [0.2, 0.3, 0.3], [0.0; 3]);
        let e = shape_excess(&slab, 0.5, &p0, &id, &ball(0.3), 0.3, &[0.1, 0.0, 0.0], &spin_z(0.4));
        assert!((e - 0.2).abs() < 1e-12, "{e}");
        // A square panel spun any way about its normal stays inside the disc through its
        // corners; a disc of its half side misses the corners by (√2 − 1)·a.
        let a = 0.5;
        let square = shape(ShapeKind::Box, [a, a, 0.005], [0.0; 3]);
        let disc = |r: f64| shape(ShapeKind::Disc, [r, 0.005, 0.0], [0.0; 3]);
        for k in 0..12 {
            let q = spin_z(0.3 * k as f64);
            assert!(
                shape_excess(&disc(a * 2f64.sqrt() + 1e-12), 1.0, &p0, &id, &square, 0.71, &p0, &q) < 1e-9
            );
        }
        let e = shape_excess(&disc(a), a, &p0, &id, &square, 0.71, &p0, &id);
        assert!((e - (2f64.sqrt() - 1.0) * a).abs() < 1e-12, "{e}");
        // A rod through a disc's centre along its axis sticks out by its half length less the
        // disc's half thickness (plus its radius).
        let e = shape_excess(&disc(0.4), 0.4, &p0, &id, &rod, 0.25, &p0, &id);
        assert!((e - (0.2 + 0.05 - 0.005)).abs() < 1e-12, "{e}");
        // An unknown predicted shape is its bounding sphere.
        let unknown = DebrisShape::default();
        assert!((shape_excess(&unknown, 0.1, &p0, &id, &rod, 0.25, &p0, &id) - 0.15).abs() < 1e-12);
        // The same shape on both sides: surface_excess, for random poses.
        let shapes = [
            shape(ShapeKind::Capsule, [0.8, 0.05, 0.0], [0.0, 0.0, 0.2]),
            shape(ShapeKind::Box, [0.6, 0.3, 0.05], [0.1, -0.2, 0.0]),
            shape(ShapeKind::Sphere, [0.3, 0.0, 0.0], [0.0; 3]),
            shape(ShapeKind::Disc, [0.6, 0.05, 0.0], [0.0; 3]),
        ];
        for (k, sh) in shapes.iter().enumerate() {
            for j in 0..20 {
                let a = 0.1 * (k * 20 + j) as f64;
                let q = [(a / 2.0).cos(), (a / 2.0).sin() * 0.6, (a / 2.0).sin() * 0.8, 0.0];
                let p = [0.1 * a.sin(), -0.05 * a, 0.2];
                let r = sh.bounding_radius();
                let two = shape_excess(sh, r, &p0, &id, sh, r, &p, &q);
                assert!((two - surface_excess(sh, &p0, &id, &p, &q)).abs() < 1e-12, "{k} {j}");
            }
        }
    }

    fn spin_z(a: f64) -> [f64; 4] {
        [(a / 2.0).cos(), 0.0, 0.0, (a / 2.0).sin()]
    }

    #[test]
    fn sigma_contains_any_error_within_the_bounds() {
        // surface_sigma with the true errors as bounds always contains: excess ≤ sigma.
        let shapes = [
            shape(ShapeKind::Capsule, [0.8, 0.05, 0.0], [0.0; 3]),
            shape(ShapeKind::Capsule, [0.8, 0.05, 0.0], [0.0, 0.0, 0.2]),
            shape(ShapeKind::Box, [0.6, 0.3, 0.05], [0.1, -0.2, 0.0]),
            shape(ShapeKind::Sphere, [0.3, 0.0, 0.0], [0.0; 3]),
            shape(ShapeKind::Disc, [0.6, 0.05, 0.0], [0.0; 3]),
        ];
        let mut seed = 1u64;
        let mut rnd = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        for _ in 0..2000 {
            let norm = |q: [f64; 4]| {
                let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
                q.map(|v| v / n)
            };
            let qp = norm([rnd(), rnd(), rnd(), rnd()]);
            let qt =
                norm([qp[0] + 0.3 * rnd(), qp[1] + 0.3 * rnd(), qp[2] + 0.3 * rnd(), qp[3] + 0.3 * rnd()]);
            let pp = [rnd(), rnd(), rnd()];
            let pt = [pp[0] + 0.2 * rnd(), pp[1] + 0.2 * rnd(), pp[2] + 0.2 * rnd()];
            let dp = ((pp[0] - pt[0]).powi(2) + (pp[1] - pt[1]).powi(2) + (pp[2] - pt[2]).powi(2)).sqrt();
            let full = crate::quat_angle(&qp, &qt);
            let zp = quat_rotate(&qp, &[0.0, 0.0, 1.0]);
            let zt = quat_rotate(&qt, &[0.0, 0.0, 1.0]);
            let axis = (zp[0] * zt[0] + zp[1] * zt[1] + zp[2] * zt[2]).abs().min(1.0).acos();
            for s in &shapes {
                let r = s.bounding_radius();
                let sig = surface_sigma(s, r, dp, full, axis);
                let e = surface_excess(s, &pp, &qp, &pt, &qt);
                assert!(e <= sig + 1e-9, "{s:?}: excess {e} > sigma {sig}");
            }
        }
    }

    #[test]
    fn past_the_horizon_a_bound_grows_at_the_larger_rate() {
        // Mean rate since the start (0.4 over 4 s) against the last interval's (0.02 per 0.1 s).
        assert!((growth_rate(0.4, 0.38, 0.1, 4.0) - 0.2).abs() < 1e-12);
        assert!((growth_rate(0.4, 0.399, 0.1, 4.0) - 0.1).abs() < 1e-12);
        // A shrinking last interval keeps the mean rate; nothing grows below 0.
        assert!((growth_rate(0.4, 0.5, 0.1, 4.0) - 0.1).abs() < 1e-12);
        assert_eq!(growth_rate(0.0, 0.1, 0.1, 4.0), 0.0);
        assert_eq!(growth_rate(0.3, 0.3, 0.0, 0.0), 0.0);
    }

    #[test]
    fn past_the_horizon_the_pose_goes_on_at_the_last_rate() {
        use crate::pose::{continue_pose, quat_angle};
        // Turns about a fixed axis at rates whose steps the slerp reads as nearly parallel
        // (< 0.063 rad per step) and not: continued 10 steps past `b`, the attitude is the
        // constant-rate one (the normalised lerp would be 0.01 rad behind at 0.05 rad a step).
        let axis = [0.0, 0.6, 0.8];
        let turn = |th: f64| {
            let (s, c) = ((0.5 * th).sin(), (0.5 * th).cos());
            [c, s * axis[0], s * axis[1], s * axis[2]]
        };
        for step in [1e-7, 0.01, 0.05, 0.3] {
            let (qa, qb) = (turn(0.7), turn(0.7 + step));
            let (p, q) = continue_pose(&[0.0, 1.0, 2.0], &qa, &[0.1, 1.0, 2.0], &qb, 11.0);
            assert!((p[0] - 1.1).abs() < 1e-12 && p[1] == 1.0 && p[2] == 2.0, "{p:?}");
            let want = turn(0.7 + 11.0 * step);
            assert!(quat_angle(&q, &want) < 1e-9, "step {step}: {}", quat_angle(&q, &want));
            // -b is the same attitude: the shorter arc is continued.
            let (_, q2) = continue_pose(&[0.0; 3], &qa, &[0.0; 3], &qb.map(|x| -x), 11.0);
            assert!(quat_angle(&q2, &want) < 1e-9, "step {step}");
        }
    }

    #[test]
    fn a_rods_step_is_its_axis_swung_without_the_spin() {
        use crate::pose::{axis_swing, quat_angle, quat_mul, quat_rotate, same_shape_nearest};
        let q_of = |axis: [f64; 3], th: f64| {
            let n = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
            let (s, c) = ((0.5 * th).sin() / n, (0.5 * th).cos());
            [c, s * axis[0], s * axis[1], s * axis[2]]
        };
        let z = [0.0, 0.0, 1.0];
        let prev = q_of([0.3, -0.5, 0.8], 1.1);
        // The next step: the axis tilted by 0.1 rad, with 2.5 rad of spin about it, and flipped
        // end over end (the same rod).
        let za = quat_rotate(&prev, &z);
        let tilt = q_of([za[1], -za[0], 0.0], 0.1);
        let spun = quat_mul(&quat_mul(&tilt, &prev), &q_of(z, 2.5));
        let q = quat_mul(&spun, &q_of([1.0, 0.0, 0.0], std::f64::consts::PI));
        let s = axis_swing(&prev, &q);
        let (zs, zq) = (quat_rotate(&s, &z), quat_rotate(&q, &z));
        // The same line as the step's axis, reached by the 0.1 rad tilt alone.
        assert!((zs[0] * zq[0] + zs[1] * zq[1] + zs[2] * zq[2]).abs() > 1.0 - 1e-12);
        assert!((quat_angle(&prev, &s) - 0.1).abs() < 1e-9, "{}", quat_angle(&prev, &s));
        let rod = shape(ShapeKind::Capsule, [0.6, 0.05, 0.0], [0.0; 3]);
        assert_eq!(same_shape_nearest(&rod, &prev, &q), s);
        // A box keeps its spin (its shape shows it), taken modulo its half turns: 2.5 rad is
        // π − 0.64 rad, so the nearest is 0.64 rad of spin the other way, with the tilt.
        let b = shape(ShapeKind::Box, [0.6, 0.3, 0.1], [0.0; 3]);
        let bq = same_shape_nearest(&b, &prev, &q);
        let a = quat_angle(&prev, &bq);
        assert!(a > 0.6 && a < 0.7, "{a}");
        assert!((quat_angle(&bq, &quat_mul(&spun, &q_of(z, std::f64::consts::PI)))) < 1e-9);
        // A sphere: as given.
        let ball = shape(ShapeKind::Sphere, [0.3, 0.0, 0.0], [0.0; 3]);
        assert_eq!(same_shape_nearest(&ball, &prev, &q), q);
    }
}
