//! Fixed-array inference: equals candle's forward pass, allocates nothing.
#![allow(clippy::needless_range_loop)]

mod common;

use candle_core::{Device, Tensor};
use dkrrt_deep::*;
use dkrrt_koopman::{Forecaster, Lifting, Rollout, StateConstraint};
use dkrrt_rt::alloc_count::{count, CountingAlloc};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc;

/// Reference forward pass with candle tensors built from the flat parameter layout.
fn candle_forward(l: &DeepLifting, xs: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let dev = Device::Cpu;
    let n = l.state_dim();
    let rows = xs.len();
    let mut u = Vec::new();
    for x in xs {
        for i in 0..n {
            u.push((x[i] - l.offset()[i]) / l.scale()[i]);
        }
    }
    let mut h = Tensor::from_vec(u, (rows, n), &dev).unwrap();
    let p = l.params();
    let mut off = 0;
    let mut fin = n;
    let widths: Vec<usize> = std::iter::repeat_n(l.hidden(), l.layers()).chain([l.extra()]).collect();
    for (k, &fo) in widths.iter().enumerate() {
        let w = Tensor::from_slice(&p[off..off + fo * fin], (fo, fin), &dev).unwrap();
        let b = Tensor::from_slice(&p[off + fo * fin..off + fo * (fin + 1)], (1, fo), &dev).unwrap();
        off += fo * (fin + 1);
        h = h.matmul(&w.t().unwrap()).unwrap().broadcast_add(&b).unwrap();
        if k + 1 < widths.len() {
            h = h.tanh().unwrap();
        }
        fin = fo;
    }
    h.to_vec2::<f64>().unwrap()
}

fn random_lifting(n: usize, hidden: usize, layers: usize, extra: usize, seed: u64) -> DeepLifting {
    let mut r = SmallRng::seed_from_u64(seed);
    let params: Vec<f64> =
        (0..param_count(n, hidden, layers, extra)).map(|_| r.random_range(-0.7..0.7)).collect();
    let offset: Vec<f64> = (0..n).map(|_| r.random_range(-1.0..1.0)).collect();
    let scale: Vec<f64> = (0..n).map(|_| r.random_range(0.2..2.0)).collect();
    DeepLifting::new(n, hidden, layers, extra, &offset, &scale, &params).unwrap()
}

#[test]
fn fixed_array_lift_equals_candle_forward() {
    let mut r = SmallRng::seed_from_u64(9);
    for (n, hidden, layers, extra) in [(7, 32, 2, 16), (2, 5, 1, 3), (16, 64, 3, 32), (13, 17, 2, 9)] {
        let l = random_lifting(n, hidden, layers, extra, n as u64);
        let xs: Vec<Vec<f64>> =
            (0..50).map(|_| (0..n).map(|_| r.random_range(-2.0..2.0)).collect()).collect();
        let reference = candle_forward(&l, &xs);
        let mut z = vec![0.0; l.dim()];
        for (x, zr) in xs.iter().zip(&reference) {
            l.lift(x, &mut z);
            assert_eq!(&z[..n], &x[..], "state block must be x itself");
            for (a, b) in z[n..].iter().zip(zr) {
                assert!(
                    (a - b).abs() <= 1e-12 * (1.0 + b.abs()),
                    "{n}/{hidden}/{layers}/{extra}: {a} vs {b}"
                );
            }
        }
    }
}

#[test]
fn lift_and_forecast_allocate_nothing() {
    let data = common::tumbling(4, 60, 1.0, 3);
    let cfg = TrainConfig { epochs: 1, horizon: 5, hidden: 16, extra: 8, ..TrainConfig::default() };
    let (dk, _) = train(&data, &cfg, &mut |_| {}).unwrap();
    let x = &data.trajectories[0][..7];
    let mut z = vec![0.0; dk.lifting.dim()];
    let mut f = Forecaster::new(dk.model.p).with_constraint(StateConstraint::UnitQuaternion { at: 0 });
    let mut out = vec![0.0; 40 * 7];
    // Warm up, then count.
    f.forecast(&dk.model, &dk.lifting, x, &[], Rollout::Relift, &mut out);
    let (_, st) = count(|| {
        for _ in 0..100 {
            dk.lifting.lift(x, &mut z);
        }
        f.forecast(&dk.model, &dk.lifting, x, &[], Rollout::Linear, &mut out);
        f.forecast(&dk.model, &dk.lifting, x, &[], Rollout::Relift, &mut out);
    });
    assert_eq!(st.allocs + st.reallocs, 0, "{st:?}");
    assert!(out.iter().all(|v| v.is_finite()));
}

#[test]
fn fast_tanh_matches_std_tanh() {
    let mut worst: f64 = 0.0;
    let mut x: f64 = -40.0;
    while x <= 40.0 {
        let (a, b) = (tanh_fast(x), x.tanh());
        let rel = (a - b).abs() / b.abs().max(f64::MIN_POSITIVE);
        worst = worst.max(if b == 0.0 { (a - b).abs() } else { rel });
        x += 0.000_731;
    }
    for x in [0.0f64, -0.0, 1e-300, 1e-9, 0.0625, -0.0625, 0.06249999, 710.0, -1e6, f64::INFINITY] {
        let (a, b) = (tanh_fast(x), x.tanh());
        assert!((a - b).abs() <= 1e-15 * b.abs(), "{x}: {a} vs {b}");
    }
    assert!(tanh_fast(f64::NAN).is_nan());
    assert!(worst < 1e-14, "worst relative error {worst:e}");
}

#[test]
fn constructor_rejects_bad_dimensions_and_values() {
    let ok = |n, h, l, e| {
        DeepLifting::new(n, h, l, e, &vec![0.0; n], &vec![1.0; n], &vec![0.0; param_count(n, h, l, e)])
    };
    assert!(ok(7, 32, 2, 16).is_ok());
    assert!(matches!(ok(MAX_IN + 1, 8, 1, 4), Err(LiftingError::OutOfRange { field: "n", .. })));
    assert!(matches!(ok(3, MAX_HIDDEN + 1, 1, 4), Err(LiftingError::OutOfRange { field: "hidden", .. })));
    assert!(matches!(ok(3, 8, MAX_LAYERS + 1, 4), Err(LiftingError::OutOfRange { field: "layers", .. })));
    assert!(matches!(ok(3, 8, 1, MAX_EXTRA + 1), Err(LiftingError::OutOfRange { field: "extra", .. })));
    let e = DeepLifting::new(2, 4, 1, 2, &[0.0, 0.0], &[1.0, 0.0], &vec![0.0; param_count(2, 4, 1, 2)]);
    assert!(matches!(e, Err(LiftingError::Invalid { field: "scale", index: 1 })));
    let e = DeepLifting::new(2, 4, 1, 2, &[0.0, 0.0], &[1.0, 1.0], &[0.0; 3]);
    assert!(matches!(e, Err(LiftingError::Length { field: "params", .. })));
}
