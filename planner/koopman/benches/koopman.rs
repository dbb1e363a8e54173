//! Benchmarks: forecast of 32 debris × 40 steps, online update per observation, EDMD fit time.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use dkrrt_koopman::debris_state::pack;
use dkrrt_koopman::*;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use std::hint::black_box;
use std::time::Duration;

const N_DEBRIS: usize = 32;
const H: usize = 40;

fn random_model(n: usize, p: usize, seed: u64) -> KoopmanModel {
    let mut r = SmallRng::seed_from_u64(seed);
    let mut m = KoopmanModel::zeros(n, p, 0, 0.05);
    m.ab.iter_mut().for_each(|v| *v = r.random_range(-0.02..0.02));
    for i in 0..p {
        m.ab[i * p + i] += 0.95;
    }
    m
}

fn states(seed: u64) -> Vec<[f64; 13]> {
    let mut r = SmallRng::seed_from_u64(seed);
    (0..N_DEBRIS)
        .map(|_| {
            let q = debris_state::quat_exp([r.random_range(-2.0..2.0), r.random_range(-2.0..2.0), 0.3]);
            pack([r.random_range(-9.0..9.0); 3], [0.05, -0.02, 0.01], q, [0.3, -0.5, 0.2])
        })
        .collect()
}

fn forecast(c: &mut Criterion) {
    let xs = states(1);
    let mut g = c.benchmark_group("forecast_32x40");
    // Recommended: translational [x, 1] (p = 7, linear roll-out) + attitude degree-2 on (q, ω)
    // (p = 36, relift with quaternion renormalisation).
    let (lt, lr) = (Polynomial::new(6, 1), Polynomial::new(7, 2));
    let (mt, mr) = (random_model(6, lt.dim(), 2), random_model(7, lr.dim(), 3));
    let mut ft = Forecaster::new(lt.dim());
    let mut fr = Forecaster::new(lr.dim()).with_constraint(StateConstraint::UnitQuaternion { at: 0 });
    let mut out_t = vec![0.0; N_DEBRIS * H * 6];
    let mut out_r = vec![0.0; N_DEBRIS * H * 7];
    g.bench_function("split_trans_p7_linear+rot_p36_relift", |b| {
        b.iter(|| {
            for (i, x) in xs.iter().enumerate() {
                ft.forecast(&mt, &lt, &x[0..6], &[], Rollout::Linear, &mut out_t[i * H * 6..(i + 1) * H * 6]);
                fr.forecast(
                    &mr,
                    &lr,
                    &x[6..13],
                    &[],
                    Rollout::Relift,
                    &mut out_r[i * H * 7..(i + 1) * H * 7],
                );
            }
            black_box(&out_r);
        })
    });
    let la = debris_state::attitude_dictionary();
    let ma = random_model(7, la.dim(), 5);
    let mut fa = Forecaster::new(la.dim()).with_constraint(StateConstraint::UnitQuaternion { at: 0 });
    g.bench_function("split_trans_p7_linear+rot_bilinear_p26_relift", |b| {
        b.iter(|| {
            for (i, x) in xs.iter().enumerate() {
                ft.forecast(&mt, &lt, &x[0..6], &[], Rollout::Linear, &mut out_t[i * H * 6..(i + 1) * H * 6]);
                fa.forecast(
                    &ma,
                    &la,
                    &x[6..13],
                    &[],
                    Rollout::Relift,
                    &mut out_r[i * H * 7..(i + 1) * H * 7],
                );
            }
            black_box(&out_r);
        })
    });
    g.bench_function("split_trans_p7_linear+rot_p36_linear", |b| {
        b.iter(|| {
            for (i, x) in xs.iter().enumerate() {
                ft.forecast(&mt, &lt, &x[0..6], &[], Rollout::Linear, &mut out_t[i * H * 6..(i + 1) * H * 6]);
                fr.forecast(
                    &mr,
                    &lr,
                    &x[6..13],
                    &[],
                    Rollout::Linear,
                    &mut out_r[i * H * 7..(i + 1) * H * 7],
                );
            }
            black_box(&out_r);
        })
    });
    // Monolithic 13-state degree-2 model (p = 105).
    let lf = Polynomial::new(13, 2);
    let mf = random_model(13, lf.dim(), 4);
    let mut ff = Forecaster::new(lf.dim()).with_constraint(StateConstraint::UnitQuaternion { at: 6 });
    let mut out_f = vec![0.0; N_DEBRIS * H * 13];
    for (name, mode) in [("full13_p105_relift", Rollout::Relift), ("full13_p105_linear", Rollout::Linear)] {
        g.bench_function(name, |b| {
            b.iter(|| {
                for (i, x) in xs.iter().enumerate() {
                    ff.forecast(&mf, &lf, x, &[], mode, &mut out_f[i * H * 13..(i + 1) * H * 13]);
                }
                black_box(&out_f);
            })
        });
    }
    let cv = ConstantVelocity { frame_rate: 0.00113 };
    g.bench_function("constant_velocity", |b| {
        b.iter(|| {
            for (i, x) in xs.iter().enumerate() {
                cv.forecast(x, 0.05, &mut out_f[i * H * 13..(i + 1) * H * 13]);
            }
            black_box(&out_f);
        })
    });
    g.finish();
}

fn online_update(c: &mut Criterion) {
    let mut g = c.benchmark_group("rls_update_per_observation");
    let mut r = SmallRng::seed_from_u64(5);
    for (name, n, lift, state_rows) in [
        ("trans_p7_all_rows", 6, Polynomial::new(6, 1), false),
        ("rot_bilinear_p26_state_rows", 7, debris_state::attitude_dictionary(), true),
        ("rot_p36_state_rows", 7, Polynomial::new(7, 2), true),
        ("rot_p36_all_rows", 7, Polynomial::new(7, 2), false),
    ] {
        let p = lift.dim();
        let mut model = random_model(n, p, 6);
        let cfg = RlsConfig { lambda: 0.995, p0: 10.0, max_trace: 1e12 };
        let mut rls =
            if state_rows { Rls::for_model_state_rows(&model, cfg) } else { Rls::for_model(&model, cfg) };
        let samples: Vec<(Vec<f64>, Vec<f64>)> = (0..64)
            .map(|_| {
                let x: Vec<f64> = (0..n).map(|_| r.random_range(-1.0..1.0)).collect();
                let y: Vec<f64> = x.iter().map(|v| 0.99 * v + 0.01).collect();
                let (mut z, mut zn) = (vec![0.0; p], vec![0.0; p]);
                lift.lift(&x, &mut z);
                lift.lift(&y, &mut zn);
                (z, zn)
            })
            .collect();
        let mut k = 0;
        g.bench_function(name, |b| {
            b.iter(|| {
                let (z, zn) = &samples[k % samples.len()];
                k += 1;
                black_box(rls.update_model(&mut model, z, zn))
            })
        });
    }
    g.finish();
}

fn edmd_fit(c: &mut Criterion) {
    let mut g = c.benchmark_group("edmd_fit_rot_p36");
    g.sample_size(10);
    let lift = Polynomial::new(7, 2);
    let mut r = SmallRng::seed_from_u64(8);
    for n_samples in [500usize, 2000, 8000, 32000] {
        let mut data = Snapshots::new(7, 0);
        for _ in 0..n_samples {
            let x: Vec<f64> = (0..7).map(|_| r.random_range(-1.0..1.0)).collect();
            let y: Vec<f64> = x.iter().map(|v| 0.99 * v + 0.01 * v * v).collect();
            data.push(&x, &y, &[]);
        }
        g.bench_with_input(BenchmarkId::from_parameter(n_samples), &data, |b, d| {
            b.iter(|| black_box(fit_edmd(&lift, d, 0.05, &LstsqOptions::default()).unwrap()))
        });
    }
    g.finish();
}

fn config() -> Criterion {
    Criterion::default()
        .measurement_time(Duration::from_secs(3))
        .warm_up_time(Duration::from_secs(1))
        .sample_size(20)
}

criterion_group! { name = benches; config = config(); targets = forecast, online_update, edmd_fit }
criterion_main!(benches);
