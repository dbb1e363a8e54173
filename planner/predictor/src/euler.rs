//! The full attitude of a tumbling box or panel, forecast by torque-free rigid-body motion.
//!
//! A body with no torque on it obeys Euler's equations `I ω̇ = −ω × I ω` (body axes =
//! principal axes) and turns by `q̇ = ½ q ⊗ ω − ½ (n ẑ) ⊗ q` in the LVLH frame, which itself
//! turns at the mean motion `n` about `z` (the convention of [`crate::filter::propagate`]).
//! With an inertia this is a far better long-horizon attitude forecast than a constant rate
//! or a learned operator: a box tumbling about its intermediate axis flips, and nothing but
//! the equations knows when.
//!
//! The inertia comes from the object's shape (a box of uniform density, [`inertia_hint`]), as
//! a perception front end would estimate it. Whether that is right for a given object is not
//! assumed: [`EulerChannel`] forecasts from its own fits every model step, scores each of
//! those forecasts against the filtered attitude as its steps come due ([`StepScores`]), and
//! the predictor uses it only at the steps where its calibrated bound is smaller than the
//! attitude model's. A wrong inertia or an unmodelled torque shows up as a large score and
//! the model's forecast is kept.
//!
//! The body rate is fitted (Gauss–Newton, three unknowns) to the last 1.5 s of filtered
//! attitudes propagated back from the newest one: the filter's instantaneous rate is too
//! noisy for a 4 s forecast. RK4 with substeps of at most 0.1 s and 0.2 rad of turn. Everything here is fixed size; nothing allocates.

use crate::axis::solve3;
use crate::calib::{StepScores, MAX_STEPS};
use crate::filter::quat_angle;
use dkrrt_koopman::debris_state::quat_mul;
use dkrrt_msg::{DebrisShape, ShapeKind};

/// The principal moments (up to a common factor) a shape descriptor suggests: a box (also a
/// panel, or a convex piece given as its box) centred on its body origin, as a uniform
/// solid. `None` for other shapes (a sphere's attitude does not matter; a rod's axis has its
/// own forecast, [`crate::axis`]) and for a box off its body origin (its centre of mass is
/// unknown).
pub fn inertia_hint(shape: &DebrisShape) -> Option<[f64; 3]> {
    (shape.kind == ShapeKind::Box as u32
        && shape.offset.iter().all(|v| *v == 0.0)
        && shape.dims.iter().all(|v| v.is_finite() && *v > 0.0))
    .then(|| box_inertia(&shape.dims))
}

/// Principal moments (up to the factor `m / 3`) of a uniform box with half extents `h`.
pub fn box_inertia(h: &[f64; 3]) -> [f64; 3] {
    let s = [h[0] * h[0], h[1] * h[1], h[2] * h[2]];
    [s[1] + s[2], s[0] + s[2], s[0] + s[1]]
}

/// The coefficients of Euler's equations `ω̇_a = e_a ω_b ω_c` of principal moments `i`.
fn euler_coefficients(i: &[f64; 3]) -> [f64; 3] {
    [(i[1] - i[2]) / i[0], (i[2] - i[0]) / i[1], (i[0] - i[1]) / i[2]]
}

/// Time derivative of `(q, ω)` (module docs); `e` = [`euler_coefficients`].
fn deriv(q: &[f64; 4], w: &[f64; 3], e: &[f64; 3], n: f64) -> ([f64; 4], [f64; 3]) {
    let qw = quat_mul(q, &[0.0, w[0], w[1], w[2]]);
    let nq = quat_mul(&[0.0, 0.0, 0.0, n], q);
    // Written out, not `array::map` (left as a call in this hot loop: the same arithmetic).
    let dq = [0.5 * (qw[0] - nq[0]), 0.5 * (qw[1] - nq[1]), 0.5 * (qw[2] - nq[2]), 0.5 * (qw[3] - nq[3])];
    let dw = [e[0] * w[1] * w[2], e[1] * w[2] * w[0], e[2] * w[0] * w[1]];
    (dq, dw)
}

/// One RK4 step of `h` seconds (`h` may be negative); the quaternion is renormalised.
/// `e` = [`euler_coefficients`] of the principal moments.
fn step_rk4(q: &[f64; 4], w: &[f64; 3], e: &[f64; 3], n: f64, h: f64) -> ([f64; 4], [f64; 3]) {
    let (k1q, k1w) = deriv(q, w, e, n);
    let at = |s: f64, dq: &[f64; 4], dw: &[f64; 3]| {
        (
            [q[0] + s * dq[0], q[1] + s * dq[1], q[2] + s * dq[2], q[3] + s * dq[3]],
            [w[0] + s * dw[0], w[1] + s * dw[1], w[2] + s * dw[2]],
        )
    };
    let (q2, w2) = at(0.5 * h, &k1q, &k1w);
    let (k2q, k2w) = deriv(&q2, &w2, e, n);
    let (q3, w3) = at(0.5 * h, &k2q, &k2w);
    let (k3q, k3w) = deriv(&q3, &w3, e, n);
    let (q4, w4) = at(h, &k3q, &k3w);
    let (k4q, k4w) = deriv(&q4, &w4, e, n);
    let mut qn = [0.0; 4];
    for (k, o) in qn.iter_mut().enumerate() {
        *o = q[k] + h / 6.0 * (k1q[k] + 2.0 * k2q[k] + 2.0 * k3q[k] + k4q[k]);
    }
    let mut wn = [0.0; 3];
    for (k, o) in wn.iter_mut().enumerate() {
        *o = w[k] + h / 6.0 * (k1w[k] + 2.0 * k2w[k] + 2.0 * k3w[k] + k4w[k]);
    }
    let nq = (qn[0] * qn[0] + qn[1] * qn[1] + qn[2] * qn[2] + qn[3] * qn[3]).sqrt();
    qn.iter_mut().for_each(|v| *v /= nq);
    (qn, wn)
}

/// Longest integration substep, s.
pub const SUBSTEP: f64 = 0.1;
/// Largest rotation per substep, rad (RK4's local error grows as its fifth power: ~3e-6 rad
/// at 0.2).
pub const SUBSTEP_ANGLE: f64 = 0.2;

/// `(q, ω)` propagated by `dt` seconds (either sign) in substeps of at most [`SUBSTEP`] and
/// [`SUBSTEP_ANGLE`] of turn.
pub fn propagate(q: &[f64; 4], w: &[f64; 3], inertia: &[f64; 3], n: f64, dt: f64) -> ([f64; 4], [f64; 3]) {
    let rate = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
    let h_max = SUBSTEP.min(SUBSTEP_ANGLE / rate.max(1e-9));
    let steps = ((dt.abs() / h_max).ceil().min(1e6) as usize).max(1);
    let h = dt / steps as f64;
    let (mut q, mut w) = (*q, *w);
    if dt != 0.0 {
        let e = euler_coefficients(inertia);
        for _ in 0..steps {
            (q, w) = step_rk4(&q, &w, &e, n, h);
        }
    }
    (q, w)
}

/// Attitude samples kept for the rate fit (one per [`EulerChannel::EVERY`]: 1.5 s).
pub const RING: usize = 16;

/// A forecast being scored: taken at `t0`, propagated so far to `t`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Probe {
    t0: f64,
    t: f64,
    q: [f64; 4],
    w: [f64; 3],
}

/// One track's torque-free attitude forecast and its online calibration (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EulerChannel {
    inertia: Option<[f64; 3]>,
    ring_t: [f64; RING],
    ring_q: [[f64; 4]; RING],
    head: usize,
    len: usize,
    /// Newest fit: time, attitude, body rate.
    fit: Option<(f64, [f64; 4], [f64; 3])>,
    probes: [Probe; MAX_STEPS + 1],
    probe_head: usize,
    probe_len: usize,
    scores: StepScores,
    last_round: f64,
}

impl Default for EulerChannel {
    fn default() -> Self {
        Self::new()
    }
}

/// Small rotation from `a` to `b` as a body-frame vector (`2 · vec(a⁻¹ b)`, sign-aligned).
fn rot_err(a: &[f64; 4], b: &[f64; 4]) -> [f64; 3] {
    let d = quat_mul(&[a[0], -a[1], -a[2], -a[3]], b);
    let s = if d[0] < 0.0 { -2.0 } else { 2.0 };
    [s * d[1], s * d[2], s * d[3]]
}

fn q4(q: &[f64]) -> [f64; 4] {
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    [q[0] / n, q[1] / n, q[2] / n, q[3] / n]
}

impl EulerChannel {
    /// Grid of the fit's samples, s.
    pub const EVERY: f64 = 0.1;
    /// Gauss–Newton iterations of a fit (each from the previous fit's rate).
    pub const ITERATIONS: usize = 2;
    /// Largest relative change of a principal moment (scaled to the same sum) that
    /// [`EulerChannel::set_inertia`] takes as a refinement of the estimate.
    pub const REFINE: f64 = 0.05;

    pub fn new() -> Self {
        EulerChannel {
            inertia: None,
            ring_t: [f64::NAN; RING],
            ring_q: [[1.0, 0.0, 0.0, 0.0]; RING],
            head: 0,
            len: 0,
            fit: None,
            probes: [Probe { t0: f64::NAN, t: f64::NAN, q: [1.0, 0.0, 0.0, 0.0], w: [0.0; 3] };
                MAX_STEPS + 1],
            probe_head: 0,
            probe_len: 0,
            scores: StepScores::new(),
            last_round: f64::NAN,
        }
    }

    /// The principal moments used (`None`: no forecast).
    pub fn inertia(&self) -> Option<[f64; 3]> {
        self.inertia
    }

    /// Sets the principal moments (any common factor). A refinement (each moment within
    /// [`EulerChannel::REFINE`] of the current one, both scaled to the same sum) keeps the
    /// samples, the fit and the scores: a camera front end's estimate of a box grows by
    /// millimetres as the box shows its sides, and starting afresh on each (1.5 s before a
    /// fit, 4 s before every step is scored) left a tumbling panel's channel unready most of
    /// the time. Any other change starts the channel afresh.
    pub fn set_inertia(&mut self, inertia: Option<[f64; 3]>) {
        let valid = inertia.filter(|i| i.iter().all(|v| v.is_finite() && *v > 0.0));
        if valid == self.inertia {
            return;
        }
        let refines = match (valid, self.inertia) {
            (Some(a), Some(b)) => {
                let (sa, sb) = (a.iter().sum::<f64>(), b.iter().sum::<f64>());
                (0..3).all(|k| (a[k] / sa - b[k] / sb).abs() <= Self::REFINE * b[k] / sb)
            }
            _ => false,
        };
        if refines {
            self.inertia = valid;
        } else {
            *self = EulerChannel { inertia: valid, ..EulerChannel::new() };
        }
    }

    /// Forget the samples, the fit and the forecasts being scored (after an attitude event);
    /// keep the scores.
    pub fn restart(&mut self) {
        self.len = 0;
        self.fit = None;
        self.probe_len = 0;
    }

    /// Absorbs the filtered attitude `q` (body → LVLH) at `t`; every `dt` seconds it scores
    /// its earlier forecasts up to `h` steps old, refits the rate and takes a new forecast.
    /// `n` is the frame's turn rate.
    pub fn update(&mut self, t: f64, q: &[f64], dt: f64, h: usize, n: f64) {
        let Some(inertia) = self.inertia else { return };
        if !t.is_finite() || !(dt > 0.0) {
            return;
        }
        let q = q4(q);
        let newest = (self.head + RING - 1) % RING;
        if self.len > 0 && t <= self.ring_t[newest] {
            return;
        }
        if self.len == 0 || t >= self.ring_t[newest] + Self::EVERY - 1e-6 {
            self.ring_t[self.head] = t;
            self.ring_q[self.head] = q;
            self.head = (self.head + 1) % RING;
            self.len = (self.len + 1).min(RING);
        }
        if self.last_round.is_finite() && t - self.last_round < dt - 1e-9 {
            return;
        }
        self.scores.decay(t);
        self.last_round = t;
        let h = h.min(MAX_STEPS);
        // Score the live forecasts, oldest first; drop those past the horizon.
        let mut live = 0;
        for j in 0..self.probe_len {
            let i = (self.probe_head + MAX_STEPS + 1 - self.probe_len + j) % (MAX_STEPS + 1);
            let p = &mut self.probes[i];
            let k = ((t - p.t0) / dt).round() as usize;
            if k > h {
                continue;
            }
            (p.q, p.w) = propagate(&p.q, &p.w, &inertia, n, t - p.t);
            p.t = t;
            if k >= 1 {
                self.scores.add(k, quat_angle(&p.q, &q));
            }
            live += 1;
        }
        self.probe_len = live;
        // Refit from the previous fit's rate carried forward (or a finite-difference rate).
        if self.len < RING {
            return;
        }
        let guess = match self.fit {
            Some((tf, qf, wf)) => propagate(&qf, &wf, &inertia, n, t - tf).1,
            None => {
                let oldest = (self.head + RING - self.len) % RING;
                let e = rot_err(&self.ring_q[oldest], &q);
                let span = (t - self.ring_t[oldest]).max(1e-3);
                e.map(|v| v / span)
            }
        };
        let Some(w) = self.fit_rate(&inertia, n, t, &q, &guess) else { return };
        self.fit = Some((t, q, w));
        self.probes[self.probe_head] = Probe { t0: t, t, q, w };
        self.probe_head = (self.probe_head + 1) % (MAX_STEPS + 1);
        self.probe_len = (self.probe_len + 1).min(MAX_STEPS + 1);
    }

    /// Residuals (body-frame rotation vectors, newest sample first) of the ring against
    /// `(q0, w)` at `t0` propagated back; their sum of squares.
    fn residuals(
        &self,
        inertia: &[f64; 3],
        n: f64,
        t0: f64,
        q0: &[f64; 4],
        w: &[f64; 3],
        r: &mut [f64],
    ) -> f64 {
        let (mut q, mut wc, mut t) = (*q0, *w, t0);
        let mut c = 0.0;
        for j in 0..self.len {
            let i = (self.head + RING - 1 - j) % RING;
            let ti = self.ring_t[i];
            (q, wc) = propagate(&q, &wc, inertia, n, ti - t);
            t = ti;
            let e = rot_err(&q, &self.ring_q[i]);
            r[3 * j..3 * j + 3].copy_from_slice(&e);
            c += e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
        }
        c
    }

    /// The body rate at `t0` (attitude `q0`) that best explains the ring, from `guess`.
    fn fit_rate(
        &self,
        inertia: &[f64; 3],
        n: f64,
        t0: f64,
        q0: &[f64; 4],
        guess: &[f64; 3],
    ) -> Option<[f64; 3]> {
        let m = 3 * self.len;
        let mut w = *guess;
        let mut r0 = [0.0; 3 * RING];
        let mut c0 = self.residuals(inertia, n, t0, q0, &w, &mut r0);
        for _ in 0..Self::ITERATIONS {
            let mut jac = [[0.0; 3]; 3 * RING];
            let eps = 1e-4;
            for k in 0..3 {
                let mut wp = w;
                wp[k] += eps;
                let mut rp = [0.0; 3 * RING];
                self.residuals(inertia, n, t0, q0, &wp, &mut rp);
                for i in 0..m {
                    jac[i][k] = (rp[i] - r0[i]) / eps;
                }
            }
            let mut a = [[0.0; 3]; 3];
            let mut g = [0.0; 3];
            for i in 0..m {
                for r in 0..3 {
                    g[r] += jac[i][r] * r0[i];
                    for c in 0..3 {
                        a[r][c] += jac[i][r] * jac[i][c];
                    }
                }
            }
            let tr = a[0][0] + a[1][1] + a[2][2];
            for d in 0..3 {
                a[d][d] += 1e-6 * tr.max(1e-9);
            }
            let dw = solve3(&a, &g)?;
            let wn = [w[0] - dw[0], w[1] - dw[1], w[2] - dw[2]];
            let mut rn = [0.0; 3 * RING];
            let cn = self.residuals(inertia, n, t0, q0, &wn, &mut rn);
            if !(cn < c0) {
                break;
            }
            let done = c0 - cn < 1e-9 * c0.max(1e-12);
            (w, r0, c0) = (wn, rn, cn);
            if done {
                break;
            }
        }
        w.iter().all(|v| v.is_finite()).then_some(w)
    }

    /// Whether a forecast is available (an inertia and a fit).
    pub fn ready(&self) -> bool {
        self.inertia.is_some() && self.fit.is_some()
    }

    /// The attitude at `t0 + k·step`, `k = 1..=out.len()`; returns `false` (nothing written)
    /// when not [`EulerChannel::ready`].
    pub fn attitudes_into(&self, n: f64, t0: f64, step: f64, out: &mut [[f64; 4]]) -> bool {
        let (Some(inertia), Some((tf, qf, wf))) = (self.inertia, self.fit) else { return false };
        let (mut q, mut w) = propagate(&qf, &wf, &inertia, n, t0 - tf);
        for o in out.iter_mut() {
            (q, w) = propagate(&q, &w, &inertia, n, step);
            *o = q;
        }
        true
    }

    /// Calibrated bounds `k = 1, 2, …` steps ahead into `out[k − 1]` while step `k` is scored
    /// (rad); returns how many were written (0 when not ready).
    pub fn radii(&self, floor: f64, factor: f64, out: &mut [f64]) -> usize {
        if !self.ready() {
            return 0;
        }
        self.scores.radii(floor, factor, out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const N_FRAME: f64 = 1.1314e-3;

    /// A box tumbling near its intermediate axis (it flips): attitudes every 20 ms.
    fn truth(inertia: &[f64; 3], secs: f64) -> Vec<(f64, [f64; 4])> {
        let (mut q, mut w) = ([0.9, 0.1, -0.3, 0.2], [0.05, 1.2, 0.08]);
        let nq = q.iter().map(|v: &f64| v * v).sum::<f64>().sqrt();
        q.iter_mut().for_each(|v| *v /= nq);
        let mut out = vec![(0.0, q)];
        let mut t = 0.0;
        while t < secs {
            // A finer reference integration than the forecast's.
            for _ in 0..4 {
                (q, w) = step_rk4(&q, &w, &euler_coefficients(inertia), N_FRAME, 0.005);
            }
            t += 0.02;
            out.push((t, q));
        }
        out
    }

    #[test]
    fn energy_and_momentum_are_kept() {
        let i = box_inertia(&[0.6, 0.15, 0.05]);
        let (q0, w0) = ([1.0, 0.0, 0.0, 0.0], [0.3, 1.0, 0.2]);
        let (_, w) = propagate(&q0, &w0, &i, 0.0, 20.0);
        let e = |w: &[f64; 3]| (0..3).map(|k| i[k] * w[k] * w[k]).sum::<f64>();
        let l = |w: &[f64; 3]| (0..3).map(|k| (i[k] * w[k]).powi(2)).sum::<f64>();
        assert!((e(&w) - e(&w0)).abs() < 1e-6 * e(&w0));
        assert!((l(&w) - l(&w0)).abs() < 1e-6 * l(&w0));
        // Backwards undoes forwards.
        let (q1, w1) = propagate(&q0, &w0, &i, N_FRAME, 3.0);
        let (q2, w2) = propagate(&q1, &w1, &i, N_FRAME, -3.0);
        assert!(quat_angle(&q0, &q2) < 1e-6 && (0..3).all(|k| (w0[k] - w2[k]).abs() < 1e-6));
    }

    #[test]
    fn hints_only_for_centred_boxes() {
        let b = DebrisShape { kind: ShapeKind::Box as u32, dims: [0.6, 0.15, 0.05], ..Default::default() };
        let i = inertia_hint(&b).unwrap();
        assert!(i[0] < i[1] && i[1] < i[2], "the long axis has the smallest moment: {i:?}");
        let off = DebrisShape { offset: [0.1, 0.0, 0.0], ..b };
        assert!(inertia_hint(&off).is_none());
        let rod =
            DebrisShape { kind: ShapeKind::Capsule as u32, dims: [1.0, 0.05, 0.0], ..Default::default() };
        assert!(inertia_hint(&rod).is_none());
    }

    #[test]
    fn forecasts_a_flipping_box_and_calibrates_its_bound() {
        let i = box_inertia(&[0.6, 0.4, 0.05]);
        let traj = truth(&i, 20.0);
        let (dt, h) = (0.1, 40);
        let mut ch = EulerChannel::new();
        ch.update(0.0, &traj[0].1, dt, h, N_FRAME);
        assert!(!ch.ready(), "no inertia: no forecast");
        ch.set_inertia(Some(i.map(|v| v * 7.0)));
        let mut seen_young = false;
        // Noisy filtered attitudes (±5 mrad).
        let mut seed = 3u64;
        let mut rnd = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let upto = traj.iter().position(|s| s.0 >= 14.0).unwrap();
        for (t, q) in &traj[..=upto] {
            let noisy = quat_mul(q, &[1.0, 0.0025 * rnd(), 0.0025 * rnd(), 0.0025 * rnd()]);
            ch.update(*t, &noisy, dt, h, N_FRAME);
            if *t < 1.4 {
                assert!(!ch.ready());
                seen_young = true;
            }
        }
        assert!(seen_young && ch.ready());
        let t_now = traj[upto].0;
        let mut qs = [[0.0; 4]; 40];
        assert!(ch.attitudes_into(N_FRAME, t_now, dt, &mut qs));
        let mut r = [0.0; 40];
        assert_eq!(ch.radii(0.02, 1.5, &mut r), 40);
        for k in [5, 20, 40] {
            let tk = t_now + k as f64 * dt;
            let truth_q = traj.iter().min_by(|a, b| (a.0 - tk).abs().total_cmp(&(b.0 - tk).abs())).unwrap().1;
            let err = quat_angle(&qs[k - 1], &truth_q);
            assert!(err < 0.05, "{k} steps: {err} rad");
            assert!(r[k - 1] >= err && r[k - 1] < 0.3, "{k} steps: bound {} vs error {err}", r[k - 1]);
        }
        // A constant-rate forecast of the same box is far off at 4 s (it flips).
        let w_now = rot_err(&traj[upto - 5].1, &traj[upto].1).map(|v| v / 0.1);
        let (qc, _) = propagate(&traj[upto].1, &w_now, &[1.0, 1.0, 1.0], N_FRAME, 4.0);
        let t4 = t_now + 4.0;
        let q4t = traj.iter().min_by(|a, b| (a.0 - t4).abs().total_cmp(&(b.0 - t4).abs())).unwrap().1;
        assert!(quat_angle(&qc, &q4t) > 0.3, "the test box must not be predictable at constant rate");
        // A wrong inertia: the channel's own scores say so.
        let mut wrong = EulerChannel::new();
        wrong.set_inertia(Some([1.0, 1.0, 1.0]));
        for (t, q) in &traj[..=upto] {
            wrong.update(*t, q, dt, h, N_FRAME);
        }
        let mut rw = [0.0; 40];
        assert_eq!(wrong.radii(0.02, 1.5, &mut rw), 40);
        assert!(rw[39] > 0.3, "wrong inertia must show as a wide bound: {}", rw[39]);
        // Restart forgets the fit, keeps the scores.
        ch.restart();
        assert!(!ch.ready() && ch.radii(0.02, 1.5, &mut r) == 0);
    }

    /// A front end refines its estimate of a box by millimetres: the channel keeps its fit
    /// and scores (its forecast barely moves); a different box starts it afresh.
    #[test]
    fn a_refined_inertia_keeps_the_channel_and_a_new_one_restarts_it() {
        let h = [0.6, 0.4, 0.05];
        let traj = truth(&box_inertia(&h), 8.0);
        let (dt, steps) = (0.1, 40);
        let mut ch = EulerChannel::new();
        ch.set_inertia(Some(box_inertia(&h)));
        for (t, q) in &traj {
            ch.update(*t, q, dt, steps, N_FRAME);
        }
        let mut r = [0.0; 40];
        assert_eq!(ch.radii(0.02, 1.5, &mut r), 40);
        let t_now = traj.last().unwrap().0;
        let mut before = [[0.0; 4]; 40];
        assert!(ch.attitudes_into(N_FRAME, t_now, dt, &mut before));
        // 2 cm more on the long side, 1 cm on the short one; a common factor is no change.
        let refined = box_inertia(&[0.62, 0.41, 0.05]).map(|v| v * 3.0);
        let mut kept = ch;
        kept.set_inertia(Some(refined));
        assert_eq!(kept.inertia(), Some(refined));
        let mut rk = [0.0; 40];
        assert_eq!(kept.radii(0.02, 1.5, &mut rk), 40, "scores kept");
        assert_eq!(rk, r);
        let mut after = [[0.0; 4]; 40];
        assert!(kept.attitudes_into(N_FRAME, t_now, dt, &mut after));
        assert!(quat_angle(&before[39], &after[39]) < 0.2, "{}", quat_angle(&before[39], &after[39]));
        // A narrower box (a moment off by far more than REFINE): afresh.
        let mut other = ch;
        let narrow = box_inertia(&[0.6, 0.2, 0.05]);
        let share = |i: &[f64; 3]| i[0] / i.iter().sum::<f64>();
        assert!(share(&narrow) < (1.0 - 2.0 * EulerChannel::REFINE) * share(&box_inertia(&h)));
        other.set_inertia(Some(narrow));
        assert!(!other.ready() && other.radii(0.02, 1.5, &mut rk) == 0);
        let mut gone = ch;
        gone.set_inertia(None);
        assert!(!gone.ready());
    }
}
