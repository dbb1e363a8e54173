//! Criterion benchmarks of the model's hot paths on the shipped arm.
//!
//! Run: `CARGO_TARGET_DIR=/work/target-model cargo bench -p dkrrt-model`

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use dkrrt_model::{ArmModel, IkOptions, JVec};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

/// A fixed pool of random in-limit states, cycled through so the branch
/// predictor and caches do not see one constant input.
struct States {
    q: Vec<JVec>,
    qd: Vec<JVec>,
    qdd: Vec<JVec>,
}

fn states(m: &ArmModel, n: usize) -> States {
    let mut r = SmallRng::seed_from_u64(7);
    let l = *m.limits();
    let mut q = Vec::new();
    let mut qd = Vec::new();
    let mut qdd = Vec::new();
    for _ in 0..n {
        q.push(JVec::from_fn(|i, _| r.random_range(l.q_min[i]..l.q_max[i])));
        qd.push(JVec::from_fn(|i, _| r.random_range(-l.v_max[i]..l.v_max[i])));
        qdd.push(JVec::from_fn(|_, _| r.random_range(-0.5..0.5)));
    }
    States { q, qd, qdd }
}

fn bench(c: &mut Criterion) {
    let mut m = ArmModel::default_arm();
    // Non-zero gravity so that the gravity path is not skipped (worst case).
    m.set_gravity(nalgebra::Vector3::new(0.0, 0.0, -9.81));
    let s = states(&m, 64);
    let n = s.q.len();
    let mut g = c.benchmark_group("dkrrt_arm");

    let mut i = 0;
    g.bench_function("rnea", |b| {
        b.iter(|| {
            i = (i + 1) % n;
            black_box(m.rnea(black_box(&s.q[i]), black_box(&s.qd[i]), black_box(&s.qdd[i])))
        })
    });
    g.bench_function("crba_mass_matrix", |b| {
        b.iter(|| {
            i = (i + 1) % n;
            black_box(m.mass_matrix(black_box(&s.q[i])))
        })
    });
    g.bench_function("forward_dynamics", |b| {
        b.iter(|| {
            i = (i + 1) % n;
            black_box(m.forward_dynamics(black_box(&s.q[i]), black_box(&s.qd[i]), black_box(&s.qdd[i])))
        })
    });
    g.bench_function("coriolis_matrix", |b| {
        b.iter(|| {
            i = (i + 1) % n;
            black_box(m.coriolis_matrix(black_box(&s.q[i]), black_box(&s.qd[i])))
        })
    });
    g.bench_function("fk", |b| {
        b.iter(|| {
            i = (i + 1) % n;
            black_box(m.fk(black_box(&s.q[i])))
        })
    });
    g.bench_function("fk_plus_jacobian", |b| {
        b.iter(|| {
            i = (i + 1) % n;
            black_box(m.fk_jacobian(black_box(&s.q[i])))
        })
    });
    g.bench_function("link_poses", |b| {
        b.iter(|| {
            i = (i + 1) % n;
            black_box(m.link_poses(black_box(&s.q[i])))
        })
    });
    // IK from a nearby start (the tracking use case), no restarts needed.
    let targets: Vec<_> = s.q.iter().map(|q| m.fk(q)).collect();
    let starts: Vec<JVec> = s.q.iter().zip(&s.qd).map(|(q, d)| m.limits().clamp(&(q + d))).collect();
    let opts = IkOptions { restarts: 0, ..IkOptions::default() };
    g.bench_function("ik_nearby_start", |b| {
        b.iter(|| {
            i = (i + 1) % n;
            black_box(m.ik(black_box(&targets[i]), black_box(&starts[i]), &opts).ok())
        })
    });
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(2))
        .sample_size(50);
    targets = bench
}
criterion_main!(benches);
