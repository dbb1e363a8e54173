//! Known distances, the conservative descriptors, the lever-arm bound, and no allocation.

use dkrrt_collision::*;
use dkrrt_model::{ArmModel, NJ};
use dkrrt_msg::DebrisShape;
use dkrrt_rt::alloc_count::{count, CountingAlloc};
use parry3d_f64::math::Vector as PVec;
use parry3d_f64::shape::SharedShape;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc;

const ID: [f64; 4] = [1.0, 0.0, 0.0, 0.0];

fn link() -> PosedCapsule {
    // Along x from 0 to 1 m, radius 0.1.
    PosedCapsule::new([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], 0.1)
}

#[test]
fn known_distances_for_every_kind() {
    let c = link();
    // Sphere r 0.2 centred 1 m above the segment's middle: 1 - 0.1 - 0.2.
    let s = Obstacle::from_desc(1, &DebrisShape::sphere(0.2), 0.0, &[0.5, 0.0, 1.0], &ID, 0.0);
    assert!((s.distance(&c) - 0.7).abs() < 1e-12);
    // Beyond the segment's end: from the end point.
    let s = Obstacle::from_desc(1, &DebrisShape::sphere(0.2), 0.0, &[2.0, 0.0, 0.0], &ID, 0.0);
    assert!((s.distance(&c) - 0.7).abs() < 1e-12);
    // Inflation shrinks the distance one for one.
    let s = Obstacle::from_desc(1, &DebrisShape::sphere(0.2), 0.0, &[2.0, 0.0, 0.0], &ID, 0.25);
    assert!((s.distance(&c) - 0.45).abs() < 1e-12);
    // Rod (capsule along z) crossing above: axis from z = 0.5 to 1.5 at x = 0.5, y = 0.3.
    let r = Obstacle::from_desc(2, &DebrisShape::capsule(0.5, 0.05), 0.0, &[0.5, 0.3, 1.0], &ID, 0.0);
    assert!((r.distance(&c) - (0.5f64.hypot(0.3) - 0.15)).abs() < 1e-12, "{}", r.distance(&c));
    // The same rod turned 90° about x (axis along y), centred above the link: vertical gap 1.0.
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let r = Obstacle::from_desc(
        2,
        &DebrisShape::capsule(0.5, 0.05),
        0.0,
        &[0.5, 0.0, 1.0],
        &[h, h, 0.0, 0.0],
        0.0,
    );
    assert!((r.distance(&c) - 0.85).abs() < 1e-12, "{}", r.distance(&c));
    // Box half extents 0.2 at z = 1: face at z = 0.8, gap 0.8 - 0.1.
    let b = Obstacle::from_desc(3, &DebrisShape::cuboid([0.2; 3], [0.0; 3]), 0.0, &[0.5, 0.0, 1.0], &ID, 0.0);
    assert!((b.distance(&c) - 0.7).abs() < 1e-12, "{}", b.distance(&c));
    // Box with a body offset of -0.3 m in z: the face comes 0.3 m closer.
    let b = Obstacle::from_desc(
        3,
        &DebrisShape::cuboid([0.2; 3], [0.0, 0.0, -0.3]),
        0.0,
        &[0.5, 0.0, 1.0],
        &ID,
        0.0,
    );
    assert!((b.distance(&c) - 0.4).abs() < 1e-12, "{}", b.distance(&c));
    // Unknown shape: the bounding sphere.
    let u = Obstacle::from_desc(4, &DebrisShape::default(), 0.3, &[0.5, 0.0, 1.0], &ID, 0.0);
    assert!((u.distance(&c) - 0.6).abs() < 1e-12);
    // Disc of radius 0.4, half thickness 0.01, flat at z = 1: gap 1 - 0.01 - 0.1.
    let d = Obstacle::from_desc(5, &DebrisShape::disc(0.4, 0.01), 0.0, &[0.5, 0.0, 1.0], &ID, 0.0);
    assert!((d.distance(&c) - 0.89).abs() < 1e-6, "{}", d.distance(&c));
    // Turned on edge (normal along y): its rim comes down to z = 0.6.
    let d =
        Obstacle::from_desc(5, &DebrisShape::disc(0.4, 0.01), 0.0, &[0.5, 0.0, 1.0], &[h, h, 0.0, 0.0], 0.0);
    assert!((d.distance(&c) - 0.5).abs() < 1e-6, "{}", d.distance(&c));
    // Beside the link's end, flat: from the end point (1, 0, 0) to the rim at x = 1.5.
    let d = Obstacle::from_desc(5, &DebrisShape::disc(0.4, 0.01), 0.0, &[1.9, 0.0, 0.0], &ID, 0.05);
    assert!((d.distance(&c) - (0.5 - 0.1 - 0.05)).abs() < 1e-6, "{}", d.distance(&c));
}

#[test]
fn disc_distances_match_brute_force() {
    // Oriented discs against capsules: the distance equals the least over the segment's
    // points of the closed-form point–solid-cylinder distance (to the sampling's step), and
    // is at most 0 where the segment meets the disc.
    let mut rng = SmallRng::seed_from_u64(6);
    let mut u = |lo: f64, hi: f64| rng.random_range(lo..hi);
    let mut touching = 0;
    for i in 0..1000 {
        let (rd, hd) = (u(0.05, 1.0), u(0.002, 0.2));
        let qv = [u(-1.0, 1.0), u(-1.0, 1.0), u(-1.0, 1.0), u(-1.0, 1.0)];
        let n = qv.iter().map(|v| v * v).sum::<f64>().sqrt();
        let q = qv.map(|v| v / n);
        let p = [u(-1.0, 1.0), u(-1.0, 1.0), u(-1.0, 1.0)];
        let spread = if i % 3 == 0 { 0.5 } else { 2.0 };
        let a = [u(-spread, spread), u(-spread, spread), u(-spread, spread)];
        let b = if i % 7 == 0 { a } else { [u(-spread, spread), u(-spread, spread), u(-spread, spread)] };
        let r = u(0.0, 0.1);
        let ob = Obstacle::from_desc(1, &DebrisShape::disc(rd, hd), 0.0, &p, &q, 0.0);
        let ours = ob.distance(&PosedCapsule::new(a, b, r));
        let qc = [q[0], -q[1], -q[2], -q[3]];
        let steps = 4000;
        let brute = (0..=steps)
            .map(|k| {
                let t = k as f64 / steps as f64;
                let x: [f64; 3] = std::array::from_fn(|j| a[j] + t * (b[j] - a[j]) - p[j]);
                let l = quat_rotate(&qc, &x);
                let (rho, z) = (l[0].hypot(l[1]), l[2].abs());
                (rho - rd).max(0.0).hypot((z - hd).max(0.0))
            })
            .fold(f64::INFINITY, f64::min)
            - r;
        let step =
            ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2) + (b[2] - a[2]).powi(2)).sqrt() / steps as f64;
        if brute <= -r + 1e-12 {
            touching += 1;
            assert!(ours <= 1e-7, "{i}: the axis meets the disc but {ours}");
        } else {
            assert!(ours <= brute + 1e-9 && ours >= brute - step - 1e-9, "{i}: {ours} vs brute {brute}");
        }
    }
    assert!(touching > 50, "crossings exercised: {touching}");
}

#[test]
fn segment_distances_match_brute_force() {
    let mut rng = SmallRng::seed_from_u64(3);
    let mut p = || [rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)];
    for _ in 0..500 {
        let (a, b, c, d) = (p(), p(), p(), p());
        let mut best = f64::INFINITY;
        for i in 0..=200 {
            let s = i as f64 / 200.0;
            let x = [a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1]), a[2] + s * (b[2] - a[2])];
            best = best.min(seg_point(&c, &d, &x));
        }
        let exact = seg_seg(&a, &b, &c, &d);
        assert!(exact <= best + 1e-12 && best - exact < 2e-2, "{exact} vs {best}");
    }
}

#[test]
fn box_distances_match_parry() {
    // Oriented boxes against capsules: the closed-form piecewise-quadratic distance equals
    // parry's GJK (to its tolerance) far, near, touching, crossing and inside.
    use parry3d_f64::math::Pose;
    use parry3d_f64::shape::{Capsule, Cuboid};
    let mut rng = SmallRng::seed_from_u64(5);
    let mut u = |lo: f64, hi: f64| rng.random_range(lo..hi);
    let mut zero = 0;
    for i in 0..3000 {
        let half = [u(0.01, 0.8), u(0.01, 0.8), u(0.005, 0.5)];
        let qv = [u(-1.0, 1.0), u(-1.0, 1.0), u(-1.0, 1.0), u(-1.0, 1.0)];
        let n = qv.iter().map(|v| v * v).sum::<f64>().sqrt();
        let q = qv.map(|v| v / n);
        let p = [u(-1.0, 1.0), u(-1.0, 1.0), u(-1.0, 1.0)];
        let spread = if i % 3 == 0 { 0.3 } else { 2.0 };
        let a = [u(-spread, spread), u(-spread, spread), u(-spread, spread)];
        // Some degenerate (point) and axis-parallel segments too.
        let b = match i % 7 {
            0 => a,
            1 => [a[0] + u(-1.0, 1.0), a[1], a[2]],
            _ => [u(-spread, spread), u(-spread, spread), u(-spread, spread)],
        };
        let r = u(0.0, 0.1);
        let ob = Obstacle::from_desc(1, &DebrisShape::cuboid(half, [0.0; 3]), 0.0, &p, &q, 0.0);
        let ours = ob.distance(&PosedCapsule::new(a, b, r));
        let pose = Pose::from_parts(
            PVec::new(p[0], p[1], p[2]),
            parry3d_f64::glamx::DQuat::from_xyzw(q[1], q[2], q[3], q[0]),
        );
        let cap = Capsule::new(PVec::new(a[0], a[1], a[2]), PVec::new(b[0], b[1], b[2]), r);
        let cub = Cuboid::new(PVec::new(half[0], half[1], half[2]));
        let theirs = parry3d_f64::query::distance(&pose, &cub, &Pose::IDENTITY, &cap).unwrap().distance;
        // parry reports 0 for any overlap; ours −r at most (the axis inside the box).
        if theirs == 0.0 {
            zero += 1;
            assert!(ours <= 1e-7, "{i}: overlap but {ours}");
        } else {
            assert!((ours - theirs).abs() < 1e-6, "{i}: {ours} vs parry {theirs}");
        }
    }
    assert!(zero > 100, "overlaps exercised: {zero}");
}

#[test]
fn descriptors_enclose_the_exact_shapes() {
    // A convex hull off-centre: its box descriptor is never farther than the hull itself.
    let pts: Vec<PVec> =
        [[0.3, 0.1, 0.0], [-0.1, 0.2, 0.1], [0.0, -0.2, 0.3], [0.1, 0.0, -0.2], [0.4, 0.3, 0.2]]
            .iter()
            .map(|p| PVec::new(p[0], p[1], p[2]))
            .collect();
    let hull = SharedShape::convex_hull(&pts).unwrap();
    let desc = descriptor_of(hull.as_ref());
    assert_eq!(desc.kind, dkrrt_msg::ShapeKind::Box as u32);
    let mut rng = SmallRng::seed_from_u64(5);
    for _ in 0..300 {
        let q = {
            let v: [f64; 4] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
            let n = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            v.map(|x| x / n)
        };
        let p = [rng.random_range(-1.5..1.5), rng.random_range(-1.5..1.5), rng.random_range(-1.5..1.5)];
        let exact = Obstacle::from_shape(1, &hull, 1.0, &p, &q);
        let boxed = Obstacle::from_desc(1, &desc, 0.0, &p, &q, 0.0);
        let c = link();
        assert!(boxed.distance(&c) <= exact.distance(&c) + 1e-9);
    }
    // Spheres, z capsules and boxes are described exactly.
    assert_eq!(descriptor_of(SharedShape::ball(0.3).as_ref()), DebrisShape::sphere(0.3));
    assert_eq!(descriptor_of(SharedShape::capsule_z(0.4, 0.03).as_ref()), DebrisShape::capsule(0.4, 0.03));
    assert_eq!(
        descriptor_of(SharedShape::cuboid(0.1, 0.2, 0.3).as_ref()),
        DebrisShape::cuboid([0.1, 0.2, 0.3], [0.0; 3])
    );
}

#[test]
fn a_hull_is_judged_by_its_vertices_not_by_its_box() {
    use dkrrt_collision::bounds::{points_excess, shape_excess};
    let pts: Vec<PVec> = [
        [0.3, 0.0, 0.0],
        [-0.2, 0.15, 0.0],
        [-0.1, -0.2, 0.05],
        [0.0, 0.0, 0.25],
        [0.05, 0.05, -0.2],
        [0.2, 0.2, 0.1],
    ]
    .iter()
    .map(|p| PVec::new(p[0], p[1], p[2]))
    .collect();
    let hull = SharedShape::convex_hull(&pts).unwrap();
    let desc = descriptor_of(hull.as_ref());
    let v = hull_vertices(hull.as_ref()).expect("a hull has vertices");
    assert!(v.len() >= 4 && v.len() <= pts.len(), "{}", v.len());
    // Spheres, capsules and boxes are their descriptors.
    assert!(hull_vertices(SharedShape::ball(0.3).as_ref()).is_none());
    assert!(hull_vertices(SharedShape::capsule_z(0.4, 0.03).as_ref()).is_none());
    assert!(hull_vertices(SharedShape::cuboid(0.1, 0.2, 0.3).as_ref()).is_none());
    let mut rng = SmallRng::seed_from_u64(17);
    let unit_q = |rng: &mut SmallRng| {
        let v: [f64; 4] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        let n = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        v.map(|x| x / n)
    };
    let preds = [
        DebrisShape::sphere(0.3),
        DebrisShape::capsule(0.3, 0.1),
        DebrisShape::cuboid([0.3, 0.2, 0.1], [0.05, 0.0, 0.0]),
        DebrisShape::disc(0.35, 0.02),
    ];
    let mut below = 0;
    for i in 0..400 {
        let pred = &preds[i % preds.len()];
        let (qp, qt) = (unit_q(&mut rng), unit_q(&mut rng));
        let pp = [rng.random_range(-0.2..0.2), rng.random_range(-0.2..0.2), rng.random_range(-0.2..0.2)];
        let pt = [0.0; 3];
        let got = points_excess(pred, 0.4, &pp, &qp, &v, &pt, &qt);
        // Oracle: each vertex as a true ball of radius 0 at its posed place.
        let brute = v
            .iter()
            .map(|x| {
                let w = quat_rotate(&qt, x);
                shape_excess(pred, 0.4, &pp, &qp, &DebrisShape::sphere(0.0), 0.0, &w, &[1.0, 0.0, 0.0, 0.0])
            })
            .fold(0.0f64, f64::max);
        assert!((got - brute).abs() < 1e-12, "{got} vs {brute}");
        // The hull lies in its box: never more than the box's corners reach.
        let boxed = shape_excess(pred, 0.4, &pp, &qp, &desc, desc.bounding_radius(), &pt, &qt);
        assert!(got <= boxed + 1e-12, "{got} vs box {boxed}");
        below += (got < boxed - 0.01) as usize;
    }
    // The box's empty corners are what the hull does not reach.
    assert!(below > 100, "{below}");
    // At its own pose, inside its own box.
    assert_eq!(
        points_excess(&desc, 0.0, &[0.0; 3], &[1.0, 0.0, 0.0, 0.0], &v, &[0.0; 3], &[1.0, 0.0, 0.0, 0.0]),
        0.0
    );
}

#[test]
fn no_arm_point_moves_faster_than_the_lever_bounds() {
    let poser = ArmPoser::new(ArmModel::default_arm());
    let lever = *poser.lever_arms();
    assert!(lever.iter().all(|l| *l > 0.0 && *l < 5.0), "{lever:?}");
    assert!(lever.windows(2).all(|w| w[0] >= w[1] - 1e-12), "outer joints move less: {lever:?}");
    let mut rng = SmallRng::seed_from_u64(9);
    let (mut a, mut b) = ([PosedCapsule::default(); NJ], [PosedCapsule::default(); NJ]);
    let mut worst: f64 = 0.0;
    let mut worst_own = [0.0f64; NJ];
    for _ in 0..2000 {
        let q: [f64; NJ] = std::array::from_fn(|_| rng.random_range(-2.5..2.5));
        let dq: [f64; NJ] = std::array::from_fn(|_| rng.random_range(-0.01..0.01));
        let q2: [f64; NJ] = std::array::from_fn(|i| q[i] + dq[i]);
        poser.pose(&q, &mut a);
        poser.pose(&q2, &mut b);
        let bound: f64 = (0..NJ).map(|i| dq[i].abs() * lever[i]).sum();
        // Per capsule: only the joints before it, with their lever arms to it alone.
        let own = poser.capsule_speeds(&dq);
        for k in 0..NJ {
            assert!(own[k] <= bound * (1.0 + 1e-12), "capsule {k}: {} > {bound}", own[k]);
            for (x, y) in [(a[k].a, b[k].a), (a[k].b, b[k].b)] {
                let m = ((x[0] - y[0]).powi(2) + (x[1] - y[1]).powi(2) + (x[2] - y[2]).powi(2)).sqrt();
                // Chords are shorter than arcs: the bound holds with room to spare.
                assert!(m <= bound * (1.0 + 1e-9), "{m} > {bound}");
                assert!(m <= own[k] * (1.0 + 1e-9), "capsule {k}: {m} > {}", own[k]);
                worst = worst.max(m / bound);
                worst_own[k] = worst_own[k].max(m / own[k]);
            }
        }
    }
    assert!(worst > 0.3, "the bound is not loose beyond use: worst ratio {worst}");
    // (The base capsule's segment lies on the first joint's axis: its ends never move.)
    assert!(worst_own[1..].iter().all(|w| *w > 0.3), "a capsule's bound is loose beyond use: {worst_own:?}");
    // The base's capsule moves only with the first joint: far slower than the hand.
    let all = poser.capsule_speeds(&[1.0; NJ]);
    assert!(all[0] < 0.2 * all[NJ - 1], "{all:?}");
}

fn scene(rng: &mut SmallRng, n: usize) -> Vec<Obstacle> {
    (0..n)
        .map(|i| {
            let p = [rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0)];
            let q = {
                let v: [f64; 4] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
                let n = v.iter().map(|x| x * x).sum::<f64>().sqrt();
                v.map(|x| x / n)
            };
            let d = match i % 4 {
                0 => DebrisShape::sphere(0.2),
                1 => DebrisShape::capsule(0.6, 0.03),
                2 => DebrisShape::disc(0.4, 0.01),
                _ => DebrisShape::cuboid([0.3, 0.2, 0.01], [0.0; 3]),
            };
            Obstacle::from_desc(i as u32, &d, 0.0, &p, &q, 0.05)
        })
        .collect()
}

#[test]
fn proximity_and_clearance_agree_with_all_pairs() {
    let poser = ArmPoser::new(ArmModel::default_arm());
    let mut rng = SmallRng::seed_from_u64(11);
    let mut caps = [PosedCapsule::default(); NJ];
    let mut contacts = [ContactPair::default(); 4];
    for _ in 0..200 {
        let obs = scene(&mut rng, 32);
        let q: [f64; NJ] = std::array::from_fn(|_| rng.random_range(-2.0..2.0));
        poser.pose(&q, &mut caps);
        let brute =
            caps.iter().flat_map(|c| obs.iter().map(move |o| o.distance(c))).fold(f64::INFINITY, f64::min);
        let pr = proximity(&caps, &obs, 0.0, &mut contacts);
        assert!((pr.min_distance - brute).abs() < 1e-12);
        assert_eq!(pr.any_contact(), brute <= 0.0);
        // With a margin: every pair within it is a contact, each counted once (the best-first
        // order measures the nearest pair before the others).
        let margin = 0.3;
        let within =
            caps.iter().flat_map(|c| obs.iter().map(move |o| o.distance(c))).filter(|d| *d <= margin).count();
        let pm = proximity(&caps, &obs, margin, &mut contacts);
        assert_eq!(pm.n_contacts, within);
        assert!((pm.min_distance - brute).abs() < 1e-12);
        let cl = clearance(&caps, &obs, 0.0, f64::INFINITY);
        if brute >= 0.0 {
            assert!((cl - brute).abs() < 1e-12);
        } else {
            assert!(cl < 0.0);
        }
        let capped = clearance(&caps, &obs, -1.0, 0.25);
        if brute >= -1.0 {
            assert!((capped - brute.min(0.25)).abs() < 1e-12, "{capped} vs {brute}");
        } else {
            assert!(capped < -1.0);
        }
    }
}

#[test]
fn clearance_pairs_is_clearance_per_obstacle_with_a_lower_bound_per_capsule() {
    let poser = ArmPoser::new(ArmModel::default_arm());
    let mut rng = SmallRng::seed_from_u64(13);
    let mut caps = [PosedCapsule::default(); NJ];
    let mut pairs = [0.0; NJ];
    let (mut measured, mut early) = (0, 0);
    for _ in 0..200 {
        let obs = scene(&mut rng, 8);
        let q: [f64; NJ] = std::array::from_fn(|_| rng.random_range(-2.0..2.0));
        poser.pose(&q, &mut caps);
        for o in &obs {
            for (stop, cap) in [(0.0, 0.5), (0.1, f64::INFINITY)] {
                let c = clearance_pairs(&caps, o, stop, cap, &mut pairs);
                assert_eq!(c.to_bits(), clearance(&caps, std::slice::from_ref(o), stop, cap).to_bits());
                for (k, p) in pairs.iter().enumerate() {
                    let d = o.distance(&caps[k]);
                    assert!(*p <= d + 1e-12, "capsule {k}: {p} above its distance {d}");
                    measured += (*p == d) as usize;
                }
                if c < stop {
                    early += 1;
                } else {
                    // Every pair reached: the result is the least of them (capped).
                    let least = pairs.iter().fold(f64::INFINITY, |a, &b| a.min(b));
                    assert_eq!(c, least.min(cap));
                }
            }
        }
    }
    assert!(measured > 1000 && early > 10, "{measured} pairs measured, {early} early returns");
}

#[test]
fn posing_and_checking_allocate_nothing() {
    let poser = ArmPoser::new(ArmModel::default_arm());
    let mut rng = SmallRng::seed_from_u64(12);
    let mut obs = Vec::with_capacity(32);
    obs.extend(scene(&mut rng, 31));
    let hull = SharedShape::convex_hull(&[
        PVec::new(0.0, 0.0, 0.0),
        PVec::new(0.3, 0.0, 0.0),
        PVec::new(0.0, 0.3, 0.0),
        PVec::new(0.0, 0.0, 0.3),
    ])
    .unwrap();
    let mut caps = [PosedCapsule::default(); NJ];
    let mut contacts = [ContactPair::default(); 8];
    let (_, st) = count(|| {
        for k in 0..500 {
            // The simulator re-poses exact shapes every tick (an Arc clone, no allocation).
            if obs.len() == 32 {
                obs.pop();
            }
            obs.push(Obstacle::from_shape(99, &hull, 0.3, &[1.0, 0.5, 0.2], &ID));
            let q = [0.001 * k as f64; NJ];
            poser.pose(&q, &mut caps);
            std::hint::black_box(proximity(&caps, &obs, 0.0, &mut contacts));
            std::hint::black_box(clearance(&caps, &obs, 0.0, 1.0));
        }
    });
    assert_eq!((st.allocs, st.reallocs, st.deallocs), (0, 0, 0), "{st:?}");
}

#[test]
fn the_reach_sphere_holds_the_arm_at_any_configuration() {
    let poser = ArmPoser::new(ArmModel::default_arm());
    let (c, r) = poser.reach_sphere();
    let l = poser.model().limits();
    let mut rng = SmallRng::seed_from_u64(4);
    let mut caps = [PosedCapsule::default(); NJ];
    let mut farthest: f64 = 0.0;
    for _ in 0..5000 {
        let q: [f64; NJ] = std::array::from_fn(|i| rng.random_range(l.q_min[i]..=l.q_max[i]));
        poser.pose(&q, &mut caps);
        for k in &caps {
            for e in [k.a, k.b] {
                let d = ((e[0] - c[0]).powi(2) + (e[1] - c[1]).powi(2) + (e[2] - c[2]).powi(2)).sqrt() + k.r;
                assert!(d <= r + 1e-9, "{d} > {r}");
                farthest = farthest.max(d);
            }
        }
    }
    // Not uselessly loose either.
    assert!(farthest > 0.6 * r, "farthest {farthest} of {r}");
}

/// An obstacle also known to lie in a ball ([`Obstacle::with_ball`]): a capsule's distance is
/// the larger of its distances to the inflated shape and to the ball, the lower bound stays
/// below it, [`clearance`] and [`proximity`] agree with all pairs, and no point lying in both
/// containers is nearer the capsule than that distance (so the distance to the object is never
/// overstated).
#[test]
fn an_obstacle_in_two_containers_is_as_far_as_the_farther() {
    let mut rng = SmallRng::seed_from_u64(5);
    let poser = ArmPoser::new(ArmModel::default_arm());
    let mut caps = [PosedCapsule::default(); NJ];
    let mut contacts = [ContactPair::default(); 4];
    for _ in 0..100 {
        let plain = scene(&mut rng, 8);
        let balls: Vec<([f64; 3], f64)> = plain
            .iter()
            .map(|o| {
                let c: [f64; 3] = std::array::from_fn(|i| o.p[i] + rng.random_range(-0.2..0.2));
                (c, rng.random_range(0.1..0.8))
            })
            .collect();
        let both: Vec<Obstacle> =
            plain.iter().zip(&balls).map(|(o, (c, r))| o.clone().with_ball(c, *r)).collect();
        let q: [f64; NJ] = std::array::from_fn(|_| rng.random_range(-2.0..2.0));
        poser.pose(&q, &mut caps);
        for (o, (b, (c_ball, r_ball))) in plain.iter().zip(both.iter().zip(&balls)) {
            for c in &caps {
                let to_ball = seg_point(&c.a, &c.b, c_ball) - c.r - r_ball;
                let d = b.distance(c);
                assert!((d - o.distance(c).max(to_ball)).abs() < 1e-12);
                assert!(b.lower_bound(c) <= d + 1e-12);
                // Points in the ball that also lie in the inflated shape: none nearer than d.
                for _ in 0..20 {
                    let u: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
                    let x: [f64; 3] = std::array::from_fn(|i| c_ball[i] + r_ball * u[i] / 3f64.sqrt());
                    if o.distance(&PosedCapsule::new(x, x, 0.0)) <= 0.0 {
                        assert!(seg_point(&c.a, &c.b, &x) - c.r >= d - 1e-9, "a point of both is nearer");
                    }
                }
            }
        }
        let brute =
            caps.iter().flat_map(|c| both.iter().map(move |o| o.distance(c))).fold(f64::INFINITY, f64::min);
        let pr = proximity(&caps, &both, 0.0, &mut contacts);
        assert!((pr.min_distance - brute).abs() < 1e-12);
        if brute >= 0.0 {
            assert!((clearance(&caps, &both, 0.0, f64::INFINITY) - brute).abs() < 1e-12);
        }
    }
}
