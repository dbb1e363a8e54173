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
//!
//! **Manoeuvre re-opening (translation).** Free debris translates on an almost straight line
//! (over 2 s the relative-orbit curvature is µm), so the translational acceleration PSD is
//! small and the velocity estimate averages over seconds of poses. An impulse would then
//! take seconds to show in the estimate; instead, the normalised innovation squared
//! `ν = mean_i y_i² / S` (expected 1) is averaged with an exponential window of
//! `maneuver_window` updates, and when the average exceeds `maneuver_nis` the velocity
//! variance is raised to `maneuver_vel_sigma²` (and the average restarts), so the next few
//! poses re-estimate the velocity. [`TrackFilter::maneuvers`] counts these re-openings.

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
    /// Manoeuvre test: threshold on the averaged normalised innovation squared (expected 1).
    pub maneuver_nis: f64,
    /// Manoeuvre test: averaging window (updates, exponential).
    pub maneuver_window: f64,
    /// Velocity std-dev the translation filter re-opens to on a manoeuvre [m/s].
    pub maneuver_vel_sigma: f64,
    /// Velocity measurement std-dev per axis [m/s] (sensors that report rates).
    pub vel_sigma: f64,
    /// Body-rate measurement std-dev per axis [rad/s] (sensors that report rates).
    pub rate_sigma: f64,
    /// Robust position update for heavy-tailed poses (e.g. poses from depth frames, whose
    /// centroid now and then jumps with the visible side): a pose whose innovation lies more
    /// than this many standard deviations (of the predicted innovation, per axis) out pulls
    /// the estimate as if its noise were that much larger (Huber), and adds at most this
    /// many squared deviations to the manoeuvre test's average, so one outlier neither drags
    /// the track nor re-opens its velocity; a manoeuvre shows as a run of large innovations.
    /// `f64::INFINITY` (the default): the plain Kalman update.
    pub outlier_sigmas: f64,
}

/// Default translational acceleration PSD (see the README's tuning sweep).
pub const ACCEL_PSD: f64 = 1e-7;

impl Default for FilterConfig {
    fn default() -> Self {
        FilterConfig {
            pos_sigma: 0.01,
            att_sigma: 0.01,
            accel_psd: ACCEL_PSD,
            ang_accel_psd: 0.01,
            init_vel_sigma: 1.0,
            init_rate_sigma: 2.0,
            frame_rate: 1.1314e-3,
            maneuver_nis: 3.0,
            maneuver_window: 8.0,
            maneuver_vel_sigma: 0.3,
            vel_sigma: 0.005,
            rate_sigma: 0.01,
            outlier_sigmas: f64::INFINITY,
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
    /// Measurement of `ẋ` with variance `r` (`H = [0 1]`): returns the gains and updates
    /// `P ← (I − K H) P`.
    fn update_rate(&mut self, r: f64) -> (f64, f64) {
        let s = self.p11 + r;
        let (k0, k1) = (self.p01 / s, self.p11 / s);
        let (p01, p11) = (self.p01, self.p11);
        self.p00 -= k0 * p01;
        self.p01 = p01 - k0 * p11;
        self.p11 = p11 - k1 * p11;
        (k0, k1)
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

/// Clohessy–Wiltshire state transition over `dt` (mean motion `n`, LVLH: x radial, y along
/// track, z cross track) applied in place to `[p, v]`. The filter's translational mean follows
/// the known relative-orbit physics (Coriolis turns a 1 m/s crossing by ≈ 5 mm in 2 s), its
/// covariance the per-axis constant-velocity model (`n·dt` ≈ 2e-5 per update).
#[inline]
pub fn cw_propagate(n: f64, dt: f64, x: &mut [f64]) {
    let (s, c) = (n * dt).sin_cos();
    let nt = n * dt;
    // (1 − cos)/n and sin/n without cancellation for small n·dt.
    let omc_n = if nt.abs() < 1e-3 { n * dt * dt / 2.0 * (1.0 - nt * nt / 12.0) } else { (1.0 - c) / n };
    let s_n = if nt.abs() < 1e-3 { dt * (1.0 - nt * nt / 6.0) } else { s / n };
    let [x0, y0, z0, vx, vy, vz] = [x[0], x[1], x[2], x[3], x[4], x[5]];
    x[0] = (4.0 - 3.0 * c) * x0 + s_n * vx + 2.0 * omc_n * vy;
    x[1] = 6.0 * (s - nt) * x0 + y0 - 2.0 * omc_n * vx + (4.0 * s_n - 3.0 * dt) * vy;
    x[2] = c * z0 + s_n * vz;
    x[3] = 3.0 * n * s * x0 + c * vx + 2.0 * s * vy;
    x[4] = -6.0 * n * (1.0 - c) * x0 - 2.0 * s * vx + (4.0 * c - 3.0) * vy;
    x[5] = -n * s * z0 + c * vz;
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
    /// Averaged normalised translational innovation squared.
    nis: f64,
    /// Manoeuvre re-openings of the translation filter.
    pub maneuvers: u32,
}

/// The filter's motion model: state `x` ([`dkrrt_koopman::debris_state`] layout) `dt`
/// seconds later — Clohessy–Wiltshire translation at mean motion `frame_rate`, constant body
/// rate, the LVLH frame turning at `frame_rate`.
pub fn propagate(x: &[f64; N], frame_rate: f64, dt: f64) -> [f64; N] {
    let mut x = *x;
    cw_propagate(frame_rate, dt, &mut x[0..6]);
    let w = [x[10] * dt, x[11] * dt, x[12] * dt];
    let q = quat_mul(&quat_mul(&quat_exp([0.0, 0.0, -frame_rate * dt]), &x[6..10]), &quat_exp(w));
    x[6..10].copy_from_slice(&q);
    normalise(&mut x[6..10]);
    x
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
            nis: 1.0,
            maneuvers: 0,
        }
    }

    /// The filter's own standard deviation of the position, per axis, `tau` seconds after the
    /// last update (its covariance propagated with the constant-velocity model), m.
    pub fn pos_std(&self, cfg: &FilterConfig, tau: f64) -> f64 {
        let mut p = self.pos;
        p.predict(tau.max(0.0), cfg.accel_psd);
        p.p00.max(0.0).sqrt()
    }

    /// The filter's own standard deviation of the attitude, per axis (small rotation), `tau`
    /// seconds after the last update (its covariance propagated with the constant-rate
    /// model), rad.
    pub fn att_std(&self, cfg: &FilterConfig, tau: f64) -> f64 {
        let mut p = self.att;
        p.predict(tau.max(0.0), cfg.ang_accel_psd);
        p.p00.max(0.0).sqrt()
    }

    /// Forget where the object is (position variance `pos_var` per axis, m²) and open its
    /// velocity to the manoeuvre variance: the next pose sets the position, the next few the
    /// velocity (the poses so far were biased: [`crate::predictor`]'s restarts).
    pub fn restart_position(&mut self, cfg: &FilterConfig, pos_var: f64) {
        self.pos = Kf2::init(pos_var, self.pos.p11.max(cfg.maneuver_vel_sigma.powi(2)));
        self.nis = 1.0;
    }

    /// Predicted state at time `t ≥ self.t` (Clohessy–Wiltshire translation, constant body
    /// rate), without updating.
    pub fn predicted(&self, cfg: &FilterConfig, t: f64) -> [f64; N] {
        propagate(&self.x, cfg.frame_rate, t - self.t)
    }

    /// Measurement update with a pose at time `t > self.t`.
    pub fn update(&mut self, cfg: &FilterConfig, t: f64, p: &[f64; 3], q: &[f64; 4]) {
        self.update_with(cfg, cfg.pos_sigma, t, p, Some(q), false);
    }

    /// [`TrackFilter::update`] with this pose's own position noise `pos_sigma` (m, per axis)
    /// in place of the configured one; `q = None`: the attitude was not measured (it is only
    /// predicted to `t`); `partial`: a partial view (an object cut by a camera's frame or
    /// hidden in part), whose centre moves with the part in view rather than with the
    /// object: its position feeds no manoeuvre test (an outlier among such poses is still
    /// weighed down).
    pub fn update_with(
        &mut self,
        cfg: &FilterConfig,
        pos_sigma: f64,
        t: f64,
        p: &[f64; 3],
        q: Option<&[f64; 4]>,
        partial: bool,
    ) {
        let dt = t - self.t;
        debug_assert!(dt > 0.0);
        let xp = self.predicted(cfg, t);
        // Translation.
        self.pos.predict(dt, cfg.accel_psd);
        let mut r = pos_sigma.powi(2);
        let y = [p[0] - xp[0], p[1] - xp[1], p[2] - xp[2]];
        let nu = (y[0] * y[0] + y[1] * y[1] + y[2] * y[2]) / (3.0 * (self.pos.p00 + r));
        let c2 = cfg.outlier_sigmas.powi(2);
        let a = 1.0 / cfg.maneuver_window.max(1.0);
        if !partial {
            self.nis += a * (nu.min(c2) - self.nis);
        }
        if !partial && self.nis > cfg.maneuver_nis {
            // Manoeuvre: re-open the velocity (and let this pose pull the position).
            self.pos.p11 = self.pos.p11.max(cfg.maneuver_vel_sigma.powi(2));
            self.pos.p00 = self.pos.p00.max(r);
            self.nis = 1.0;
            self.maneuvers += 1;
        } else if nu > c2 {
            // An outlier: weighed as a pose whose innovation lies c deviations out.
            r = (self.pos.p00 + r) * nu / c2 - self.pos.p00;
        }
        let (k0, k1) = self.pos.update(r);
        for i in 0..3 {
            self.x[i] = xp[i] + k0 * y[i];
            self.x[3 + i] = xp[3 + i] + k1 * y[i];
        }
        // Attitude (error state in body axes).
        self.att.predict(dt, cfg.ang_accel_psd);
        let Some(q) = q else {
            self.x[6..13].copy_from_slice(&xp[6..13]);
            self.t = t;
            return;
        };
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

    /// Second measurement update at the time of the last [`TrackFilter::update`] with the
    /// sensor's rates (`v` LVLH velocity, `w` body rate; optional in the contract,
    /// `has_rates`), each with its own variance (`vel_sigma`, `rate_sigma`). Sequential
    /// updates are exact here because the pose and rate noises are independent.
    pub fn update_rates(&mut self, cfg: &FilterConfig, v: &[f64; 3], w: &[f64; 3]) {
        let (k0, k1) = self.pos.update_rate(cfg.vel_sigma.powi(2));
        for i in 0..3 {
            let y = v[i] - self.x[3 + i];
            self.x[i] += k0 * y;
            self.x[3 + i] += k1 * y;
        }
        let (k0, k1) = self.att.update_rate(cfg.rate_sigma.powi(2));
        let y = [w[0] - self.x[10], w[1] - self.x[11], w[2] - self.x[12]];
        let qn = quat_mul(&self.x[6..10], &quat_exp([k0 * y[0], k0 * y[1], k0 * y[2]]));
        self.x[6..10].copy_from_slice(&qn);
        normalise(&mut self.x[6..10]);
        for i in 0..3 {
            self.x[10 + i] += k1 * y[i];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dkrrt_koopman::debris_state::nominal_rhs;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    const N_LEO: f64 = 1.1314e-3;

    /// RK4 of the Clohessy–Wiltshire equations with small steps.
    fn cw_rk4(x: &mut [f64; 6], t: f64) {
        let steps = (t / 0.01).ceil() as usize;
        let h = t / steps as f64;
        let f = |x: &[f64; 6]| {
            let mut d = [0.0; 6];
            nominal_rhs(N_LEO, x, &mut d);
            d
        };
        for _ in 0..steps {
            let k1 = f(x);
            let a: [f64; 6] = std::array::from_fn(|i| x[i] + 0.5 * h * k1[i]);
            let k2 = f(&a);
            let b: [f64; 6] = std::array::from_fn(|i| x[i] + 0.5 * h * k2[i]);
            let k3 = f(&b);
            let c: [f64; 6] = std::array::from_fn(|i| x[i] + h * k3[i]);
            let k4 = f(&c);
            for i in 0..6 {
                x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
            }
        }
    }

    #[test]
    fn cw_transition_matches_integration() {
        let x0 = [3.0, -2.0, 1.5, 0.4, -0.7, 0.2];
        for &dt in &[0.02, 2.0, 100.0, 2000.0] {
            let mut a = x0;
            cw_propagate(N_LEO, dt, &mut a);
            let mut b = x0;
            cw_rk4(&mut b, dt);
            for i in 0..6 {
                assert!(
                    (a[i] - b[i]).abs() < 1e-9 * (1.0 + b[i].abs()),
                    "dt {dt} coord {i}: {} vs {}",
                    a[i],
                    b[i]
                );
            }
        }
        // Over 2 s a 1 m/s along-track crossing bends by Coriolis (what a straight line misses).
        let mut a = [0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        cw_propagate(N_LEO, 2.0, &mut a);
        assert!((a[0] - 2.0 * N_LEO * 2.0).abs() < 1e-6 && a[0] > 4e-3, "radial drift {}", a[0]);
    }

    /// Noisy poses (and, with `rates`, velocities) of an object on a CW trajectory with an
    /// optional velocity impulse; returns
    /// the filter after `t_end` and the true state then.
    fn track(
        cfg: &FilterConfig,
        rates: bool,
        seed: u64,
        impulse: Option<(f64, [f64; 3])>,
        t_end: f64,
    ) -> (TrackFilter, [f64; 6]) {
        let cfg = FilterConfig { frame_rate: N_LEO, ..*cfg };
        let mut rng = SmallRng::seed_from_u64(seed);
        let mut gauss = || {
            let (u, v): (f64, f64) = (rng.random::<f64>().max(1e-300), rng.random());
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        };
        let q = [1.0, 0.0, 0.0, 0.0];
        let mut x = [2.0, -3.0, 1.0, -0.05, 0.08, 0.01];
        let dt = 0.02;
        let z = |x: &[f64; 6], g: &mut dyn FnMut() -> f64| {
            [x[0] + 0.01 * g(), x[1] + 0.01 * g(), x[2] + 0.01 * g()]
        };
        let mut f = TrackFilter::new(&cfg, 0.0, &z(&x, &mut gauss), &q);
        let mut t = 0.0;
        let mut kicked = false;
        while t < t_end - 1e-9 {
            cw_propagate(N_LEO, dt, &mut x);
            t += dt;
            if let Some((ti, dv)) = impulse {
                if !kicked && t >= ti {
                    kicked = true;
                    (0..3).for_each(|i| x[3 + i] += dv[i]);
                }
            }
            f.update(&cfg, t, &z(&x, &mut gauss), &q);
            if rates {
                let v = [x[3] + 0.005 * gauss(), x[4] + 0.005 * gauss(), x[5] + 0.005 * gauss()];
                f.update_rates(&cfg, &v, &[0.0; 3]);
            }
        }
        (f, x)
    }

    #[test]
    fn free_motion_converges_without_manoeuvres() {
        for seed in 0..5 {
            let (f, x) = track(&FilterConfig::default(), false, seed, None, 20.0);
            let ev = (0..3).map(|i| (f.x[3 + i] - x[3 + i]).powi(2)).sum::<f64>().sqrt();
            assert!(ev < 2e-3, "seed {seed}: velocity error {ev} m/s after 20 s");
            assert_eq!(f.maneuvers, 0, "seed {seed}: false manoeuvre detections");
        }
    }

    #[test]
    fn impulse_reopens_the_velocity_estimate() {
        let kick = Some((10.0, [0.1, -0.05, 0.0]));
        for seed in 0..5 {
            let (f, x) = track(&FilterConfig::default(), false, seed, kick, 11.5);
            let ev = (0..3).map(|i| (f.x[3 + i] - x[3 + i]).powi(2)).sum::<f64>().sqrt();
            assert!(f.maneuvers >= 1, "seed {seed}: impulse not detected");
            assert!(ev < 0.02, "seed {seed}: velocity error {ev} m/s 1.5 s after a 0.11 m/s impulse");
        }
        // Without re-opening, the slow filter is still far off 1.5 s after the impulse.
        let off = FilterConfig { maneuver_nis: f64::INFINITY, ..FilterConfig::default() };
        let (f, x) = track(&off, false, 0, kick, 11.5);
        let ev = (0..3).map(|i| (f.x[3 + i] - x[3 + i]).powi(2)).sum::<f64>().sqrt();
        assert!(f.maneuvers == 0 && ev > 0.05, "without re-opening: velocity error {ev} m/s");
    }

    #[test]
    fn the_attitude_deviation_grows_ahead_and_shrinks_with_poses() {
        let cfg = FilterConfig::default();
        let q = [1.0, 0.0, 0.0, 0.0];
        let mut f = TrackFilter::new(&cfg, 0.0, &[0.0; 3], &q);
        // At the pose: the pose's noise; ahead: the unknown body rate (2 rad/s) dominates.
        assert!((f.att_std(&cfg, 0.0) - cfg.att_sigma).abs() < 1e-12);
        let young = f.att_std(&cfg, 0.5);
        assert!(young > 0.9 * cfg.init_rate_sigma * 0.5, "{young}");
        for k in 1..=50 {
            f.update(&cfg, 0.02 * k as f64, &[0.0; 3], &q);
        }
        let a = [0.0, 0.1, 0.5, 1.0, 4.0].map(|tau| f.att_std(&cfg, tau));
        assert!(a.windows(2).all(|w| w[1] > w[0]), "{a:?}");
        assert!(a[2] < 0.1 * young, "after 1 s of poses: {} vs {young}", a[2]);
        // Far ahead the rate's random walk (`ang_accel_psd`) dominates: √(q τ³ / 3).
        let walk = (cfg.ang_accel_psd * 64.0 / 3.0).sqrt();
        assert!(a[4] >= walk && a[4] < 1.1 * walk, "{} vs {walk}", a[4]);
    }

    #[test]
    fn measured_rates_sharpen_a_young_track() {
        let vel_err = |rates: bool| {
            (0..5)
                .map(|seed| {
                    let (f, x) = track(&FilterConfig::default(), rates, seed, None, 0.5);
                    (0..3).map(|i| (f.x[3 + i] - x[3 + i]).powi(2)).sum::<f64>().sqrt()
                })
                .fold(0.0, f64::max)
        };
        let (with, without) = (vel_err(true), vel_err(false));
        assert!(with < 4e-3, "0.5 s with rates: velocity error {with} m/s");
        assert!(with < 0.5 * without, "rates {with} vs poses only {without} m/s");
    }
}
