//! Per-horizon forecast error bounds for inflating debris shapes in the planner.

use crate::lifting::Lifting;
use crate::model::{Forecaster, KoopmanModel, Rollout};

/// Maximum forecast horizon (steps) supported by [`ErrorBound`].
pub const MAX_HORIZON: usize = 128;

/// Error radius per forecast step: `r(k) = base[k] + event_pos + event_vel · k · dt` for
/// `k = 1..=H` steps ahead. `base` comes from validation residuals (a quantile times a
/// margin); the event terms grow after detected events / impulses and relax exponentially.
/// Everything except [`ErrorBound::from_residuals`] is allocation-free.
#[derive(Debug, Clone, PartialEq)]
pub struct ErrorBound {
    h: usize,
    dt: f64,
    base: [f64; MAX_HORIZON],
    event_pos: f64,
    event_vel: f64,
    /// Relaxation time constant of the event terms [s].
    pub relax_tau: f64,
}

impl ErrorBound {
    /// Constant bound `r` for all `h` steps.
    pub fn constant(h: usize, dt: f64, r: f64) -> Self {
        assert!((1..=MAX_HORIZON).contains(&h));
        let mut base = [0.0; MAX_HORIZON];
        base[..h].iter_mut().for_each(|b| *b = r);
        ErrorBound { h, dt, base, event_pos: 0.0, event_vel: 0.0, relax_tau: 5.0 }
    }

    /// From validation errors `errors` (`runs × h`, row-major: error norm of run `r` at step
    /// `k+1`): `base[k] = margin · quantile_q(errors[:, k])`, made non-decreasing in `k`.
    pub fn from_residuals(errors: &[f64], h: usize, dt: f64, quantile: f64, margin: f64) -> Self {
        assert!((1..=MAX_HORIZON).contains(&h) && errors.len().is_multiple_of(h) && !errors.is_empty());
        assert!((0.0..=1.0).contains(&quantile));
        let runs = errors.len() / h;
        let mut out = Self::constant(h, dt, 0.0);
        let mut col = vec![0.0; runs];
        let mut running: f64 = 0.0;
        for k in 0..h {
            for r in 0..runs {
                col[r] = errors[r * h + k];
            }
            running = running.max(margin * self::quantile(&mut col, quantile));
            out.base[k] = running;
        }
        out
    }

    /// Horizon length `H`.
    pub fn horizon(&self) -> usize {
        self.h
    }
    /// Step `dt` [s].
    pub fn dt(&self) -> f64 {
        self.dt
    }
    /// Radius `k` steps ahead (`1 ≤ k ≤ H`; clamped).
    pub fn radius(&self, k: usize) -> f64 {
        let k = k.clamp(1, self.h);
        self.base[k - 1] + self.event_pos + self.event_vel * k as f64 * self.dt
    }
    /// `out[k − 1] = radius(k)` for `k = 1..=out.len()` (clamped like [`ErrorBound::radius`]).
    #[inline]
    pub fn radii(&self, out: &mut [f64]) {
        for (i, o) in out.iter_mut().enumerate() {
            let k = (i + 1).min(self.h);
            *o = self.base[k - 1] + self.event_pos + self.event_vel * k as f64 * self.dt;
        }
    }
    /// Validation-only part of the radius `k` steps ahead.
    pub fn base(&self, k: usize) -> f64 {
        self.base[k.clamp(1, self.h) - 1]
    }
    /// Grow after an event: position uncertainty `dpos` [m] and velocity uncertainty `dvel`
    /// [m/s] (spreading linearly over the horizon).
    pub fn grow(&mut self, dpos: f64, dvel: f64) {
        self.event_pos += dpos.max(0.0);
        self.event_vel += dvel.max(0.0);
    }
    /// Let the event terms decay over `elapsed` seconds (call as the model re-converges).
    pub fn relax(&mut self, elapsed: f64) {
        let f = (-elapsed.max(0.0) / self.relax_tau).exp();
        self.event_pos *= f;
        self.event_vel *= f;
    }
    /// Whether an observed `k`-step error exceeds `factor` times the current radius
    /// (innovation test for event detection).
    pub fn exceeds(&self, k: usize, err: f64, factor: f64) -> bool {
        err > factor * self.radius(k)
    }
}

/// The `level` quantile of `v`: the sample at index `⌈level·(n − 1)⌉` of the sorted values
/// (NaN for an empty set). Sorts `v`.
pub fn quantile(v: &mut [f64], level: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let i = ((level.clamp(0.0, 1.0) * (v.len() - 1) as f64).ceil() as usize).min(v.len() - 1);
    v[i]
}

/// Validation errors for [`ErrorBound::from_residuals`]: for every start index of every
/// trajectory (`T × n` row-major, constant input `u`) with `h` steps of ground truth ahead,
/// forecast `h` steps and record `‖x̂_k − x_k‖` over the coordinates `dims`. Returns `runs × h`.
pub fn validation_errors(
    model: &KoopmanModel,
    lifting: &dyn Lifting,
    trajectories: &[&[f64]],
    u: &[f64],
    h: usize,
    mode: Rollout,
    dims: std::ops::Range<usize>,
    stride: usize,
) -> Vec<f64> {
    let n = model.n;
    let mut fc = Forecaster::new(model.p);
    let mut out = vec![0.0; h * n];
    let mut errs = Vec::new();
    for traj in trajectories {
        let t = traj.len() / n;
        let mut s = 0;
        while s + h < t {
            fc.forecast(model, lifting, &traj[s * n..(s + 1) * n], u, mode, &mut out);
            for k in 0..h {
                let truth = &traj[(s + k + 1) * n..(s + k + 2) * n];
                let e: f64 = dims.clone().map(|i| (out[k * n + i] - truth[i]).powi(2)).sum::<f64>().sqrt();
                errs.push(e);
            }
            s += stride.max(1);
        }
    }
    errs
}
