//! Train deep Koopman models on tumbling rigid-body data of growing size and compare with
//! polynomial EDMD (degree 2) at the training horizon. Prints training time and RMSE.
//!
//! `cargo run --release -p dkrrt-deep --example train_tumble [trajectories...]`
//! (environment overrides: EPOCHS, HIDDEN, LAYERS, EXTRA, LR, BATCH, RESOLVE, RIDGE; VERBOSE=1
//! prints per-epoch progress).

use dkrrt_deep::testdata::tumbling;
use dkrrt_deep::*;
use dkrrt_koopman::linalg::LstsqOptions;
use dkrrt_koopman::{fit_edmd, Lifting, Polynomial, Snapshots};

fn edmd_rmse(lifting: &dyn Lifting, fit: &TrainData, test: &TrainData, h: usize) -> Vec<f64> {
    let n = fit.n;
    let mut s = Snapshots::new(n, 0);
    for t in &fit.trajectories {
        s.push_trajectory(t, &[]);
    }
    let (model, _) =
        fit_edmd(lifting, &s, fit.dt, &LstsqOptions { ridge: 1e-9, ..Default::default() }).unwrap();
    let dk_like = |x: &[f64], z: &mut [f64]| lifting.lift(x, z);
    let p = model.p;
    let (mut sse, mut cnt) = (vec![0.0; h], 0);
    let (mut z, mut zn) = (vec![0.0; p], vec![0.0; p]);
    for tr in &test.trajectories {
        for s0 in 0..tr.len() / n - h {
            dk_like(&tr[s0 * n..], &mut z);
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

fn main() {
    let sizes: Vec<usize> = std::env::args().skip(1).filter_map(|a| a.parse().ok()).collect();
    let sizes = if sizes.is_empty() { vec![100, 250, 500] } else { sizes };
    let steps = 100;
    let test = tumbling(50, steps, 1.0, 999);
    let all: Vec<usize> = (0..test.trajectories.len()).collect();
    // Optional overrides: EPOCHS, HIDDEN, LAYERS, EXTRA, LR, BATCH, RESOLVE, RIDGE.
    let env = |k: &str| std::env::var(k).ok().and_then(|v| v.parse::<f64>().ok());
    let d = TrainConfig::default();
    let cfg = TrainConfig {
        epochs: env("EPOCHS").map_or(d.epochs, |v| v as usize),
        hidden: env("HIDDEN").map_or(d.hidden, |v| v as usize),
        layers: env("LAYERS").map_or(d.layers, |v| v as usize),
        extra: env("EXTRA").map_or(d.extra, |v| v as usize),
        batch: env("BATCH").map_or(d.batch, |v| v as usize),
        resolve_every: env("RESOLVE").map_or(d.resolve_every, |v| v as usize),
        lr: env("LR").unwrap_or(d.lr),
        ridge: env("RIDGE").unwrap_or(d.ridge),
        ..d
    };
    println!("config {cfg:?}");
    println!("| trajectories | samples | train s | epochs | best | deep RMSE @H | EDMD poly2 RMSE @H |");
    for &nt in &sizes {
        let data = tumbling(nt, steps, 1.0, 1);
        let (dk, rep) = train(&data, &cfg, &mut |p| {
            if std::env::var_os("VERBOSE").is_some() {
                eprintln!("{p:?}")
            }
        })
        .unwrap();
        let h = cfg.horizon;
        let deep = rmse_per_step(&dk, &test, &all, h);
        let poly = edmd_rmse(&Polynomial::new(7, 2), &data, &test, h);
        println!(
            "| {nt} | {} | {:.1} | {} | {} | {:.2e} | {:.2e} |",
            nt * steps,
            rep.seconds,
            rep.epochs,
            rep.best_epoch,
            deep[h - 1],
            poly[h - 1]
        );
    }
}
