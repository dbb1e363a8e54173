//! Deep model training entry points: tiny training, model file round trip, clear errors,
//! deep methods in the predictor.

mod common;

use common::free_rods;
use dkrrt_debris::SensorConfig;
use dkrrt_koopman::debris_state::N;
use dkrrt_predictor::eval::{record, training_set};
use dkrrt_predictor::models::Engine;
use dkrrt_predictor::training::{train_models, TrainOptions, TrainedModels};
use dkrrt_predictor::{FitConfig, Method, Models, PredictorConfig};

#[test]
fn train_save_load_and_fit_deep_methods() {
    let t = std::time::Instant::now();
    let mut epochs = 0;
    let tm = train_models(&TrainOptions::tiny(), &mut |p| epochs = p.epoch).unwrap();
    eprintln!("tiny training {:.1} s, validation {:?}", t.elapsed().as_secs_f64(), tm.validation);
    let rep = tm.report.as_ref().unwrap();
    assert_eq!(epochs, TrainOptions::tiny().deep.epochs);
    assert!(rep.n_train > 0 && rep.valid_rmse.iter().all(|v| v.is_finite()));
    assert_eq!(tm.validation.len(), 4);
    assert!(tm.validation.iter().all(|r| r.att_err_rad.is_finite() && r.rmse.is_finite() && r.n > 50));
    assert_eq!((tm.attitude.model.n, tm.attitude.model.p), (7, 7 + TrainOptions::tiny().deep.extra));

    // Round trip through the model file.
    let dir = std::env::temp_dir().join(format!("dkrrt-pred-train-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("deep.dkm");
    tm.save(&path).unwrap();
    let back = TrainedModels::load(&path).unwrap();
    assert!(back.report.is_none() && back.validation.is_empty());
    assert_eq!(back.attitude.model.ab, tm.attitude.model.ab);

    // Models of both deep methods from the original and the loaded model forecast identically.
    let recs: Vec<_> = (0..1)
        .map(|i| record(&free_rods(200 + i), SensorConfig::default(), 8.0, 0.01, 200 + i).unwrap())
        .collect();
    let fit = FitConfig { frame_rate: recs[0].mean_motion, ..Default::default() };
    let ts = training_set(&recs, fit.dt, fit.horizon, 1.0, &PredictorConfig::default());
    for method in [Method::DeepKoopman, Method::DeepKoopmanOnline] {
        let a = Models::fit_with_deep(method, &ts, &fit, Some(&tm.attitude)).unwrap();
        let b = Models::fit_with_deep(method, &ts, &fit, Some(&back.attitude)).unwrap();
        let x0 = ts.segments[0].est[3];
        let (mut oa, mut ob) = (vec![0.0; 40 * N], vec![0.0; 40 * N]);
        Engine::new(&a).run(&a, &a.trans, &a.att, &x0, 40, &mut oa);
        Engine::new(&b).run(&b, &b.trans, &b.att, &x0, 40, &mut ob);
        assert_eq!(oa, ob, "{method:?}");
        assert!(oa.iter().all(|v| v.is_finite()));
    }
    // Deep methods without a model: a clear error.
    let e = Models::fit(Method::DeepKoopman, &ts, &fit).unwrap_err().to_string();
    assert!(e.contains("needs a trained deep Koopman model"), "{e}");

    // Not a model file / missing file: clear errors.
    let junk = dir.join("junk.dkm");
    std::fs::write(&junk, b"hello, not a model").unwrap();
    let e = TrainedModels::load(&junk).unwrap_err().to_string();
    assert!(e.contains("not a dkrrt deep Koopman model file"), "{e}");
    let e = TrainedModels::load(&dir.join("missing.dkm")).unwrap_err().to_string();
    assert!(e.contains("cannot read model file"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}
