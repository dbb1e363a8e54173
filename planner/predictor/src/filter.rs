//! Per-track pose filter: position/velocity and attitude/body-rate estimates from noisy pose
//! observations.
//!
//! Two decoupled constant-velocity Kalman filters with white-acceleration process noise:
//!
//! * translation, per LVLH axis: state `[p_i, v_i]`;
//! * attitude, error-state (multiplicative) form, per body axis: state `[δθ_i, ω_i]` where
//!   `δθ` is the small body-frame rotation between the predicted and the estimated attitude.
//!   Prediction `q⁻ = exp(−n ẑ Δt/2) ⊗ q ⊗ exp(ω Δt/2)` (constant body rate in the LVLH frame
//!   rotating at `n`), innovation `δ = Log(q⁻⁻¹ ⊗ z)` with the sign of `z` aligned to `q⁻`,
//!   correction `q = q⁻ ⊗ Exp(k₀ δ)`, `ω += k₁ δ`.
//!
//! Because the three axes of each block share the time step and the noise levels, one 2×2
//! covariance per block serves all three axes. Everything is `Copy` and allocation-free.

use dkrrt_koopman::debris_state::{quat_exp, quat_mul, N};
use serde::Serialize;

/// Noise and initialisation parameters of [`TrackFilter`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FilterConfig {
    /// Position measurement std-dev per axis [m].
    pub pos_sigma: f64,
    /// Attitude measurement std-dev per axis (small rotation) [rad].
    pub att_sigma: f64,
    /// Translational white-acceleration spectral density [(m/s²)²·s].
    pub accel_psd: f64,
    /// Rotational white-angular-acceleration spectral density [(rad/s²)²·s] (torque-free
    /// tumbling of an asymmetric body changes the body rate: this must not be tiny).
    pub ang_accel_psd: f64,
    /// Initial velocity std-dev [m/s].
    pub init_vel_sigma: f64,
    /// Initial body-rate std-dev [rad/s].
    pub init_rate_sigma: f64,
    /// LVLH frame rotation rate about z (orbital mean motion) [rad/s].
    pub frame_rate: f64,
}

impl Default for FilterConfig {
    fn default() -> Self {
        FilterConfig {
            pos_sigma: 0.01,
            att_sigma: 0.01,
            accel_psd: 1e-3,
            ang_accel_psd: 0.01,
            init_vel_sigma: 1.0,
            init_rate_sigma: 2.0,
            frame_rate: 1.1314e-3,
        }
    }
}

/// 2×2 symmetric covariance of a constant-velocity axis `[x, ẋ]`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct Kf2 {
    p00: f64,
    p01: f64,
    p11: f64,
}

impl Kf2 {
    fn init(var_x: f64, var_v: f64) -> Self {
        Kf2 { p00: var_x, p01: 0.0, p11: var_v }
    }
    fn predict(&mut self, dt: f64, q: f64) {
        self.p00 += dt * (2.0 * self.p01 + dt * self.p11) + q * dt * dt * dt / 3.0;
        self.p01 += dt * self.p11 + q * dt * dt / 2.0;
        self.p11 += q * dt;
    }
    /// Measurement of `x` with variance `r`: returns the gains and updates `P ← (I − K H) P`.
    fn update(&mut self, r: f64) -> (f64, f64) {
        let s = self.p00 + r;
        let (k0, k1) = (self.p00 / s, self.p01 / s);
        let (p00, p01) = (self.p00, self.p01);
        self.p00 = p00 - k0 * p00;
        self.p01 = p01 - k0 * p01;
        self.p11 -= k1 * p01;
        (k0, k1)
    }
}

/// Conjugate of a unit quaternion.
#[inline]
pub fn quat_conj(q: &[f64]) -> [f64; 4] {
    [q[0], -q[1], -q[2], -q[3]]
}

/// Rotation vector of a unit quaternion (logarithm map), shortest rotation.
#[inline]
pub fn quat_log(q: &[f64]) -> [f64; 3] {
    let (w, v) = if q[0] < 0.0 { (-q[0], [-q[1], -q[2], -q[3]]) } else { (q[0], [q[1], q[2], q[3]]) };
    let s = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if s < 1e-12 {
        return [2.0 * v[0], 2.0 * v[1], 2.0 * v[2]];
    }
    let k = 2.0 * s.atan2(w) / s;
    [k * v[0], k * v[1], k * v[2]]
}

/// Rotation angle between two attitudes (sign-invariant) [rad].
#[inline]
pub fn quat_angle(a: &[f64], b: &[f64]) -> f64 {
    let na = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2] + a[3] * a[3]).sqrt();
    let nb = (b[0] * b[0] + b[1] * b[1] + b[2] * b[2] + b[3] * b[3]).sqrt();
    let d = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]).abs() / (na * nb);
    2.0 * d.min(1.0).acos()
}

fn normalise(q: &mut [f64]) {
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    q[..4].iter_mut().for_each(|v| *v /= n);
}

/// Pose filter of one track. State layout: [`dkrrt_koopman::debris_state`]
/// (`[p, v, q(w,x,y,z), ω_body]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackFilter {
    /// Current estimate.
    pub x: [f64; N],
    /// Time of the estimate (last measurement) [s].
    pub t: f64,
    pos: Kf2,
    att: Kf2,
}

impl TrackFilter {
    /// Initialise from the first pose (velocity and rate zero, large uncertainty).
    pub fn new(cfg: &FilterConfig, t: f64, p: &[f64; 3], q: &[f64; 4]) -> Self {
        let mut x = [0.0; N];
        x[0..3].copy_from_slice(p);
        x[6..10].copy_from_slice(q);
        normalise(&mut x[6..10]);
        TrackFilter {
            x,
            t,
            pos: Kf2::init(cfg.pos_sigma.powi(2), cfg.init_vel_sigma.powi(2)),
            att: Kf2::init(cfg.att_sigma.powi(2), cfg.init_rate_sigma.powi(2)),
        }
    }

    /// Predicted state at time `t ≥ self.t` (constant velocity / body rate), without updating.
    pub fn predicted(&self, cfg: &FilterConfig, t: f64) -> [f64; N] {
        let dt = t - self.t;
        let mut x = self.x;
        for i in 0..3 {
            x[i] += x[3 + i] * dt;
        }
        let w = [x[10] * dt, x[11] * dt, x[12] * dt];
        let q = quat_mul(&quat_mul(&quat_exp([0.0, 0.0, -cfg.frame_rate * dt]), &x[6..10]), &quat_exp(w));
        x[6..10].copy_from_slice(&q);
        normalise(&mut x[6..10]);
        x
    }

    /// Measurement update with a pose at time `t > self.t`.
    pub fn update(&mut self, cfg: &FilterConfig, t: f64, p: &[f64; 3], q: &[f64; 4]) {
        let dt = t - self.t;
        debug_assert!(dt > 0.0);
        let xp = self.predicted(cfg, t);
        // Translation.
        self.pos.predict(dt, cfg.accel_psd);
        let (k0, k1) = self.pos.update(cfg.pos_sigma.powi(2));
        for i in 0..3 {
            let y = p[i] - xp[i];
            self.x[i] = xp[i] + k0 * y;
            self.x[3 + i] = xp[3 + i] + k1 * y;
        }
        // Attitude (error state in body axes).
        self.att.predict(dt, cfg.ang_accel_psd);
        let (k0, k1) = self.att.update(cfg.att_sigma.powi(2));
        let e = quat_mul(&quat_conj(&xp[6..10]), q);
        let d = quat_log(&e);
        let qn = quat_mul(&xp[6..10], &quat_exp([k0 * d[0], k0 * d[1], k0 * d[2]]));
        self.x[6..10].copy_from_slice(&qn);
        normalise(&mut self.x[6..10]);
        for i in 0..3 {
            self.x[10 + i] = xp[10 + i] + k1 * d[i];
        }
        self.t = t;
    }
}
