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
    // The pose sensor's settings, and those for heavy-tailed poses (a depth front end's:
    // Huber updates, persistent events, size-scaled noise, the filter's own deviation in the
    // bound, revived tracks; object 0 is hidden from 8 s to 9.5 s, so its track is dropped
    // and taken up again inside the counted region).
    let mut heavy = PredictorConfig::default();
    heavy.filter.pos_sigma = 0.05;
    heavy.filter.outlier_sigmas = 3.0;
    heavy.event_persist = 2;
    heavy.pos_sigma_per_m = 0.08;
    heavy.track_sigmas = 3.0;
    heavy.revive_s = 5.0;
    let hidden = |o: &dkrrt_debris::Observation| o.id == 0 && o.t > 8.0 && o.t < 9.5;
    for (method, cfg) in
        [(Method::DeepKoopmanOnline, heavy), (Method::KoopmanOnline, heavy)].into_iter().chain(
            [
                Method::ConstantVelocity,
                Method::EdmdRbf,
                Method::KoopmanOnline,
                Method::DualData,
                Method::DeepKoopmanOnline,
            ]
            .map(|m| (m, PredictorConfig::default())),
        )
    {
        let models = if method == Method::ConstantVelocity {
            Models::constant_velocity(0.1, 40, rec.mean_motion, 0.05, 0.05)
        } else if method.deep() {
            fitted_deep(method, &deep.attitude)
        } else {
            fitted(method)
        };
        let mut pr = DebrisPredictor::new(models, cfg);
        let mut buf = ForecastBuffer::for_predictor(&pr);
        let split = rec.obs.iter().position(|o| o.t >= 2.0).unwrap();
        for o in &rec.obs[..split] {
            pr.observe(o);
        }
        pr.forecast(&mut buf);
        let (mut forecasts, mut calibrations) = (0, 0);
        let (_, stats) = count(|| {
            for (i, o) in rec.obs[split..].iter().enumerate() {
                if cfg.revive_s > 0.0 && hidden(o) {
                    continue;
                }
                pr.observe(o);
                if i % 40 == 0 {
                    // Shapes as the process passes them: boxes run the torque-free channel.
                    for (id, shape, _) in &rec.shapes {
                        pr.set_shape(*id, shape);
                    }
                    forecasts += pr.forecast(&mut buf);
                } else if i % 8 == 0 {
                    // The lockstep's forecasts nobody reads: their calibration alone.
                    calibrations += pr.forecast_for_calibration(&mut buf);
                }
            }
        });
        assert_eq!((stats.allocs, stats.reallocs, stats.deallocs), (0, 0, 0), "{method:?}: {stats:?}");
        // The region really exercised the machinery: the fragment got a track, pairs formed.
        assert!(pr.track(100).is_some(), "{method:?}: fragment track missing");
        assert!(forecasts > 1000 && pr.stats().model_pairs > 1000, "{method:?}: {:?}", pr.stats());
        assert!(calibrations > 1000, "{method:?}: {calibrations}");
        if cfg.revive_s > 0.0 {
            assert!(pr.stats().revived >= 1, "{method:?}: the hidden track was not taken up again");
        }
    }
}
