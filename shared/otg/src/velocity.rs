//! Velocity interface for one joint: reach a target velocity and acceleration
//! (position free) under acceleration and jerk limits.
//!
//! Every such profile has the shape jerk `s·J`, `0`, `-s·J` (s = ±1) with a
//! peak acceleration `ap` held in the middle phase. The velocity change is
//! `Δv = (2ap² − a0² − af²)/(2sJ) + ap·t2`.

/// A three-phase velocity profile `(durations, jerks)`.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct VelProfile {
    pub t: [f64; 3],
    pub j: [f64; 3],
}

impl VelProfile {
    pub fn duration(&self) -> f64 {
        self.t[0] + self.t[1] + self.t[2]
    }
}

const TOL: f64 = 1e-12;

#[inline]
fn build(s: f64, ap: f64, t2: f64, a0: f64, af: f64, jm: f64) -> Option<VelProfile> {
    let sj = s * jm;
    let t1 = (ap - a0) / sj;
    let t3 = (ap - af) / sj;
    let scale = 1.0 + t1.abs() + t3.abs() + t2.abs();
    if t1 < -TOL * scale || t3 < -TOL * scale || t2 < -TOL * scale || !(t1 + t2 + t3).is_finite() {
        return None;
    }
    Some(VelProfile { t: [t1.max(0.0), t2.max(0.0), t3.max(0.0)], j: [sj, 0.0, -sj] })
}

/// Time-optimal profile from `(v0, a0)` to `(vf, af)`; requires `|a0|, |af| <= am`.
pub(crate) fn min_time(v0: f64, a0: f64, vf: f64, af: f64, am: f64, jm: f64) -> Option<VelProfile> {
    let dv = vf - v0;
    let mut best: Option<VelProfile> = None;
    for s in [1.0f64, -1.0] {
        let sj = s * jm;
        let sq = sj * dv + (a0 * a0 + af * af) / 2.0;
        if sq < -TOL * (1.0 + a0 * a0 + af * af) {
            continue;
        }
        let mut ap = s * sq.max(0.0).sqrt();
        let mut t2 = 0.0;
        if ap.abs() > am {
            ap = s * am;
            t2 = (dv - (2.0 * am * am - a0 * a0 - af * af) / (2.0 * sj)) / ap;
        }
        if let Some(p) = build(s, ap, t2, a0, af, jm) {
            if best.is_none_or(|b| p.duration() < b.duration()) {
                best = Some(p);
            }
        }
    }
    best
}

/// Duration of [`min_time`] (`INFINITY` where it has no profile), without
/// building the profile.
#[inline]
pub(crate) fn min_time_duration(v0: f64, a0: f64, vf: f64, af: f64, am: f64, jm: f64) -> f64 {
    let dv = vf - v0;
    let mut best = f64::INFINITY;
    let ss = (a0 * a0 + af * af) / 2.0;
    let tol_sq = -TOL * (1.0 + a0 * a0 + af * af);
    for s in [1.0f64, -1.0] {
        let sj = s * jm;
        let sq = sj * dv + ss;
        if sq < tol_sq {
            continue;
        }
        let mut ap = s * sq.max(0.0).sqrt();
        let mut t2 = 0.0;
        if ap.abs() > am {
            ap = s * am;
            t2 = (dv - (2.0 * am * am - a0 * a0 - af * af) / (2.0 * sj)) / ap;
        }
        let t1 = (ap - a0) / sj;
        let t3 = (ap - af) / sj;
        let scale = 1.0 + t1.abs() + t3.abs() + t2.abs();
        if t1 < -TOL * scale || t3 < -TOL * scale || t2 < -TOL * scale || !(t1 + t2 + t3).is_finite() {
            continue;
        }
        let d = t1.max(0.0) + t2.max(0.0) + t3.max(0.0);
        if d < best {
            best = d;
        }
    }
    best
}

/// A profile of exactly duration `tt` from `(v0, a0)` to `(vf, af)` with
/// `|ap| <= am`, if one exists. The two ramps may have any directions
/// (`s1`, `s3`): jerk `s1·J` from `a0` to `ap`, hold `ap`, jerk `s3·J` to `af`.
pub(crate) fn with_duration(
    v0: f64,
    a0: f64,
    vf: f64,
    af: f64,
    am: f64,
    jm: f64,
    tt: f64,
) -> Option<VelProfile> {
    let dv = vf - v0;
    let mut best: Option<(f64, VelProfile)> = None;
    for (s1, s3) in [(1.0f64, -1.0f64), (-1.0, 1.0), (1.0, 1.0), (-1.0, -1.0)] {
        let (j1, j3) = (s1 * jm, s3 * jm);
        // qa ap² + qb ap + qc = 0
        let qa = -1.0 / (2.0 * j1) + 1.0 / (2.0 * j3);
        let qb = tt + a0 / j1 - af / j3;
        let qc = -a0 * a0 / (2.0 * j1) + af * af / (2.0 * j3) - dv;
        let mut roots = [f64::NAN; 2];
        if qa == 0.0 {
            if qb != 0.0 {
                roots[0] = -qc / qb;
            }
        } else {
            let disc = qb * qb - 4.0 * qa * qc;
            if disc < -1e-12 * (qb * qb + (4.0 * qa * qc).abs()) {
                continue;
            }
            let sq = disc.max(0.0).sqrt();
            let q = -0.5 * (qb + if qb >= 0.0 { sq } else { -sq });
            roots = [q / qa, if q != 0.0 { qc / q } else { 0.0 }];
        }
        for ap in roots {
            if !ap.is_finite() || ap.abs() > am * (1.0 + 1e-12) {
                continue;
            }
            let ap = ap.clamp(-am, am);
            let t1 = (ap - a0) / j1;
            let t3 = (af - ap) / j3;
            let t2 = tt - t1 - t3;
            let scale = 1e-12 * (1.0 + tt);
            if t1 < -scale || t3 < -scale || t2 < -scale {
                continue;
            }
            let p = VelProfile { t: [t1.max(0.0), t2.max(0.0), t3.max(0.0)], j: [j1, 0.0, j3] };
            let (v1, a1) = (v0 + p.t[0] * (a0 + p.t[0] * j1 / 2.0), a0 + p.t[0] * j1);
            let v2 = v1 + p.t[1] * a1;
            let v_end = v2 + p.t[2] * (a1 + p.t[2] * j3 / 2.0);
            let a_end = a1 + p.t[2] * j3;
            let err = (v_end - vf).abs() / (1.0 + vf.abs()) + (a_end - af).abs() + (p.duration() - tt).abs();
            if err < 1e-9 && best.is_none_or(|(e, _)| err < e) {
                best = Some((err, p));
            }
        }
    }
    best.map(|(_, p)| p)
}

/// The earliest duration `>= tt` for which [`with_duration`] has a profile
/// (the velocity interface can have a blocked duration interval, e.g. when the
/// acceleration must change sign and back). Candidates are the durations at
/// which a ramp pattern's quadratic gains a (double) root.
pub(crate) fn next_feasible(
    v0: f64,
    a0: f64,
    vf: f64,
    af: f64,
    am: f64,
    jm: f64,
    tt: f64,
) -> Option<(f64, VelProfile)> {
    if let Some(p) = with_duration(v0, a0, vf, af, am, jm, tt) {
        return Some((tt, p));
    }
    let dv = vf - v0;
    let mut best: Option<(f64, VelProfile)> = None;
    for (s1, s3) in [(1.0f64, -1.0f64), (-1.0, 1.0)] {
        let (j1, j3) = (s1 * jm, s3 * jm);
        let qa = -1.0 / (2.0 * j1) + 1.0 / (2.0 * j3);
        let qc = -a0 * a0 / (2.0 * j1) + af * af / (2.0 * j3) - dv;
        let prod = 4.0 * qa * qc;
        if prod < 0.0 {
            continue;
        }
        // qb(T) = T + a0/j1 − af/j3 = ±sqrt(4 qa qc)
        let r = prod.sqrt();
        for sgn in [1.0, -1.0] {
            let t = sgn * r - (a0 / j1 - af / j3);
            if !(t > tt) || best.as_ref().is_some_and(|(b, _)| t >= *b) {
                continue;
            }
            for tc in [t, t * (1.0 + 1e-12), t * (1.0 + 1e-9)] {
                if let Some(p) = with_duration(v0, a0, vf, af, am, jm, tc) {
                    best = Some((tc, p));
                    break;
                }
            }
        }
    }
    best
}
