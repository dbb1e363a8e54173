//! `observe()` and `forecast()` never allocate after warm-up (counting allocator).

mod common;

use common::{fitted, fitted_deep};
use dkrrt_debris::SensorConfig;
use dkrrt_predictor::eval::{perturbed_scene, record};
use dkrrt_predictor::training::{train_models, TrainOptions};
use dkrrt_predictor::{DebrisPredictor, ForecastBuffer, Method, Models, PredictorConfig};
use dkrrt_rt::alloc_count::{count, CountingAlloc};

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc;

#[test]
fn observe_and_forecast_do_not_allocate() {
    // Tumbling-rods with its events: impulse at 10 s, split at 15 s (new track, id 100).
    let scene = perturbed_scene("tumbling-rods", 3, 1.0).unwrap();
    let rec = record(&scene, SensorConfig::default(), 17.0, 0.01, 3).unwrap();
    let deep = train_models(&TrainOptions::tiny(), &mut |_| {}).unwrap();
    for method in [
        Method::ConstantVelocity,
        Method::EdmdRbf,
        Method::KoopmanOnline,
        Method::DualData,
        Method::DeepKoopmanOnline,
    ] {
        let models = if method == Method::ConstantVelocity {
            Models::constant_velocity(0.1, 40, rec.mean_motion, 0.05, 0.05)
        } else if method.deep() {
            fitted_deep(method, &deep.attitude)
        } else {
            fitted(method)
        };
        let mut pr = DebrisPredictor::new(models, PredictorConfig::default());
        let mut buf = ForecastBuffer::for_predictor(&pr);
        let split = rec.obs.iter().position(|o| o.t >= 2.0).unwrap();
        for o in &rec.obs[..split] {
            pr.observe(o);
        }
        pr.forecast(&mut buf);
        let mut forecasts = 0;
        let (_, stats) = count(|| {
            for (i, o) in rec.obs[split..].iter().enumerate() {
                pr.observe(o);
                if i % 40 == 0 {
                    // Shapes as the process passes them: boxes run the torque-free channel.
                    for (id, shape, _) in &rec.shapes {
                        pr.set_shape(*id, shape);
                    }
                    forecasts += pr.forecast(&mut buf);
                }
            }
        });
        assert_eq!((stats.allocs, stats.reallocs, stats.deallocs), (0, 0, 0), "{method:?}: {stats:?}");
        // The region really exercised the machinery: the fragment got a track, pairs formed.
        assert!(pr.track(100).is_some(), "{method:?}: fragment track missing");
        assert!(forecasts > 1000 && pr.stats().model_pairs > 1000, "{method:?}: {:?}", pr.stats());
    }
}
