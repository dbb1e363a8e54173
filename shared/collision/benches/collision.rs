//! One configuration against 32 obstacles (target ≤ 3 µs mean): pose + proximity, and the
//! planner's early-exit clearance, on random scenes around the arm; and one link against one
//! near obstacle per kind (the narrow phases).

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use dkrrt_collision::{clearance, proximity, ArmPoser, ContactPair, Obstacle, PosedCapsule};
use dkrrt_model::{ArmModel, NJ};
use dkrrt_msg::DebrisShape;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

fn scenes(n_obs: usize, range: f64) -> (Vec<Vec<Obstacle>>, Vec<[f64; NJ]>) {
    let mut rng = SmallRng::seed_from_u64(1);
    let mut out = Vec::new();
    let mut qs = Vec::new();
    for _ in 0..64 {
        let obs = (0..n_obs)
            .map(|i| {
                let p = [
                    rng.random_range(-range..range),
                    rng.random_range(-range..range),
                    rng.random_range(-range..range),
                ];
                let v: [f64; 4] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
                let n = v.iter().map(|x| x * x).sum::<f64>().sqrt();
                let d = match i % 4 {
                    0 => DebrisShape::sphere(0.2),
                    1 => DebrisShape::capsule(0.6, 0.03),
                    2 => DebrisShape::cuboid([0.35, 0.25, 0.008], [0.0; 3]),
                    _ => DebrisShape::cuboid([0.2, 0.15, 0.1], [0.02, 0.0, 0.01]),
                };
                Obstacle::from_desc(i as u32, &d, 0.0, &p, &v.map(|x| x / n), 0.05)
            })
            .collect();
        out.push(obs);
        qs.push(std::array::from_fn(|_| rng.random_range(-2.0..2.0)));
    }
    (out, qs)
}

fn bench(c: &mut Criterion) {
    let poser = ArmPoser::new(ArmModel::default_arm());
    let mut caps = [PosedCapsule::default(); NJ];
    let mut contacts = [ContactPair::default(); 8];
    for (name, range) in [("near_6m", 3.0), ("field_20m", 10.0)] {
        let (sc, qs) = scenes(32, range);
        let mut k = 0;
        c.bench_function(&format!("pose_proximity_32obj_{name}"), |b| {
            b.iter(|| {
                k = (k + 1) % sc.len();
                poser.pose(&qs[k], &mut caps);
                black_box(proximity(&caps, &sc[k], 0.0, &mut contacts))
            })
        });
        c.bench_function(&format!("pose_clearance_32obj_{name}"), |b| {
            b.iter(|| {
                k = (k + 1) % sc.len();
                poser.pose(&qs[k], &mut caps);
                black_box(clearance(&caps, &sc[k], 0.0, 0.5))
            })
        });
    }
}

fn narrow(c: &mut Criterion) {
    let mut rng = SmallRng::seed_from_u64(2);
    let links: Vec<PosedCapsule> = (0..256)
        .map(|_| {
            let a: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
            let b: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
            PosedCapsule::new(a, b, 0.05)
        })
        .collect();
    let q = [0.9, 0.3, -0.2, 0.24];
    let n = q.iter().map(|x: &f64| x * x).sum::<f64>().sqrt();
    let q = q.map(|x| x / n);
    for (name, d) in [
        ("capsule", DebrisShape::capsule(0.6, 0.03)),
        ("box", DebrisShape::cuboid([0.5, 0.5, 0.01], [0.0; 3])),
        ("disc", DebrisShape::disc(0.7, 0.01)),
    ] {
        let ob = Obstacle::from_desc(1, &d, 0.0, &[0.2, 0.1, 0.0], &q, 0.05);
        let mut k = 0;
        c.bench_function(&format!("narrow_{name}"), |b| {
            b.iter(|| {
                k = (k + 1) % links.len();
                black_box(ob.distance(&links[k]))
            })
        });
    }
}

criterion_group!(benches, bench, narrow);
criterion_main!(benches);
