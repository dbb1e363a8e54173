//! Criterion benchmark: calculation time for 6 and 7 joints with full random
//! states, ours vs rsruckig in the same run. For a mean/worst table run
//! `cargo run --release -p dkrrt-otg --example otg_bench`.

use criterion::{criterion_group, criterion_main, Criterion};
use dkrrt_otg::{KinState, Limits, Options, Trajectory};
use rand::rngs::SmallRng;
use rand::SeedableRng;
use rsruckig::prelude::*;
use std::hint::black_box;

#[path = "../tests/support/problems.rs"]
mod problems;
use problems::{draw, ruckig_input};

type Case<const N: usize> = (KinState<N>, KinState<N>, Limits<N>, InputParameter<N>);

fn corpus<const N: usize>(n: usize) -> Vec<Case<N>> {
    let mut rng = SmallRng::seed_from_u64(N as u64);
    let mut otg = Ruckig::<N, ThrowErrorHandler>::new(None, 0.001);
    let mut traj = rsruckig::prelude::Trajectory::new(None);
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let (s, t, l) = draw::<N>(&mut rng, 0.0);
        let input = ruckig_input(&s, &t, &l);
        if matches!(otg.calculate(&input, &mut traj), Ok(RuckigResult::Working))
            && Trajectory::calculate(&s, &t, &l, &Options::default()).is_ok()
        {
            out.push((s, t, l, input));
        }
    }
    out
}

fn bench_n<const N: usize>(c: &mut Criterion) {
    let cases = corpus::<N>(200);
    let o = Options::default();
    c.bench_function(&format!("dkrrt_otg_calculate_{N}dof_x200"), |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for (s, t, l, _) in &cases {
                acc += Trajectory::calculate(black_box(s), black_box(t), l, &o)
                    .map(|x| x.duration())
                    .unwrap_or(0.0);
            }
            black_box(acc)
        })
    });
    let mut otg = Ruckig::<N, ThrowErrorHandler>::new(None, 0.001);
    let mut traj = rsruckig::prelude::Trajectory::new(None);
    c.bench_function(&format!("rsruckig_calculate_{N}dof_x200"), |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for (.., input) in &cases {
                let _ = otg.calculate(black_box(input), &mut traj);
                acc += traj.get_duration();
            }
            black_box(acc)
        })
    });
    let tr = Trajectory::calculate(&cases[0].0, &cases[0].1, &cases[0].2, &o).unwrap();
    c.bench_function(&format!("dkrrt_otg_sample_{N}dof"), |b| {
        let mut t = 0.0;
        b.iter(|| {
            t += 0.001;
            if t > tr.duration() {
                t = 0.0;
            }
            black_box(tr.at(black_box(t)))
        })
    });
}

fn benches(c: &mut Criterion) {
    bench_n::<6>(c);
    bench_n::<7>(c);
}

criterion_group!(g, benches);
criterion_main!(g);
