//! Recursive least squares with exponential forgetting for online refinement of `[A B]`.

use crate::model::KoopmanModel;

/// RLS settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RlsConfig {
    /// Forgetting factor λ ∈ (0, 1]; 1 = no forgetting.
    pub lambda: f64,
    /// Initial / reset covariance `P = p0 · I` (large = trust data more than the prior model).
    pub p0: f64,
    /// Covariance blow-up guard: reset when `trace(P) > max_trace` or non-finite.
    pub max_trace: f64,
}

impl Default for RlsConfig {
    fn default() -> Self {
        RlsConfig { lambda: 0.995, p0: 1e2, max_trace: 1e8 }
    }
}

/// Outcome of one update.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RlsStatus {
    /// Euclidean norm of the a-priori prediction error `y − Θφ`.
    pub prior_error: f64,
    /// The covariance was reset by the guard during this update.
    pub reset: bool,
}

/// Multi-output RLS state for `y ≈ Θ φ`, `Θ: q × d` (column-major, leading dimension `ld`).
/// [`Rls::update`] is `O(d² + q d)` and allocation-free.
#[derive(Debug, Clone)]
pub struct Rls {
    d: usize,
    q: usize,
    cfg: RlsConfig,
    p: Vec<f64>,
    pphi: Vec<f64>,
    e: Vec<f64>,
    resets: u64,
    updates: u64,
}

impl Rls {
    /// Regressor dimension `d`, `q` outputs.
    pub fn new(d: usize, q: usize, cfg: RlsConfig) -> Self {
        assert!(cfg.lambda > 0.0 && cfg.lambda <= 1.0, "RLS lambda must be in (0, 1]");
        assert!(cfg.p0 > 0.0, "RLS p0 must be > 0");
        let mut r = Rls {
            d,
            q,
            cfg,
            p: vec![0.0; d * d],
            pphi: vec![0.0; d],
            e: vec![0.0; q],
            resets: 0,
            updates: 0,
        };
        r.init_p();
        r.resets = 0;
        r
    }
    /// For refining all `p` lifted rows of `model` (regressor `[z; u]`, `d = p + m`).
    pub fn for_model(model: &KoopmanModel, cfg: RlsConfig) -> Self {
        Self::new(model.p + model.m, model.p, cfg)
    }
    /// For refining only the `n` state rows of `model` (enough for [`crate::Rollout::Relift`]).
    pub fn for_model_state_rows(model: &KoopmanModel, cfg: RlsConfig) -> Self {
        Self::new(model.p + model.m, model.n, cfg)
    }
    fn init_p(&mut self) {
        self.p.iter_mut().for_each(|v| *v = 0.0);
        for i in 0..self.d {
            self.p[i * self.d + i] = self.cfg.p0;
        }
    }
    /// Reset the covariance to `p0 · I` (e.g. after a detected event: adapt fast).
    pub fn reset_covariance(&mut self) {
        self.init_p();
        self.resets += 1;
    }
    /// Number of covariance resets (guard or explicit).
    pub fn resets(&self) -> u64 {
        self.resets
    }
    /// Number of updates applied.
    pub fn updates(&self) -> u64 {
        self.updates
    }
    /// Covariance `P` (column-major `d × d`).
    pub fn covariance(&self) -> &[f64] {
        &self.p
    }
    /// Settings.
    pub fn config(&self) -> &RlsConfig {
        &self.cfg
    }

    /// One RLS step on `theta` (`q × d` column-major, leading dimension `ld ≥ q`) with
    /// regressor `phi` (len `d`) and target `y` (len `≥ q`). Allocation-free.
    pub fn update(&mut self, theta: &mut [f64], ld: usize, phi: &[f64], y: &[f64]) -> RlsStatus {
        let (d, q, lam) = (self.d, self.q, self.cfg.lambda);
        debug_assert!(ld >= q && theta.len() >= ld * (d - 1) + q && phi.len() >= d && y.len() >= q);
        // Pφ (P symmetric, column-major: axpy over columns).
        self.pphi.iter_mut().for_each(|v| *v = 0.0);
        for j in 0..d {
            let f = phi[j];
            if f == 0.0 {
                continue;
            }
            for (o, pv) in self.pphi.iter_mut().zip(&self.p[j * d..(j + 1) * d]) {
                *o += pv * f;
            }
        }
        let denom = lam + phi[..d].iter().zip(&self.pphi).map(|(a, b)| a * b).sum::<f64>();
        // A-priori error e = y − Θφ.
        self.e.copy_from_slice(&y[..q]);
        for j in 0..d {
            let f = phi[j];
            for (e, t) in self.e.iter_mut().zip(&theta[j * ld..j * ld + q]) {
                *e -= t * f;
            }
        }
        let prior_error = self.e.iter().map(|v| v * v).sum::<f64>().sqrt();
        if !(denom.is_finite() && denom > 0.0 && prior_error.is_finite()) {
            self.reset_covariance();
            return RlsStatus { prior_error, reset: true };
        }
        // Θ += e kᵀ, k = Pφ / denom.
        for j in 0..d {
            let kj = self.pphi[j] / denom;
            for (t, e) in theta[j * ld..j * ld + q].iter_mut().zip(&self.e) {
                *t += e * kj;
            }
        }
        // P ← (P − Pφ φᵀP / denom) / λ, column by column (contiguous, so it vectorises). P
        // stays exactly symmetric: it starts as p0·I, and entries (i, j) and (j, i) are the
        // same operations on the same numbers (P's two equal entries, Pφ_i·Pφ_j = Pφ_j·Pφ_i),
        // so no symmetrising is needed (test `the_covariance_stays_exactly_symmetric`).
        let inv_lam = 1.0 / lam;
        let mut trace = 0.0;
        let mut bad = false;
        for j in 0..d {
            let pj = self.pphi[j];
            for (v, pi) in self.p[j * d..(j + 1) * d].iter_mut().zip(&self.pphi) {
                *v = (*v - pi * pj / denom) * inv_lam;
            }
            let dj = self.p[j * d + j];
            bad |= !(dj > 0.0) || !dj.is_finite();
            trace += dj;
        }
        self.updates += 1;
        if bad || !(trace <= self.cfg.max_trace) {
            self.reset_covariance();
            return RlsStatus { prior_error, reset: true };
        }
        RlsStatus { prior_error, reset: false }
    }

    /// Refine `model` from one observed transition: regressor `[z; u]`, target `z_next`
    /// (first `q` rows: all lifted rows or the state rows). Allocation-free.
    pub fn update_model(&mut self, model: &mut KoopmanModel, phi_zu: &[f64], z_next: &[f64]) -> RlsStatus {
        let ld = model.p;
        self.update(&mut model.ab, ld, phi_zu, z_next)
    }
}
