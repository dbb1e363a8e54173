//! lift() and 40-step roll-out times for the default model size (n = 7, hidden 32 × 2, extra 16).
//! Training time vs data size: `cargo run --release -p dkrrt-deep --example train_tumble`.

use criterion::{criterion_group, criterion_main, Criterion};
use dkrrt_deep::*;
use dkrrt_koopman::{Forecaster, KoopmanModel, Lifting, Rollout, StateConstraint};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use std::hint::black_box;

fn default_model() -> DeepKoopman {
    let c = TrainConfig::default();
    let n = 7;
    let mut r = SmallRng::seed_from_u64(1);
    let params: Vec<f64> =
        (0..param_count(n, c.hidden, c.layers, c.extra)).map(|_| r.random_range(-0.5..0.5)).collect();
    let lifting = DeepLifting::new(n, c.hidden, c.layers, c.extra, &[0.0; 7], &[0.5; 7], &params).unwrap();
    let p = n + c.extra;
    let ab = (0..p * p).map(|k| if k % (p + 1) == 0 { 0.98 } else { r.random_range(-0.02..0.02) }).collect();
    DeepKoopman { lifting, model: KoopmanModel { n, p, m: 0, dt: 0.1, ab } }
}

fn bench(c: &mut Criterion) {
    let dk = default_model();
    let x = [0.5, 0.5, 0.5, 0.5, 0.3, -0.2, 0.1];
    let mut z = vec![0.0; dk.lifting.dim()];
    c.bench_function("lift n7 h32x2 e16", |b| b.iter(|| dk.lifting.lift(black_box(&x), &mut z)));
    let mut f = Forecaster::new(dk.model.p).with_constraint(StateConstraint::UnitQuaternion { at: 0 });
    let mut out = vec![0.0; 40 * 7];
    for (name, mode) in [("linear", Rollout::Linear), ("relift", Rollout::Relift)] {
        c.bench_function(&format!("rollout 40 steps {name}"), |b| {
            b.iter(|| f.forecast(&dk.model, &dk.lifting, black_box(&x), &[], mode, &mut out))
        });
        c.bench_function(&format!("32 debris x 40 steps {name}"), |b| {
            b.iter(|| {
                for _ in 0..32 {
                    f.forecast(&dk.model, &dk.lifting, black_box(&x), &[], mode, &mut out);
                }
            })
        });
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
