#![allow(dead_code)]

use dkrrt_debris::{Observation, Scene};
use dkrrt_predictor::eval::{perturbed_scene, record, training_set, Recording};
use dkrrt_predictor::{FitConfig, Method, Models, PredictorConfig};

/// Tumbling-rods without its scheduled events (free tumbling).
pub fn free_rods(seed: u64) -> Scene {
    let mut s = perturbed_scene("tumbling-rods", seed, 1.0).unwrap();
    s.events.clear();
    s
}

/// Models of `method` fitted on two free-tumbling training runs.
pub fn fitted(method: Method) -> Models {
    let sensor = dkrrt_debris::SensorConfig::default();
    let recs: Vec<Recording> =
        (0..2).map(|i| record(&free_rods(100 + i), sensor, 12.0, 0.01, 100 + i).unwrap()).collect();
    let fit = FitConfig { frame_rate: recs[0].mean_motion, ..Default::default() };
    let ts = training_set(&recs, fit.dt, fit.horizon, 1.0, &PredictorConfig::default());
    Models::fit(method, &ts, &fit).unwrap()
}

/// Models of a deep `method` (translation fitted like [`fitted`], attitude = `deep`).
pub fn fitted_deep(method: Method, deep: &dkrrt_deep::DeepKoopman) -> Models {
    let sensor = dkrrt_debris::SensorConfig::default();
    let recs: Vec<Recording> =
        (0..2).map(|i| record(&free_rods(100 + i), sensor, 12.0, 0.01, 100 + i).unwrap()).collect();
    let fit = FitConfig { frame_rate: recs[0].mean_motion, ..Default::default() };
    let ts = training_set(&recs, fit.dt, fit.horizon, 1.0, &PredictorConfig::default());
    Models::fit_with_deep(method, &ts, &fit, Some(deep)).unwrap()
}

/// Observation of a pose.
pub fn obs(id: u32, t: f64, p: [f64; 3], q: [f64; 4]) -> Observation {
    Observation { id, t, t_avail: t, p, q, ..Default::default() }
}
