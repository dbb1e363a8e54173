//! A test and benchmark scene: `n` objects of every kind in front of the default camera, and
//! the arm's capsules below them.

use dkrrt_collision::{ArmPoser, PosedCapsule};
use dkrrt_model::{ArmModel, NJ};
use parry3d_f64::math::Vector as PVec;
use parry3d_f64::shape::SharedShape;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

use crate::Target;

/// One object: id, exact shape, position, attitude (w, x, y, z), bounding radius.
pub type Object = (u32, SharedShape, [f64; 3], [f64; 4], f64);

/// `n` objects 2–8 m ahead of a camera at the origin looking along +x (the default), inside
/// its field of view: balls, z capsules (rods), thin boxes (panels) and convex hulls of 12
/// random points (fragments), at random attitudes. Seeded.
pub fn objects_ahead(n: usize, seed: u64) -> Vec<Object> {
    let mut rng = SmallRng::seed_from_u64(seed);
    (0..n)
        .map(|i| {
            let x = rng.random_range(2.0..8.0);
            let p = [x, rng.random_range(-0.45..0.45) * x, rng.random_range(-0.35..0.35) * x];
            let v: [f64; 4] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
            let m = v.iter().map(|a| a * a).sum::<f64>().sqrt();
            let q = v.map(|a| a / m);
            let s = rng.random_range(0.1..0.4);
            let (shape, bound) = match i % 4 {
                0 => (SharedShape::ball(s), s),
                1 => (SharedShape::capsule_z(3.0 * s, 0.03), 3.0 * s + 0.03),
                2 => (SharedShape::cuboid(s, 0.7 * s, 0.01), (s * s + 0.49 * s * s + 1e-4).sqrt()),
                _ => {
                    let pts: Vec<PVec> = (0..12)
                        .map(|_| {
                            PVec::new(
                                rng.random_range(-s..s),
                                rng.random_range(-s..s),
                                rng.random_range(-s..s),
                            )
                        })
                        .collect();
                    (SharedShape::convex_hull(&pts).expect("12 random points span a hull"), 3f64.sqrt() * s)
                }
            };
            (i as u32 + 1, shape, p, q, bound)
        })
        .collect()
}

/// The objects as render targets.
pub fn targets(objects: &[Object]) -> Vec<Target<'_>> {
    objects
        .iter()
        .map(|(id, s, p, q, b)| Target { id: *id, shape: s.as_ref(), p: *p, q: *q, bound: *b })
        .collect()
}

/// The default arm reaching up and forward, its base 2 m ahead of the default camera and
/// 0.8 m below its axis: in front of most objects of [`objects_ahead`].
pub fn arm_ahead() -> [PosedCapsule; NJ] {
    let poser = ArmPoser::with_offset(ArmModel::default_arm(), [2.0, 0.0, -0.8]);
    let mut arm = [PosedCapsule::default(); NJ];
    poser.pose(&[0.3, -0.5, 1.0, 0.0, 0.5, 0.0], &mut arm);
    arm
}
