//! Forecast timing robust to a loaded machine: the bench's setup (32 random debris, 3 s of
//! observations), then the *minimum* over 300 batches of 20 `forecast()` calls per method
//! (preemption by other processes only ever adds time). Complements the criterion bench.
//!
//! `cargo run --release -p dkrrt-predictor --example forecast_timing [METHOD…]`

use dkrrt_debris::{RandomSceneParams, Scene, SensorConfig};
use dkrrt_predictor::eval::{record, training_set};
use dkrrt_predictor::TrainedModels;
use dkrrt_predictor::{DebrisPredictor, FitConfig, ForecastBuffer, Method, Models, PredictorConfig};
use std::hint::black_box;
use std::time::Instant;

fn main() {
    let run = |seed: u64, d: f64| {
        record(
            &Scene::random(seed, 32, &RandomSceneParams::default()),
            SensorConfig::default(),
            d,
            0.01,
            seed,
        )
        .unwrap()
    };
    let train = vec![run(1, 10.0)];
    let test = run(2, 3.5);
    let fit = FitConfig { frame_rate: train[0].mean_motion, ..Default::default() };
    let ts = training_set(&train, fit.dt, fit.horizon, 1.0, &PredictorConfig::default());
    let only: Vec<String> = std::env::args().skip(1).collect();
    // Deep methods: the shipped model (`models/deep-attitude.dkm`), or `DEEP_MODEL=FILE`.
    let path = dkrrt_predictor::training::bench_model_path();
    let deep = TrainedModels::load(&path).unwrap_or_else(|e| panic!("deep model {}: {e}", path.display()));
    eprintln!("deep model: {}", path.display());
    let deep = Some(deep);
    for method in Method::ALL {
        if (!only.is_empty() && !only.iter().any(|o| o == method.name())) || (method.deep() && deep.is_none())
        {
            continue;
        }
        let m = if method == Method::ConstantVelocity {
            Models::constant_velocity(fit.dt, fit.horizon, fit.frame_rate, 0.05, 0.05)
        } else {
            Models::fit_with_deep(method, &ts, &fit, deep.as_ref().map(|d| &d.attitude)).unwrap()
        };
        let mut pr = DebrisPredictor::new(m, PredictorConfig::default());
        for o in test.obs.iter().filter(|o| o.t < 3.0) {
            pr.observe(o);
        }
        let mut buf = ForecastBuffer::for_predictor(&pr);
        assert_eq!(pr.forecast(&mut buf), 32);
        let mut best = f64::INFINITY;
        for _ in 0..300 {
            let t = Instant::now();
            for _ in 0..20 {
                black_box(pr.forecast(&mut buf));
            }
            best = best.min(t.elapsed().as_secs_f64() / 20.0);
        }
        println!("forecast 32x40 {:<22} min {:7.1} µs", method.name(), best * 1e6);
        if std::env::var("LIFT").is_ok() {
            use dkrrt_koopman::Lifting;
            let l = &pr.models().att_lift;
            let mut z = vec![0.0; l.dim()];
            let x = [0.5, 0.5, 0.5, 0.5, 0.1, 0.2, 0.3];
            let mut best = f64::INFINITY;
            for _ in 0..100 {
                let t = Instant::now();
                for _ in 0..1000 {
                    l.lift(black_box(&x), &mut z);
                    black_box(&z);
                }
                best = best.min(t.elapsed().as_secs_f64() / 1000.0);
            }
            println!("  attitude lift min {:.1} ns", best * 1e9);
        }
    }
}
