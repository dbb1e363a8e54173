//! Reference orbit of the module and nonlinear relative translational dynamics.
//!
//! # Frame
//! All relative states are expressed in the **LVLH (Hill) frame** of the module's reference
//! orbit: origin at the module centre of mass, `x` radial (away from Earth), `y` along-track
//! (completing the right-handed triad, velocity direction for a circular orbit), `z` along the
//! orbit normal (orbital angular momentum). The frame rotates with the true-anomaly rate `ν̇`
//! about `z`.
//!
//! # Model
//! The module's reference orbit is a Keplerian ellipse (circular by default, 400 km LEO),
//! propagated analytically with Kepler's equation. A debris object at relative position `ρ`
//! obeys the full nonlinear relative two-body equations (no linearisation):
//!
//! ```text
//! ẍ − 2ν̇ẏ − ν̈y − ν̇²x = −μ(r+x)/R³ + μ/r²
//! ÿ + 2ν̇ẋ + ν̈x − ν̇²y = −μy/R³
//! z̈                  = −μz/R³,        R = |(r+x, y, z)|
//! ```
//!
//! Optional **differential J2**: `a_J2(r_c + ρ) − a_J2(r_c)` evaluated in ECI and rotated into
//! LVLH, with the frame still following the unperturbed reference ellipse (the module is assumed
//! to experience J2 as well; the frame-rotation perturbation of J2 is neglected). This is an
//! approximation valid over the short (minutes) horizons of the manipulation task.

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// Earth gravitational parameter [m³/s²].
pub const MU_EARTH: f64 = 3.986_004_418e14;
/// Earth equatorial radius [m].
pub const R_EARTH: f64 = 6_378_137.0;
/// Earth J2 zonal coefficient.
pub const J2_EARTH: f64 = 1.082_626_68e-3;

/// Orbit configuration of the module (scene `[orbit]` table).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OrbitConfig {
    /// Semi-major axis minus Earth radius [km] (altitude for a circular orbit).
    pub altitude_km: f64,
    /// Eccentricity, `0 ≤ e < 0.9`.
    pub eccentricity: f64,
    /// Inclination [deg] (only matters with J2).
    pub inclination_deg: f64,
    /// Right ascension of the ascending node [deg] (only matters with J2).
    pub raan_deg: f64,
    /// Argument of perigee [deg].
    pub arg_perigee_deg: f64,
    /// True anomaly at t = 0 [deg].
    pub true_anomaly_deg: f64,
    /// Enable the differential J2 perturbation.
    pub j2: bool,
}

impl Default for OrbitConfig {
    fn default() -> Self {
        OrbitConfig {
            altitude_km: 400.0,
            eccentricity: 0.0,
            inclination_deg: 51.6,
            raan_deg: 0.0,
            arg_perigee_deg: 0.0,
            true_anomaly_deg: 0.0,
            j2: false,
        }
    }
}

/// Instantaneous state of the reference orbit (the LVLH frame) at a time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChiefState {
    /// Orbit radius [m].
    pub r: f64,
    /// Radial rate [m/s].
    pub r_dot: f64,
    /// True anomaly [rad].
    pub nu: f64,
    /// True-anomaly rate (frame angular rate about z) [rad/s].
    pub nu_dot: f64,
    /// True-anomaly acceleration [rad/s²].
    pub nu_ddot: f64,
    /// LVLH basis expressed in ECI: columns are x̂ (radial), ŷ (along-track), ẑ (normal).
    pub lvlh_to_eci: Matrix3<f64>,
}

impl ChiefState {
    /// ECI position of the module.
    pub fn r_eci(&self) -> Vector3<f64> {
        self.lvlh_to_eci.column(0) * self.r
    }
    /// ECI velocity of the module.
    pub fn v_eci(&self) -> Vector3<f64> {
        self.lvlh_to_eci * Vector3::new(self.r_dot, self.r * self.nu_dot, 0.0)
    }
    /// Frame angular velocity expressed in LVLH.
    pub fn omega_lvlh(&self) -> Vector3<f64> {
        Vector3::new(0.0, 0.0, self.nu_dot)
    }
}

/// Keplerian reference orbit of the module, propagated analytically.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RefOrbit {
    /// Gravitational parameter [m³/s²].
    pub mu: f64,
    /// Semi-major axis [m].
    pub a: f64,
    /// Eccentricity.
    pub e: f64,
    /// Inclination [rad].
    pub inc: f64,
    /// RAAN [rad].
    pub raan: f64,
    /// Argument of perigee [rad].
    pub argp: f64,
    /// Mean anomaly at t = 0 [rad].
    pub m0: f64,
    /// Differential J2 enabled.
    pub j2: bool,
}

impl RefOrbit {
    /// Build from a scene orbit configuration (Earth constants).
    pub fn from_config(c: &OrbitConfig) -> Self {
        let e = c.eccentricity;
        let nu0 = c.true_anomaly_deg.to_radians();
        let ecc_anom =
            2.0 * ((1.0 - e).sqrt() * (nu0 / 2.0).sin()).atan2((1.0 + e).sqrt() * (nu0 / 2.0).cos());
        RefOrbit {
            mu: MU_EARTH,
            a: R_EARTH + c.altitude_km * 1e3,
            e,
            inc: c.inclination_deg.to_radians(),
            raan: c.raan_deg.to_radians(),
            argp: c.arg_perigee_deg.to_radians(),
            m0: ecc_anom - e * ecc_anom.sin(),
            j2: c.j2,
        }
    }

    /// Circular orbit of the given radius in the equatorial plane (tests, examples).
    pub fn circular(mu: f64, a: f64) -> Self {
        RefOrbit { mu, a, e: 0.0, inc: 0.0, raan: 0.0, argp: 0.0, m0: 0.0, j2: false }
    }

    /// Mean motion `n = sqrt(μ/a³)` [rad/s].
    pub fn mean_motion(&self) -> f64 {
        (self.mu / (self.a * self.a * self.a)).sqrt()
    }

    /// Orbital period [s].
    pub fn period(&self) -> f64 {
        std::f64::consts::TAU / self.mean_motion()
    }

    /// Reference-orbit state at time `t` (Kepler's equation, Newton iterations; no allocation).
    pub fn at(&self, t: f64) -> ChiefState {
        let n = self.mean_motion();
        let e = self.e;
        let m = self.m0 + n * t;
        let mut ea = if e < 0.8 { m } else { std::f64::consts::PI };
        for _ in 0..30 {
            let f = ea - e * ea.sin() - m;
            let d = f / (1.0 - e * ea.cos());
            ea -= d;
            if d.abs() < 1e-15 {
                break;
            }
        }
        let nu = 2.0 * ((1.0 + e).sqrt() * (ea / 2.0).sin()).atan2((1.0 - e).sqrt() * (ea / 2.0).cos());
        let p = self.a * (1.0 - e * e);
        let r = p / (1.0 + e * nu.cos());
        let h = (self.mu * p).sqrt();
        let nu_dot = h / (r * r);
        let r_dot = self.mu / h * e * nu.sin();
        let nu_ddot = -2.0 * r_dot * nu_dot / r;
        let u = self.argp + nu;
        ChiefState { r, r_dot, nu, nu_dot, nu_ddot, lvlh_to_eci: lvlh_basis(self.raan, self.inc, u) }
    }

    /// Relative acceleration in LVLH of a free body at relative position `p`, velocity `v`.
    pub fn relative_accel(&self, c: &ChiefState, p: &Vector3<f64>, v: &Vector3<f64>) -> Vector3<f64> {
        let mu = self.mu;
        let rx = c.r + p.x;
        let rr2 = rx * rx + p.y * p.y + p.z * p.z;
        let rr3 = rr2 * rr2.sqrt();
        let k = mu / rr3;
        let (w, wd) = (c.nu_dot, c.nu_ddot);
        let mut a = Vector3::new(
            2.0 * w * v.y + wd * p.y + w * w * p.x - k * rx + mu / (c.r * c.r),
            -2.0 * w * v.x - wd * p.x + w * w * p.y - k * p.y,
            -k * p.z,
        );
        if self.j2 {
            let rc = c.r_eci();
            let rd = rc + c.lvlh_to_eci * p;
            let da = j2_accel(mu, &rd) - j2_accel(mu, &rc);
            a += c.lvlh_to_eci.transpose() * da;
        }
        a
    }

    /// Convert an ECI state of a body into an LVLH relative state at time `t`.
    pub fn eci_to_lvlh(&self, t: f64, r: &Vector3<f64>, v: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
        let c = self.at(t);
        let ct = c.lvlh_to_eci.transpose();
        let p = ct * (r - c.r_eci());
        let vrel = ct * (v - c.v_eci()) - c.omega_lvlh().cross(&p);
        (p, vrel)
    }
}

/// LVLH basis (columns x̂, ŷ, ẑ) in ECI for RAAN `raan`, inclination `inc`, argument of latitude `u`.
pub fn lvlh_basis(raan: f64, inc: f64, u: f64) -> Matrix3<f64> {
    let (so, co) = raan.sin_cos();
    let (si, ci) = inc.sin_cos();
    let (su, cu) = u.sin_cos();
    let xr = Vector3::new(co * cu - so * su * ci, so * cu + co * su * ci, su * si);
    let yr = Vector3::new(-co * su - so * cu * ci, -so * su + co * cu * ci, cu * si);
    let zr = Vector3::new(so * si, -co * si, ci);
    Matrix3::from_columns(&[xr, yr, zr])
}

/// J2 acceleration in ECI at position `r` [m/s²].
pub fn j2_accel(mu: f64, r: &Vector3<f64>) -> Vector3<f64> {
    let r2 = r.norm_squared();
    let rn = r2.sqrt();
    let zr2 = r.z * r.z / r2;
    let k = -1.5 * J2_EARTH * mu * R_EARTH * R_EARTH / (r2 * r2 * rn);
    Vector3::new(k * r.x * (1.0 - 5.0 * zr2), k * r.y * (1.0 - 5.0 * zr2), k * r.z * (3.0 - 5.0 * zr2))
}

/// ECI position and velocity from classical orbital elements (angles in rad).
pub fn kepler_to_eci(
    mu: f64,
    a: f64,
    e: f64,
    inc: f64,
    raan: f64,
    argp: f64,
    nu: f64,
) -> (Vector3<f64>, Vector3<f64>) {
    let p = a * (1.0 - e * e);
    let r = p / (1.0 + e * nu.cos());
    let b = lvlh_basis(raan, inc, argp + nu);
    let h = (mu * p).sqrt();
    let r_dot = mu / h * e * nu.sin();
    let pos = b.column(0) * r;
    let vel = b * Vector3::new(r_dot, h / r, 0.0);
    (pos, vel)
}

/// Clohessy–Wiltshire closed-form solution (circular orbit, mean motion `n`, same LVLH axes):
/// returns relative position and velocity at `t` from `p0`, `v0`.
pub fn clohessy_wiltshire(
    n: f64,
    p0: &Vector3<f64>,
    v0: &Vector3<f64>,
    t: f64,
) -> (Vector3<f64>, Vector3<f64>) {
    let (s, c) = (n * t).sin_cos();
    let (x0, y0, z0) = (p0.x, p0.y, p0.z);
    let (vx0, vy0, vz0) = (v0.x, v0.y, v0.z);
    let p = Vector3::new(
        4.0 * x0 - 3.0 * x0 * c + vx0 / n * s + 2.0 * vy0 / n * (1.0 - c),
        y0 + 6.0 * x0 * (s - n * t) - 2.0 * vx0 / n * (1.0 - c) + vy0 / n * (4.0 * s - 3.0 * n * t),
        z0 * c + vz0 / n * s,
    );
    let v = Vector3::new(
        3.0 * x0 * n * s + vx0 * c + 2.0 * vy0 * s,
        6.0 * x0 * n * (c - 1.0) - 2.0 * vx0 * s + vy0 * (4.0 * c - 3.0),
        -z0 * n * s + vz0 * c,
    );
    (p, v)
}
