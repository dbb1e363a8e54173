//! The attitudes a shape cannot tell apart.
//!
//! A sensor that sees only the shape (a depth camera and its front end) measures a box's
//! attitude up to its half turns about its body axes (and its quarter turns about an axis
//! whose other two extents agree), and a capsule's up to its spin about its axis and its
//! end-for-end turn: which of those equivalent attitudes it reports depends on its view, and
//! can change from one frame to the next (a principal axis's sign, a panel seen edge-on). A
//! tracker that took such a report at face value would see a jump of π.
//!
//! [`Symmetry`] lists the discrete turns of a shape; [`Symmetry::nearest`] picks the
//! equivalent attitude nearest to a reference (the track's prediction), and
//! [`symmetric_angle`] measures an attitude error modulo the shape's symmetry. The spin of
//! a capsule is continuous: [`symmetric_angle`] compares its axes; [`Symmetry::nearest`] only
//! resolves its end-for-end turn (the front end turns a capsule's attitude from its last one
//! by the smallest rotation, so its spin does not jump). Nothing here allocates.

use dkrrt_collision::pose::quat_mul;
use dkrrt_msg::{DebrisShape, ShapeKind};

use crate::filter::quat_angle;

/// Turns of one shape, body frame, `(w, x, y, z)`; the first is the identity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Symmetry {
    n: usize,
    g: [[f64; 4]; 16],
}

impl Default for Symmetry {
    fn default() -> Self {
        Symmetry::NONE
    }
}

const H: f64 = std::f64::consts::FRAC_1_SQRT_2;
const ONE: [f64; 4] = [1.0, 0.0, 0.0, 0.0];
const HALF: [[f64; 4]; 4] = [ONE, [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]];

impl Symmetry {
    /// No symmetry known (the identity only).
    pub const NONE: Symmetry = Symmetry { n: 1, g: [ONE; 16] };

    /// The discrete turns of `shape`: a box centred on its body origin, its half turns about
    /// the body axes times its quarter turns about an axis whose other two half extents agree
    /// within 1 %; a capsule or a disc, its end-for-end turn (half turn about body x); anything else
    /// (a sphere, whose attitude does not matter, an off-centre box, unknown) none.
    pub fn of(shape: &DebrisShape) -> Symmetry {
        let mut s = Symmetry::NONE;
        match ShapeKind::from_u32(shape.kind) {
            Some(ShapeKind::Box) if shape.offset == [0.0; 3] => {
                let d = shape.dims;
                let same = |a: f64, b: f64| (a - b).abs() <= 0.01 * a.max(b);
                let quarters = [
                    Some(ONE),
                    same(d[1], d[2]).then_some([H, H, 0.0, 0.0]),
                    same(d[0], d[2]).then_some([H, 0.0, H, 0.0]),
                    same(d[0], d[1]).then_some([H, 0.0, 0.0, H]),
                ];
                s.n = 0;
                for quarter in quarters.into_iter().flatten() {
                    for g in &HALF {
                        s.g[s.n] = quat_mul(g, &quarter);
                        s.n += 1;
                    }
                }
            }
            Some(ShapeKind::Capsule | ShapeKind::Disc) => {
                s.g[1] = HALF[1];
                s.n = 2;
            }
            _ => {}
        }
        s
    }

    /// Whether the shape is a capsule's or a disc's: symmetric about its body z axis, so its
    /// attitude is that axis.
    pub fn axial(&self) -> bool {
        self.n == 2
    }

    /// The turns (the identity first).
    pub fn turns(&self) -> &[[f64; 4]] {
        &self.g[..self.n]
    }

    /// Of the attitudes `q ⊗ g` (`g` a turn) the one nearest to `reference`, its sign aligned
    /// with `reference`'s; ties keep the earlier turn (the identity first). A capsule's
    /// end-for-end turn is chosen by its axis alone (the one whose body z points along
    /// `reference`'s): its spin about the axis is nobody's measurement, and a spin that has
    /// drifted apart from `reference`'s by over a quarter turn would otherwise pick the turn
    /// that reverses the axis.
    pub fn nearest(&self, q: &[f64; 4], reference: &[f64]) -> [f64; 4] {
        if self.axial() {
            let along = dot(&crate::axis::body_z(q), &crate::axis::body_z(reference)) >= 0.0;
            return signed_like(if along { *q } else { quat_mul(q, &self.g[1]) }, reference);
        }
        let mut best = (f64::NEG_INFINITY, *q);
        for g in self.turns() {
            let c = quat_mul(q, g);
            let d = dot(&c, reference);
            if d.abs() > best.0 + 1e-12 {
                best = (d.abs(), signed_like(c, reference));
            }
        }
        best.1
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// `c` or `−c` (the same attitude), whichever lies on `reference`'s side.
fn signed_like(c: [f64; 4], reference: &[f64]) -> [f64; 4] {
    if dot(&c, reference) < 0.0 {
        c.map(|v| -v)
    } else {
        c
    }
}

/// An attitude that measures only its body z axis (`Observation::axis_only`: a rod seen by a
/// camera), taken onto `reference` (the track's prediction): `reference` turned by the
/// smallest rotation that takes its body z onto the line of `q`'s, sign-aligned with it. The
/// spin about the axis and the axis's sign are `reference`'s: a report carries neither.
pub fn on_axis(q: &[f64; 4], reference: &[f64]) -> [f64; 4] {
    let (z, zr) = (crate::axis::body_z(q), crate::axis::body_z(reference));
    let z = if dot(&z, &zr) < 0.0 { z.map(|v| -v) } else { z };
    let c = crate::axis::AxisPrecession::align(reference, &z);
    let n = dot(&c, &c).sqrt();
    signed_like(c.map(|v| v / n), reference)
}

/// The angle between attitudes `q` and `truth` (w, x, y, z) modulo the symmetry of `shape`
/// (its body frame): 0 for a sphere; for a capsule or a disc the angle between the body z axes,
/// sign-free; for a centred box the least angle over its [`Symmetry`] turns; otherwise
/// (unknown, or an off-centre box) the full angle. No camera can tell these attitudes apart,
/// and they are the same shape to a planner.
pub fn symmetric_angle(q: &[f64], truth: &[f64], shape: &DebrisShape) -> f64 {
    let t = [truth[0], truth[1], truth[2], truth[3]];
    match ShapeKind::from_u32(shape.kind) {
        Some(ShapeKind::Sphere) => 0.0,
        Some(ShapeKind::Capsule | ShapeKind::Disc) => {
            crate::axis::line_angle(&crate::axis::body_z(q), &crate::axis::body_z(&t))
        }
        _ => Symmetry::of(shape)
            .turns()
            .iter()
            .map(|g| quat_angle(q, &quat_mul(&t, g)))
            .fold(f64::INFINITY, f64::min),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn boxed(d: [f64; 3]) -> DebrisShape {
        DebrisShape::cuboid(d, [0.0; 3])
    }

    fn axis_angle(axis: [f64; 3], a: f64) -> [f64; 4] {
        let (s, c) = (0.5 * a).sin_cos();
        [c, axis[0] * s, axis[1] * s, axis[2] * s]
    }

    #[test]
    fn a_box_has_its_half_turns_and_a_square_panel_its_quarter_turns() {
        assert_eq!(Symmetry::of(&boxed([0.6, 0.15, 0.05])).turns().len(), 4);
        assert_eq!(Symmetry::of(&boxed([0.5, 0.5, 0.01])).turns().len(), 8);
        assert_eq!(Symmetry::of(&DebrisShape::capsule(1.0, 0.05)).turns().len(), 2);
        assert_eq!(Symmetry::of(&DebrisShape::default()).turns().len(), 1);
        let off = DebrisShape::cuboid([0.6, 0.15, 0.05], [0.1, 0.0, 0.0]);
        assert_eq!(Symmetry::of(&off).turns().len(), 1);
    }

    #[test]
    fn nearest_undoes_a_half_turn_and_keeps_a_small_error() {
        let shape = boxed([0.6, 0.15, 0.05]);
        let truth = axis_angle([0.36, 0.48, 0.8], 1.1);
        let near = quat_mul(&truth, &axis_angle([1.0, 0.0, 0.0], 0.03));
        // The same attitude reported turned by half about body y (a principal axis's sign).
        let flipped = quat_mul(&near, &HALF[2]);
        assert!(quat_angle(&flipped, &truth) > 3.0);
        let n = Symmetry::of(&shape).nearest(&flipped, &truth);
        assert!((quat_angle(&n, &truth) - 0.03).abs() < 1e-9, "{}", quat_angle(&n, &truth));
        assert!(n.iter().zip(&truth).map(|(a, b)| a * b).sum::<f64>() > 0.0);
        assert!((symmetric_angle(&flipped, &truth, &shape) - 0.03).abs() < 1e-9);
        // Without a symmetry nothing changes.
        assert_eq!(Symmetry::NONE.nearest(&near, &truth), near);
        // A quarter turn of a long box is a real error.
        let quarter = quat_mul(&truth, &axis_angle([0.0, 0.0, 1.0], std::f64::consts::FRAC_PI_2));
        assert!((symmetric_angle(&quarter, &truth, &shape) - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
        assert!(symmetric_angle(&quarter, &truth, &boxed([0.5, 0.5, 0.01])) < 1e-7);
    }

    #[test]
    fn an_axis_only_report_keeps_the_references_spin_and_sign() {
        let reference = axis_angle([0.36, 0.48, 0.8], 1.1);
        // The truth: the reference tilted by 0.2 rad; the report spun arbitrarily about its
        // axis and turned end for end.
        let truth = quat_mul(&reference, &axis_angle([0.0, 1.0, 0.0], 0.2));
        for spin in [0.0, 1.0, 2.5, 3.05] {
            let report = quat_mul(&quat_mul(&truth, &axis_angle([0.0, 0.0, 1.0], spin)), &HALF[1]);
            let m = on_axis(&report, &reference);
            // The axis is the report's (the truth's line), the rest the reference's: the
            // measurement differs from the reference by the tilt alone.
            assert!(
                (quat_angle(&m, &reference) - 0.2).abs() < 1e-9,
                "{spin}: {}",
                quat_angle(&m, &reference)
            );
            assert!(quat_angle(&m, &truth) < 1e-9, "{spin}");
            assert!(m.iter().zip(&reference).map(|(a, b)| a * b).sum::<f64>() > 0.0);
        }
    }

    #[test]
    fn a_capsule_or_a_disc_is_measured_by_its_axis() {
        for shape in [DebrisShape::capsule(1.0, 0.05), DebrisShape::disc(0.7, 0.01)] {
            capsule_or_disc(shape);
        }
    }

    fn capsule_or_disc(shape: DebrisShape) {
        assert!(Symmetry::of(&shape).axial());
        let truth = axis_angle([0.0, 0.6, 0.8], 0.7);
        let spun = quat_mul(&truth, &axis_angle([0.0, 0.0, 1.0], 2.0));
        assert!(symmetric_angle(&spun, &truth, &shape) < 1e-7);
        let tilted = quat_mul(&truth, &axis_angle([1.0, 0.0, 0.0], 0.2));
        assert!((symmetric_angle(&tilted, &truth, &shape) - 0.2).abs() < 1e-9);
        let ends = quat_mul(&tilted, &HALF[1]);
        let n = Symmetry::of(&shape).nearest(&ends, &truth);
        assert!((quat_angle(&n, &truth) - 0.2).abs() < 1e-9);
        // A report whose spin has drifted from the reference's by more than a quarter turn
        // (a depth camera does not see it): the turn is still chosen by the axis, and the
        // report's own spin is kept.
        let tilted = quat_mul(&truth, &axis_angle([0.0, 1.0, 0.0], 0.2));
        let drifted = quat_mul(&tilted, &axis_angle([0.0, 0.0, 1.0], 3.05));
        for r in [drifted, quat_mul(&drifted, &HALF[1])] {
            let n = Symmetry::of(&shape).nearest(&r, &truth);
            assert!((symmetric_angle(&n, &truth, &shape) - 0.2).abs() < 1e-9);
            let (zn, zt) = (crate::axis::body_z(&n), crate::axis::body_z(&truth));
            assert!(zn.iter().zip(&zt).map(|(a, b)| a * b).sum::<f64>() > 0.9, "{zn:?} {zt:?}");
            assert!((quat_angle(&n, &drifted) < 1e-9) || (quat_angle(&n, &drifted.map(|v| -v)) < 1e-9));
        }
    }
}
