//! Finds the slowest problems of an `otg_bench`-like run (7 joints) and
//! re-times each of them many times, to tell algorithmic worst cases from
//! scheduler noise on a shared machine.
//!
//! `cargo run --release -p dkrrt-otg --example otg_worst [problems] [slowest] [repeats]`

use dkrrt_otg::{Options, Trajectory};
use rand::rngs::SmallRng;
use rand::SeedableRng;
use rsruckig::prelude::*;
use std::hint::black_box;
use std::time::Instant;

#[path = "../tests/support/problems.rs"]
mod problems;
use problems::{draw, ruckig_input};

fn main() {
    let arg = |i: usize, d: usize| std::env::args().nth(i).and_then(|a| a.parse().ok()).unwrap_or(d);
    let (n, k, reps) = (arg(1, 20_000), arg(2, 10), arg(3, 20));
    let mut rng = SmallRng::seed_from_u64(7);
    let mut otg = Ruckig::<7, ThrowErrorHandler>::new(None, 0.001);
    let mut traj = rsruckig::prelude::Trajectory::new(None);
    let o = Options::default();
    let mut runs = Vec::with_capacity(n);
    while runs.len() < n {
        let (s, t, l) = draw::<7>(&mut rng, 0.2);
        if !matches!(otg.calculate(&ruckig_input(&s, &t, &l), &mut traj), Ok(RuckigResult::Working)) {
            continue;
        }
        let mut best = f64::INFINITY;
        for _ in 0..3 {
            let t0 = Instant::now();
            let r = Trajectory::calculate(black_box(&s), black_box(&t), black_box(&l), &o);
            best = best.min(t0.elapsed().as_secs_f64());
            black_box(&r);
        }
        runs.push((best * 1e6, s, t, l));
    }
    runs.sort_by(|a, b| b.0.total_cmp(&a.0));
    for (first, s, t, l) in runs.iter().take(k) {
        let mut best = f64::INFINITY;
        for _ in 0..reps {
            let t0 = Instant::now();
            let r = Trajectory::calculate(black_box(s), black_box(t), black_box(l), &o);
            best = best.min(t0.elapsed().as_secs_f64());
            black_box(&r);
        }
        println!("first run {first:7.2} µs, best of {reps} re-runs {:7.2} µs", best * 1e6);
    }
}
