//! Train the deep attitude model on debris-world data and write a model file:
//! `cargo run --release -p dkrrt-predictor --example train -- OUT.dkm`
//!
//! Environment overrides (tuning): `EPOCHS`, `HIDDEN`, `LAYERS`, `EXTRA`, `HORIZON`, `LR`,
//! `RUNS` (per named scene), `RANDOM_RUNS`, `DURATION`, `RESOLVE`, `BATCH`, `RIDGE`.

use dkrrt_predictor::training::{train_models, TrainOptions};

fn env<T: std::str::FromStr>(name: &str) -> Option<T> {
    std::env::var(name).ok().and_then(|v| v.parse().ok())
}

fn main() {
    let out = std::env::args().nth(1).unwrap_or_else(|| "deep-attitude.dkm".into());
    let mut o = TrainOptions::default();
    if let Some(v) = env("EPOCHS") {
        o.deep.epochs = v;
    }
    if let Some(v) = env("HIDDEN") {
        o.deep.hidden = v;
    }
    if let Some(v) = env("LAYERS") {
        o.deep.layers = v;
    }
    if let Some(v) = env("EXTRA") {
        o.deep.extra = v;
    }
    if let Some(v) = env("HORIZON") {
        o.deep.horizon = v;
    }
    if let Some(v) = env("LR") {
        o.deep.lr = v;
    }
    if let Some(v) = env("RESOLVE") {
        o.deep.resolve_every = v;
    }
    if let Some(v) = env("BATCH") {
        o.deep.batch = v;
    }
    if let Some(v) = env("RIDGE") {
        o.deep.ridge = v;
    }
    if let Some(v) = env("RUNS") {
        o.runs_per_scene = v;
    }
    if let Some(v) = env("RANDOM_RUNS") {
        o.random_runs = v;
    }
    if let Some(v) = env("DURATION") {
        o.duration = v;
    }
    eprintln!("options: {o:?}");
    let t = std::time::Instant::now();
    let m = train_models(&o, &mut |p| {
        eprintln!(
            "epoch {}/{}: train {:.3e} valid {:.3e} ({:.1} s)",
            p.epoch, p.epochs, p.train_loss, p.valid_loss, p.elapsed_s
        )
    })
    .unwrap_or_else(|e| {
        eprintln!("training failed: {e}");
        std::process::exit(1)
    });
    let r = m.report.as_ref().unwrap();
    eprintln!(
        "total {:.1} s (training {:.1} s, {} epochs, best {}, {} train / {} valid trajectories)",
        t.elapsed().as_secs_f64(),
        r.seconds,
        r.epochs,
        r.best_epoch,
        r.n_train,
        r.n_valid
    );
    println!("| horizon [s] | deep median att err [rad] | deep RMSE (q, ω) | const. rate median att err [rad] | n |");
    println!("|---|---|---|---|---|");
    for v in &m.validation {
        println!(
            "| {} | {:.4} | {:.4} | {:.4} | {} |",
            v.horizon_s, v.att_err_rad, v.rmse, v.cv_att_err_rad, v.n
        );
    }
    m.save(std::path::Path::new(&out)).expect("write model file");
    eprintln!("wrote {out}");
}
