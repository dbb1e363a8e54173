//! Training: accuracy on systems with known structure, determinism, progress, validation split.

mod common;

use dkrrt_deep::*;
use dkrrt_koopman::linalg::LstsqOptions;
use dkrrt_koopman::{fit_edmd, Lifting, Polynomial, Snapshots};

/// Multi-step RMSE per step of an EDMD model (linear lifted roll-out) on the given trajectories.
fn edmd_rmse(lifting: &dyn Lifting, fit: &TrainData, test: &TrainData, h: usize) -> Vec<f64> {
    let n = fit.n;
    let mut s = Snapshots::new(n, 0);
    for t in &fit.trajectories {
        s.push_trajectory(t, &[]);
    }
    let (model, _) =
        fit_edmd(lifting, &s, fit.dt, &LstsqOptions { ridge: 1e-9, ..Default::default() }).unwrap();
    let p = model.p;
    let (mut sse, mut cnt) = (vec![0.0; h], 0);
    let (mut z, mut zn) = (vec![0.0; p], vec![0.0; p]);
    for tr in &test.trajectories {
        let steps = tr.len() / n;
        for s0 in 0..steps - h {
            lifting.lift(&tr[s0 * n..], &mut z);
            for k in 0..h {
                model.step(&z, &[], &mut zn);
                std::mem::swap(&mut z, &mut zn);
                sse[k] += (0..n).map(|i| (z[i] - tr[(s0 + k + 1) * n + i]).powi(2)).sum::<f64>();
            }
            cnt += 1;
        }
    }
    sse.iter().map(|v| (v / (cnt * n) as f64).sqrt()).collect()
}

fn deep_rmse(dk: &DeepKoopman, test: &TrainData, h: usize) -> Vec<f64> {
    let all: Vec<usize> = (0..test.trajectories.len()).collect();
    rmse_per_step(dk, test, &all, h)
}

#[test]
fn learns_a_system_that_is_linear_in_a_quadratic_lifting() {
    let data = common::quadratic_map(60, 30, 1);
    let test = common::quadratic_map(20, 30, 2);
    let h = 10;
    let cfg = TrainConfig {
        hidden: 16,
        layers: 1,
        extra: 4,
        horizon: h,
        epochs: 40,
        resolve_every: 5,
        lr: 5e-3,
        batch: 64,
        ridge: 1e-8,
        valid_fraction: 0.2,
        seed: 7,
    };
    let mut calls = 0;
    let (dk, rep) = train(&data, &cfg, &mut |p| {
        calls += 1;
        assert_eq!(p.epochs, 40);
        assert!(p.train_loss.is_finite() && p.valid_loss.is_finite());
    })
    .unwrap();
    assert_eq!(calls, 40);
    assert_eq!(rep.valid_rmse.len(), h);
    assert_eq!((rep.n_train, rep.n_valid), (48, 12));
    let deep = deep_rmse(&dk, &test, h);
    let dmd = edmd_rmse(&Polynomial::new(2, 1), &data, &test, h);
    eprintln!("deep {deep:?}\n dmd {dmd:?}\n report {rep:?}");
    // State spread is ~0.6; DMD (affine) cannot represent x1², the deep lifting can.
    assert!(deep[h - 1] < 0.02, "deep multi-step error too large: {:?}", deep);
    assert!(deep[h - 1] < 0.2 * dmd[h - 1], "deep {deep:?} vs dmd {dmd:?}");
    // The report's validation RMSE is that of the returned model.
    assert!(rep.valid_rmse[h - 1] < 0.02, "{:?}", rep.valid_rmse);
}

#[test]
fn training_is_deterministic_for_a_seed() {
    let data = common::quadratic_map(10, 20, 3);
    let cfg = TrainConfig {
        hidden: 8,
        layers: 2,
        extra: 4,
        horizon: 5,
        epochs: 3,
        batch: 32,
        ..Default::default()
    };
    let (a, ra) = train(&data, &cfg, &mut |_| {}).unwrap();
    let (b, rb) = train(&data, &cfg, &mut |_| {}).unwrap();
    assert_eq!(to_bytes(&[("m", &a)]), to_bytes(&[("m", &b)]));
    assert_eq!(ra.valid_rmse, rb.valid_rmse);
    let (c, _) = train(&data, &TrainConfig { seed: 99, ..cfg }, &mut |_| {}).unwrap();
    assert_ne!(to_bytes(&[("m", &a)]), to_bytes(&[("m", &c)]));
}

#[test]
fn tumbling_rigid_body_beats_polynomial_edmd() {
    let data = common::tumbling(60, 80, 1.0, 11);
    let test = common::tumbling(20, 80, 1.0, 12);
    let h = 20; // 2 s
    let cfg = TrainConfig { horizon: h, epochs: 25, batch: 128, ..Default::default() };
    let t = std::time::Instant::now();
    let (dk, rep) = train(&data, &cfg, &mut |p| eprintln!("{p:?}")).unwrap();
    eprintln!("train {:.1} s, report {rep:?}", t.elapsed().as_secs_f64());
    let deep = deep_rmse(&dk, &test, h);
    let poly2 = edmd_rmse(&Polynomial::new(7, 2), &data, &test, h);
    eprintln!("deep  {deep:?}\npoly2 {poly2:?}");
    // Polynomial EDMD is near-exact for one step (the dynamics are quadratic) but drifts; the
    // multi-step-trained deep model must be better at the 2 s horizon.
    assert!(deep[h - 1] < 0.8 * poly2[h - 1], "deep {:?} vs poly2 {:?}", deep[h - 1], poly2[h - 1]);
    assert!(rep.valid_rmse[h - 1] < 0.8 * poly2[h - 1]);
}

#[test]
fn rejects_bad_config_and_data() {
    let data = common::quadratic_map(4, 20, 3);
    let bad = |cfg: TrainConfig| matches!(train(&data, &cfg, &mut |_| {}), Err(TrainError::Config(_)));
    let d = TrainConfig::default;
    assert!(bad(TrainConfig { hidden: MAX_HIDDEN + 1, ..d() }));
    assert!(bad(TrainConfig { layers: 0, ..d() }));
    assert!(bad(TrainConfig { extra: 1, ..d() }));
    assert!(bad(TrainConfig { horizon: 0, ..d() }));
    assert!(bad(TrainConfig { lr: -1.0, ..d() }));
    assert!(bad(TrainConfig { valid_fraction: 1.0, ..d() }));
    let short = TrainConfig { horizon: 50, ..d() };
    assert!(matches!(train(&data, &short, &mut |_| {}), Err(TrainError::Data(_))));
    let mut nan = data.clone();
    nan.trajectories[1][3] = f64::NAN;
    assert!(matches!(train(&nan, &d(), &mut |_| {}), Err(TrainError::Data(_))));
    let mut ragged = data.clone();
    ragged.trajectories[0].pop();
    assert!(matches!(train(&ragged, &d(), &mut |_| {}), Err(TrainError::Data(_))));
}
