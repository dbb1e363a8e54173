//! Online calibration of a track's published forecasts: every forecast a track publishes is
//! kept (position and attitude per step) and scored against the track's filtered pose when its
//! steps come due. Per step `k` the score is a decaying maximum of the errors seen (time
//! constant [`ForecastScore::STAT_TAU`]); the bound `k` steps ahead is
//! `floor + factor · max_{j ≤ k} score_j`, so a bound never shrinks with the horizon and an
//! error seen at a short horizon (after an impulse) raises every longer one at once.
//!
//! This replaces a bound fitted once on training data (a quantile over every kind of object)
//! by one measured on the object itself: a slowly turning panel gets a tight bound, a fast
//! tumbler a wide one. Steps that have not been scored yet have no bound: the caller keeps
//! the fitted one. That is so for a young track, and for one whose filter started again (a
//! manoeuvre re-opened its velocity, or a whole view restarted its position): the predictor
//! clears the scores there as the fitted bound grows, and keeps forecasts for scoring only
//! from `PredictorConfig::calib_min_obs` poses on, since a converging filter's forecasts tell
//! nothing of the settled ones. Storage is allocated once ([`ForecastScore::new`]).

/// Forecasts kept per track (one per model step of start time: 4.8 s at 0.1 s, more than the
/// horizon).
pub const SLOTS: usize = 48;

/// Per-track store of published forecasts and their per-step error scores.
#[derive(Debug, Clone, PartialEq)]
pub struct ForecastScore {
    h: usize,
    dt: f64,
    t0: [f64; SLOTS],
    next_k: [usize; SLOTS],
    /// `SLOTS × h` rows of `[p (3), q (4)]`.
    poses: Vec<[f64; 7]>,
    head: usize,
    score_p: Vec<f64>,
    score_a: Vec<f64>,
    scored: Vec<bool>,
    last_decay: f64,
}

impl ForecastScore {
    /// Memory of the per-step scores, s.
    pub const STAT_TAU: f64 = 20.0;

    /// Store for forecasts of `h` steps of `dt` seconds (allocates once).
    pub fn new(h: usize, dt: f64) -> Self {
        ForecastScore {
            h,
            dt,
            t0: [f64::NAN; SLOTS],
            next_k: [usize::MAX; SLOTS],
            poses: vec![[0.0; 7]; SLOTS * h],
            head: 0,
            score_p: vec![0.0; h],
            score_a: vec![0.0; h],
            scored: vec![false; h],
            last_decay: f64::NAN,
        }
    }

    /// Forget everything (a new track in this slot).
    pub fn clear(&mut self) {
        self.t0 = [f64::NAN; SLOTS];
        self.next_k = [usize::MAX; SLOTS];
        self.score_p.iter_mut().for_each(|s| *s = 0.0);
        self.score_a.iter_mut().for_each(|s| *s = 0.0);
        self.scored.iter_mut().for_each(|s| *s = false);
        self.last_decay = f64::NAN;
    }

    /// Whether [`ForecastScore::record`] would keep a forecast from `t0`: at most one per model
    /// step of start time, so the kept ones span `SLOTS · dt` (more than the horizon) however
    /// often the caller forecasts.
    pub fn wants(&self, t0: f64) -> bool {
        let last = (self.head + SLOTS - 1) % SLOTS;
        !(self.t0[last].is_finite() && t0 < self.t0[last] + self.dt - 1e-9)
    }

    /// Keeps a published forecast from `t0` (unless one was kept less than a model step
    /// earlier): `states` is `h` rows of 13-states
    /// ([`dkrrt_koopman::debris_state`] layout) at `t0 + k·dt`, `k = 1..=h`.
    pub fn record(&mut self, t0: f64, states: &[f64]) {
        use dkrrt_koopman::debris_state::N;
        if !self.wants(t0) {
            return;
        }
        let slot = self.head;
        for k in 0..self.h.min(states.len() / N) {
            let x = &states[k * N..(k + 1) * N];
            self.poses[slot * self.h + k] = [x[0], x[1], x[2], x[6], x[7], x[8], x[9]];
        }
        self.t0[slot] = t0;
        self.next_k[slot] = 1;
        self.head = (self.head + 1) % SLOTS;
    }

    /// Scores every kept forecast step that has come due by `t`: `truth(τ)` is the track's
    /// filtered `(p, q)` at time `τ ≤ t`.
    pub fn score(&mut self, t: f64, truth: impl Fn(f64) -> ([f64; 3], [f64; 4])) {
        if self.last_decay.is_finite() {
            let f = (-(t - self.last_decay).max(0.0) / Self::STAT_TAU).exp();
            self.score_p.iter_mut().for_each(|s| *s *= f);
            self.score_a.iter_mut().for_each(|s| *s *= f);
        }
        self.last_decay = t;
        for s in 0..SLOTS {
            while self.next_k[s] <= self.h {
                let k = self.next_k[s];
                let tk = self.t0[s] + k as f64 * self.dt;
                if tk > t + 1e-9 {
                    break;
                }
                let (p, q) = truth(tk);
                let f = &self.poses[s * self.h + k - 1];
                let ep = ((f[0] - p[0]).powi(2) + (f[1] - p[1]).powi(2) + (f[2] - p[2]).powi(2)).sqrt();
                let ea = crate::filter::quat_angle(&f[3..7], &q);
                self.score_p[k - 1] = self.score_p[k - 1].max(ep);
                self.score_a[k - 1] = self.score_a[k - 1].max(ea);
                self.scored[k - 1] = true;
                self.next_k[s] += 1;
            }
        }
    }

    /// Calibrated `(position m, attitude rad)` bounds `k` steps ahead, or `None` while step `k`
    /// has not been scored.
    pub fn radius(&self, k: usize, floor: [f64; 2], factor: f64) -> Option<(f64, f64)> {
        let k = k.clamp(1, self.h);
        if !self.scored[k - 1] {
            return None;
        }
        let mp = self.score_p[..k].iter().fold(0.0f64, |a, &b| a.max(b));
        let ma = self.score_a[..k].iter().fold(0.0f64, |a, &b| a.max(b));
        Some((floor[0] + factor * mp, floor[1] + factor * ma))
    }
}

/// Longest forecast (steps) a [`StepScores`] covers.
pub const MAX_STEPS: usize = 64;

/// Per-step error scores of one forecast channel: a decaying maximum (time constant
/// [`StepScores::STAT_TAU`]) of the errors seen `k` steps ahead, and the bound
/// `floor + factor · max_{j ≤ k} score_j` (never shrinking with the horizon). Fixed size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepScores {
    score: [f64; MAX_STEPS],
    scored: [bool; MAX_STEPS],
    last_decay: f64,
}

impl Default for StepScores {
    fn default() -> Self {
        Self::new()
    }
}

impl StepScores {
    /// Memory of the scores, s.
    pub const STAT_TAU: f64 = 20.0;

    pub fn new() -> Self {
        StepScores { score: [0.0; MAX_STEPS], scored: [false; MAX_STEPS], last_decay: f64::NAN }
    }

    /// Decays every score to time `t`.
    pub fn decay(&mut self, t: f64) {
        if self.last_decay.is_finite() {
            let f = (-(t - self.last_decay).max(0.0) / Self::STAT_TAU).exp();
            self.score.iter_mut().for_each(|s| *s *= f);
        }
        self.last_decay = t;
    }

    /// An error `e` seen `k` steps ahead (`1 ≤ k ≤ MAX_STEPS`; others are ignored).
    pub fn add(&mut self, k: usize, e: f64) {
        if (1..=MAX_STEPS).contains(&k) {
            self.score[k - 1] = self.score[k - 1].max(e);
            self.scored[k - 1] = true;
        }
    }

    /// The bound `k` steps ahead, or `None` while step `k` has not been scored.
    pub fn radius(&self, k: usize, floor: f64, factor: f64) -> Option<f64> {
        let k = k.clamp(1, MAX_STEPS);
        self.scored[k - 1].then(|| floor + factor * self.score[..k].iter().fold(0.0f64, |a, &b| a.max(b)))
    }

    /// [`StepScores::radius`] for `k = 1, 2, …` into `out[k − 1]` while step `k` is scored;
    /// returns how many were written.
    pub fn radii(&self, floor: f64, factor: f64, out: &mut [f64]) -> usize {
        let mut m: f64 = 0.0;
        for (k, o) in out.iter_mut().enumerate().take(MAX_STEPS) {
            if !self.scored[k] {
                return k;
            }
            m = m.max(self.score[k]);
            *o = floor + factor * m;
        }
        out.len().min(MAX_STEPS)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dkrrt_koopman::debris_state::N;

    #[test]
    fn scores_per_step_and_bounds_are_monotone() {
        let (h, dt) = (10, 0.1);
        let mut s = ForecastScore::new(h, dt);
        assert!(s.radius(1, [0.0; 2], 1.0).is_none());
        // A forecast that drifts 1 cm per step from a truth at rest.
        let mut states = vec![0.0; h * N];
        for k in 0..h {
            states[k * N] = 0.01 * (k + 1) as f64;
            states[k * N + 6] = 1.0;
        }
        s.record(0.0, &states);
        let truth = |_t: f64| ([0.0; 3], [1.0, 0.0, 0.0, 0.0]);
        s.score(0.25, truth);
        let (p2, a2) = s.radius(2, [0.0; 2], 1.0).unwrap();
        assert!((p2 - 0.02).abs() < 1e-12 && a2.abs() < 1e-12);
        assert!(s.radius(3, [0.0; 2], 1.0).is_none(), "step 3 is not due at 0.25 s");
        s.score(1.0, truth);
        let (p10, _) = s.radius(10, [0.005, 0.0], 2.0).unwrap();
        assert!((p10 - (0.005 + 2.0 * 0.1)).abs() < 1e-3, "{p10}");
        // Monotone: step 1 seen large raises every horizon.
        let mut bad = states.clone();
        bad[0] = 0.5;
        s.record(1.0, &bad);
        s.score(1.1, truth);
        for k in 1..=h {
            assert!(s.radius(k, [0.0; 2], 1.0).unwrap().0 >= 0.49);
        }
        s.clear();
        assert!(s.radius(1, [0.0; 2], 1.0).is_none());
        // Forecasts every 20 ms: one kept per 0.1 s, so the longest step still gets scored.
        for i in 0..200 {
            s.record(0.02 * i as f64, &states);
        }
        s.score(4.0 + 1.0, truth);
        assert!(s.radius(h, [0.0; 2], 1.0).is_some());
    }
}
