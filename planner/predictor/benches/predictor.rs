//! Benchmarks: forecast of 32 debris × 40 steps per method, and `observe()` per observation
//! (shapes set: box tracks run the torque-free attitude channel).

use criterion::{criterion_group, criterion_main, Criterion};
use dkrrt_debris::{RandomSceneParams, Scene, SensorConfig};
use dkrrt_predictor::eval::{record, training_set, Recording};
use dkrrt_predictor::training::TrainedModels;
use dkrrt_predictor::{DebrisPredictor, FitConfig, ForecastBuffer, Method, Models, PredictorConfig};
use std::hint::black_box;
use std::time::{Duration, Instant};

/// 32 random debris, 0.5 rad/s tumble, sensor at 50 Hz with dropouts.
fn run(seed: u64, duration: f64) -> Recording {
    let scene = Scene::random(seed, 32, &RandomSceneParams::default());
    record(&scene, SensorConfig::default(), duration, 0.01, seed).unwrap()
}

fn models(method: Method, train: &[Recording], deep: &TrainedModels) -> Models {
    let fit = FitConfig { frame_rate: train[0].mean_motion, ..Default::default() };
    if method == Method::ConstantVelocity {
        return Models::constant_velocity(fit.dt, fit.horizon, fit.frame_rate, 0.05, 0.05);
    }
    let ts = training_set(train, fit.dt, fit.horizon, 1.0, &PredictorConfig::default());
    Models::fit_with_deep(method, &ts, &fit, Some(&deep.attitude)).unwrap()
}

fn bench(c: &mut Criterion) {
    let train = vec![run(1, 10.0)];
    let test = run(2, 60.0);
    // Deep model: the shipped one (`models/deep-attitude.dkm`), or `DEEP_MODEL=FILE`.
    let path = dkrrt_predictor::training::bench_model_path();
    let deep = TrainedModels::load(&path).unwrap_or_else(|e| panic!("deep model {}: {e}", path.display()));
    eprintln!("deep model: {}", path.display());
    let mut g = c.benchmark_group("predictor");
    for method in Method::ALL {
        let m = models(method, &train, &deep);
        let (p_t, p_a) = (m.trans.p, m.att.p);
        let mut pr = DebrisPredictor::new(m.clone(), PredictorConfig::default());
        let warm = test.obs.iter().position(|o| o.t >= 3.0).unwrap();
        for o in &test.obs[..warm] {
            pr.observe(o);
        }
        // Shapes as the process passes them: boxes run the torque-free attitude forecast.
        for (id, shape, _) in &test.shapes {
            pr.set_shape(*id, shape);
        }
        let mut buf = ForecastBuffer::for_predictor(&pr);
        assert_eq!(pr.forecast(&mut buf), 32);
        let label = if method == Method::ConstantVelocity {
            format!("forecast_32x40_{}", method.name())
        } else {
            format!("forecast_32x40_{}_pt{p_t}_pa{p_a}", method.name())
        };
        g.bench_function(label, |b| b.iter(|| black_box(pr.forecast(&mut buf))));
        // observe(): replay the 60 s stream (≈ 94k observations) in order; a fresh predictor
        // (warmed up for 3 s, untimed) whenever the stream is exhausted.
        let mut pr = DebrisPredictor::new(m, PredictorConfig::default());
        let mut i = usize::MAX;
        g.bench_function(format!("observe_{}", method.name()), |b| {
            b.iter_custom(|iters| {
                let mut total = Duration::ZERO;
                let mut done = 0;
                while done < iters {
                    if i >= test.obs.len() {
                        pr = DebrisPredictor::new(pr.models().clone(), PredictorConfig::default());
                        for o in &test.obs[..warm] {
                            pr.observe(o);
                        }
                        for (id, shape, _) in &test.shapes {
                            pr.set_shape(*id, shape);
                        }
                        i = warm;
                    }
                    let n = ((iters - done) as usize).min(test.obs.len() - i);
                    let t = Instant::now();
                    for o in &test.obs[i..i + n] {
                        black_box(pr.observe(o));
                    }
                    total += t.elapsed();
                    i += n;
                    done += n as u64;
                }
                total
            })
        });
    }
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(2)).sample_size(20);
    targets = bench
}
criterion_main!(benches);
