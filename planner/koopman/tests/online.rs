//! Online refinement (RLS), error bounds, constant-velocity baseline, allocation-free hot paths.

use dkrrt_koopman::debris_state::{self, nominal_rhs, pack, quat_exp, quat_mul};
use dkrrt_koopman::*;
use dkrrt_rt::alloc_count::{count, CountingAlloc};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc;

fn random_problem(seed: u64, n: usize, d: usize, q: usize, noise: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let mut r = SmallRng::seed_from_u64(seed);
    let theta: Vec<f64> = (0..q * d).map(|_| r.random_range(-1.0..1.0)).collect(); // q×d col-major
    let mut phis = Vec::new();
    let mut ys = Vec::new();
    for _ in 0..n {
        let phi: Vec<f64> = (0..d).map(|_| r.random_range(-1.0..1.0)).collect();
        for i in 0..q {
            let mut y = (0..d).map(|j| theta[j * q + i] * phi[j]).sum::<f64>();
            y += noise * r.random_range(-1.0..1.0);
            ys.push(y);
        }
        phis.extend(phi);
    }
    (theta, phis, ys)
}

#[test]
fn rls_converges_to_the_batch_least_squares_solution() {
    let (d, q, n) = (6, 4, 200);
    let (_, phis, ys) = random_problem(1, n, d, q, 0.05);
    let mut rls = Rls::new(d, q, RlsConfig { lambda: 1.0, p0: 1e8, max_trace: 1e12 });
    let mut theta = vec![0.0; q * d];
    for k in 0..n {
        let st = rls.update(&mut theta, q, &phis[k * d..(k + 1) * d], &ys[k * q..(k + 1) * q]);
        assert!(!st.reset);
    }
    let m = DMat::from_fn(n, d, |i, j| phis[i * d + j]);
    let y = DMat::from_fn(n, q, |i, j| ys[i * q + j]);
    let (batch, _) = dkrrt_koopman::linalg::lstsq(&m, &y, &LstsqOptions::default()).unwrap(); // d×q
    for i in 0..q {
        for j in 0..d {
            let (a, b) = (theta[j * q + i], batch.get(j, i));
            assert!((a - b).abs() < 1e-6, "Θ[{i},{j}]: rls {a} vs batch {b}");
        }
    }
    // P is the inverse Gram matrix (up to the 1/p0 prior).
    let gram = m.transpose().mul(&m);
    let p = DMat { rows: d, cols: d, data: rls.covariance().to_vec() };
    let should_be_i = gram.mul(&p);
    assert!(should_be_i.add_scaled(&DMat::identity(d), -1.0).max_abs() < 1e-6);
}

#[test]
fn the_covariance_stays_exactly_symmetric() {
    // The update writes P column by column without symmetrising: entries (i, j) and (j, i)
    // must come out bit for bit equal, and equal to the symmetrised update
    // (0.5·(P_ij + P_ji) − Pφ_i·Pφ_j / denom) / λ that it replaced.
    let (d, q, n) = (23, 7, 400);
    let (_, phis, ys) = random_problem(9, n, d, q, 0.1);
    let cfg = RlsConfig { lambda: 0.97, p0: 50.0, max_trace: 1e12 };
    let mut rls = Rls::new(d, q, cfg);
    let mut theta = vec![0.0; q * d];
    let mut reference = rls.covariance().to_vec();
    for k in 0..n {
        let phi = &phis[k * d..(k + 1) * d];
        let pphi: Vec<f64> =
            (0..d).map(|i| (0..d).fold(0.0, |a, j| a + reference[j * d + i] * phi[j])).collect();
        let st = rls.update(&mut theta, q, phi, &ys[k * q..(k + 1) * q]);
        assert!(!st.reset);
        let p = rls.covariance();
        let denom = cfg.lambda + phi.iter().zip(&pphi).map(|(a, b)| a * b).sum::<f64>();
        let mut next = reference.clone();
        for j in 0..d {
            for i in 0..=j {
                let v = (0.5 * (reference[j * d + i] + reference[i * d + j]) - pphi[i] * pphi[j] / denom)
                    * (1.0 / cfg.lambda);
                (next[j * d + i], next[i * d + j]) = (v, v);
            }
        }
        for i in 0..d {
            for j in 0..d {
                assert_eq!(p[j * d + i].to_bits(), p[i * d + j].to_bits(), "P[{i},{j}] after update {k}");
                // Pφ summed in the update's order (over columns): the same bits.
                assert_eq!(p[j * d + i].to_bits(), next[j * d + i].to_bits(), "P[{i},{j}] after update {k}");
            }
        }
        reference = p.to_vec();
    }
}

#[test]
fn forgetting_factor_tracks_a_change() {
    let (d, q, n) = (5, 2, 300);
    let (t1, p1, y1) = random_problem(2, n, d, q, 0.0);
    let (t2, p2, y2) = random_problem(3, n, d, q, 0.0);
    let run = |lambda: f64| {
        let mut rls = Rls::new(d, q, RlsConfig { lambda, p0: 1e4, max_trace: 1e12 });
        let mut theta = vec![0.0; q * d];
        for k in 0..n {
            rls.update(&mut theta, q, &p1[k * d..(k + 1) * d], &y1[k * q..(k + 1) * q]);
        }
        let e1 = theta.iter().zip(&t1).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        for k in 0..100 {
            rls.update(&mut theta, q, &p2[k * d..(k + 1) * d], &y2[k * q..(k + 1) * q]);
        }
        let e2 = theta.iter().zip(&t2).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        (e1, e2)
    };
    let (e1_f, e2_f) = run(0.9);
    let (e1_n, e2_n) = run(1.0);
    assert!(e1_f < 1e-6 && e1_n < 1e-6, "{e1_f} {e1_n}");
    assert!(e2_f < 1e-3, "with forgetting: {e2_f}");
    assert!(e2_n > 0.05, "without forgetting the old data dominate: {e2_n}");
}

#[test]
fn rls_guard_resets_on_blow_up_and_ignores_non_finite_data() {
    let (d, q) = (3, 1);
    let mut rls = Rls::new(d, q, RlsConfig { lambda: 0.5, p0: 1.0, max_trace: 1e3 });
    let mut theta = vec![0.5; d];
    let st = rls.update(&mut theta, q, &[f64::NAN, 0.0, 0.0], &[1.0]);
    assert!(st.reset);
    assert_eq!(theta, vec![0.5; 3]);
    // Unexciting data with strong forgetting: P grows as λ⁻ᵏ along unexcited directions.
    let mut resets = 0;
    for _ in 0..40 {
        if rls.update(&mut theta, q, &[1.0, 0.0, 0.0], &[2.0]).reset {
            resets += 1;
        }
        assert!(rls.covariance().iter().all(|v| v.is_finite()));
        let tr: f64 = (0..d).map(|i| rls.covariance()[i * d + i]).sum();
        assert!(tr <= 1e3 + 1e-9);
    }
    assert!(resets >= 1);
    assert!((theta[0] - 2.0).abs() < 1e-6);
    let p = rls.covariance();
    for i in 0..d {
        for j in 0..d {
            assert_eq!(p[i * d + j], p[j * d + i]);
        }
    }
}

#[test]
fn online_update_of_a_koopman_model_converges_to_the_true_system() {
    // Truth: damped rotation with an affine drift; model starts as the identity.
    let lift = Polynomial::new(2, 1);
    let (c, s) = (0.1f64.cos() * 0.99, 0.1f64.sin() * 0.99);
    let truth = |x: &[f64]| [c * x[0] - s * x[1] + 0.05, s * x[0] + c * x[1] - 0.02];
    let mut model = KoopmanModel::zeros(2, 3, 0, 0.1);
    for i in 0..3 {
        model.ab[i * 3 + i] = 1.0;
    }
    let mut rls = Rls::for_model(&model, RlsConfig { lambda: 0.98, p0: 1e3, max_trace: 1e9 });
    let mut r = SmallRng::seed_from_u64(4);
    let (mut z, mut zn) = ([0.0; 3], [0.0; 3]);
    let mut last_err = f64::INFINITY;
    for k in 0..300 {
        let x = [r.random_range(-1.0..1.0), r.random_range(-1.0..1.0)];
        lift.lift(&x, &mut z);
        lift.lift(&truth(&x), &mut zn);
        let st = rls.update_model(&mut model, &z, &zn);
        if k == 299 {
            last_err = st.prior_error;
        }
    }
    // The initial (identity) model's prior weight decays as λᵏ / p0.
    assert!(last_err < 1e-6, "prior error {last_err}");
    assert!(
        (model.a(0, 0) - c).abs() < 1e-6
            && (model.a(1, 0) - s).abs() < 1e-6
            && (model.a(0, 2) - 0.05).abs() < 1e-6
    );
    assert!((model.a(2, 2) - 1.0).abs() < 1e-6);
}

#[test]
fn error_bound_from_residuals_grows_and_relaxes() {
    // 100 runs × 4 steps, error at step k = (k+1) · (run / 100).
    let h = 4;
    let errs: Vec<f64> =
        (0..100).flat_map(|r| (0..h).map(move |k| (k + 1) as f64 * r as f64 / 100.0)).collect();
    let mut b = ErrorBound::from_residuals(&errs, h, 0.1, 0.9, 1.5);
    for k in 1..=h {
        let q90 = k as f64 * 0.90;
        assert!((b.radius(k) - 1.5 * q90).abs() < 0.02 * k as f64, "k={k}: {}", b.radius(k));
        if k > 1 {
            assert!(b.radius(k) >= b.radius(k - 1));
        }
    }
    let r4 = b.radius(4);
    assert!(b.exceeds(1, 3.0 * b.radius(1), 2.0) && !b.exceeds(1, 0.5 * b.radius(1), 1.0));
    b.grow(0.2, 0.5);
    assert!((b.radius(4) - (r4 + 0.2 + 0.5 * 4.0 * 0.1)).abs() < 1e-12);
    // radii() fills the same values (clamped beyond the horizon).
    let mut r = [0.0; 6];
    b.radii(&mut r);
    assert!((1..=6).all(|k| r[k - 1] == b.radius(k)), "{r:?}");
    b.relax(1e3);
    assert!((b.radius(4) - r4).abs() < 1e-9);
    assert_eq!(b.radius(100), b.radius(4)); // clamped to the horizon
}

#[test]
fn validation_errors_are_zero_for_an_exact_model_and_positive_otherwise() {
    let lift = Polynomial::new(1, 1);
    let mut model = KoopmanModel::zeros(1, 2, 0, 1.0);
    model.ab = vec![0.5, 0.0, 0.0, 1.0]; // x⁺ = 0.5 x
    let traj: Vec<f64> = (0..20).map(|k| 0.5f64.powi(k)).collect();
    let e = validation_errors(&model, &lift, &[&traj], &[], 5, Rollout::Linear, 0..1, 1);
    assert_eq!(e.len(), 15 * 5);
    assert!(e.iter().all(|v| *v < 1e-15));
    model.ab[0] = 0.6;
    let e = validation_errors(&model, &lift, &[&traj], &[], 5, Rollout::Relift, 0..1, 3);
    // Run 0 starts at x = 1: error after k steps is 0.6ᵏ − 0.5ᵏ.
    assert!((e[0] - 0.1).abs() < 1e-15 && (e[4] - (0.6f64.powi(5) - 0.5f64.powi(5))).abs() < 1e-15);
    assert_eq!(e.len(), 5 * 5); // starts 0, 3, 6, 9, 12
}

#[test]
fn constant_velocity_baseline_matches_integrated_nominal_kinematics() {
    let n = 0.00113;
    let cv = ConstantVelocity { frame_rate: n };
    let q0 = quat_exp([0.3, -0.2, 0.5]);
    let x0 = pack([1.0, 2.0, 3.0], [0.1, -0.2, 0.05], q0, [0.4, -0.7, 0.2]);
    let dt = 0.05;
    let mut out = vec![0.0; 13 * 40];
    assert_eq!(cv.forecast(&x0, dt, &mut out), 40);
    // Integrate the nominal attitude kinematics (constant ω) with fine RK4 and compare.
    let mut x: Vec<f64> = x0[debris_state::ROT].to_vec();
    let h = dt / 20.0;
    let f = |x: &[f64]| {
        let mut d = [0.0; 7];
        nominal_rhs(n, x, &mut d);
        d
    };
    for _ in 0..40 * 20 {
        let k1 = f(&x);
        let x2: Vec<f64> = (0..7).map(|i| x[i] + 0.5 * h * k1[i]).collect();
        let k2 = f(&x2);
        let x3: Vec<f64> = (0..7).map(|i| x[i] + 0.5 * h * k2[i]).collect();
        let k3 = f(&x3);
        let x4: Vec<f64> = (0..7).map(|i| x[i] + h * k3[i]).collect();
        let k4 = f(&x4);
        for i in 0..7 {
            x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
    }
    let last = &out[39 * 13..40 * 13];
    for i in 0..4 {
        assert!((last[6 + i] - x[i]).abs() < 1e-10, "q[{i}] {} vs {}", last[6 + i], x[i]);
    }
    assert!((last[0] - (1.0 + 0.1 * 2.0)).abs() < 1e-12 && (last[1] - (2.0 - 0.2 * 2.0)).abs() < 1e-12);
    let qn: f64 = last[6..10].iter().map(|v| v * v).sum();
    assert!((qn - 1.0).abs() < 1e-12);
    // Sanity of the helpers: q ⊗ q⁻¹ = 1.
    let qi = [q0[0], -q0[1], -q0[2], -q0[3]];
    let one = quat_mul(&q0, &qi);
    assert!((one[0] - 1.0).abs() < 1e-15 && one[1].abs() < 1e-15);
}

#[test]
fn quaternion_constraint_and_sign_alignment() {
    let mut q = [-0.5, -0.5, -0.5, -0.5];
    debris_state::align_quaternion(&mut q, &[0.5, 0.5, 0.5, 0.5]);
    assert_eq!(q, [0.5; 4]);
    let mut x = [0.0, 2.0, 0.0, 0.0, 0.0];
    StateConstraint::UnitQuaternion { at: 1 }.apply(&mut x);
    assert_eq!(x, [0.0, 1.0, 0.0, 0.0, 0.0]);
}

#[test]
fn hot_paths_do_not_allocate() {
    // Rotational sub-model: degree-2 polynomial on (q, ω), p = 36.
    let lift = Polynomial::new(7, 2);
    let p = lift.dim();
    let mut model = KoopmanModel::zeros(7, p, 0, 0.05);
    let mut r = SmallRng::seed_from_u64(1);
    model.ab.iter_mut().for_each(|v| *v = r.random_range(-0.05..0.05));
    for i in 0..p {
        model.ab[i * p + i] += 0.9;
    }
    let mut fc = Forecaster::new(p).with_constraint(StateConstraint::UnitQuaternion { at: 0 });
    let mut rls = Rls::for_model(&model, RlsConfig::default());
    let mut out = vec![0.0; 7 * 40];
    let mut cv_out = vec![0.0; 13 * 40];
    let x0 = [0.9, 0.1, 0.3, 0.2, 0.1, -0.2, 0.3];
    let mut z = vec![0.0; p];
    let mut zn = vec![0.0; p];
    let mut bound = ErrorBound::constant(40, 0.05, 0.1);
    let cv = ConstantVelocity { frame_rate: 0.001 };
    let x13 = pack([1.0; 3], [0.1; 3], [1.0, 0.0, 0.0, 0.0], [0.1; 3]);
    let (_, stats) = count(|| {
        for k in 0..50 {
            fc.forecast(&model, &lift, &x0, &[], Rollout::Relift, &mut out);
            fc.forecast(&model, &lift, &x0, &[], Rollout::Linear, &mut out);
            lift.lift(&x0, &mut z);
            fc.forecast_lifted(&model, &z, &[], &mut out);
            lift.lift(&out[..7], &mut zn);
            rls.update_model(&mut model, &z, &zn);
            cv.forecast(&x13, 0.05, &mut cv_out);
            bound.grow(0.01, 0.0);
            bound.relax(0.05);
            std::hint::black_box(bound.radius(k % 40 + 1));
        }
    });
    assert_eq!((stats.allocs, stats.reallocs, stats.deallocs), (0, 0, 0), "{stats:?}");
    assert!(out.iter().all(|v| v.is_finite()));
}
