//! One joint's motion: a short sequence of constant-jerk phases starting from a
//! known state, with exact closed-form integration.

/// Most phases a single-section, single-joint profile can have: a braking
/// pre-trajectory of at most 2 phases plus the 7 phases of the main profile.
pub(crate) const MAX_PHASES: usize = 9;

/// Integrate one constant-jerk phase of duration `t` exactly.
#[inline(always)]
pub(crate) fn integrate(t: f64, p: f64, v: f64, a: f64, j: f64) -> (f64, f64, f64) {
    (p + t * (v + t * (a / 2.0 + t * j / 6.0)), v + t * (a + t * j / 2.0), a + t * j)
}

/// How far a profile's end acceleration may be from its target's: relative to the target
/// and to the acceleration's swing over the profile (|a0| + Σ|j·t|, what rounding in the
/// phase durations scales with: a profile swinging to 17 000 rad/s² in 0.08 s ends within
/// a few 1e-12 of its target, not within 1e-11 of 0).
#[inline]
pub(crate) fn accel_tol(af: f64, swing: f64) -> f64 {
    1e-11 * (1.0 + af.abs()) + 8e-15 * swing
}

/// A piecewise-constant-jerk motion of one joint.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Profile {
    pub n: usize,
    pub t: [f64; MAX_PHASES],
    pub j: [f64; MAX_PHASES],
    pub p0: f64,
    pub v0: f64,
    pub a0: f64,
}

impl Profile {
    pub fn new(p0: f64, v0: f64, a0: f64) -> Self {
        Profile { n: 0, t: [0.0; MAX_PHASES], j: [0.0; MAX_PHASES], p0, v0, a0 }
    }

    /// Append a phase; phases of zero (or negative rounding-noise) duration are dropped.
    #[inline]
    pub fn push(&mut self, t: f64, j: f64) {
        if t > 0.0 && self.n < MAX_PHASES {
            self.t[self.n] = t;
            self.j[self.n] = j;
            self.n += 1;
        }
    }

    /// Append all phases of `other` (which must start where `self` ends).
    #[allow(dead_code)]
    pub fn extend(&mut self, other: &Profile) {
        for i in 0..other.n {
            self.push(other.t[i], other.j[i]);
        }
    }

    pub fn duration(&self) -> f64 {
        self.t[..self.n].iter().sum()
    }

    /// |a0| + Σ|j·t|: the acceleration's swing over the profile ([`accel_tol`]).
    pub fn accel_swing(&self) -> f64 {
        self.a0.abs() + (0..self.n).map(|i| (self.j[i] * self.t[i]).abs()).sum::<f64>()
    }

    /// State at the end of the profile.
    pub fn end_state(&self) -> (f64, f64, f64) {
        let (mut p, mut v, mut a) = (self.p0, self.v0, self.a0);
        for i in 0..self.n {
            (p, v, a) = integrate(self.t[i], p, v, a, self.j[i]);
        }
        (p, v, a)
    }

    /// Whether the profile stays within `vlo <= v <= vhi` and `|a| <= amax` (with a
    /// small relative tolerance) at every phase boundary and at every interior
    /// velocity extremum. `skip` leading phases (a braking pre-trajectory) are
    /// not checked.
    #[allow(dead_code)]
    pub fn within_limits(&self, vlo: f64, vhi: f64, amax: f64, skip: usize) -> bool {
        let vt_hi = vhi + (vhi.abs() * 1e-9 + 1e-12);
        let vt_lo = vlo - (vlo.abs() * 1e-9 + 1e-12);
        let at = amax * (1.0 + 1e-9) + 1e-12;
        let (mut p, mut v, mut a) = (self.p0, self.v0, self.a0);
        for i in 0..self.n {
            let (t, j) = (self.t[i], self.j[i]);
            if i >= skip {
                if v > vt_hi || v < vt_lo || a.abs() > at {
                    return false;
                }
                if j != 0.0 {
                    let tz = -a / j;
                    if tz > 0.0 && tz < t {
                        let vz = v + tz * (a + tz * j / 2.0);
                        if vz > vt_hi || vz < vt_lo {
                            return false;
                        }
                    }
                }
            }
            (p, v, a) = integrate(t, p, v, a, j);
        }
        let _ = p;
        v <= vt_hi && v >= vt_lo && a.abs() <= at
    }
}

/// Limit check on a structural phase list (zero-length phases included, so
/// indices keep their meaning): `|a| <= amax` everywhere; velocity at every
/// phase end and interior velocity extremum within `±vmax` from phase index
/// `skip_v` on. The first `skip_v` phases may still be correcting the start
/// state, so there the velocity bound is widened only by the excursion the
/// start state makes inevitable (`v0` itself and `v0 + a0|a0|/(2 jmax)`), as
/// right after a braking pre-trajectory.
#[allow(clippy::too_many_arguments)]
pub(crate) fn raw_within_limits(
    v0: f64,
    a0: f64,
    t: &[f64],
    j: &[f64],
    vmax: f64,
    amax: f64,
    jmax: f64,
    skip_v: usize,
) -> bool {
    let tol = vmax * 1e-9 + 1e-12;
    let at = amax * (1.0 + 1e-9) + 1e-12;
    let ex = v0 + a0 * a0.abs() / (2.0 * jmax);
    let (wlo, whi) = ((-vmax).min(v0).min(ex) - tol, vmax.max(v0).max(ex) + tol);
    let (slo, shi) = (-vmax - tol, vmax + tol);
    let (mut v, mut a) = (v0, a0);
    for i in 0..t.len() {
        let (lo, hi) = if i < skip_v { (wlo, whi) } else { (slo, shi) };
        let (ti, ji) = (t[i], j[i]);
        if ji != 0.0 {
            let tz = -a / ji;
            if tz > 0.0 && tz < ti {
                let vz = v + tz * (a + tz * ji / 2.0);
                if vz > hi || vz < lo {
                    return false;
                }
            }
        }
        v += ti * (a + ti * ji / 2.0);
        a += ti * ji;
        if a.abs() > at || v > hi || v < lo {
            return false;
        }
    }
    true
}
