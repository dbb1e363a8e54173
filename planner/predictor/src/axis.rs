//! The symmetry axis of a tumbling rod, forecast by its precession.
//!
//! A torque-free body with two equal principal moments (`I_x = I_y`: every rod, capsule or
//! cylinder) has a body axis `z` that rotates about the fixed angular momentum `L` at the
//! constant rate `|L| / I_x`: with `ω = ω_⊥ + ω_z z` and `L = I_x ω_⊥ + I_z ω_z z`,
//! `ż = ω × z = ω_⊥ × z = (L / I_x) × z`. So the axis follows `ż = Ω × z` with one constant
//! vector `Ω`, whatever the spin about the axis does (for a thin rod that spin is fast and
//! erratic, `I_z ≪ I_x`, and it is what makes a full-attitude forecast of a rod poor). The
//! spin does not change a capsule's shape, so the axis is all a planner needs.
//!
//! [`AxisPrecession`] estimates `Ω` by exponentially weighted least squares over the sampled
//! axis directions: each sample contributes `P_z Ω = z × ż` (`P_z = I − z zᵀ`: the component
//! of `Ω` along `z` is invisible at one instant, the axis's motion around its cone fixes it),
//! with `ż` from chords of the axis over a fixed lag and a small ridge toward the filter's
//! instantaneous rate. The forecast turns the current axis about `Ω` (Rodrigues). `Ω` is
//! fitted to the filter's axes, the current axis is the measured ones averaged
//! ([`AxisPrecession::smoothed`]: the filter's attitude trails a coning axis, a spinning
//! disc's normal, by a tenth of a radian), and no chord spans a gap in which the axis may
//! have turned far ([`AxisPrecession::MAX_CHORD`]). Nothing here allocates.
//!
//! The bound on this forecast's error is calibrated online per track ([`AxisPrecession`]
//! keeps its own past forecasts and scores them when the horizon has passed).

use dkrrt_collision::quat_rotate;
use dkrrt_koopman::debris_state::quat_mul;

/// Samples kept for the chord differences (at 50 Hz: 0.3 s).
const RING: usize = 16;

/// Online estimate of an axis's precession vector `Ω` (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisPrecession {
    a: [[f64; 3]; 3],
    b: [f64; 3],
    /// Time of the newest sample, s.
    pub t: f64,
    /// Newest axis direction (unit).
    pub z: [f64; 3],
    ring_t: [f64; RING],
    ring_z: [[f64; 3]; RING],
    /// The measured axes of the same samples.
    ring_seen: [[f64; 3]; RING],
    head: usize,
    len: usize,
    /// Samples absorbed.
    pub n: u32,
    w_rate: [f64; 3],
}

/// The body z axis of the attitude `q` (body → frame, `(w, x, y, z)`).
pub fn body_z(q: &[f64]) -> [f64; 3] {
    quat_rotate(&unit(q), &[0.0, 0.0, 1.0])
}

/// Angle between two axes of an end-to-end symmetric shape (a line: `u` and `−u` are the
/// same), rad, in `[0, π/2]`.
pub fn line_angle(u: &[f64; 3], v: &[f64; 3]) -> f64 {
    let d = (u[0] * v[0] + u[1] * v[1] + u[2] * v[2]).abs();
    let c = cross(u, v);
    let s = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
    s.atan2(d)
}

fn cross(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn unit(q: &[f64]) -> [f64; 4] {
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    [q[0] / n, q[1] / n, q[2] / n, q[3] / n]
}

/// `v` turned by the rotation vector `r` (Rodrigues).
pub fn rotate(r: &[f64; 3], v: &[f64; 3]) -> [f64; 3] {
    let th = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
    if th < 1e-12 {
        return *v;
    }
    let k = r.map(|c| c / th);
    let (s, c) = th.sin_cos();
    let kv = cross(&k, v);
    let kd = k[0] * v[0] + k[1] * v[1] + k[2] * v[2];
    [0, 1, 2].map(|i| v[i] * c + kv[i] * s + k[i] * kd * (1.0 - c))
}

impl Default for AxisPrecession {
    fn default() -> Self {
        Self::new()
    }
}

impl AxisPrecession {
    /// Forgetting time constant of the least squares, s.
    pub const TAU: f64 = 2.0;
    /// Chord lag for the axis rate, s (the oldest ring sample at least this old is used).
    pub const LAG: f64 = 0.15;
    /// Ridge toward the filter's instantaneous rate (relative weight).
    pub const RIDGE: f64 = 1e-3;
    /// Longest chord, s, unless the estimated rate turns the axis by at most
    /// [`AxisPrecession::MAX_TURN`] over it: over a gap between samples (an object unseen or its
    /// attitude unmeasured for a while) a fast tumbler's axis may have turned by any angle, a
    /// full turn or more, and a chord across it says nothing of its rate; a slow one's chord
    /// still does. After a gap too long the chords start again from the samples after it
    /// (the least squares keep what came before, decaying).
    pub const MAX_CHORD: f64 = 4.0 * Self::LAG;
    /// Largest turn of the axis over a chord longer than [`AxisPrecession::MAX_CHORD`], rad
    /// (the chord's rate is then within 1 % of the rate at its middle).
    pub const MAX_TURN: f64 = 0.5;
    /// The samples averaged into the current axis are at most this old, s.
    pub const SMOOTH: f64 = 2.0 * Self::LAG;

    pub fn new() -> Self {
        AxisPrecession {
            a: [[0.0; 3]; 3],
            b: [0.0; 3],
            t: f64::NAN,
            z: [0.0, 0.0, 1.0],
            ring_t: [f64::NAN; RING],
            ring_z: [[0.0; 3]; RING],
            ring_seen: [[0.0; 3]; RING],
            head: 0,
            len: 0,
            n: 0,
            w_rate: [0.0; 3],
        }
    }

    /// Absorbs a filtered attitude `q` (body → frame) at time `t`, the measured one `seen`
    /// and the filter's body rate `w_body` (used only as the ridge's prior): the rate is fitted
    /// to the filtered axes (smooth; a filter's lag shifts them along the cone, which leaves
    /// the rate as it is), the forecasts start from the measured ones
    /// ([`AxisPrecession::smoothed`]: a filter trails a coning axis). Samples not newer than
    /// the last are ignored.
    pub fn update(&mut self, t: f64, q: &[f64], seen: &[f64], w_body: &[f64]) {
        if !t.is_finite() || (self.t.is_finite() && t <= self.t) {
            return;
        }
        let z = body_z(q);
        let mut zs = body_z(seen);
        if zs[0] * z[0] + zs[1] * z[1] + zs[2] * z[2] < 0.0 {
            zs = zs.map(|c| -c);
        }
        self.w_rate = quat_rotate(&unit(q), &[w_body[0], w_body[1], w_body[2]]);
        // Chord to the newest ring sample at least LAG old.
        let mut chord = None;
        for j in 0..self.len {
            let i = (self.head + RING - 1 - j) % RING;
            let dt = t - self.ring_t[i];
            if dt >= Self::LAG {
                let fits = || {
                    let w = self.omega();
                    (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt() * dt <= Self::MAX_TURN
                };
                chord = (dt <= Self::MAX_CHORD || fits()).then_some((dt, self.ring_z[i]));
                break;
            }
        }
        if let Some((dt, z0)) = chord {
            // Midpoint direction and rate of the chord.
            let m = [z[0] + z0[0], z[1] + z0[1], z[2] + z0[2]];
            let mn = (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt().max(1e-12);
            let zm = m.map(|c| c / mn);
            let zd = [(z[0] - z0[0]) / dt, (z[1] - z0[1]) / dt, (z[2] - z0[2]) / dt];
            let lam = (-(t - self.t) / Self::TAU).exp();
            let rhs = cross(&zm, &zd);
            for r in 0..3 {
                for c in 0..3 {
                    let p = if r == c { 1.0 } else { 0.0 } - zm[r] * zm[c];
                    self.a[r][c] = lam * self.a[r][c] + p;
                }
                self.b[r] = lam * self.b[r] + rhs[r];
            }
            self.n += 1;
        }
        self.ring_t[self.head] = t;
        self.ring_z[self.head] = z;
        self.ring_seen[self.head] = zs;
        self.head = (self.head + 1) % RING;
        self.len = (self.len + 1).min(RING);
        self.t = t;
        self.z = zs;
    }

    /// Whether an axis was absorbed since the start (or the last restart): the forecasts
    /// ([`AxisPrecession::axis_at`]) start from the newest one.
    pub fn has_samples(&self) -> bool {
        self.len > 0
    }

    /// The precession vector `Ω` (frame axes), rad/s: the least-squares solution with a ridge
    /// toward the filter's rate (which alone it is before the first chord).
    pub fn omega(&self) -> [f64; 3] {
        let tr = self.a[0][0] + self.a[1][1] + self.a[2][2];
        let eps = Self::RIDGE * tr.max(1.0);
        let mut m = self.a;
        let mut r = self.b;
        for i in 0..3 {
            m[i][i] += eps;
            r[i] += eps * self.w_rate[i];
        }
        solve3(&m, &r).unwrap_or(self.w_rate)
    }

    /// The axis at the newest sample's time, from the samples of the last
    /// [`AxisPrecession::SMOOTH`] seconds each turned on by `omega` to that time and averaged
    /// (weights decaying with their age over [`AxisPrecession::LAG`]): a measured axis's noise
    /// averaged, without the lag of a filter.
    pub fn smoothed(&self, omega: &[f64; 3]) -> [f64; 3] {
        let mut m = [0.0; 3];
        for j in 0..self.len {
            let i = (self.head + RING - 1 - j) % RING;
            let age = self.t - self.ring_t[i];
            if age > Self::SMOOTH {
                break;
            }
            let z = rotate(&omega.map(|w| w * age), &self.ring_seen[i]);
            // A line: each sample on the newest one's side.
            let s = if z[0] * self.z[0] + z[1] * self.z[1] + z[2] * self.z[2] < 0.0 { -1.0 } else { 1.0 };
            let w = s * (-age / Self::LAG).exp();
            (0..3).for_each(|k| m[k] += w * z[k]);
        }
        let n = (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt();
        if n > 1e-9 {
            m.map(|c| c / n)
        } else {
            self.z
        }
    }

    /// The axis `dt` seconds after the newest sample ([`AxisPrecession::smoothed`] turned on).
    pub fn axis_at(&self, omega: &[f64; 3], dt: f64) -> [f64; 3] {
        rotate(&omega.map(|w| w * dt), &self.smoothed(omega))
    }

    /// The axis at `t0 + k·step`, `k = 1..=out.len()`, with `t0` = the newest sample + `offset`
    /// (one rotation matrix applied step by step).
    pub fn axes_into(&self, omega: &[f64; 3], offset: f64, step: f64, out: &mut [[f64; 3]]) {
        let r = omega.map(|w| w * step);
        // Columns of the rotation by r: the images of the unit vectors.
        let cols = [rotate(&r, &[1.0, 0.0, 0.0]), rotate(&r, &[0.0, 1.0, 0.0]), rotate(&r, &[0.0, 0.0, 1.0])];
        let mut z = self.axis_at(omega, offset);
        for o in out.iter_mut() {
            z = [0, 1, 2].map(|i| cols[0][i] * z[0] + cols[1][i] * z[1] + cols[2][i] * z[2]);
            *o = z;
        }
    }

    /// Rotates the attitude `q` (body → frame) so that its body z axis lies along `axis` by the
    /// smallest rotation (the spin about the axis is kept as `q` has it).
    pub fn align(q: &[f64], axis: &[f64; 3]) -> [f64; 4] {
        let z = body_z(q);
        let c = cross(&z, axis);
        let d = z[0] * axis[0] + z[1] * axis[1] + z[2] * axis[2];
        // Quaternion of the rotation z → axis: (1 + d, c), normalised.
        let mut r = [1.0 + d, c[0], c[1], c[2]];
        let n = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2] + r[3] * r[3]).sqrt();
        if n < 1e-9 {
            // Opposite: the same line for a symmetric shape.
            return [q[0], q[1], q[2], q[3]];
        }
        r.iter_mut().for_each(|x| *x /= n);
        quat_mul(&r, q)
    }
}

/// `m x = r` for a 3×3 `m` by Cramer's rule; `None` when `|det m| < 1e-15`.
pub(crate) fn solve3(m: &[[f64; 3]; 3], r: &[f64; 3]) -> Option<[f64; 3]> {
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    if det.abs() < 1e-15 {
        return None;
    }
    let col = |j: usize| {
        let mut a = *m;
        for i in 0..3 {
            a[i][j] = r[i];
        }
        a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
    };
    Some([col(0) / det, col(1) / det, col(2) / det])
}

use crate::calib::StepScores;
pub use crate::calib::MAX_STEPS;

/// One track's axis forecast and its online calibration: [`AxisPrecession`] plus its own
/// forecasts taken every model step `dt`, each scored against the measured axis when `k`
/// steps have passed ([`StepScores`]: per step a decaying maximum of the angles seen; the
/// bound `k` steps ahead is `floor + factor · max_{j ≤ k} score_j`). Steps not yet scored
/// since the track began (a young track) have no calibrated bound: the caller falls back to
/// the attitude model's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisChannel {
    /// The precession estimate.
    pub prec: AxisPrecession,
    snap_t: [f64; MAX_STEPS + 1],
    snap_z: [[f64; 3]; MAX_STEPS + 1],
    snap_w: [[f64; 3]; MAX_STEPS + 1],
    head: usize,
    len: usize,
    scores: StepScores,
    last_round: f64,
}

impl Default for AxisChannel {
    fn default() -> Self {
        Self::new()
    }
}

impl AxisChannel {
    /// Chords the precession estimate needs before its forecasts are scored and its bound is
    /// used (at 50 Hz: 1 s); before, the caller uses the attitude model's bound.
    pub const MATURE: u32 = 50;

    pub fn new() -> Self {
        AxisChannel {
            prec: AxisPrecession::new(),
            snap_t: [f64::NAN; MAX_STEPS + 1],
            snap_z: [[0.0; 3]; MAX_STEPS + 1],
            snap_w: [[0.0; 3]; MAX_STEPS + 1],
            head: 0,
            len: 0,
            scores: StepScores::new(),
            last_round: f64::NAN,
        }
    }

    /// Absorbs a filtered and a measured attitude (see [`AxisPrecession::update`]); every `dt`
    /// seconds it scores its earlier forecasts up to `h` steps old and takes a new one.
    pub fn update(&mut self, t: f64, q: &[f64], seen: &[f64], w_body: &[f64], dt: f64, h: usize) {
        let before = self.prec.t;
        self.prec.update(t, q, seen, w_body);
        if self.prec.t == before || dt.is_nan() || dt <= 0.0 {
            return;
        }
        let h = h.min(MAX_STEPS);
        if self.last_round.is_finite() && t - self.last_round < dt - 1e-9 {
            return;
        }
        self.scores.decay(t);
        self.last_round = t;
        let z = self.prec.z;
        for j in 0..self.len {
            let i = (self.head + MAX_STEPS - j) % (MAX_STEPS + 1);
            let tau = t - self.snap_t[i];
            let k = (tau / dt).round() as usize;
            if k == 0 || k > h {
                continue;
            }
            let p = rotate(&self.snap_w[i].map(|w| w * tau), &self.snap_z[i]);
            self.scores.add(k, line_angle(&p, &z));
        }
        if self.prec.n < Self::MATURE {
            return;
        }
        let w = self.prec.omega();
        self.snap_t[self.head] = t;
        self.snap_z[self.head] = self.prec.smoothed(&w);
        self.snap_w[self.head] = w;
        self.head = (self.head + 1) % (MAX_STEPS + 1);
        self.len = (self.len + 1).min(MAX_STEPS + 1);
    }

    /// Calibrated bound `k` steps ahead (`1 ≤ k`), rad, or `None` if step `k` has not been
    /// scored yet.
    pub fn radius(&self, k: usize, floor: f64, factor: f64) -> Option<f64> {
        (self.prec.n >= Self::MATURE).then(|| self.scores.radius(k, floor, factor)).flatten()
    }

    /// [`AxisChannel::radius`] for `k = 1, 2, …` into `out[k − 1]` while step `k` is scored;
    /// returns how many were written (the rest: no calibrated bound).
    pub fn radii(&self, floor: f64, factor: f64, out: &mut [f64]) -> usize {
        if self.prec.n < Self::MATURE {
            return 0;
        }
        self.scores.radii(floor, factor, out)
    }

    /// Forget the precession estimate and the forecasts made with it (after an attitude
    /// event), keep the scores.
    pub fn restart(&mut self) {
        self.prec = AxisPrecession::new();
        self.len = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{UnitQuaternion, Vector3};

    /// A rod whose axis precesses about `om` while it spins about itself at a rate that
    /// changes (as a thin rod's does): attitude at `t`.
    fn rod(t: f64) -> [f64; 4] {
        let om = Vector3::new(0.3, -0.5, 0.2);
        let q0 = UnitQuaternion::from_scaled_axis(Vector3::new(0.4, 0.1, -0.7));
        let q = UnitQuaternion::from_scaled_axis(om * t)
            * q0
            * UnitQuaternion::from_scaled_axis(Vector3::z() * 2.0 * t * t);
        [q.w, q.i, q.j, q.k]
    }

    #[test]
    fn precession_forecasts_the_axis_whatever_the_spin() {
        let mut ax = AxisPrecession::new();
        for i in 0..200 {
            let t = i as f64 * 0.02;
            ax.update(t, &rod(t), &rod(t), &[0.0; 3]);
        }
        let o = ax.omega();
        let t_last = 199.0 * 0.02;
        for (dt, tol) in [(0.5, 0.005), (2.0, 0.01), (4.0, 0.02)] {
            let err = line_angle(&ax.axis_at(&o, dt), &body_z(&rod(t_last + dt)));
            assert!(err < tol, "{dt} s: {err}");
        }
        // The full attitude is not predictable this way (the spin): the axis is all we claim.
        let q = AxisPrecession::align(&rod(t_last), &ax.axis_at(&o, 2.0));
        assert!(line_angle(&body_z(&q), &body_z(&rod(t_last + 2.0))) < 0.01);
    }

    /// Samples resuming after a gap (the object unseen, or its attitude unmeasured, for 3 s,
    /// in which the axis turned 1.9 rad) make no chord across it: the forecast right after is
    /// as good as before (with chords across the gap it was 4 times as far off 1 s ahead). A
    /// slow axis, which the gap turned by less than `MAX_TURN`, keeps its chord across it.
    #[test]
    fn no_chord_spans_a_gap_the_axis_turned_far_in() {
        let run = |rate: f64| {
            let at = |t: f64| rod(rate * t);
            let mut ax = AxisPrecession::new();
            let mut t = 0.0;
            for i in 0..200 {
                t = i as f64 * 0.02;
                ax.update(t, &at(t), &at(t), &[0.0; 3]);
            }
            let (t_gap, n_before) = (t + 3.0, ax.n);
            ax.update(t_gap, &at(t_gap), &at(t_gap), &[0.0; 3]);
            let chord_across = ax.n > n_before;
            for i in 1..12 {
                t = t_gap + i as f64 * 0.02;
                ax.update(t, &at(t), &at(t), &[0.0; 3]);
            }
            let o = ax.omega();
            let errs = [1.0, 2.0].map(|dt| line_angle(&ax.axis_at(&o, dt), &body_z(&at(t + dt))));
            (chord_across, errs)
        };
        let (across, errs) = run(1.0);
        assert!(!across);
        for (dt, err) in [1.0, 2.0].into_iter().zip(errs) {
            assert!(err < 0.004 * dt + 0.003, "{dt} s after: {err} rad");
        }
        // 0.15 × 0.62 rad/s: 0.28 rad in the 3 s.
        let (across, errs) = run(0.15);
        assert!(across && errs[1] < 0.005, "{errs:?}");
    }

    #[test]
    fn channel_bound_is_calibrated_online_and_absent_while_young() {
        let (dt, h) = (0.1, 40);
        let mut ch = AxisChannel::new();
        let mut seen_young = false;
        for i in 0..500 {
            let t = i as f64 * 0.02;
            ch.update(t, &rod(t), &rod(t), &[0.0; 3], dt, h);
            if t < 1.0 {
                assert!(ch.radius(1, 0.02, 1.5).is_none(), "young at {t}");
                seen_young = true;
            }
        }
        assert!(seen_young);
        // Exact precession: a small bound at every horizon scored, containing the error of
        // the current forecast.
        let t_last = 499.0 * 0.02;
        let o = ch.prec.omega();
        for k in [1, 10, 40] {
            let r = ch.radius(k, 0.02, 1.5).unwrap();
            let err = line_angle(&ch.prec.axis_at(&o, k as f64 * dt), &body_z(&rod(t_last + k as f64 * dt)));
            assert!(r < 0.2 && r >= err, "k {k}: bound {r}, error {err}");
        }
        // After a sudden change of the precession the short-horizon scores rise, and every
        // longer horizon with them.
        let mut ch2 = ch;
        for i in 500..560 {
            let t = i as f64 * 0.02;
            let q = UnitQuaternion::from_scaled_axis(Vector3::x() * 1.5 * (t - 10.0))
                * UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                    rod(t)[0],
                    rod(t)[1],
                    rod(t)[2],
                    rod(t)[3],
                ));
            ch2.update(t, &[q.w, q.i, q.j, q.k], &[q.w, q.i, q.j, q.k], &[0.0; 3], dt, h);
        }
        assert!(ch2.radius(40, 0.02, 1.5).unwrap() >= ch2.radius(1, 0.02, 1.5).unwrap());
        // The batch forms agree with the one-step ones.
        let mut r = [0.0; 40];
        assert_eq!(ch2.radii(0.02, 1.5, &mut r), 40);
        for k in 1..=40 {
            assert!((r[k - 1] - ch2.radius(k, 0.02, 1.5).unwrap()).abs() < 1e-12);
        }
        let o = ch2.prec.omega();
        let mut zs = [[0.0; 3]; 40];
        ch2.prec.axes_into(&o, 0.01, 0.1, &mut zs);
        for k in 1..=40 {
            let z = ch2.prec.axis_at(&o, 0.01 + 0.1 * k as f64);
            assert!((0..3).all(|i| (z[i] - zs[k - 1][i]).abs() < 1e-9), "{k}");
        }
        assert!(ch2.radius(40, 0.02, 1.5).unwrap() > 2.0 * ch.radius(40, 0.02, 1.5).unwrap());
    }
}
