//! f_θ: crops, targets, fixed-array inference against candle's training graph, the Koopman
//! re-solve against plain least squares, a training run whose loss falls, the model file's
//! errors, and allocation-free inference.

use dkrrt_msg::{DepthImage, Zeroed};
use dkrrt_rt::alloc_count::{count, CountingAlloc};
use dkrrt_visual::file::{from_bytes, to_bytes, VisualFileError};
use dkrrt_visual::train::{
    candle_forward, initial, resolve_koopman, train, Sample, Sequence, VisualTrainConfig,
};
use dkrrt_visual::{decode, targets, FrameScan, LearnedAxes, View, CROP, N_OBS, N_OUT, P, SURE};

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc;

const ID: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

fn rot_z(a: f64) -> [[f64; 3]; 3] {
    let (s, c) = a.sin_cos();
    [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
}

fn angle(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).abs().min(1.0).acos()
}

#[test]
fn targets_are_the_axes_a_shape_defines_and_decode_recovers_them() {
    // A box with half extents 0.6 (x), 0.15 (y), 0.05 (z), turned 0.4 rad about z.
    let r = rot_z(0.4);
    let y = targets(&ID, &r, &[0.6, 0.15, 0.05]);
    let (seen, lam) = decode(&y);
    assert!(angle(&seen.long.unwrap(), &[0.4f64.cos(), 0.4f64.sin(), 0.0]) < 1e-9);
    assert!(angle(&seen.short.unwrap(), &[0.0, 0.0, 1.0]) < 1e-9);
    assert!((lam[0] - 1.0).abs() < 1e-9 && (lam[1] - 1.0).abs() < 1e-9);
    // A rod (capsule along z): the long axis only; the short one is anywhere in the plane.
    let (seen, lam) = decode(&targets(&ID, &ID, &[0.05, 0.05, 1.05]));
    assert!(angle(&seen.long.unwrap(), &[0.0, 0.0, 1.0]) < 1e-9);
    assert!(seen.short.is_none() && (lam[1] - 0.5).abs() < 1e-9 && lam[1] < SURE);
    // A square panel: its normal only. A ball: nothing.
    let (seen, _) = decode(&targets(&ID, &ID, &[0.5, 0.5, 0.005]));
    assert!(seen.long.is_none() && angle(&seen.short.unwrap(), &[0.0, 0.0, 1.0]) < 1e-9);
    let (seen, lam) = decode(&targets(&ID, &ID, &[0.3, 0.3, 0.3]));
    assert!(seen.long.is_none() && seen.short.is_none() && (lam[0] - 1.0 / 3.0).abs() < 1e-9);
    // Camera axes: a camera turned 0.4 rad about z sees the turned box's long axis along x.
    let (seen, _) = decode(&targets(&r, &r, &[0.6, 0.15, 0.05]));
    assert!(angle(&seen.long.unwrap(), &[1.0, 0.0, 0.0]) < 1e-9);
}

/// A 128 × 96 frame with instance 1 a horizontal bar of 40 × 6 pixels at 5 m, tilted in depth.
fn bar_frame() -> Box<DepthImage> {
    let mut img = Box::new(<DepthImage as Zeroed>::zeroed());
    img.width = 128;
    img.height = 96;
    img.focal_px = 100.0;
    img.cx = 64.0;
    img.cy = 48.0;
    img.orientation = [1.0, 0.0, 0.0, 0.0];
    img.range_min_m = 0.1;
    img.range_max_m = 20.0;
    img.n_instances = 1;
    img.ids[0] = 42;
    for v in 45..51 {
        for u in 44..84 {
            let k = v * 128 + u;
            img.instance[k] = 1;
            img.depth_mm[k] = (5000 + (u as i32 - 64) * 10) as u16;
        }
    }
    img
}

#[test]
fn a_crop_is_square_about_the_object_with_its_depth_relief() {
    let img = bar_frame();
    let mut scan = FrameScan::default();
    scan.scan(&img);
    let mut v = View::default();
    assert!(scan.crop(&img, 1, &mut v));
    assert!(!scan.crop(&img, 2, &mut v.clone()), "no pixel of instance 2");
    let (mask, depth) = v.px.split_at(CROP * CROP);
    let rows: Vec<f32> = (0..CROP).map(|i| mask[i * CROP..(i + 1) * CROP].iter().sum()).collect();
    let cols: Vec<f32> = (0..CROP).map(|j| (0..CROP).map(|i| mask[i * CROP + j]).sum()).collect();
    let (nr, nc) = (rows.iter().filter(|r| **r > 0.0).count(), cols.iter().filter(|c| **c > 0.0).count());
    assert!(nc > 4 * nr && nc >= CROP * 3 / 4, "a wide bar: {nr} rows, {nc} columns");
    // Depth grows to the right about the mean.
    let row = CROP / 2;
    let d: Vec<f32> =
        (0..CROP).filter(|j| mask[row * CROP + j] > 0.0).map(|j| depth[row * CROP + j]).collect();
    assert!(d.first().unwrap() < &-0.05 && d.last().unwrap() > &0.05, "{d:?}");
    // Width in metres: 40 px · 1.15 + 2 px at 5 m and f = 100 px.
    assert!((v.scalars[0] as f64 - (48.0f64 * 5.0 / 100.0).ln()).abs() < 0.05, "{:?}", v.scalars);
}

fn random_view(seed: u32) -> View {
    let mut v = View::default();
    let mut x = seed.wrapping_mul(2654435761);
    for p in v.px.iter_mut() {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        *p = (x % 1000) as f32 / 500.0 - 1.0;
    }
    v.scalars = [0.3, -0.1, 0.2];
    v
}

#[test]
fn fixed_array_inference_matches_the_candle_training_graph() {
    let mut net = initial(3).unwrap();
    let (cur, prev) = (random_view(1), random_view(2));
    let mut out = [0.0; N_OUT];
    net.forward(&cur, &prev, &mut out);
    let reference = candle_forward(&net, &cur, &prev).unwrap();
    for (a, b) in out.iter().zip(&reference) {
        assert!((a - b).abs() <= 1e-4 * (1.0 + b.abs()), "{out:?} vs {reference:?}");
    }
    assert!(out.iter().any(|v| v.abs() > 1e-3), "a non-trivial output");
}

#[test]
fn the_koopman_re_solve_is_plain_least_squares() {
    // Features of 3 sequences; K from the solver vs the normal equations.
    let n = 60;
    let mut f = vec![0.0; n * N_OUT];
    let mut x = 12345u64;
    for v in f.iter_mut() {
        x = x.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        *v = ((x >> 33) as f64 / (1u64 << 31) as f64) - 0.5;
    }
    let pairs: Vec<u32> = (0..n as u32 - 1).filter(|i| i % 20 != 19).collect();
    let k = resolve_koopman(&f, &pairs, 0.0).unwrap();
    let z = |i: usize| nalgebra::DVector::from_fn(P, |j, _| if j == N_OUT { 1.0 } else { f[i * N_OUT + j] });
    let mut a = nalgebra::DMatrix::<f64>::zeros(P, P);
    let mut b = nalgebra::DMatrix::<f64>::zeros(P, P);
    for &i in &pairs {
        let (z0, z1) = (z(i as usize), z(i as usize + 1));
        a += &z0 * z0.transpose();
        b += &z1 * z0.transpose();
    }
    let k_ref = b * a.try_inverse().unwrap(); // K = Z1 Z0ᵀ (Z0 Z0ᵀ)⁻¹
    for i in 0..N_OUT {
        for j in 0..P {
            assert!(
                (k[i * P + j] - k_ref[(i, j)]).abs() < 1e-8,
                "K[{i}][{j}] {} vs {}",
                k[i * P + j],
                k_ref[(i, j)]
            );
        }
    }
    // The constant's row is e_c.
    assert!((0..P).all(|j| k[N_OUT * P + j] == if j == N_OUT { 1.0 } else { 0.0 }));
    assert!(resolve_koopman(&f, &pairs[..5], 0.0).is_err(), "too few pairs");
}

/// Sequences of a bar turning in the image plane: the view shows its angle, the target is
/// its axis.
fn turning_bars(n_seq: usize, len: usize, seed: u64) -> Vec<Sequence> {
    let mut out = Vec::new();
    for s in 0..n_seq {
        let phi0 = (seed as f64 * 0.37 + s as f64 * 1.3) % std::f64::consts::PI;
        let w = 0.05 + 0.02 * (s % 5) as f64;
        let mut seq = Sequence::default();
        for t in 0..len {
            let phi = phi0 + w * t as f64;
            let (sn, cs) = phi.sin_cos();
            let mut v = View::default();
            for i in 0..CROP {
                for j in 0..CROP {
                    let (x, y) = (j as f64 - 11.5, i as f64 - 11.5);
                    let along = x * cs + y * sn;
                    let across = -x * sn + y * cs;
                    if along.abs() < 10.0 && across.abs() < 1.5 {
                        v.px[i * CROP + j] = 1.0;
                    }
                }
            }
            let r = rot_z(phi);
            let y = targets(&ID, &r, &[1.0, 0.1, 0.1]);
            seq.samples.push(Sample { view: v, y: std::array::from_fn(|i| y[i] as f32) });
        }
        out.push(seq);
    }
    out
}

#[test]
fn training_lowers_the_multi_step_loss_on_held_out_sequences() {
    let (tr, va) = (turning_bars(24, 30, 1), turning_bars(6, 30, 2));
    let cfg =
        VisualTrainConfig { epochs: 6, resolve_every: 2, max_windows: 2000, ..VisualTrainConfig::default() };
    let mut seen = 0;
    let (mut net, rep) = train(&tr, &va, &cfg, &mut |p| {
        seen += 1;
        assert!(p.train_loss.is_finite() && p.valid_loss.is_finite());
    })
    .unwrap();
    assert_eq!(seen, 6);
    let best = rep.valid_loss[rep.best_epoch - 1];
    assert!(rep.best_epoch >= 1 && best < 0.5 * rep.initial_valid_loss, "{rep:?}");
    assert_eq!(rep.valid_rmse.len(), cfg.horizon + 1);
    // The trained f_θ reads a held-out bar's axis.
    let s = &va[0].samples[10];
    let mut out = [0.0; N_OUT];
    net.forward(&s.view, &va[0].samples[9].view, &mut out);
    let (seen, _) = decode(&out[..N_OBS]);
    let truth = decode(&s.y.map(|v| v as f64)).0.long.unwrap();
    assert!(angle(&seen.long.expect("a sure long axis"), &truth) < 0.3, "{out:?}");
    // Bad data is refused.
    let mut bad = turning_bars(2, 10, 3);
    bad[1].samples[4].y[0] = f32::NAN;
    assert!(train(&bad, &[], &cfg, &mut |_| {}).unwrap_err().to_string().contains("sequence 1, sample 4"));
}

#[test]
fn the_model_file_round_trips_and_its_errors_name_the_field() {
    let net = initial(5).unwrap();
    let bytes = to_bytes(&net);
    assert_eq!(from_bytes(&bytes).unwrap(), net);
    let err = |b: &[u8]| from_bytes(b).unwrap_err();
    let mut b = bytes.clone();
    b[0] = b'X';
    assert!(matches!(err(&b), VisualFileError::BadMagic(_)));
    let mut b = bytes.clone();
    b[8] = 9;
    assert_eq!(err(&b), VisualFileError::UnsupportedVersion { found: 9 });
    assert!(matches!(err(&bytes[..bytes.len() - 3]), VisualFileError::LengthMismatch { .. }));
    let mut b = bytes.clone();
    let mid = b.len() / 2;
    b[mid] ^= 0x40;
    assert!(matches!(err(&b), VisualFileError::Checksum { .. }));
    // A file of another architecture (c1 = 9), with a valid checksum.
    let reseal = |mut b: Vec<u8>| {
        let n = b.len() - 8;
        let sum = dkrrt_deep::file::fnv1a64(&b[..n]);
        b[n..].copy_from_slice(&sum.to_le_bytes());
        b
    };
    let mut b = bytes.clone();
    b[20 + 8..20 + 12].copy_from_slice(&9u32.to_le_bytes());
    let e = err(&reseal(b));
    assert!(e.to_string().starts_with("arch.c1: the file has 9"), "{e}");
    // A NaN weight in w2.
    let mut b = bytes.clone();
    let at = 20 + 36 + 4 * (dkrrt_visual::PARAM_SIZES[0] + dkrrt_visual::PARAM_SIZES[1]) + 8;
    b[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    assert_eq!(err(&reseal(b)), VisualFileError::NonFinite { field: "w2", index: 2 });
    let path = std::env::temp_dir().join(format!("dkrrt-visual-{}.dkv", std::process::id()));
    std::fs::write(&path, b"short").unwrap();
    let e = dkrrt_visual::file::load(&path).unwrap_err();
    assert!(e.contains(&path.display().to_string()) && e.contains("magic"), "{e}");
    let _ = std::fs::remove_file(&path);
}

#[test]
fn inference_allocates_nothing_after_construction() {
    let img = bar_frame();
    let mut axes = LearnedAxes::new(initial(7).unwrap());
    let mut out = [0.0; N_OUT];
    let mut img2 = img.clone();
    assert!(axes.features(&img, 1, 42, &mut out)); // warm-up: the object is remembered
    let ((), stats) = count(|| {
        for k in 1..20u64 {
            img2.header.stamp_ns = k * 50_000_000;
            assert!(axes.features(&img2, 1, 42, &mut out));
        }
    });
    assert_eq!(stats.allocs, 0, "{stats:?}");
    assert!(out.iter().all(|v| v.is_finite()));
}
