//! Batch fits: EDMD / DMDc exact recovery, dictionaries, dual-data scheme and its ablation.

use dkrrt_koopman::*;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

fn rng() -> SmallRng {
    SmallRng::seed_from_u64(7)
}

fn matvec(m: &[[f64; 3]; 3], x: &[f64]) -> [f64; 3] {
    let mut y = [0.0; 3];
    for i in 0..3 {
        for j in 0..3 {
            y[i] += m[i][j] * x[j];
        }
    }
    y
}

const M3: [[f64; 3]; 3] = [[0.9, 0.2, 0.0], [-0.1, 0.95, 0.05], [0.02, 0.0, 0.8]];

#[test]
fn sparse_polynomial_and_attitude_dictionary() {
    let p = Polynomial::from_monomials(3, &[vec![1, 0], vec![2, 2, 1], vec![0, 1, 1]]);
    let mut out = vec![0.0; p.dim()];
    p.lift(&[2.0, 3.0, 5.0], &mut out);
    assert_eq!(out, vec![2.0, 3.0, 5.0, 1.0, 6.0, 75.0, 18.0]);
    let a = debris_state::attitude_dictionary();
    assert_eq!(a.dim(), 26);
    let mut z = vec![0.0; 26];
    a.lift(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0], &mut z);
    assert_eq!(&z[8..11], &[5.0, 6.0, 7.0]); // q0·ω
    assert_eq!(&z[20..26], &[25.0, 30.0, 35.0, 36.0, 42.0, 49.0]); // ω_i ω_j
}

#[test]
fn polynomial_dictionary_layout() {
    let p = Polynomial::new(13, 2);
    assert_eq!(p.dim(), 13 + 1 + 91);
    assert_eq!(Polynomial::new(3, 3).dim(), 3 + 1 + 6 + 10);
    let mut out = vec![0.0; 10];
    Polynomial::new(3, 2).lift(&[2.0, 3.0, 5.0], &mut out);
    assert_eq!(out, vec![2.0, 3.0, 5.0, 1.0, 4.0, 6.0, 10.0, 9.0, 15.0, 25.0]);
    let mut out = vec![0.0; 10];
    Polynomial::new(3, 2).with_scale(&[2.0, 1.0, 5.0]).lift(&[2.0, 3.0, 5.0], &mut out);
    assert_eq!(out, vec![2.0, 3.0, 5.0, 1.0, 1.0, 3.0, 1.0, 9.0, 3.0, 1.0]);
}

/// Finite-difference reference for the analytic `lift_derivative`s.
struct Fd<'a>(&'a dyn Lifting);
impl Lifting for Fd<'_> {
    fn state_dim(&self) -> usize {
        self.0.state_dim()
    }
    fn dim(&self) -> usize {
        self.0.dim()
    }
    fn lift(&self, x: &[f64], out: &mut [f64]) {
        self.0.lift(x, out)
    }
}

#[test]
fn analytic_lift_derivatives_match_finite_differences() {
    let mut r = rng();
    let centres: Vec<f64> = (0..12).map(|_| r.random_range(-1.0..1.0)).collect();
    let dicts: Vec<Box<dyn Lifting>> = vec![
        Box::new(Polynomial::new(3, 3).with_scale(&[1.0, 2.0, 0.5])),
        Box::new(Rbf::new(3, centres.clone(), RbfKind::Gaussian { sigma: 0.7 })),
        Box::new(Rbf::new(3, centres, RbfKind::ThinPlate).with_scale(&[1.0, 2.0, 1.0])),
        Box::new(Fourier::new(vec![1.0, 2.0, 0.5], 3)),
        // Sparse: degree-3 monomial whose prefix is absent (generic path) and one whose is present.
        Box::new(
            Polynomial::from_monomials(3, &[vec![0, 1], vec![2, 2, 1], vec![0, 1, 1]])
                .with_scale(&[1.0, 3.0, 0.5]),
        ),
    ];
    for d in &dicts {
        let p = d.dim();
        for _ in 0..5 {
            let x: Vec<f64> = (0..3).map(|_| r.random_range(-1.5..1.5)).collect();
            let v: Vec<f64> = (0..3).map(|_| r.random_range(-1.0..1.0)).collect();
            let (mut a, mut b) = (vec![0.0; p], vec![0.0; p]);
            d.lift_derivative(&x, &v, &mut a);
            Fd(d.as_ref()).lift_derivative(&x, &v, &mut b);
            for i in 0..p {
                assert!((a[i] - b[i]).abs() < 1e-6 * (1.0 + a[i].abs()), "entry {i}: {} vs {}", a[i], b[i]);
            }
            assert_eq!(&a[..3], &v[..]);
        }
    }
}

#[test]
fn edmd_recovers_linear_system_exactly_in_quadratic_dictionary() {
    // x⁺ = M x: the span of all monomials of degree ≤ 2 is invariant, so EDMD is exact.
    let lift = Polynomial::new(3, 2);
    let mut data = Snapshots::new(3, 0);
    let mut r = rng();
    for _ in 0..60 {
        let x: Vec<f64> = (0..3).map(|_| r.random_range(-1.0..1.0)).collect();
        data.push(&x, &matvec(&M3, &x), &[]);
    }
    let (model, rank) = fit_edmd(&lift, &data, 0.1, &LstsqOptions::default()).unwrap();
    assert_eq!(rank, lift.dim());
    for i in 0..3 {
        for j in 0..lift.dim() {
            let want = if j < 3 { M3[i][j] } else { 0.0 };
            assert!((model.a(i, j) - want).abs() < 1e-10, "A[{i},{j}] = {}", model.a(i, j));
        }
    }
    // Linear roll-out in the lifted space reproduces the lifted true trajectory.
    let x0 = [0.7, -0.4, 0.9];
    let mut z0 = vec![0.0; lift.dim()];
    lift.lift(&x0, &mut z0);
    let mut fc = Forecaster::new(lift.dim());
    let mut out = vec![0.0; 3 * 25];
    assert_eq!(fc.forecast_lifted(&model, &z0, &[], &mut out), 25);
    let mut x = x0.to_vec();
    for k in 0..25 {
        x = matvec(&M3, &x).to_vec();
        for i in 0..3 {
            assert!((out[k * 3 + i] - x[i]).abs() < 1e-9, "step {k}");
        }
    }
}

#[test]
fn edmd_state_rows_exact_for_nonlinear_map_in_span_and_relift_forecast_is_exact() {
    // x1⁺ = a x1, x2⁺ = b x2 + c x1²: nonlinear, but x⁺ lies in span{x, x²}.
    let (a, b, c) = (0.9, 0.5, 0.3);
    let f = |x: &[f64]| [a * x[0], b * x[1] + c * x[0] * x[0]];
    let lift = Polynomial::new(2, 2);
    let mut data = Snapshots::new(2, 0);
    let mut r = rng();
    for _ in 0..40 {
        let x = [r.random_range(-1.0..1.0), r.random_range(-1.0..1.0)];
        data.push(&x, &f(&x), &[]);
    }
    let (model, _) = fit_edmd(&lift, &data, 1.0, &LstsqOptions::default()).unwrap();
    let mut fc = Forecaster::new(lift.dim());
    let mut out = vec![0.0; 2 * 30];
    fc.forecast(&model, &lift, &[0.8, -0.6], &[], Rollout::Relift, &mut out);
    let mut x = [0.8, -0.6];
    for k in 0..30 {
        x = f(&x);
        assert!((out[2 * k] - x[0]).abs() < 1e-10 && (out[2 * k + 1] - x[1]).abs() < 1e-10, "step {k}");
    }
    // Plain DMD (linear dictionary) cannot represent it.
    let (dmd, _) = fit_dmdc(&data, 1.0, &LstsqOptions::default()).unwrap();
    let mut out2 = vec![0.0; 2 * 30];
    Forecaster::new(3).forecast(&dmd, &Polynomial::new(2, 1), &[0.8, -0.6], &[], Rollout::Relift, &mut out2);
    let err_dmd = (out2[1] - f(&[0.8, -0.6])[1]).abs();
    assert!(err_dmd > 1e-3, "DMD unexpectedly exact: {err_dmd}");
}

#[test]
fn fourier_dictionary_is_exact_for_translations() {
    // x⁺ = x + s: sin/cos harmonics are mapped linearly into themselves.
    let s = [0.3, -0.2];
    let lift = Fourier::new(vec![1.0, 0.5], 2);
    let mut data = Snapshots::new(2, 0);
    let mut r = rng();
    for _ in 0..40 {
        let x = [r.random_range(-3.0..3.0), r.random_range(-3.0..3.0)];
        data.push(&x, &[x[0] + s[0], x[1] + s[1]], &[]);
    }
    let (model, _) = fit_edmd(&lift, &data, 1.0, &LstsqOptions::default()).unwrap();
    let mut z0 = vec![0.0; lift.dim()];
    lift.lift(&[1.0, 2.0], &mut z0);
    let mut out = vec![0.0; 2 * 10];
    Forecaster::new(lift.dim()).forecast_lifted(&model, &z0, &[], &mut out);
    for k in 0..10 {
        let t = (k + 1) as f64;
        assert!((out[2 * k] - (1.0 + t * s[0])).abs() < 1e-8);
        assert!((out[2 * k + 1] - (2.0 + t * s[1])).abs() < 1e-8);
    }
}

#[test]
fn rbf_edmd_beats_dmd_on_a_nonlinear_system() {
    let f = |x: &[f64]| [x[0] + 0.1 * x[1], x[1] + 0.1 * (-x[0].sin() - 0.1 * x[1])]; // pendulum
    let mut r = rng();
    let mut data = Snapshots::new(2, 0);
    let mut test = Snapshots::new(2, 0);
    for i in 0..600 {
        let x = [r.random_range(-2.5..2.5), r.random_range(-2.0..2.0)];
        if i < 500 {
            data.push(&x, &f(&x), &[]);
        } else {
            test.push(&x, &f(&x), &[]);
        }
    }
    let centres: Vec<f64> = (0..2 * 40)
        .map(|i| if i % 2 == 0 { r.random_range(-2.5..2.5) } else { r.random_range(-2.0..2.0) })
        .collect();
    let rbf = Rbf::new(2, centres, RbfKind::Gaussian { sigma: 0.8 });
    let lin = Polynomial::new(2, 1);
    let opts = LstsqOptions { rel_tol: 1e-10, ..Default::default() };
    let err = |l: &dyn Lifting| {
        let (m, _) = fit_edmd(l, &data, 0.1, &opts).unwrap();
        let mut fc = Forecaster::new(l.dim());
        let mut out = [0.0; 2];
        let mut e = 0.0;
        for k in 0..test.len() {
            let (x, y, _) = test.get(k);
            fc.forecast(&m, l, x, &[], Rollout::Relift, &mut out);
            e += (out[0] - y[0]).powi(2) + (out[1] - y[1]).powi(2);
        }
        (e / test.len() as f64).sqrt()
    };
    let (e_rbf, e_lin) = (err(&rbf), err(&lin));
    assert!(e_rbf < 0.1 * e_lin, "rbf {e_rbf} vs dmd {e_lin}");
}

#[test]
fn dmdc_recovers_a_and_b() {
    let bm = [0.5, -1.0, 0.25];
    let mut r = rng();
    let mut data = Snapshots::new(3, 1);
    for _ in 0..30 {
        let x: Vec<f64> = (0..3).map(|_| r.random_range(-1.0..1.0)).collect();
        let u = r.random_range(-1.0..1.0);
        let mut y = matvec(&M3, &x);
        for i in 0..3 {
            y[i] += bm[i] * u;
        }
        data.push(&x, &y, &[u]);
    }
    let (model, _) = fit_dmdc(&data, 0.1, &LstsqOptions::default()).unwrap();
    assert_eq!((model.p, model.m), (4, 1));
    for i in 0..3 {
        assert!((model.b(i, 0) - bm[i]).abs() < 1e-10);
        for j in 0..3 {
            assert!((model.a(i, j) - M3[i][j]).abs() < 1e-10);
        }
        assert!(model.a(i, 3).abs() < 1e-10); // no spurious affine term
    }
    assert!((model.a(3, 3) - 1.0).abs() < 1e-10); // constant observable stays 1
}

#[test]
fn fit_rejects_bad_data() {
    let mut d = Snapshots::new(2, 0);
    assert!(matches!(fit_dmdc(&d, 0.1, &LstsqOptions::default()), Err(FitError::NotEnoughData(_))));
    d.push(&[f64::NAN, 0.0], &[0.0, 0.0], &[]);
    assert!(matches!(fit_dmdc(&d, 0.1, &LstsqOptions::default()), Err(FitError::NonFinite(_))));
    assert!(matches!(
        fit_edmd(&Polynomial::new(3, 1), &d, 0.1, &LstsqOptions::default()),
        Err(FitError::Dim(_))
    ));
}

#[test]
fn expm_and_truncated_lstsq() {
    let w = 2.0;
    let a = DMat::from_fn(2, 2, |i, j| match (i, j) {
        (0, 1) => w,
        (1, 0) => -w,
        _ => 0.0,
    });
    let e = a.scale(1.3).expm();
    let (s, c) = (w * 1.3f64).sin_cos();
    assert!(
        (e.get(0, 0) - c).abs() < 1e-13 && (e.get(0, 1) - s).abs() < 1e-13 && (e.get(1, 0) + s).abs() < 1e-13
    );
    let big = DMat::from_fn(1, 1, |_, _| 20.0).expm();
    assert!((big.get(0, 0) / 20f64.exp() - 1.0).abs() < 1e-12);
    // Rank-deficient regressor: duplicated column → minimum-norm solution splits the weight.
    let m = DMat::from_fn(10, 2, |i, _| i as f64 + 1.0);
    let y = DMat::from_fn(10, 1, |i, _| 2.0 * (i as f64 + 1.0));
    let (x, rank) = dkrrt_koopman::linalg::lstsq(&m, &y, &LstsqOptions::default()).unwrap();
    assert_eq!(rank, 1);
    assert!((x.get(0, 0) - 1.0).abs() < 1e-12 && (x.get(1, 0) - 1.0).abs() < 1e-12);
}

// ---------- dual-data scheme ----------

/// Harmonic oscillator nominal `ẋ1 = x2, ẋ2 = −ω² x1`; the "true" system adds an unmodelled
/// constant acceleration `bias` (affine, so exactly representable with `[x, 1]`).
const OMEGA: f64 = 1.5;
fn nominal(x: &[f64], _u: &[f64], dx: &mut [f64]) {
    dx[0] = x[1];
    dx[1] = -OMEGA * OMEGA * x[0];
}
fn true_step(x: &[f64], bias: f64, dt: f64) -> [f64; 2] {
    // Exact flow of ẍ = −ω² x + b: shift the equilibrium to b/ω².
    let e = bias / (OMEGA * OMEGA);
    let (s, c) = (OMEGA * dt).sin_cos();
    let y0 = x[0] - e;
    [e + y0 * c + x[1] / OMEGA * s, -y0 * OMEGA * s + x[1] * c]
}
fn collocation(n: usize) -> Vec<f64> {
    let mut r = SmallRng::seed_from_u64(11);
    (0..2 * n).map(|_| r.random_range(-2.0..2.0)).collect()
}
fn rollout_error(model: &KoopmanModel, lift: &dyn Lifting, bias: f64, dt: f64) -> f64 {
    let mut out = vec![0.0; 2 * 40];
    Forecaster::new(lift.dim()).forecast(model, lift, &[1.0, 0.0], &[], Rollout::Linear, &mut out);
    let mut x = [1.0, 0.0];
    let mut e: f64 = 0.0;
    for k in 0..40 {
        x = true_step(&x, bias, dt);
        e = e.max(((out[2 * k] - x[0]).powi(2) + (out[2 * k + 1] - x[1]).powi(2)).sqrt());
    }
    e
}

#[test]
fn generator_from_collocation_reproduces_the_nominal_flow() {
    let lift = Polynomial::new(2, 1);
    let gen = fit_generator(&lift, &collocation(50), &[], 0, nominal, &LstsqOptions::default()).unwrap();
    let dt = 0.1;
    let fit =
        fit_dual(&lift, &gen, &Snapshots::new(2, 0), dt, DualVariant::NominalOnly, &LstsqOptions::default())
            .unwrap();
    assert!(rollout_error(&fit.model, &lift, 0.0, dt) < 1e-12);
    assert_eq!(fit.h, DMat::identity(3));
}

#[test]
fn correction_is_identity_when_nominal_is_exact() {
    let lift = Polynomial::new(2, 2);
    let gen = fit_generator(&lift, &collocation(80), &[], 0, nominal, &LstsqOptions::default()).unwrap();
    let dt = 0.1;
    let mut traj = Snapshots::new(2, 0);
    let mut x = [1.0, 0.3];
    for _ in 0..50 {
        let y = true_step(&x, 0.0, dt);
        traj.push(&x, &y, &[]);
        x = y;
    }
    let fit = fit_dual(&lift, &gen, &traj, dt, DualVariant::Corrected, &LstsqOptions::default()).unwrap();
    // Degree-2 monomials of a linear flow stay degree-2: the generator is exact, so H = I.
    assert!(fit.h.add_scaled(&DMat::identity(lift.dim()), -1.0).max_abs() < 1e-7, "{:?}", fit.h);
}

#[test]
fn dual_data_ablation_correction_fixes_unmodelled_bias_and_beats_edmd_on_scarce_data() {
    let (lift, dt, bias) = (Polynomial::new(2, 1), 0.1, 0.4);
    let gen = fit_generator(&lift, &collocation(50), &[], 0, nominal, &LstsqOptions::default()).unwrap();
    // Only 2 observed transitions (fewer than the 3 lifted dimensions).
    let mut traj = Snapshots::new(2, 0);
    let mut x = [0.5, 0.2];
    for _ in 0..2 {
        let y = true_step(&x, bias, dt);
        traj.push(&x, &y, &[]);
        x = y;
    }
    let opts = LstsqOptions::default();
    let nominal_only = fit_dual(&lift, &gen, &traj, dt, DualVariant::NominalOnly, &opts).unwrap();
    let corrected = fit_dual(&lift, &gen, &traj, dt, DualVariant::Corrected, &opts).unwrap();
    let (edmd, _) = fit_edmd(&lift, &traj, dt, &opts).unwrap();
    let e_nom = rollout_error(&nominal_only.model, &lift, bias, dt);
    let e_cor = rollout_error(&corrected.model, &lift, bias, dt);
    let e_edmd = rollout_error(&edmd, &lift, bias, dt);
    // Rank-deficient data: EDMD's minimum-norm solution is useless, the correction (shrunk
    // towards H = I) improves on the nominal model.
    assert!(e_nom > 0.1, "bias should hurt the nominal model: {e_nom}");
    assert!(e_cor < 0.9 * e_nom, "corrected {e_cor} vs nominal {e_nom}");
    assert!(e_cor < 0.2 * e_edmd, "corrected {e_cor} vs EDMD {e_edmd}");
    // Few noisy samples with Tikhonov regularisation: the correction shrinks towards the
    // nominal model, EDMD towards zero.
    let noisy_traj = |ns: usize, sigma: f64| {
        let mut r = SmallRng::seed_from_u64(5);
        let mut traj = Snapshots::new(2, 0);
        let mut x = [0.5, 0.2];
        let noisy = |v: &[f64; 2], r: &mut SmallRng| {
            [v[0] + sigma * (r.random::<f64>() - 0.5) * 3.46, v[1] + sigma * (r.random::<f64>() - 0.5) * 3.46]
        };
        for _ in 0..ns {
            let y = true_step(&x, bias, dt);
            traj.push(&noisy(&x, &mut r), &noisy(&y, &mut r), &[]);
            x = y;
        }
        traj
    };
    let traj6 = noisy_traj(6, 1e-3);
    let ridge = LstsqOptions { ridge: 1e-2, ..opts };
    let e_cor = rollout_error(
        &fit_dual(&lift, &gen, &traj6, dt, DualVariant::Corrected, &ridge).unwrap().model,
        &lift,
        bias,
        dt,
    );
    let e_edmd_r = rollout_error(&fit_edmd(&lift, &traj6, dt, &ridge).unwrap().0, &lift, bias, dt);
    let e_edmd = rollout_error(&fit_edmd(&lift, &traj6, dt, &opts).unwrap().0, &lift, bias, dt);
    assert!(
        e_cor < 0.3 * e_edmd_r && e_cor < 0.3 * e_edmd,
        "corrected {e_cor}, EDMD {e_edmd} / ridge {e_edmd_r}"
    );
    // Without regularisation and with full-rank data, K H K = Θ′Θ† is exactly the EDMD
    // solution (K is invertible): the scheme only differs from EDMD through regularisation.
    let traj20 = noisy_traj(20, 1e-3);
    let c = fit_dual(&lift, &gen, &traj20, dt, DualVariant::Corrected, &opts).unwrap().model;
    let e = fit_edmd(&lift, &traj20, dt, &opts).unwrap().0;
    let diff = c.ab.iter().zip(&e.ab).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(diff < 1e-8, "dual vs EDMD differ by {diff}");
    // With enough trajectory data the correction becomes exact.
    let mut traj = Snapshots::new(2, 0);
    let mut x = [0.5, 0.2];
    for _ in 0..30 {
        let y = true_step(&x, bias, dt);
        traj.push(&x, &y, &[]);
        x = y;
    }
    let corrected = fit_dual(&lift, &gen, &traj, dt, DualVariant::Corrected, &opts).unwrap();
    assert!(rollout_error(&corrected.model, &lift, bias, dt) < 1e-9);
}

#[test]
fn dual_data_with_control_input_matches_exact_discretisation() {
    // ẋ = −a x + u (zero-order hold): x⁺ = e^{−a dt} x + (1 − e^{−a dt})/a · u.
    let a = 0.7;
    let lift = Polynomial::new(1, 1);
    let mut r = rng();
    let xs: Vec<f64> = (0..40).map(|_| r.random_range(-2.0..2.0)).collect();
    let us: Vec<f64> = (0..40).map(|_| r.random_range(-1.0..1.0)).collect();
    let gen =
        fit_generator(&lift, &xs, &us, 1, |x, u, dx| dx[0] = -a * x[0] + u[0], &LstsqOptions::default())
            .unwrap();
    let dt = 0.2;
    let fit =
        fit_dual(&lift, &gen, &Snapshots::new(1, 1), dt, DualVariant::NominalOnly, &LstsqOptions::default())
            .unwrap();
    let e = (-a * dt).exp();
    assert!((fit.model.a(0, 0) - e).abs() < 1e-12);
    assert!((fit.model.b(0, 0) - (1.0 - e) / a).abs() < 1e-12);
}

#[test]
fn nominal_translational_model_is_clohessy_wiltshire() {
    let n = 0.00113;
    let lift = Polynomial::new(6, 1);
    let mut r = rng();
    let xs: Vec<f64> = (0..6 * 30).map(|_| r.random_range(-10.0..10.0)).collect();
    let gen = fit_generator(
        &lift,
        &xs,
        &[],
        0,
        |x, _, dx| debris_state::nominal_rhs(n, x, dx),
        &LstsqOptions::default(),
    )
    .unwrap();
    let dt = 0.5;
    let fit =
        fit_dual(&lift, &gen, &Snapshots::new(6, 0), dt, DualVariant::NominalOnly, &LstsqOptions::default())
            .unwrap();
    let (x0, v0) = ([3.0, -2.0, 1.0], [0.01, -0.02, 0.005]);
    let mut out = vec![0.0; 6 * 100];
    Forecaster::new(7).forecast(
        &fit.model,
        &lift,
        &[x0[0], x0[1], x0[2], v0[0], v0[1], v0[2]],
        &[],
        Rollout::Linear,
        &mut out,
    );
    let t = 100.0 * dt;
    let (s, c) = (n * t).sin_cos();
    let x = 4.0 * x0[0] - 3.0 * x0[0] * c + v0[0] / n * s + 2.0 * v0[1] / n * (1.0 - c);
    let y =
        x0[1] + 6.0 * x0[0] * (s - n * t) - 2.0 * v0[0] / n * (1.0 - c) + v0[1] / n * (4.0 * s - 3.0 * n * t);
    let z = x0[2] * c + v0[2] / n * s;
    let k = 99 * 6;
    assert!((out[k] - x).abs() < 1e-9 && (out[k + 1] - y).abs() < 1e-9 && (out[k + 2] - z).abs() < 1e-9);
}

#[test]
fn exp_fast_matches_std_exp_within_a_few_ulp() {
    let mut r = rng();
    let mut worst: f64 = 0.0;
    for i in 0..200_000 {
        let x = if i % 2 == 0 { -50.0 * r.random::<f64>() } else { 1400.0 * r.random::<f64>() - 700.0 };
        let (a, b) = (exp_fast(x), x.exp());
        worst = worst.max((a - b).abs() / b);
    }
    assert!(worst < 5e-16, "max relative error {worst:e}");
    assert_eq!(exp_fast(0.0), 1.0);
    assert!(exp_fast(-1e4) < 1e-300 && exp_fast(-1e4) >= 0.0);
}

#[test]
fn rbf_lift_equals_the_definition() {
    let mut r = rng();
    let (n, k) = (7, 24);
    let centres: Vec<f64> = (0..n * k).map(|_| r.random::<f64>() - 0.5).collect();
    let scale: Vec<f64> = (0..n).map(|i| 0.2 + 0.1 * i as f64).collect();
    for kind in [RbfKind::Gaussian { sigma: 1.5 }, RbfKind::ThinPlate] {
        let rbf = Rbf::new(n, centres.clone(), kind).with_scale(&scale);
        let mut out = vec![0.0; rbf.dim()];
        for _ in 0..100 {
            let x: Vec<f64> = (0..n).map(|_| r.random::<f64>() - 0.5).collect();
            rbf.lift(&x, &mut out);
            assert_eq!(&out[..n], &x[..]);
            assert_eq!(out[n], 1.0);
            for (c, cen) in centres.chunks_exact(n).enumerate() {
                let r2: f64 = (0..n).map(|i| ((x[i] - cen[i]) / scale[i]).powi(2)).sum();
                let want = match kind {
                    RbfKind::Gaussian { sigma } => (-r2 / (2.0 * sigma * sigma)).exp(),
                    RbfKind::ThinPlate => 0.5 * r2 * r2.ln(),
                };
                assert!((out[n + 1 + c] - want).abs() < 1e-13 * (1.0 + want.abs()), "{kind:?} centre {c}");
            }
        }
    }
}
