//! Prediction methods, their fitted models, and the allocation-free roll-out engine.
//!
//! Every method predicts the 13-state of [`dkrrt_koopman::debris_state`]. Koopman methods use
//! two decoupled models (the koopman crate's design): translation on `[p, v, 1]` (p = 7) and
//! attitude on `(q, ω)` with either the sparse bilinear/quadratic polynomial dictionary
//! (`attitude_dictionary`, p = 26) or a Gaussian RBF dictionary; both rolled out in relift mode
//! with the quaternion renormalised every step.

use crate::events::{first_event_step, EventAllowance, Sample};
use crate::filter::quat_angle;
use crate::kernels::{self, ROWS};
use dkrrt_deep::{DeepKoopman, DeepLifting};
use dkrrt_koopman::debris_state::{self, attitude_dictionary, nominal_rhs, N};
use dkrrt_koopman::{
    fit_dual, fit_edmd, fit_generator, ConstantVelocity, DualVariant, ErrorBound, FitError, KoopmanModel,
    Lifting, LstsqOptions, Polynomial, Rbf, RbfKind, Rollout, Snapshots, MAX_HORIZON,
};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use serde::Serialize;

/// Prediction method (for the accuracy study and for selecting the online predictor).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub enum Method {
    /// Straight line + constant body rate from the filtered state (baseline).
    ConstantVelocity,
    /// EDMD, polynomial dictionaries (translation `[x,1]`, attitude sparse degree 2), fixed.
    EdmdPoly,
    /// EDMD, translation `[x,1]`, attitude Gaussian RBF dictionary, fixed.
    EdmdRbf,
    /// [`Method::EdmdPoly`] refined online per track by RLS, bounds grown after events.
    KoopmanOnline,
    /// The paper's dual-data scheme (nominal CW + attitude-kinematics generator, correction
    /// `H` learned from trajectories with ridge), refined online per track by RLS.
    DualData,
    /// Deep Koopman attitude model (`dkrrt-deep`: `φ(q, ω) = [q, ω, NN(q, ω)]`, trained on
    /// simulated tumbling, linear roll-out in the lifted space) + the dual-data translation
    /// model; fixed.
    DeepKoopman,
    /// [`Method::DeepKoopman`] refined online per track: RLS on all rows of the lifted
    /// attitude model (targets `φ(x⁺)`) and on the translation state rows.
    DeepKoopmanOnline,
}

impl Method {
    /// All methods of the study.
    pub const ALL: [Method; 7] = [
        Method::ConstantVelocity,
        Method::EdmdPoly,
        Method::EdmdRbf,
        Method::KoopmanOnline,
        Method::DualData,
        Method::DeepKoopman,
        Method::DeepKoopmanOnline,
    ];
    /// The methods that need no trained deep model.
    pub const CLASSIC: [Method; 5] = [
        Method::ConstantVelocity,
        Method::EdmdPoly,
        Method::EdmdRbf,
        Method::KoopmanOnline,
        Method::DualData,
    ];
    /// Short name (study tables, CLI).
    pub fn name(&self) -> &'static str {
        match self {
            Method::ConstantVelocity => "constant-velocity",
            Method::EdmdPoly => "edmd-poly",
            Method::EdmdRbf => "edmd-rbf",
            Method::KoopmanOnline => "koopman-online",
            Method::DualData => "dual-data",
            Method::DeepKoopman => "deep-koopman",
            Method::DeepKoopmanOnline => "deep-koopman-online",
        }
    }
    /// Parse a [`Method::name`].
    pub fn from_name(s: &str) -> Option<Method> {
        Method::ALL.iter().copied().find(|m| m.name() == s)
    }
    /// Whether the models are refined online by RLS.
    pub fn online(&self) -> bool {
        matches!(self, Method::KoopmanOnline | Method::DualData | Method::DeepKoopmanOnline)
    }
    /// Whether the method's forecasts include the predictor's physical attitude channels: a
    /// rod's axis by torque-free precession ([`crate::axis`]) and a box's attitude by Euler's
    /// equations ([`crate::euler`]), each calibrated online. The online Koopman methods (ours)
    /// do; the baselines (constant velocity, fixed EDMD) forecast attitude with their model
    /// alone.
    pub fn attitude_physics(&self) -> bool {
        self.online()
    }
    /// Whether the method needs a trained deep Koopman model ([`Models::fit_with_deep`]).
    pub fn deep(&self) -> bool {
        matches!(self, Method::DeepKoopman | Method::DeepKoopmanOnline)
    }
    /// Whether the method uses Koopman models (everything but the baseline).
    pub fn koopman(&self) -> bool {
        !matches!(self, Method::ConstantVelocity)
    }
}

/// Attitude dictionary (closed set, so the lifting is `Clone` and needs no trait object).
#[derive(Debug, Clone)]
pub enum AttitudeLifting {
    /// Polynomial (e.g. [`attitude_dictionary`]).
    Poly(Polynomial),
    /// Gaussian radial basis functions.
    Rbf(GaussianRbf),
    /// Learned MLP lifting of `dkrrt-deep` (boxed: fixed parameter arrays).
    Deep(Box<DeepLifting>),
}

impl AttitudeLifting {
    /// [`Lifting::lift`], the deep lifting compiled for AVX2 where the CPU has it (the same
    /// operations in the same order: bit-identical, `kernels::tests::deep_lift_equals_reference_bitwise`).
    #[inline]
    pub fn lift_fast(&self, x: &[f64], out: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        if let AttitudeLifting::Deep(l) = self {
            if std::is_x86_feature_detected!("avx2") {
                // SAFETY: AVX2 checked at run time just above.
                return unsafe { kernels::avx2::deep_lift(l, x, out) };
            }
        }
        self.lift(x, out)
    }
}

impl Lifting for AttitudeLifting {
    fn state_dim(&self) -> usize {
        match self {
            AttitudeLifting::Poly(l) => l.state_dim(),
            AttitudeLifting::Rbf(l) => l.state_dim(),
            AttitudeLifting::Deep(l) => l.state_dim(),
        }
    }
    fn dim(&self) -> usize {
        match self {
            AttitudeLifting::Poly(l) => l.dim(),
            AttitudeLifting::Rbf(l) => l.dim(),
            AttitudeLifting::Deep(l) => l.dim(),
        }
    }
    #[inline]
    fn lift(&self, x: &[f64], out: &mut [f64]) {
        match self {
            AttitudeLifting::Poly(l) => l.lift(x, out),
            AttitudeLifting::Rbf(l) => l.lift(x, out),
            AttitudeLifting::Deep(l) => l.lift(x, out),
        }
    }
    fn lift_derivative(&self, x: &[f64], xdot: &[f64], out: &mut [f64]) {
        match self {
            AttitudeLifting::Poly(l) => l.lift_derivative(x, xdot, out),
            AttitudeLifting::Rbf(l) => l.lift_derivative(x, xdot, out),
            AttitudeLifting::Deep(l) => l.lift_derivative(x, xdot, out),
        }
    }
}

/// Gaussian RBF dictionary of the attitude state `(q, ω)` (n = 7):
/// `[x, 1, exp(−‖(x − c_k) ⊘ s‖² / (2σ²)) for each centre c_k]`.
///
/// Wraps the reference [`Rbf`] of `dkrrt-koopman` (used by the fits, [`Lifting::lift`] and
/// `observe`) and keeps the scaled centres in blocks of 4 for the roll-out [`Engine`], whose
/// lift computes 4 centres per vector and all 7 coordinates in registers. The squared
/// distances are bit-identical to the reference; the exponential is
/// [`dkrrt_koopman::exp_fast`] without FMA in every code path (the reference uses FMA where
/// the CPU has it: ≤ 1 ulp apart).
#[derive(Debug, Clone)]
pub struct GaussianRbf {
    rbf: Rbf,
    k: usize,
    inv_scale: [f64; 7],
    /// `cs[(b·7 + i)·4 + l] = c_{4b+l}[i] / s_i` (the last block padded with copies of the
    /// last centre; padded lanes are never stored).
    cs: Vec<f64>,
    /// `−1 / (2σ²)`.
    g: f64,
}

impl GaussianRbf {
    /// `centres` is `k × 7` row-major (k ≥ 1), `scale` the per-coordinate distance scale.
    pub fn new(centres: Vec<f64>, scale: &[f64], sigma: f64) -> Self {
        assert!(!centres.is_empty() && centres.len().is_multiple_of(7), "GaussianRbf: centres must be k × 7");
        assert_eq!(scale.len(), 7, "GaussianRbf: scale must have 7 entries");
        let k = centres.len() / 7;
        let mut inv_scale = [0.0; 7];
        for i in 0..7 {
            inv_scale[i] = 1.0 / scale[i];
        }
        let nb = k.div_ceil(4);
        let mut cs = vec![0.0; nb * 28];
        for b in 0..nb {
            for i in 0..7 {
                for l in 0..4 {
                    let c = (4 * b + l).min(k - 1);
                    cs[(b * 7 + i) * 4 + l] = centres[c * 7 + i] * inv_scale[i];
                }
            }
        }
        let rbf = Rbf::new(7, centres, RbfKind::Gaussian { sigma }).with_scale(scale);
        GaussianRbf { rbf, k, inv_scale, cs, g: -1.0 / (2.0 * sigma * sigma) }
    }
    /// The reference dictionary.
    pub fn rbf(&self) -> &Rbf {
        &self.rbf
    }
    /// Number of centres.
    pub fn n_centres(&self) -> usize {
        self.k
    }
    /// The engine's lift (see the type's documentation) of `T` states at once (block by
    /// block, the lanes' independent chains interleaved): `out[t][..8 + k]` from `x[t][..7]`;
    /// with `AVX` (only from code compiled with the `avx2` feature) the bit-identical AVX2
    /// kernels.
    #[inline(always)]
    fn lift_blocks<const AVX: bool, const T: usize>(&self, x: &[[f64; ROWS]; T], out: &mut [Vec<f64>]) {
        let k = self.k;
        let out: &mut [Vec<f64>; T] = (&mut out[..T]).try_into().unwrap();
        let mut xs = [[0.0; 7]; T];
        for t in 0..T {
            let o = &mut out[t][..8 + k];
            o[..7].copy_from_slice(&x[t][..7]);
            o[7] = 1.0;
            for i in 0..7 {
                xs[t][i] = x[t][i] * self.inv_scale[i];
            }
        }
        let full = k / 4;
        let blocks = self.cs.chunks_exact(28).map(|b| -> &[f64; 28] { b.try_into().unwrap() });
        #[cfg(target_arch = "x86_64")]
        if AVX {
            use std::arch::x86_64::_mm256_storeu_pd;
            // SAFETY: `AVX` is only set by `Engine::roll_avx2` (AVX2 checked at run time);
            // the stores write `out[t][8 + 4b..12 + 4b]`, `b < k / 4`.
            unsafe {
                for (b, blk) in blocks.enumerate() {
                    let es = kernels::avx2::rbf_lanes::<T>(&xs, blk, self.g);
                    for (t, &e) in es.iter().enumerate() {
                        if b < full {
                            _mm256_storeu_pd(out[t][8 + 4 * b..12 + 4 * b].as_mut_ptr(), e);
                        } else {
                            let mut v = [0.0; 4];
                            _mm256_storeu_pd(v.as_mut_ptr(), e);
                            out[t][8 + 4 * b..8 + k].copy_from_slice(&v[..k - 4 * b]);
                        }
                    }
                }
            }
            return;
        }
        for (b, blk) in blocks.enumerate() {
            for t in 0..T {
                let e = kernels::rbf_block(&xs[t], blk, self.g);
                let m = (k - 4 * b).min(4);
                out[t][8 + 4 * b..8 + 4 * b + m].copy_from_slice(&e[..m]);
            }
        }
    }
}

impl Lifting for GaussianRbf {
    fn state_dim(&self) -> usize {
        7
    }
    fn dim(&self) -> usize {
        8 + self.k
    }
    #[inline]
    fn lift(&self, x: &[f64], out: &mut [f64]) {
        self.rbf.lift(x, out)
    }
    fn lift_derivative(&self, x: &[f64], xdot: &[f64], out: &mut [f64]) {
        self.rbf.lift_derivative(x, xdot, out)
    }
}

/// Training data on the model time grid: segments of filtered state estimates of one object
/// at consecutive grid times `t0 + k·dt`, plus the true state over the same grid extended by
/// the horizon (NaN where unknown) for the error bounds.
#[derive(Debug, Clone, Default)]
pub struct TrainingSet {
    /// Grid step [s].
    pub dt: f64,
    /// Horizon `H` (steps) covered by `truth` beyond the end of `est`.
    pub horizon: usize,
    /// Segments.
    pub segments: Vec<Segment>,
}

/// One contiguous run of estimates of one object.
#[derive(Debug, Clone, Default)]
pub struct Segment {
    /// Debris id.
    pub id: u32,
    /// Time of `est[0]` [s].
    pub t0: f64,
    /// Filtered estimates at `t0 + k dt`.
    pub est: Vec<[f64; N]>,
    /// True states at `t0 + k dt`, `k < est.len() + horizon` (NaN rows where unknown).
    pub truth: Vec<[f64; N]>,
    /// Times of the events that acted on the object within `truth`'s span (impulses, splits:
    /// [`crate::eval::Recording::events`]), ascending.
    pub events: Vec<f64>,
}

impl TrainingSet {
    /// Number of consecutive estimate pairs.
    pub fn n_pairs(&self) -> usize {
        self.segments.iter().map(|s| s.est.len().saturating_sub(1)).sum()
    }
}

/// Fitting parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FitConfig {
    /// Model step [s].
    pub dt: f64,
    /// Forecast horizon (steps, ≤ 128).
    pub horizon: usize,
    /// LVLH frame rotation rate (mean motion) [rad/s].
    pub frame_rate: f64,
    /// Relative SVD truncation of the EDMD fits.
    pub rel_tol: f64,
    /// RBF: number of centres (drawn from the training states).
    pub rbf_centres: usize,
    /// RBF: Gaussian width in units of the per-coordinate data spread.
    pub rbf_sigma: f64,
    /// Dual-data: number of collocation points for the nominal generator.
    pub collocation: usize,
    /// Dual-data: ridge of the correction, per training pair (λ = `dual_ridge` · N), used
    /// when `dual_ridge_auto` is off (or the data have fewer than 8 segments).
    pub dual_ridge: f64,
    /// Dual-data: choose the ridge of each model from [`DUAL_RIDGES`] by validation on a
    /// quarter of the training segments.
    pub dual_ridge_auto: bool,
    /// Error bound: quantile of the validation errors.
    pub bound_quantile: f64,
    /// Error bound: margin factor.
    pub bound_margin: f64,
    /// Error bound: start stride (grid points) of the validation forecasts.
    pub bound_stride: usize,
    /// Error bound: the share of all forecasts that may miss through events no forecast can
    /// foresee (impulses, splits), half of the 1 % a 99 % bound may miss. Where events fall
    /// into more of the training forecasts than this, the bound covers them
    /// ([`crate::events`]).
    pub event_budget: f64,
    /// Seed (RBF centres, collocation points).
    pub seed: u64,
    /// Attitude roll-out of the deep methods: [`Rollout::Linear`] (lifted-linear, what the
    /// deep model is trained for; online RLS on all rows towards `φ(x⁺)`) or
    /// [`Rollout::Relift`] (`x⁺ = (A φ(x))[..7]`, RLS on the state rows).
    #[serde(skip)]
    pub deep_rollout: Rollout,
}

impl Default for FitConfig {
    fn default() -> Self {
        FitConfig {
            dt: 0.1,
            horizon: 40,
            frame_rate: 1.1314e-3,
            rel_tol: 1e-10,
            rbf_centres: 24,
            rbf_sigma: 1.5,
            collocation: 2000,
            dual_ridge: 1e-2,
            dual_ridge_auto: true,
            bound_quantile: 0.99,
            bound_margin: 1.5,
            bound_stride: 5,
            event_budget: 0.005,
            seed: 1,
            deep_rollout: Rollout::Linear,
        }
    }
}

/// Fitted models of one method plus its per-horizon error bounds.
#[derive(Debug, Clone)]
pub struct Models {
    /// Method.
    pub method: Method,
    /// Model step [s].
    pub dt: f64,
    /// Forecast horizon (steps).
    pub horizon: usize,
    /// LVLH frame rotation rate [rad/s].
    pub frame_rate: f64,
    /// Translational dictionary `[p, v, 1]`.
    pub trans_lift: Polynomial,
    /// Attitude dictionary.
    pub att_lift: AttitudeLifting,
    /// Translational model (n = 6).
    pub trans: KoopmanModel,
    /// Attitude model (n = 7).
    pub att: KoopmanModel,
    /// Roll-out of the attitude model: [`Rollout::Relift`] for the dictionaries (EDMD /
    /// dual-data), [`Rollout::Linear`] for the deep model (trained for lifted-linear
    /// multi-step prediction).
    pub att_rollout: Rollout,
    /// Position error bound [m] per step.
    pub pos_bound: ErrorBound,
    /// Attitude error bound [rad] per step.
    pub att_bound: ErrorBound,
    /// Per-step allowance for events (impulses, splits) that no forecast foresees
    /// ([`crate::events`]): the least a calibrated bound may be.
    pub events: EventAllowance,
    /// Dual-data correction ridge per training pair actually used, translation and attitude
    /// (`∞` = nominal generator alone; NaN where the method has no dual-data model).
    pub dual_ridge: [f64; 2],
}

impl Models {
    /// Constant-velocity baseline with constant error bounds (no data needed).
    pub fn constant_velocity(
        dt: f64,
        horizon: usize,
        frame_rate: f64,
        pos_radius: f64,
        att_radius: f64,
    ) -> Self {
        let trans_lift = Polynomial::new(6, 1);
        let att_lift = AttitudeLifting::Poly(attitude_dictionary());
        Models {
            method: Method::ConstantVelocity,
            dt,
            horizon,
            frame_rate,
            trans: KoopmanModel::zeros(6, trans_lift.dim(), 0, dt),
            att: KoopmanModel::zeros(7, att_lift.dim(), 0, dt),
            trans_lift,
            att_lift,
            att_rollout: Rollout::Relift,
            pos_bound: ErrorBound::constant(horizon, dt, pos_radius),
            att_bound: ErrorBound::constant(horizon, dt, att_radius),
            events: EventAllowance::none(horizon),
            dual_ridge: [f64::NAN; 2],
        }
    }

    /// Fit `method` on `data` (grid step must equal `cfg.dt`). Error bounds from validation
    /// forecasts on the same data against the true states. Deep methods need
    /// [`Models::fit_with_deep`].
    pub fn fit(method: Method, data: &TrainingSet, cfg: &FitConfig) -> Result<Models, FitError> {
        Self::fit_with_deep(method, data, cfg, None)
    }

    /// [`Models::fit`] for every method: the deep methods take their attitude model from
    /// `deep` (a trained `dkrrt-deep` model on the 7-d state `(q, ω)`, e.g.
    /// [`crate::training::TrainedModels::attitude`]) and fit the dual-data translation model
    /// on `data`; `deep` is ignored by the other methods.
    pub fn fit_with_deep(
        method: Method,
        data: &TrainingSet,
        cfg: &FitConfig,
        deep: Option<&DeepKoopman>,
    ) -> Result<Models, FitError> {
        assert!((1..=MAX_HORIZON).contains(&cfg.horizon), "horizon must be in 1..=128");
        if (data.dt - cfg.dt).abs() > 1e-9 {
            return Err(FitError::Dim(format!("training grid dt {} != model dt {}", data.dt, cfg.dt)));
        }
        let mut st = Snapshots::new(6, 0);
        let mut sa = Snapshots::new(7, 0);
        for seg in &data.segments {
            for w in seg.est.windows(2) {
                st.push(&w[0][debris_state::TRANS], &w[1][debris_state::TRANS], &[]);
                let mut y = [0.0; 7];
                y.copy_from_slice(&w[1][debris_state::ROT]);
                debris_state::align_quaternion(&mut y[0..4], &w[0][debris_state::QUAT]);
                sa.push(&w[0][debris_state::ROT], &y, &[]);
            }
        }
        if st.len() < 30 {
            return Err(FitError::NotEnoughData(format!("{} training pairs (need ≥ 30)", st.len())));
        }
        let mut m = Models::constant_velocity(cfg.dt, cfg.horizon, cfg.frame_rate, 0.0, 0.0);
        m.method = method;
        let opts = LstsqOptions { rel_tol: cfg.rel_tol, ..Default::default() };
        let mut rng = SmallRng::seed_from_u64(cfg.seed);
        match method {
            Method::ConstantVelocity => {}
            Method::EdmdPoly | Method::KoopmanOnline => {
                m.trans = fit_edmd(&m.trans_lift, &st, cfg.dt, &opts)?.0;
                m.att = fit_edmd(&m.att_lift, &sa, cfg.dt, &opts)?.0;
            }
            Method::EdmdRbf => {
                m.trans = fit_edmd(&m.trans_lift, &st, cfg.dt, &opts)?.0;
                // Per-coordinate spread of the attitude states; centres drawn from the data.
                let nn = sa.len();
                let mut mean = [0.0; 7];
                let mut var = [0.0; 7];
                for k in 0..nn {
                    for i in 0..7 {
                        mean[i] += sa.x[k * 7 + i] / nn as f64;
                    }
                }
                for k in 0..nn {
                    for i in 0..7 {
                        var[i] += (sa.x[k * 7 + i] - mean[i]).powi(2) / nn as f64;
                    }
                }
                let scale: Vec<f64> = var.iter().map(|v| v.sqrt().max(1e-3)).collect();
                let mut centres = Vec::with_capacity(cfg.rbf_centres * 7);
                for _ in 0..cfg.rbf_centres {
                    let k = rng.random_range(0..nn);
                    centres.extend_from_slice(&sa.x[k * 7..(k + 1) * 7]);
                }
                m.att_lift = AttitudeLifting::Rbf(GaussianRbf::new(centres, &scale, cfg.rbf_sigma));
                m.att = fit_edmd(&m.att_lift, &sa, cfg.dt, &opts)?.0;
            }
            Method::DeepKoopman | Method::DeepKoopmanOnline => {
                let Some(dk) = deep else {
                    return Err(FitError::Dim(format!(
                        "{} needs a trained deep Koopman model (training::train_models or TrainedModels::load)",
                        method.name()
                    )));
                };
                if dk.model.n != 7 || dk.lifting.state_dim() != 7 || dk.model.m != 0 {
                    return Err(FitError::Dim(format!(
                        "deep model has state dimension {} (inputs {}), the attitude model needs 7 (q, ω) and none",
                        dk.model.n, dk.model.m
                    )));
                }
                if (dk.model.dt - cfg.dt).abs() > 1e-9 {
                    return Err(FitError::Dim(format!(
                        "deep model dt {} != model dt {}",
                        dk.model.dt, cfg.dt
                    )));
                }
                (m.trans, m.dual_ridge[0]) = fit_dual_part(&m.trans_lift, data, Part::Trans, cfg, &mut rng)?;
                m.att_lift = AttitudeLifting::Deep(Box::new(dk.lifting.clone()));
                m.att = dk.model.clone();
                m.att_rollout = cfg.deep_rollout;
            }
            Method::DualData => {
                (m.trans, m.dual_ridge[0]) = fit_dual_part(&m.trans_lift, data, Part::Trans, cfg, &mut rng)?;
                (m.att, m.dual_ridge[1]) = fit_dual_part(&m.att_lift, data, Part::Rot, cfg, &mut rng)?;
            }
        }
        m.fit_bounds(data, cfg);
        Ok(m)
    }

    /// (Re)compute the per-horizon bounds from validation forecasts on `data` vs truth.
    pub fn fit_bounds(&mut self, data: &TrainingSet, cfg: &FitConfig) {
        let h = self.horizon;
        let mut eng = Engine::new(self);
        let mut out = vec![0.0; h * N];
        let (mut ep, mut ea, mut first) = (Vec::new(), Vec::new(), Vec::new());
        for seg in &data.segments {
            let mut s = 0;
            while s < seg.est.len() {
                if seg.truth.len() > s + h && seg.truth[s + 1..=s + h].iter().all(|r| r[0].is_finite()) {
                    first.push(first_event_step(&seg.events, seg.t0 + s as f64 * data.dt, data.dt, h));
                    eng.run(self, &self.trans, &self.att, &seg.est[s], h, &mut out);
                    for k in 0..h {
                        let (xh, xt) = (&out[k * N..(k + 1) * N], &seg.truth[s + k + 1]);
                        let dp = (0..3).map(|i| (xh[i] - xt[i]).powi(2)).sum::<f64>().sqrt();
                        ep.push(dp);
                        ea.push(quat_angle(&xh[6..10], &xt[6..10]));
                    }
                }
                s += cfg.bound_stride.max(1);
            }
        }
        let sane = |v: &mut Vec<f64>| v.iter_mut().for_each(|e| *e = if e.is_finite() { *e } else { 1e3 });
        sane(&mut ep);
        sane(&mut ea);
        if !ep.is_empty() {
            self.pos_bound =
                ErrorBound::from_residuals(&ep, h, self.dt, cfg.bound_quantile, cfg.bound_margin);
            self.att_bound =
                ErrorBound::from_residuals(&ea, h, self.dt, cfg.bound_quantile, cfg.bound_margin);
            let samples = first.iter().zip(ep.chunks_exact(h).zip(ea.chunks_exact(h)));
            self.events = EventAllowance::fit(
                samples.map(|(&first_event, (pos, att))| Sample { first_event, pos, att }),
                h,
                cfg.event_budget,
                cfg.bound_margin,
            );
        }
    }
}

/// Copy the `n ≤ 8` state rows of `[A B]` (column-major) into `dst` as `p` columns of
/// [`ROWS`] entries (zero padded): `dst[j·8 + i] = A[i, j]`.
fn load_state_rows(model: &KoopmanModel, dst: &mut [f64]) {
    let (n, p) = (model.n, model.p);
    assert!(n <= ROWS);
    // Whole 8-entry columns built in registers (no per-column memcpy / memset calls).
    for (d, col) in dst[..p * ROWS].chunks_exact_mut(ROWS).zip(model.ab.chunks_exact(p)) {
        let mut v = [0.0; ROWS];
        match n {
            6 => v[..6].copy_from_slice(&col[..6]),
            7 => v[..7].copy_from_slice(&col[..7]),
            _ => {
                for i in 0..n {
                    v[i] = col[i];
                }
            }
        }
        d.copy_from_slice(&v);
    }
}

/// [`kernels::state_rows`], with `AVX` (only from code compiled with the `avx2` feature) its
/// bit-identical AVX2 version.
#[inline(always)]
fn state_rows_times<const AVX: bool>(cols: &[f64], z: &[f64]) -> [f64; ROWS] {
    #[cfg(target_arch = "x86_64")]
    if AVX {
        // SAFETY: `AVX` is only set by `Engine::roll_avx2` (AVX2 checked at run time).
        return unsafe { kernels::avx2::state_rows(cols, z) };
    }
    kernels::state_rows(cols, z)
}

/// Dual-data translation model (nominal CW generator from collocation points around the
/// training states + ridge correction), as in [`Method::DualData`].
/// Ridge candidates (per training pair) of the dual-data correction `H`; `∞` = the nominal
/// generator alone (`H = I`).
pub const DUAL_RIDGES: [f64; 7] = [1e-3, 1e-2, 1e-1, 1.0, 10.0, 100.0, f64::INFINITY];

/// Which sub-state a dual-data model predicts.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Part {
    Trans,
    Rot,
}

impl Part {
    fn n(self) -> usize {
        match self {
            Part::Trans => 6,
            Part::Rot => 7,
        }
    }
    fn of(self, x: &[f64; N]) -> &[f64] {
        match self {
            Part::Trans => &x[debris_state::TRANS],
            Part::Rot => &x[debris_state::ROT],
        }
    }
}

/// Consecutive estimate pairs of `segs` for one part (quaternion of the successor aligned).
fn snapshots<'a>(segs: impl Iterator<Item = &'a Segment>, part: Part) -> Snapshots {
    let mut sn = Snapshots::new(part.n(), 0);
    for seg in segs {
        for w in seg.est.windows(2) {
            let mut y = [0.0; 7];
            y[..part.n()].copy_from_slice(part.of(&w[1]));
            if part == Part::Rot {
                debris_state::align_quaternion(&mut y[0..4], &w[0][debris_state::QUAT]);
            }
            sn.push(part.of(&w[0]), &y[..part.n()], &[]);
        }
    }
    sn
}

/// Validation score of a relift model of one part: median over start points (every
/// `bound_stride` grid points with the truth known) of the summed error at 1/4, 1/2 and the
/// whole horizon (position [m] or attitude angle [rad]) against the true state.
fn validation_score(
    lift: &dyn Lifting,
    model: &KoopmanModel,
    segs: &[&Segment],
    part: Part,
    cfg: &FitConfig,
) -> f64 {
    let h = cfg.horizon;
    let checks = [(h / 4).max(1), (h / 2).max(1), h];
    let n = part.n();
    let mut phi = vec![0.0; lift.dim()];
    let mut scores = Vec::new();
    for seg in segs {
        let mut s = 0;
        while s < seg.est.len() {
            if seg.truth.len() > s + h && seg.truth[s + 1..=s + h].iter().all(|r| r[0].is_finite()) {
                let mut x = [0.0; 7];
                x[..n].copy_from_slice(part.of(&seg.est[s]));
                let mut e = 0.0;
                for k in 1..=h {
                    lift.lift(&x[..n], &mut phi);
                    let mut xn = [0.0; 7];
                    model.step_rows(n, &phi, &[], &mut xn[..n]);
                    if part == Part::Rot {
                        let qn = xn[..4].iter().map(|v| v * v).sum::<f64>().sqrt();
                        xn[..4].iter_mut().for_each(|v| *v /= qn);
                    }
                    x = xn;
                    if checks.contains(&k) {
                        let t = part.of(&seg.truth[s + k]);
                        e += match part {
                            Part::Trans => (0..3).map(|i| (x[i] - t[i]).powi(2)).sum::<f64>().sqrt(),
                            Part::Rot => quat_angle(&x[..4], &t[..4]),
                        };
                    }
                }
                // A diverging candidate scores as the worst.
                scores.push(if e.is_finite() { e } else { f64::INFINITY });
            }
            s += cfg.bound_stride.max(1);
        }
    }
    if scores.is_empty() {
        return f64::INFINITY;
    }
    scores.sort_by(|a, b| a.total_cmp(b));
    scores[scores.len() / 2]
}

/// Dual-data model of one part: nominal generator (Clohessy–Wiltshire translation / attitude
/// kinematics with `ω̇ = 0`) from collocation points around the training states, plus the
/// correction `H` with its ridge chosen from [`DUAL_RIDGES`] by the validation score on every
/// fourth segment (fit on the others), then refitted on all pairs. With fewer than 8
/// segments, or `cfg.dual_ridge_auto == false`, the ridge is `cfg.dual_ridge`.
/// Returns the model and the chosen ridge.
fn fit_dual_part(
    lift: &dyn Lifting,
    data: &TrainingSet,
    part: Part,
    cfg: &FitConfig,
    rng: &mut SmallRng,
) -> Result<(KoopmanModel, f64), FitError> {
    let all = snapshots(data.segments.iter(), part);
    let nn = all.len();
    let n = part.n();
    let opts = LstsqOptions { rel_tol: cfg.rel_tol, ..Default::default() };
    let nc = cfg.collocation.max(50);
    let mut xc = Vec::with_capacity(nc * n);
    for _ in 0..nc {
        let k = rng.random_range(0..nn);
        let mut a = [0.0; 7];
        for i in 0..n {
            a[i] = all.x[k * n + i] + 0.1 * (rng.random::<f64>() - 0.5);
        }
        if part == Part::Rot {
            let qn = a[..4].iter().map(|v| v * v).sum::<f64>().sqrt();
            a[..4].iter_mut().for_each(|v| *v /= qn);
        }
        xc.extend_from_slice(&a[..n]);
    }
    let w = cfg.frame_rate;
    let gen = fit_generator(lift, &xc, &[], 0, |x, _, dx| nominal_rhs(w, x, dx), &opts)?;
    let fit = |sn: &Snapshots, lambda: f64| -> Result<KoopmanModel, FitError> {
        if lambda.is_infinite() {
            return Ok(fit_dual(lift, &gen, sn, cfg.dt, DualVariant::NominalOnly, &opts)?.model);
        }
        let ridge = LstsqOptions { rel_tol: cfg.rel_tol, ridge: lambda * sn.len() as f64, max_rank: None };
        Ok(fit_dual(lift, &gen, sn, cfg.dt, DualVariant::Corrected, &ridge)?.model)
    };
    let mut lambda = cfg.dual_ridge;
    if cfg.dual_ridge_auto && data.segments.len() >= 8 {
        let train =
            snapshots(data.segments.iter().enumerate().filter(|(i, _)| i % 4 != 0).map(|(_, s)| s), part);
        let valid: Vec<&Segment> = data.segments.iter().step_by(4).collect();
        let mut best = (f64::INFINITY, lambda);
        for &l in &DUAL_RIDGES {
            let score = validation_score(lift, &fit(&train, l)?, &valid, part, cfg);
            if score < best.0 {
                best = (score, l);
            }
        }
        lambda = best.1;
    }
    Ok((fit(&all, lambda)?, lambda))
}

/// Copy a column-major `p × p` matrix into columns padded to `pp = p` rounded up to 4 (zero
/// rows), so the lifted step runs on whole 4-wide vectors. Returns `pp`.
fn load_lifted(model: &KoopmanModel, dst: &mut [f64]) -> usize {
    let p = model.p;
    let pp = p.next_multiple_of(4);
    let full = p / 4;
    // Fixed-size pieces (no per-column memcpy / memset calls).
    for (d, col) in dst[..p * pp].chunks_exact_mut(pp).zip(model.ab.chunks_exact(p)) {
        for (dc, cc) in d[..4 * full].chunks_exact_mut(4).zip(col.chunks_exact(4)) {
            let cc: &[f64; 4] = cc.try_into().unwrap();
            dc.copy_from_slice(cc);
        }
        let mut v = [0.0; 4];
        match p % 4 {
            1 => v[..1].copy_from_slice(&col[4 * full..]),
            2 => v[..2].copy_from_slice(&col[4 * full..]),
            3 => v[..3].copy_from_slice(&col[4 * full..]),
            _ => {}
        }
        if pp > 4 * full {
            d[4 * full..].copy_from_slice(&v);
        }
    }
    pp
}

/// `out[..pp] = A z` with `A` as written by [`load_lifted`] (padding rows stay 0; the sums run
/// over `j` in order, bit-identical to the unpadded column axpys); returns `out[..8]`. Common padded sizes use a
/// fixed-size accumulator that stays in registers ([`kernels::lifted`]; with `AVX`, only
/// from code compiled with the `avx2` feature, its bit-identical AVX2 version).
#[inline(always)]
fn lifted_step<const AVX: bool>(a: &[f64], p: usize, pp: usize, z: &[f64], out: &mut [f64]) -> [f64; ROWS] {
    let z = &z[..p];
    #[cfg(target_arch = "x86_64")]
    if AVX {
        use kernels::avx2::lifted;
        // SAFETY: `AVX` is only set by `Engine::roll_avx2` (AVX2 checked at run time).
        unsafe {
            match pp {
                8 => return lifted::<2>(a, z, out),
                12 => return lifted::<3>(a, z, out),
                16 => return lifted::<4>(a, z, out),
                20 => return lifted::<5>(a, z, out),
                24 => return lifted::<6>(a, z, out),
                28 => return lifted::<7>(a, z, out),
                32 => return lifted::<8>(a, z, out),
                _ => {}
            }
        }
    }
    use kernels::lifted;
    match pp {
        8 => lifted::<2>(a, z, out),
        12 => lifted::<3>(a, z, out),
        16 => lifted::<4>(a, z, out),
        20 => lifted::<5>(a, z, out),
        24 => lifted::<6>(a, z, out),
        28 => lifted::<7>(a, z, out),
        32 => lifted::<8>(a, z, out),
        _ => {
            let out = &mut out[..pp];
            out.iter_mut().for_each(|o| *o = 0.0);
            for (col, &zj) in a[..p * pp].chunks_exact(pp).zip(z) {
                for (o, c) in out.iter_mut().zip(col) {
                    *o += c * zj;
                }
            }
            let mut head = [0.0; ROWS];
            head.copy_from_slice(&out[..ROWS]);
            head
        }
    }
}

/// Allocation-free roll-out of a 13-state with one method (scratch preallocated).
///
/// Koopman methods roll out both models fused in one loop over the steps. Relift mode,
/// `x⁺ = (A φ(x))[..n]` (translation; attitude of the dictionary methods): the `n` state rows
/// are copied once per call into padded columns (`8` entries), so a step is one lift plus `p`
/// 8-wide multiply-adds. Linear mode (deep attitude model): `z⁺ = A z` from `z₀ = φ(x₀)`,
/// decoded `x = z[..7]`, `A` copied once per call into columns padded to a multiple of 4.
/// The decoded quaternion is renormalised every step (the lifted state `z` is left as is).
///
/// Speed: [`Engine::run_lanes`] rolls up to 4 tracks out in lockstep (their dependency
/// chains overlap; [`crate::DebrisPredictor::forecast`] uses it), the dense kernels
/// (`kernels.rs`) have AVX2 versions selected at run time, and the Gaussian RBF lift
/// computes 4 centres per vector for all lanes at once. Every code path and lane count gives
/// bit-identical results (no FMA; tests `code_paths_and_lanes_are_bit_identical` and the
/// kernel unit tests).
///
/// Trust region: a Koopman roll-out started outside the training distribution (e.g. a
/// noisy rate estimate of a fresh track) can diverge polynomially. From the first step whose
/// state is non-finite or implies a speed above `max_speed` or a spin above `max_spin`, the
/// remaining steps are replaced by a constant-velocity continuation of the last good state
/// (counted in [`Engine::fallbacks`]).
#[derive(Debug, Clone)]
pub struct Engine {
    /// Per lane (track rolled out in lockstep, see [`Engine::run2`]): translation state rows.
    ct: [Vec<f64>; LANES],
    /// Attitude state rows (relift).
    ca: [Vec<f64>; LANES],
    /// Lifted translation state (dictionaries other than `[x, 1]`).
    zt: [Vec<f64>; LANES],
    /// Lifted attitude state.
    za: [Vec<f64>; LANES],
    /// Next lifted attitude state (linear roll-out).
    zn: [Vec<f64>; LANES],
    /// Lifted matrix of a linear attitude roll-out, columns padded to `pp` rows.
    ka: [Vec<f64>; LANES],
    pp: usize,
    /// Trust region: maximum speed [m/s].
    pub max_speed: f64,
    /// Trust region: maximum spin [rad/s].
    pub max_spin: f64,
    /// Roll-outs that left the trust region and were continued by constant velocity.
    pub fallbacks: u64,
    /// Always use the portable code path (no AVX2 even where the CPU has it; for tests and
    /// comparisons: both paths give bit-identical results).
    pub portable: bool,
}

/// Most tracks rolled out in lockstep ([`Engine::run_lanes`]).
const LANES: usize = 4;

/// One track of [`Engine::run2`]: its (possibly per-track refined) models, start state and
/// output rows.
#[derive(Debug)]
pub struct Job<'a> {
    /// Translational model.
    pub trans: &'a KoopmanModel,
    /// Attitude model.
    pub att: &'a KoopmanModel,
    /// Start 13-state.
    pub x0: &'a [f64],
    /// Output, at least `h · 13` entries.
    pub out: &'a mut [f64],
}

impl Engine {
    /// Scratch for the models' sizes (trust region 5 m/s, 15 rad/s).
    pub fn new(models: &Models) -> Self {
        let (pt, pa) = (models.trans.p, models.att.p);
        let pp = pa.next_multiple_of(4);
        let lanes = |n: usize| std::array::from_fn(|_| vec![0.0; n]);
        Engine {
            ct: lanes(pt * ROWS),
            ca: lanes(pa * ROWS),
            zt: lanes(pt),
            za: lanes(pp),
            zn: lanes(pp),
            ka: lanes(if models.att_rollout == Rollout::Linear { pa * pp } else { 0 }),
            pp,
            max_speed: 5.0,
            max_spin: 15.0,
            fallbacks: 0,
            portable: false,
        }
    }

    /// All entries finite, speed and spin within the trust region.
    fn trusted(&self, x: &[f64]) -> bool {
        let v2 = x[3] * x[3] + x[4] * x[4] + x[5] * x[5];
        let w2 = x[10] * x[10] + x[11] * x[11] + x[12] * x[12];
        x.iter().all(|v| v.is_finite()) && v2 <= self.max_speed.powi(2) && w2 <= self.max_spin.powi(2)
    }

    /// [`Engine::roll`] compiled for AVX2 (4-wide vectors, no FMA contraction: bit-identical
    /// to the portable path).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn roll_avx2<const T: usize>(
        &mut self,
        models: &Models,
        pt: usize,
        pa: usize,
        x0: [&[f64]; T],
        out: [&mut [f64]; T],
    ) -> [Option<usize>; T] {
        self.roll::<true, T>(models, pt, pa, x0, out)
    }

    /// The lifted start state of a linear attitude roll-out (the deep lifting, compiled for
    /// AVX2 when `AVX`; no FMA, so bit-identical).
    #[inline(always)]
    fn lift_start<const AVX: bool>(lift: &AttitudeLifting, x: &[f64], out: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        if AVX {
            if let AttitudeLifting::Deep(l) = lift {
                // SAFETY: `AVX` is only set by `Engine::roll_avx2` (AVX2 checked at run time).
                return unsafe { kernels::avx2::deep_lift(l, x, out) };
            }
        }
        lift.lift(x, out)
    }

    /// The fused roll-out loop of `T ≤ 2` tracks in lockstep (independent dependency chains
    /// that the CPU overlaps) over `out[t].len() / 13` steps; returns each track's first
    /// untrusted step (its later rows are not written). Translation: relift with the state
    /// rows in `ct`. Attitude: relift with the state rows in `ca`, or (deep model) linear in
    /// the lifted space with the padded matrix in `ka`.
    #[inline(always)]
    fn roll<const AVX: bool, const T: usize>(
        &mut self,
        models: &Models,
        pt: usize,
        pa: usize,
        x0: [&[f64]; T],
        out: [&mut [f64]; T],
    ) -> [Option<usize>; T] {
        let linear = models.att_rollout == Rollout::Linear;
        // `[x, 1]` (the default translation dictionary) is lifted in place.
        let plain_t = models.trans_lift.dim() == 7;
        let h = out[0].len() / N;
        let (max_v2, max_w2) = (self.max_speed.powi(2), self.max_spin.powi(2));
        let Engine { ct, ca, zt, za, zn, ka, pp, .. } = self;
        let pp = *pp;
        // States as 8-entry values (`xt[6] = 1` is the constant of `[x, 1]`): whole-vector
        // moves, no partial reloads of just written memory (failed store forwarding).
        let mut xt = [[0.0; ROWS]; T];
        let mut xa = [[0.0; ROWS]; T];
        for t in 0..T {
            xt[t][..6].copy_from_slice(&x0[t][debris_state::TRANS]);
            xt[t][6] = 1.0;
            xa[t][..7].copy_from_slice(&x0[t][debris_state::ROT]);
            if linear {
                Self::lift_start::<AVX>(&models.att_lift, &xa[t][..7], &mut za[t]);
            }
        }
        let mut bad = [None; T];
        let mut alive = T;
        for k in 0..h {
            for t in 0..T {
                xt[t] = if plain_t {
                    state_rows_times::<AVX>(&ct[t], &xt[t][..7])
                } else {
                    models.trans_lift.lift(&xt[t][..6], &mut zt[t]);
                    state_rows_times::<AVX>(&ct[t], &zt[t][..pt])
                };
                xt[t][6] = 1.0;
            }
            if linear {
                for t in 0..T {
                    xa[t] = lifted_step::<AVX>(&ka[t], pa, pp, &za[t], &mut zn[t]);
                    std::mem::swap(&mut za[t], &mut zn[t]);
                }
            } else {
                match &models.att_lift {
                    AttitudeLifting::Rbf(l) => l.lift_blocks::<AVX, T>(&xa, &mut za[..]),
                    l => {
                        for t in 0..T {
                            l.lift(&xa[t][..7], &mut za[t]);
                        }
                    }
                }
                for t in 0..T {
                    xa[t] = state_rows_times::<AVX>(&ca[t], &za[t][..pa]);
                }
            }
            for t in 0..T {
                // Unit quaternion (as `StateConstraint::UnitQuaternion`, same operations).
                let q = &mut xa[t];
                let nq = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
                if nq > 1e-12 {
                    for v in &mut q[..4] {
                        *v /= nq;
                    }
                }
            }
            for t in 0..T {
                if bad[t].is_some() {
                    continue;
                }
                let o = &mut out[t][k * N..(k + 1) * N];
                o[..6].copy_from_slice(&xt[t][..6]);
                o[6..].copy_from_slice(&xa[t][..7]);
                let (a, b) = (&xt[t], &xa[t]);
                let v2 = a[3] * a[3] + a[4] * a[4] + a[5] * a[5];
                let w2 = b[4] * b[4] + b[5] * b[5] + b[6] * b[6];
                let ok = a[..6].iter().chain(&b[..7]).fold(true, |ok, v| ok & v.is_finite())
                    & (v2 <= max_v2)
                    & (w2 <= max_w2);
                if !ok {
                    bad[t] = Some(k);
                    alive -= 1;
                }
            }
            if alive == 0 {
                break;
            }
        }
        bad
    }

    /// Check the model shapes and the scratch sizes; load lane `t`'s matrices.
    fn load(&mut self, models: &Models, t: usize, trans: &KoopmanModel, att: &KoopmanModel) {
        let (pt, pa) = (trans.p, att.p);
        assert!(trans.n == 6 && att.n == 7 && trans.m == 0 && att.m == 0, "Engine: unexpected model shape");
        assert!(
            self.ct[t].len() >= pt * ROWS
                && self.zt[t].len() >= pt
                && self.zn[t].len() >= pa.next_multiple_of(4)
                && if models.att_rollout == Rollout::Linear {
                    self.ka[t].len() >= pa * pa.next_multiple_of(4)
                } else {
                    self.ca[t].len() >= pa * ROWS
                },
            "Engine: scratch too small"
        );
        load_state_rows(trans, &mut self.ct[t]);
        if models.att_rollout == Rollout::Relift {
            load_state_rows(att, &mut self.ca[t]);
        } else {
            self.pp = load_lifted(att, &mut self.ka[t]);
        }
    }

    /// [`Engine::roll`] on the best code path for this CPU.
    fn roll_dispatch<const T: usize>(
        &mut self,
        models: &Models,
        pt: usize,
        pa: usize,
        x0: [&[f64]; T],
        out: [&mut [f64]; T],
    ) -> [Option<usize>; T] {
        #[cfg(target_arch = "x86_64")]
        if !self.portable && std::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked at run time).
            return unsafe { self.roll_avx2::<T>(models, pt, pa, x0, out) };
        }
        self.roll::<false, T>(models, pt, pa, x0, out)
    }

    /// Constant-velocity continuation from step `bad` on (trust region left).
    fn fallback(&mut self, models: &Models, x0: &[f64], out: &mut [f64], bad: usize) {
        self.fallbacks += 1;
        let mut start = [0.0; N];
        start.copy_from_slice(if bad == 0 { &x0[..N] } else { &out[(bad - 1) * N..bad * N] });
        if !self.trusted(&start) {
            // Even the start is implausible: clamp its rates to the trust region.
            let clamp = |v: &mut [f64], lim: f64| {
                let n = v.iter().map(|a| a * a).sum::<f64>().sqrt();
                if !n.is_finite() {
                    v.iter_mut().for_each(|a| *a = 0.0);
                } else if n > lim {
                    v.iter_mut().for_each(|a| *a *= lim / n);
                }
            };
            clamp(&mut start[3..6], self.max_speed);
            clamp(&mut start[10..13], self.max_spin);
        }
        ConstantVelocity { frame_rate: models.frame_rate }.forecast(&start, models.dt, &mut out[bad * N..]);
    }

    /// Forecast `h ≤ models.horizon` steps of the 13-state from `x0` with the given (possibly
    /// per-track refined) models into `out[..h*13]` (row-major, states at `dt, 2dt, …`).
    pub fn run(
        &mut self,
        models: &Models,
        trans: &KoopmanModel,
        att: &KoopmanModel,
        x0: &[f64],
        h: usize,
        out: &mut [f64],
    ) {
        let out = &mut out[..h * N];
        if models.method == Method::ConstantVelocity {
            ConstantVelocity { frame_rate: models.frame_rate }.forecast(x0, models.dt, out);
            return;
        }
        self.load(models, 0, trans, att);
        let [bad] = self.roll_dispatch::<1>(models, trans.p, att.p, [x0], [&mut *out]);
        if let Some(bad) = bad {
            self.fallback(models, x0, out, bad);
        }
    }

    /// [`Engine::run`] for two tracks at once (same results as two calls: the tracks are
    /// rolled out in lockstep so that their dependency chains overlap).
    pub fn run2(&mut self, models: &Models, a: Job<'_>, b: Job<'_>, h: usize) {
        self.run_lanes::<2>(models, [a, b], h)
    }

    /// [`Engine::run`] for `T ≤ 4` tracks at once (same results as `T` calls: the tracks are
    /// rolled out in lockstep so that their dependency chains overlap).
    pub fn run_lanes<const T: usize>(&mut self, models: &Models, jobs: [Job<'_>; T], h: usize) {
        assert!(T >= 1 && T <= LANES, "Engine::run_lanes: 1 ≤ T ≤ {LANES}");
        let mut x0 = [&[][..]; T];
        let mut jobs = jobs.map(|j| (j.trans, j.att, j.x0, j.out));
        if models.method == Method::ConstantVelocity {
            let cv = ConstantVelocity { frame_rate: models.frame_rate };
            for (_, _, x, o) in jobs.iter_mut() {
                cv.forecast(x, models.dt, &mut o[..h * N]);
            }
            return;
        }
        let (pt, pa) = (jobs[0].0.p, jobs[0].1.p);
        for t in 0..T {
            let (trans, att, x, _) = &jobs[t];
            assert!(trans.p == pt && att.p == pa, "Engine::run_lanes: different model sizes");
            self.load(models, t, trans, att);
            x0[t] = x;
        }
        let bad = {
            let rows: [&mut [f64]; T] = jobs.each_mut().map(|j| &mut j.3[..h * N]);
            self.roll_dispatch::<T>(models, pt, pa, x0, rows)
        };
        let outs = jobs.map(|j| j.3);
        for t in 0..T {
            if let Some(k) = bad[t] {
                self.fallback(models, x0[t], &mut outs[t][..h * N], k);
            }
        }
    }
}
