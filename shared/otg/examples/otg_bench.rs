//! Prints a table of calculation times, ours vs rsruckig, for 6 and 7 joints
//! with full random states (drawn like Ruckig's tests).
//!
//! `cargo run --release -p dkrrt-otg --example otg_bench [problems]`
//!
//! Each problem is calculated 3 times by each generator and the fastest of
//! the three is kept (to suppress scheduler noise on a shared machine); the
//! table shows the mean and the worst of these over all problems.

use dkrrt_otg::{Options, Trajectory};
use rand::rngs::SmallRng;
use rand::SeedableRng;
use rsruckig::prelude::*;
use std::hint::black_box;
use std::time::Instant;

#[path = "../tests/support/problems.rs"]
mod problems;
use problems::{draw, ruckig_input};

struct Stats {
    ours: Vec<f64>,
    theirs: Vec<f64>,
    failures: usize,
}

fn run<const N: usize>(n: usize, seed: u64) -> Stats {
    let mut rng = SmallRng::seed_from_u64(seed);
    let mut otg = Ruckig::<N, ThrowErrorHandler>::new(None, 0.001);
    let mut traj = rsruckig::prelude::Trajectory::new(None);
    let mut st = Stats { ours: Vec::with_capacity(n), theirs: Vec::with_capacity(n), failures: 0 };
    while st.ours.len() < n {
        let (s, t, l) = draw::<N>(&mut rng, 0.2);
        let input = ruckig_input(&s, &t, &l);
        if !matches!(otg.calculate(&input, &mut traj), Ok(RuckigResult::Working)) {
            continue; // infeasible draw: redraw
        }
        let mut o = Options::default();
        if std::env::var("OTG_SYNC_NONE").is_ok() {
            o.sync = dkrrt_otg::Sync::None;
        }
        let (mut best_ours, mut best_theirs) = (f64::INFINITY, f64::INFINITY);
        let mut ok = true;
        for _ in 0..3 {
            let t0 = Instant::now();
            let r = Trajectory::calculate(black_box(&s), black_box(&t), black_box(&l), &o);
            let dt = t0.elapsed().as_secs_f64();
            ok &= r.is_ok();
            black_box(&r);
            best_ours = best_ours.min(dt);
            let t0 = Instant::now();
            let r2 = otg.calculate(black_box(&input), &mut traj);
            let dt = t0.elapsed().as_secs_f64();
            black_box(&r2);
            best_theirs = best_theirs.min(dt);
        }
        if !ok {
            st.failures += 1;
        }
        st.ours.push(best_ours * 1e6);
        st.theirs.push(best_theirs * 1e6);
    }
    st
}

fn main() {
    let n: usize = std::env::args().nth(1).and_then(|a| a.parse().ok()).unwrap_or(20_000);
    println!("{n} random full-state problems per row (p~N(0,4), v,a~N(0,0.8), limits~U(0.08,16)), time sync");
    println!("| joints | generator | mean [µs] | worst [µs] | p99 [µs] | failures |");
    println!("|---|---|---|---|---|---|");
    let row = |dof: usize, name: &str, v: &mut Vec<f64>, fails: usize| {
        v.sort_by(|a, b| a.total_cmp(b));
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        let p99 = v[(v.len() as f64 * 0.99) as usize];
        println!("| {dof} | {name} | {mean:.2} | {:.2} | {p99:.2} | {fails} |", v[v.len() - 1]);
    };
    let mut s6 = run::<6>(n, 6);
    row(6, "dkrrt-otg", &mut s6.ours, s6.failures);
    row(6, "rsruckig 3.0", &mut s6.theirs, 0);
    let mut s7 = run::<7>(n, 7);
    row(7, "dkrrt-otg", &mut s7.ours, s7.failures);
    row(7, "rsruckig 3.0", &mut s7.theirs, 0);
}
