//! Run the accuracy study: `cargo run --release -p dkrrt-predictor --example study -- [small|medium|full] [--json]`.
//!
//! Environment overrides (for tuning sweeps): `PSD_ATT` (filter rotational PSD), `PSD_POS`,
//! `MAN_NIS`, `MAN_WIN`, `MAN_VEL` (manoeuvre re-opening), `SEED` (master seed),
//! `RLS_T_P0`, `RBF_CENTRES`, `RATES` (1 = the sensor reports rates), `RLS_A_P0`, `RLS_A_LAMBDA`, `RLS_A_MAXTRACE`, `RLS_D_P0`, `RLS_D_LAMBDA` (deep), `DUAL_RIDGE`, `SCENES`, `METHODS`
//! (comma-separated), `DEEP_RELIFT` (deep attitude model rolled out in relift mode), `DEEP_MODEL` (pre-trained model file for the deep methods; without it
//! the study trains one with `StudyConfig::deep_train` first).

use dkrrt_predictor::eval::markdown_table;
use dkrrt_predictor::{run_study, Method, StudyConfig};

fn env(name: &str) -> Option<f64> {
    std::env::var(name).ok().and_then(|v| v.parse().ok())
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut cfg = match args.first().map(String::as_str).unwrap_or("medium") {
        "small" => StudyConfig::small(),
        "full" => StudyConfig::full(),
        _ => StudyConfig::medium(),
    };
    // Numeric overrides: (variable, setter).
    type Set = fn(&mut StudyConfig, f64);
    let numeric: [(&str, Set); 15] = [
        ("PSD_ATT", |c, v| c.predictor.filter.ang_accel_psd = v),
        ("PSD_POS", |c, v| c.predictor.filter.accel_psd = v),
        ("MAN_NIS", |c, v| c.predictor.filter.maneuver_nis = v),
        ("MAN_WIN", |c, v| c.predictor.filter.maneuver_window = v),
        ("MAN_VEL", |c, v| c.predictor.filter.maneuver_vel_sigma = v),
        ("SEED", |c, v| c.seed = v as u64),
        ("RLS_T_P0", |c, v| c.predictor.rls_trans.p0 = v),
        ("RLS_A_P0", |c, v| c.predictor.rls_att.p0 = v),
        ("RLS_A_LAMBDA", |c, v| c.predictor.rls_att.lambda = v),
        ("RLS_A_MAXTRACE", |c, v| c.predictor.rls_att.max_trace = v),
        ("RLS_D_P0", |c, v| c.predictor.rls_att_deep.p0 = v),
        ("RLS_D_LAMBDA", |c, v| c.predictor.rls_att_deep.lambda = v),
        ("DUAL_RIDGE", |c, v| {
            c.fit.dual_ridge = v;
            c.fit.dual_ridge_auto = false;
        }),
        ("RBF_CENTRES", |c, v| c.fit.rbf_centres = v as usize),
        ("RATES", |c, v| c.sensor.report_rates = v != 0.0),
    ];
    for (name, set) in numeric {
        if let Some(v) = env(name) {
            set(&mut cfg, v);
        }
    }
    if let Ok(s) = std::env::var("SCENES") {
        cfg.scenes = s.split(',').map(str::to_string).collect();
    }
    if let Ok(s) = std::env::var("METHODS") {
        cfg.methods = s.split(',').map(|m| Method::from_name(m).expect("unknown method")).collect();
    }
    if std::env::var("DEEP_RELIFT").is_ok() {
        cfg.fit.deep_rollout = dkrrt_koopman::Rollout::Relift;
    }
    if let Ok(s) = std::env::var("DEEP_MODEL") {
        cfg.deep_model = Some(s.into());
    }
    eprintln!(
        "study: {} train + {} held-out runs × {} s per scene, warm-up {} s, forecasts every {} s",
        cfg.train_runs, cfg.test_runs, cfg.duration, cfg.warmup, cfg.eval_every
    );
    let t = std::time::Instant::now();
    let rows = run_study(&cfg).unwrap_or_else(|e| {
        eprintln!("study failed: {e}");
        std::process::exit(1)
    });
    eprintln!("study took {:.1} s", t.elapsed().as_secs_f64());
    if args.iter().any(|a| a == "--json") {
        println!("{}", serde_json::to_string_pretty(&rows).unwrap());
    } else {
        print!("{}", markdown_table(&rows));
    }
}
