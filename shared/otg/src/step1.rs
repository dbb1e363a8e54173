//! Step 1: all time-optimal candidate profiles of one joint, the minimum
//! duration, and the blocked duration intervals.
//!
//! After braking, every candidate is a 7-phase "UDDU" profile in direction
//! `d = ±1` with jerks `dJ, 0, −dJ, 0, −dJ, 0, dJ`. Phase 2 is a plateau at
//! the acceleration limit `dA` (ACC0), phase 4 a cruise at `dV` (VEL), phase 6
//! a plateau at `−dA` (ACC1). Families:
//!
//! * VEL (any plateaus): two time-optimal velocity profiles to/from the cruise,
//!   cruise time from the distance (closed form).
//! * ACC0_ACC1: plateau times from the velocity (linear) and position
//!   (quadratic) equations.
//! * ACC0 / ACC1: one free peak acceleration, a quartic.
//! * NONE: peak accelerations `A1, A2` with `A1² − A2² = C` from the velocity
//!   equation, parameterized by `u = A1 − A2`; the position equation becomes
//!   the depressed quartic `u⁴ + 4K1·u² + 2K2·u − C² = 0`.
//!
//! The step-1 families' position equations are expanded in closed form (see
//! `solve`; the step-2 hold families are assembled by fixed-size polynomial
//! products, the Laurent-polynomial assembly is kept as the test reference).
//! Real roots in the family's parameter window are counted with Budan's
//! theorem (recursive derivative bracketing only where that is inconclusive)
//! and polished by safeguarded Halley steps; every root is turned into a
//! numeric profile that is verified by exact forward integration and limit
//! checks before acceptance.

#[cfg(test)]
use crate::poly::Lp;
use crate::poly::{real_roots, MAX_ROOTS};
use crate::profile::{accel_tol, integrate, raw_within_limits, Profile};
use crate::velocity;

/// Most candidates collected per joint.
const MAX_CAND: usize = 12;

/// One joint's step-1 result.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Step1 {
    /// The fastest profile (main phases only, starting at the post-brake state).
    pub best: Profile,
    pub t_min: f64,
    /// Durations in `(left, right)` for which no profile exists: the families' two, and a
    /// moving joint already at its target's state has `(0, shortest motion)` before them.
    pub blocked: [(f64, f64); 3],
    /// Profiles of duration exactly `blocked[i].1`.
    pub right: [Profile; 3],
    pub n_blocked: usize,
}

#[derive(Clone, Copy, Debug)]
pub(crate) struct Problem {
    pub p0: f64,
    pub v0: f64,
    pub a0: f64,
    pub pf: f64,
    pub vf: f64,
    pub af: f64,
    pub vm: f64,
    pub am: f64,
    pub jm: f64,
}

/// ACC0 / ACC1: the plateau duration `ts[k] = q0 + q2 x²` (`q2 > 0`) must not
/// be negative (beyond the profile check's rounding tolerance, bounded here
/// from the other durations' largest values), so `|x| >= r` when `q0 < 0`.
/// Returns `[lo, hi]` narrowed to the one side that remains, or unchanged
/// when both remain (`lo > hi`: nothing remains).
fn hold_window(ts: &[[f64; 3]; 5], k: usize, lo: f64, hi: f64, am: f64, jm: f64) -> (f64, f64) {
    let (q0, q2) = (ts[k][0], ts[k][2]);
    if !(q0 < 0.0 && q2 > 0.0) {
        return (lo, hi);
    }
    let others = (ts[0][0].abs() + ts[4][0].abs()) + 6.0 * am / jm;
    let tol = 1e-9 * (1.0 + others + q0.abs() + q2 * am * am);
    let q0t = q0 + tol;
    if q0t >= 0.0 {
        return (lo, hi);
    }
    let r = (-q0t / q2).sqrt() * (1.0 - 1e-9);
    let neg = lo <= -r;
    let pos = hi >= r;
    match (neg, pos) {
        (true, true) => (lo, hi),
        (true, false) => (lo, hi.min(-r)),
        (false, true) => (lo.max(r), hi),
        (false, false) => (1.0, 0.0),
    }
}

#[inline(always)]
fn mul33(a: &[f64; 3], b: &[f64; 3]) -> [f64; 5] {
    let mut r = [0.0; 5];
    for i in 0..3 {
        for k in 0..3 {
            r[i + k] += a[i] * b[k];
        }
    }
    r
}

#[inline(always)]
fn mul35(a: &[f64; 3], b: &[f64; 5]) -> [f64; 7] {
    let mut r = [0.0; 7];
    for i in 0..3 {
        for k in 0..5 {
            r[i + k] += a[i] * b[k];
        }
    }
    r
}

/// Verified candidate profiles, stored compactly (every jerk of a
/// candidate is `0` or `±jm`, and it has at most 7 phases).
struct Cands {
    n: usize,
    /// Durations.
    t: [f64; MAX_CAND],
    len: [u8; MAX_CAND],
    ph: [[f64; 7]; MAX_CAND],
    sign: [[i8; 7]; MAX_CAND],
    /// Also try each family's touching roots ([`Problem::family_poly`]).
    touching: bool,
}

impl Cands {
    fn new() -> Self {
        Cands {
            n: 0,
            t: [0.0; MAX_CAND],
            len: [0; MAX_CAND],
            ph: [[0.0; 7]; MAX_CAND],
            sign: [[0; 7]; MAX_CAND],
            touching: false,
        }
    }

    /// Candidate `i` as a profile of `pb`.
    fn get(&self, pb: &Problem, i: usize) -> Profile {
        let mut pr = Profile::new(pb.p0, pb.v0, pb.a0);
        for k in 0..self.len[i] as usize {
            pr.push(self.ph[i][k], f64::from(self.sign[i][k]) * pb.jm);
        }
        pr
    }
}

impl Problem {
    /// Verify a numeric profile reaches the target (limits are checked in `build`).
    pub fn accept(&self, pr: &Profile) -> bool {
        let (p, v, a) = pr.end_state();
        (p - self.pf).abs() <= 4e-10 * (1.0 + self.pf.abs())
            && (v - self.vf).abs() <= 4e-10 * (1.0 + self.vf.abs())
            && (a - self.af).abs() <= accel_tol(self.af, pr.accel_swing())
    }

    /// Build a profile from structural phase durations (clamping rounding
    /// noise) if it respects the limits (see [`raw_within_limits`]).
    pub fn build(&self, t: &[f64], j: &[f64]) -> Option<Profile> {
        let scale: f64 = 1e-10 * (1.0 + t.iter().map(|x| x.abs()).sum::<f64>());
        // Durations first (cheap, and most rejected roots fail here).
        if !t.iter().all(|&ti| ti >= -scale && ti.is_finite()) {
            return None;
        }
        let mut tc = [0.0; 7];
        for (k, &ti) in t.iter().enumerate() {
            tc[k] = ti.max(0.0);
        }
        if !raw_within_limits(self.v0, self.a0, &tc[..t.len()], j, self.vm, self.am, self.jm, 2) {
            return None;
        }
        let mut pr = Profile::new(self.p0, self.v0, self.a0);
        for (&ti, &ji) in t.iter().zip(j) {
            pr.push(ti, ji);
        }
        Some(pr)
    }

    /// [`Self::build`] and [`Self::add`] in one, without building the
    /// profile: returns whether the candidate was added.
    fn add_raw(&self, c: &mut Cands, t: &[f64], j: &[f64]) -> bool {
        let n = t.len();
        let scale: f64 = 1e-10 * (1.0 + t.iter().map(|x| x.abs()).sum::<f64>());
        if !t.iter().all(|&ti| ti >= -scale && ti.is_finite()) {
            return false;
        }
        let mut tc = [0.0; 7];
        for (k, &ti) in t.iter().enumerate() {
            tc[k] = ti.max(0.0);
        }
        if c.n >= MAX_CAND || !raw_within_limits(self.v0, self.a0, &tc[..n], j, self.vm, self.am, self.jm, 2)
        {
            return false;
        }
        // End state and duration as the profile (phases of zero duration
        // dropped; integrating them is exact anyway) would give.
        let (mut p, mut v, mut a) = (self.p0, self.v0, self.a0);
        let mut dur = 0.0;
        for k in 0..n {
            if tc[k] > 0.0 {
                (p, v, a) = integrate(tc[k], p, v, a, j[k]);
                dur += tc[k];
            }
        }
        let swing = self.a0.abs() + (0..n).map(|k| (tc[k] * j[k]).abs()).sum::<f64>();
        if !((p - self.pf).abs() <= 4e-10 * (1.0 + self.pf.abs())
            && (v - self.vf).abs() <= 4e-10 * (1.0 + self.vf.abs())
            && (a - self.af).abs() <= accel_tol(self.af, swing))
        {
            return false;
        }
        let i = c.n;
        c.t[i] = dur;
        let mut len = 0;
        for k in 0..n {
            if tc[k] > 0.0 {
                c.ph[i][len] = tc[k];
                debug_assert!(j[k] == 0.0 || j[k].abs() == self.jm);
                c.sign[i][len] = if j[k] > 0.0 {
                    1
                } else if j[k] < 0.0 {
                    -1
                } else {
                    0
                };
                len += 1;
            }
        }
        c.len[i] = len as u8;
        c.n += 1;
        true
    }

    #[cfg(test)]
    fn add(&self, c: &mut Cands, pr: Profile) {
        if c.n < MAX_CAND && pr.n <= 7 && self.accept(&pr) {
            let i = c.n;
            c.t[i] = pr.duration();
            c.len[i] = pr.n as u8;
            for k in 0..pr.n {
                c.ph[i][k] = pr.t[k];
                let j = pr.j[k];
                debug_assert!(j == 0.0 || j.abs() == self.jm);
                c.sign[i][k] = if j > 0.0 {
                    1
                } else if j < 0.0 {
                    -1
                } else {
                    0
                };
            }
            c.n += 1;
        }
    }

    /// Solve a family whose phase durations are Laurent polynomials in `x`:
    /// position residual roots in `[lo, hi]` become candidates.
    #[cfg(test)]
    fn family(&self, c: &mut Cands, ts: &[Lp], js: &[f64], lo: f64, hi: f64) {
        let (mut p, mut v, mut a) = (Lp::constant(self.p0), Lp::constant(self.v0), Lp::constant(self.a0));
        for (k, (t, &j)) in ts.iter().zip(js).enumerate() {
            // p += t(v + t(a/2 + t j/6)), v += t(a + t j/2), a += t j
            let tj = t.scale(j);
            let inner_p = a.scale(0.5).add(&tj.scale(1.0 / 6.0));
            p = p.add(&t.mul(&v.add(&t.mul(&inner_p))));
            if k + 1 < ts.len() {
                v = v.add(&t.mul(&a.add(&tj.scale(0.5))));
                a = a.add(&tj);
            }
        }
        let r = p.add_const(-self.pf);
        let mut coeffs = [0.0; crate::poly::LEN];
        let n = r.to_poly(&mut coeffs);
        let mut roots = [0.0; MAX_ROOTS];
        let nr = real_roots(&coeffs[..n], lo, hi, &mut roots);
        let mut tv = [0.0; 7];
        for &x in &roots[..nr] {
            for (k, t) in ts.iter().enumerate() {
                tv[k] = t.eval(x);
            }
            if let Some(pr) = self.build(&tv[..ts.len()], js) {
                self.add(c, pr);
            }
        }
    }

    /// Like [`Self::family`] for the step-1 families, with fixed-size
    /// polynomial arithmetic: every phase duration is `T_k(x) / x^s` with
    /// `T_k` at most quadratic (`s = 1` for NONE, whose durations have a
    /// `1/u` term, else `0`); the position residual times `x^(3s)` is a
    /// polynomial of degree <= 6. Same arithmetic (and order) as the Laurent
    /// assembly.
    #[inline]
    fn family5(&self, c: &mut Cands, ts: &[[f64; 3]; 5], js: &[f64; 5], s: usize, lo: f64, hi: f64) {
        let mut p = [0.0f64; 7];
        let mut v = [0.0f64; 5];
        let mut a = [0.0f64; 3];
        p[3 * s] = self.p0;
        v[2 * s] = self.v0;
        a[s] = self.a0;
        for k in 0..5 {
            let t = &ts[k];
            let j = js[k];
            if t[0] == 0.0 && t[1] == 0.0 && t[2] == 0.0 {
                continue;
            }
            let tj = [t[0] * j, t[1] * j, t[2] * j];
            let inner = [
                a[0] * 0.5 + tj[0] * (1.0 / 6.0),
                a[1] * 0.5 + tj[1] * (1.0 / 6.0),
                a[2] * 0.5 + tj[2] * (1.0 / 6.0),
            ];
            let ti = mul33(t, &inner);
            let mut w = v;
            for i in 0..5 {
                w[i] += ti[i];
            }
            let dp = mul35(t, &w);
            for i in 0..7 {
                p[i] += dp[i];
            }
            if k + 1 < 5 {
                let q = [a[0] + tj[0] * 0.5, a[1] + tj[1] * 0.5, a[2] + tj[2] * 0.5];
                let dv = mul33(t, &q);
                for i in 0..5 {
                    v[i] += dv[i];
                }
                for i in 0..3 {
                    a[i] += tj[i];
                }
            }
        }
        p[3 * s] += -self.pf;
        let mut roots = [0.0; MAX_ROOTS];
        let nr = real_roots(&p, lo, hi, &mut roots);
        self.candidates(c, ts, js, s, &roots[..nr]);
    }

    /// Real roots of `poly` (ascending coefficients) in `[lo, hi]` as candidates.
    #[inline]
    fn family_poly(
        &self,
        c: &mut Cands,
        poly: &[f64],
        ts: &[[f64; 3]; 5],
        js: &[f64; 5],
        s: usize,
        (lo, hi): (f64, f64),
    ) {
        let mut roots = [0.0; MAX_ROOTS];
        let nr = real_roots(poly, lo, hi, &mut roots);
        self.candidates(c, ts, js, s, &roots[..nr]);
        if c.touching && poly.len() > 1 {
            // A double root that rounding turned into a complex pair (the residual touches
            // zero without crossing it: a profile whose two phases end exactly at zero
            // length) is a root of the derivative: try those; verification keeps only
            // the profiles that reach the target.
            let mut d = [0.0f64; 10];
            for k in 1..poly.len().min(11) {
                d[k - 1] = poly[k] * k as f64;
            }
            let nd = real_roots(&d[..poly.len().min(11) - 1], lo, hi, &mut roots);
            self.candidates(c, ts, js, s, &roots[..nd]);
        }
    }

    /// Turn parameter values `roots` of a family (durations `T_k(x) / x^s`)
    /// into verified candidates.
    #[inline]
    fn candidates(&self, c: &mut Cands, ts: &[[f64; 3]; 5], js: &[f64; 5], s: usize, roots: &[f64]) {
        let mut tv = [0.0; 5];
        for &x in roots {
            let sc = if s == 1 { x.powi(-1) } else { 1.0 };
            for (k, t) in ts.iter().enumerate() {
                tv[k] = ((t[2] * x + t[1]) * x + t[0]) * sc;
            }
            self.add_raw(c, &tv, js);
        }
    }

    /// Step-2 families with a prescribed duration `tt` (five merged phases
    /// `dJ, 0, −dJ, 0, dJ` where one hold is at a free acceleration level,
    /// holds at the start / end / junction, two holds, four ramps); the
    /// phase durations (times `x` where they have a `1/x` term) are
    /// quadratics in the family's parameter `x`. Returns a verified profile
    /// of duration `tt`.
    pub fn with_duration_holds(&self, tt: f64) -> Option<Profile> {
        let mut c = Cands::new();
        let (v0, a0, vf, af, am, jm) = (self.v0, self.a0, self.vf, self.af, self.am, self.jm);
        let dv = vf - v0;
        let z = [0.0; 3];
        let win = |d: f64, open: bool| {
            let e = if open { 1e-300 } else { 0.0 };
            if d > 0.0 {
                (e, 2.0 * am * (1.0 + 1e-9))
            } else {
                (-2.0 * am * (1.0 + 1e-9), -e)
            }
        };
        // Free hold level: w = A1 − A2.
        for d in [1.0f64, -1.0] {
            let jd = d * jm;
            let ij = 1.0 / jd;
            let js = [jd, 0.0, -jd, 0.0, jd];
            let kk = tt - (af - a0) / jd;
            if kk == 0.0 {
                continue;
            }
            let ik = 1.0 / kk;
            let hold = [tt - (af - a0) / jd, -2.0 / jd, 0.0];
            let base = (af * af - a0 * a0) / (2.0 * jd);
            let (lo, hi) = win(d, false);
            // Hold at A1: A1 = (w²/jd + Δv − base)/kk, A2 = A1 − w.
            let a1 = [(dv - base) * ik, 0.0, ij * ik];
            let ts = [
                [(a1[0] - a0) * ij, 0.0, a1[2] * ij],
                hold,
                [0.0, ij, 0.0],
                z,
                [(-a1[0] + af) * ij, ij, -a1[2] * ij],
            ];
            self.family5(&mut c, &ts, &js, 0, lo, hi);
            // Hold at A2: A2 = (−w²/jd + Δv − base)/kk, A1 = A2 + w.
            let a2 = [(dv - base) * ik, 0.0, (-1.0 / jd) * ik];
            let ts = [
                [(a2[0] - a0) * ij, ij, a2[2] * ij],
                z,
                [0.0, ij, 0.0],
                hold,
                [(-a2[0] + af) * ij, 0.0, -a2[2] * ij],
            ];
            self.family5(&mut c, &ts, &js, 0, lo, hi);
        }
        // Hold at the start (at a0) or at the end (at af), then / before three
        // ramps `−dJ, dJ, −dJ` through M and A2; w = A2 − M,
        // M = ((Δv − ah·h − (a0² − af²)/(2jd))·jd/w − w)/2 (durations times w).
        for d in [1.0f64, -1.0] {
            let jd = d * jm;
            let ij = 1.0 / jd;
            let h = [0.0, tt - (a0 - af) / jd, -2.0 / jd];
            let (lo, hi) = win(d, true);
            for which in 0..2 {
                let ah = if which == 0 { a0 } else { af };
                let k0 = dv - (a0 * a0 - af * af) / (2.0 * jd);
                let rest = [h[1] * -ah + k0, h[2] * -ah];
                // M: exponents −1, 0, 1
                let m = [rest[0] * jd * 0.5, rest[1] * jd * 0.5, -0.5];
                let r1 = [-m[0] * ij, (-m[1] + a0) * ij, 0.5 * ij];
                let r2 = [0.0, 0.0, ij];
                let r3 = [m[0] * ij, (m[1] - af) * ij, 0.5 * ij];
                if which == 0 {
                    self.family5(&mut c, &[h, r1, r2, r3, z], &[0.0, -jd, jd, -jd, 0.0], 1, lo, hi);
                } else {
                    self.family5(&mut c, &[r1, r2, r3, h, z], &[-jd, jd, -jd, 0.0, 0.0], 1, lo, hi);
                }
            }
        }
        // Three ramps `−dJ, dJ, −dJ` through M and A2 with a hold at M or at
        // A2 (w = A2 − M); M follows linearly from the velocity equation.
        for d in [1.0f64, -1.0] {
            let jd = d * jm;
            let ij = 1.0 / jd;
            let kk = tt - (a0 - af) / jd;
            if kk == 0.0 {
                continue;
            }
            let ik = 1.0 / kk;
            let h = [kk, -2.0 / jd, 0.0];
            let base = dv - (a0 * a0 - af * af) / (2.0 * jd);
            let (lo, hi) = win(d, false);
            for which in 0..2 {
                let num = if which == 0 { [base, 0.0, -1.0 / jd] } else { [base, -kk, -1.0 / jd + 2.0 / jd] };
                let m = [num[0] * ik, num[1] * ik, num[2] * ik];
                let r1 = [(-m[0] + a0) * ij, -m[1] * ij, -m[2] * ij];
                let r2 = [0.0, ij, 0.0];
                let r3 = [(m[0] - af) * ij, (m[1] + 1.0) * ij, m[2] * ij];
                if which == 0 {
                    self.family5(&mut c, &[r1, h, r2, r3, z], &[-jd, 0.0, jd, -jd, 0.0], 0, lo, hi);
                } else {
                    self.family5(&mut c, &[r1, r2, h, r3, z], &[-jd, jd, 0.0, -jd, 0.0], 0, lo, hi);
                }
            }
        }
        // Two holds joined by same-direction ramps: hold a0, −dJ to M, hold M,
        // −dJ to af; parameter y = M − a0, the second hold from the velocity
        // equation (∝ 1/y).
        for d in [1.0f64, -1.0] {
            let jd = d * jm;
            let ij = 1.0 / jd;
            let kk = tt - (a0 - af) / jd;
            let r = dv - a0 * kk - (a0 * a0 - af * af) / (2.0 * jd);
            let h1 = [-r, kk, 0.0];
            let r1 = [0.0, 0.0, -1.0 / jd];
            let h2 = [r, 0.0, 0.0];
            let r2 = [0.0, (a0 - af) * ij, ij];
            let (lo, hi) = win(-d, true);
            self.family5(&mut c, &[h1, r1, h2, r2, z], &[0.0, -jd, 0.0, -jd, 0.0], 1, lo, hi);
        }
        // Two holds joined by opposite ramps, one hold at an end's acceleration: hold a0,
        // dJ to M, hold M, −dJ to af (y = M − a0); or dJ from a0 to M, hold M, −dJ to af,
        // hold af (y = M − af). The holds follow from the duration and the velocity
        // equations (∝ 1/y). A start at the acceleration limit (after a brake) that must
        // hold there and then at a level within the limits needs the first (found by
        // Ruckig-like random problems: no profile at durations between two that had one).
        for d in [1.0f64, -1.0] {
            let jd = d * jm;
            let ij = 1.0 / jd;
            let (lo, hi) = win(d, true);
            let kk = tt - (a0 - af) / jd;
            let r = dv - a0 * kk - (a0 * a0 - af * af) / (2.0 * jd);
            let h1 = [-r, kk, -ij];
            let r1 = [0.0, 0.0, ij];
            let hm = [r, 0.0, -ij];
            let r2 = [0.0, (a0 - af) * ij, ij];
            self.family5(&mut c, &[h1, r1, hm, r2, z], &[0.0, jd, 0.0, -jd, 0.0], 1, lo, hi);
            let kk = tt - (af - a0) / jd;
            let r = af * kk - dv + (af * af - a0 * a0) / (2.0 * jd);
            let r1 = [0.0, (af - a0) * ij, ij];
            let hm = [-r, 0.0, -ij];
            let r2 = [0.0, 0.0, ij];
            let hf = [r, kk, -ij];
            self.family5(&mut c, &[r1, hm, r2, hf, z], &[jd, 0.0, -jd, 0.0, 0.0], 1, lo, hi);
        }
        // Four ramps `dJ, −dJ, dJ, −dJ` without holds (a0 → A1 → M → A2 → af).
        // With x = A1 − M, y = A2 − M the duration gives A1 + A2 − M = S and the
        // velocity A1² + A2² − M² = Q, hence x·y = (S² − Q)/2 = P, y = P/x.
        for d in [1.0f64, -1.0] {
            let jd = d * jm;
            let ij = 1.0 / jd;
            let ss = (jd * tt + a0 + af) / 2.0;
            let q = jd * dv + (a0 * a0 + af * af) / 2.0;
            let pp = (ss * ss - q) / 2.0;
            let t1 = [-pp * ij, (ss - a0) * ij, 0.0];
            let t2 = [0.0, 0.0, ij];
            let t3 = [pp * ij, 0.0, 0.0];
            let t4 = [0.0, (ss - af) * ij, -ij];
            let (lo, hi) = win(d, true);
            self.family5(&mut c, &[t1, t2, t3, t4, z], &[jd, -jd, jd, -jd, 0.0], 1, lo, hi);
        }
        (0..c.n).find(|&i| (c.t[i] - tt).abs() <= 1e-9 * (1.0 + tt)).map(|i| c.get(self, i))
    }

    /// Step-2 families with a prescribed duration `tt` (five merged phases
    /// `dJ, 0, −dJ, 0, dJ` where one hold is at a free acceleration level),
    /// parameterized by `w = A1 − A2`; returns a verified profile of duration `tt`.
    #[cfg(test)]
    pub fn with_duration_holds_lp(&self, tt: f64) -> Option<Profile> {
        let mut c = Cands::new();
        let (v0, a0, vf, af, am, jm) = (self.v0, self.a0, self.vf, self.af, self.am, self.jm);
        let dv = vf - v0;
        for d in [1.0f64, -1.0] {
            let jd = d * jm;
            let js = [jd, 0.0, -jd, 0.0, jd];
            let kk = tt - (af - a0) / jd;
            if kk == 0.0 {
                continue;
            }
            let w = Lp::mono(1.0, 1);
            let w2 = w.mul(&w);
            let hold = w.scale(-2.0 / jd).add_const(tt - (af - a0) / jd);
            let base = (af * af - a0 * a0) / (2.0 * jd);
            let (lo, hi) =
                if d > 0.0 { (0.0, 2.0 * am * (1.0 + 1e-9)) } else { (-2.0 * am * (1.0 + 1e-9), 0.0) };
            for which in 0..2 {
                let (a1, a2, ts);
                if which == 0 {
                    a1 = w2.scale(1.0 / jd).add_const(dv - base).scale(1.0 / kk);
                    a2 = a1.add(&w.scale(-1.0));
                    ts = [
                        a1.add_const(-a0).scale(1.0 / jd),
                        hold,
                        w.scale(1.0 / jd),
                        Lp::ZERO,
                        a2.scale(-1.0).add_const(af).scale(1.0 / jd),
                    ];
                } else {
                    a2 = w2.scale(-1.0 / jd).add_const(dv - base).scale(1.0 / kk);
                    a1 = a2.add(&w);
                    ts = [
                        a1.add_const(-a0).scale(1.0 / jd),
                        Lp::ZERO,
                        w.scale(1.0 / jd),
                        hold,
                        a2.scale(-1.0).add_const(af).scale(1.0 / jd),
                    ];
                }
                self.family(&mut c, &ts, &js, lo, hi);
            }
        }
        // Hold at the start (at a0) or at the end (at af), then / before three
        // ramps `−dJ, dJ, −dJ` through M and A2; w = A2 − M.
        for d in [1.0f64, -1.0] {
            let jd = d * jm;
            let w = Lp::mono(1.0, 1);
            let winv = Lp::mono(1.0, -1);
            let h = w.scale(-2.0 / jd).add_const(tt - (a0 - af) / jd);
            let (lo, hi) =
                if d > 0.0 { (1e-300, 2.0 * am * (1.0 + 1e-9)) } else { (-2.0 * am * (1.0 + 1e-9), -1e-300) };
            for which in 0..2 {
                let ah = if which == 0 { a0 } else { af };
                // M = ((Δv − ah·h − (a0² − af²)/(2jd))·jd/w − w)/2
                let rest = h.scale(-ah).add_const(dv - (a0 * a0 - af * af) / (2.0 * jd));
                let m = rest.mul(&winv).scale(jd).add(&w.scale(-1.0)).scale(0.5);
                let a2 = m.add(&w);
                let r1 = m.scale(-1.0).add_const(a0).scale(1.0 / jd);
                let r2 = w.scale(1.0 / jd);
                let r3 = a2.add_const(-af).scale(1.0 / jd);
                if which == 0 {
                    self.family(&mut c, &[h, r1, r2, r3], &[0.0, -jd, jd, -jd], lo, hi);
                } else {
                    self.family(&mut c, &[r1, r2, r3, h], &[-jd, jd, -jd, 0.0], lo, hi);
                }
            }
        }
        // Three ramps `−dJ, dJ, −dJ` through M and A2 with a hold at M or at
        // A2 (w = A2 − M); M follows linearly from the velocity equation.
        for d in [1.0f64, -1.0] {
            let jd = d * jm;
            let kk = tt - (a0 - af) / jd;
            if kk == 0.0 {
                continue;
            }
            let w = Lp::mono(1.0, 1);
            let w2 = w.mul(&w);
            let h = w.scale(-2.0 / jd).add_const(kk);
            let base = dv - (a0 * a0 - af * af) / (2.0 * jd);
            let (lo, hi) =
                if d > 0.0 { (0.0, 2.0 * am * (1.0 + 1e-9)) } else { (-2.0 * am * (1.0 + 1e-9), 0.0) };
            for which in 0..2 {
                let mut num = w2.scale(-1.0 / jd).add_const(base);
                if which == 1 {
                    num = num.add(&w.mul(&h).scale(-1.0));
                }
                let m = num.scale(1.0 / kk);
                let a2 = m.add(&w);
                let r1 = m.scale(-1.0).add_const(a0).scale(1.0 / jd);
                let r2 = w.scale(1.0 / jd);
                let r3 = a2.add_const(-af).scale(1.0 / jd);
                if which == 0 {
                    self.family(&mut c, &[r1, h, r2, r3], &[-jd, 0.0, jd, -jd], lo, hi);
                } else {
                    self.family(&mut c, &[r1, r2, h, r3], &[-jd, jd, 0.0, -jd], lo, hi);
                }
            }
        }
        // Two holds joined by same-direction ramps: hold a0, −dJ to M, hold M,
        // −dJ to af; parameter y = M − a0, the second hold from the velocity
        // equation (∝ 1/y).
        for d in [1.0f64, -1.0] {
            let jd = d * jm;
            let kk = tt - (a0 - af) / jd;
            let r = dv - a0 * kk - (a0 * a0 - af * af) / (2.0 * jd);
            let y = Lp::mono(1.0, 1);
            let h2 = Lp::mono(r, -1);
            let h1 = h2.scale(-1.0).add_const(kk);
            let r1 = y.scale(-1.0 / jd);
            let r2 = y.add_const(a0 - af).scale(1.0 / jd);
            let (lo, hi) =
                if d > 0.0 { (-2.0 * am * (1.0 + 1e-9), -1e-300) } else { (1e-300, 2.0 * am * (1.0 + 1e-9)) };
            self.family(&mut c, &[h1, r1, h2, r2], &[0.0, -jd, 0.0, -jd], lo, hi);
        }
        // Two holds joined by opposite ramps: hold a0, dJ to M, hold M, −dJ to af
        // (y = M − a0), and dJ to M, hold M, −dJ to af, hold af (y = M − af): the sum of
        // the holds from the duration, their split from the velocity equation.
        for d in [1.0f64, -1.0] {
            let jd = d * jm;
            let y = Lp::mono(1.0, 1);
            let (lo, hi) =
                if d > 0.0 { (1e-300, 2.0 * am * (1.0 + 1e-9)) } else { (-2.0 * am * (1.0 + 1e-9), -1e-300) };
            // a0·h1 + M·hm = Δv − (2M² − a0² − af²)/(2jd), h1 + hm = tt − r1 − r2.
            let kk = tt - (a0 - af) / jd;
            let r1 = y.scale(1.0 / jd);
            let r2 = y.add_const(a0 - af).scale(1.0 / jd);
            let sum = y.scale(-2.0 / jd).add_const(kk);
            let m = y.add_const(a0);
            let vrest = m.mul(&m).scale(-1.0 / jd).add_const(dv + (a0 * a0 + af * af) / (2.0 * jd));
            let hm = vrest.add(&sum.scale(-a0)).mul(&Lp::mono(1.0, -1));
            let h1 = sum.add(&hm.scale(-1.0));
            self.family(&mut c, &[h1, r1, hm, r2], &[0.0, jd, 0.0, -jd], lo, hi);
            // M·hm + af·hf = Δv − (2M² − a0² − af²)/(2jd), hm + hf = tt − r1 − r2.
            let kk = tt - (af - a0) / jd;
            let r1 = y.add_const(af - a0).scale(1.0 / jd);
            let r2 = y.scale(1.0 / jd);
            let sum = y.scale(-2.0 / jd).add_const(kk);
            let m = y.add_const(af);
            let vrest = m.mul(&m).scale(-1.0 / jd).add_const(dv + (a0 * a0 + af * af) / (2.0 * jd));
            let hm = vrest.add(&sum.scale(-af)).mul(&Lp::mono(1.0, -1));
            let hf = sum.add(&hm.scale(-1.0));
            self.family(&mut c, &[r1, hm, r2, hf], &[jd, 0.0, -jd, 0.0], lo, hi);
        }
        // Four ramps `dJ, −dJ, dJ, −dJ` without holds (a0 → A1 → M → A2 → af).
        // With x = A1 − M, y = A2 − M the duration gives A1 + A2 − M = S and the
        // velocity A1² + A2² − M² = Q, hence x·y = (S² − Q)/2 = P, y = P/x.
        for d in [1.0f64, -1.0] {
            let jd = d * jm;
            let ss = (jd * tt + a0 + af) / 2.0;
            let q = jd * dv + (a0 * a0 + af * af) / 2.0;
            let pp = (ss * ss - q) / 2.0;
            let x = Lp::mono(1.0, 1);
            let y = Lp::mono(pp, -1);
            let t1 = y.scale(-1.0).add_const(ss - a0).scale(1.0 / jd);
            let t2 = x.scale(1.0 / jd);
            let t3 = y.scale(1.0 / jd);
            let t4 = x.scale(-1.0).add_const(ss - af).scale(1.0 / jd);
            let (lo, hi) =
                if d > 0.0 { (1e-300, 2.0 * am * (1.0 + 1e-9)) } else { (-2.0 * am * (1.0 + 1e-9), -1e-300) };
            self.family(&mut c, &[t1, t2, t3, t4], &[jd, -jd, jd, -jd], lo, hi);
        }
        (0..c.n).find(|&i| (c.t[i] - tt).abs() <= 1e-9 * (1.0 + tt)).map(|i| c.get(self, i))
    }

    /// All step-1 candidates; `None` if there is none (numerical failure).
    pub fn solve(&self) -> Option<Step1> {
        // Families' roots first; only when none gives a profile, their touching roots too
        // (a target reached exactly at the end of a single jerk phase, e.g. a joint braking
        // to rest where its current brake ends: 1 of 6 such joints in a planner's edge failed).
        self.solve_with(false).or_else(|| self.solve_with(true))
    }

    fn solve_with(&self, touching: bool) -> Option<Step1> {
        let mut c = Cands::new();
        c.touching = touching;
        if touching {
            // One jerk phase from a0 to af: no profile is shorter (|Δa| ≤ J·t), so when it
            // reaches the target it is the answer (the case the touching roots stand for,
            // found exactly: the families' candidates there end a phase a rounding below 0).
            for d in [1.0f64, -1.0] {
                let t = (self.af - self.a0) / (d * self.jm);
                if t > 0.0 && self.add_raw(&mut c, &[t], &[d * self.jm]) {
                    break;
                }
            }
        }
        let (v0, a0, vf, af) = (self.v0, self.a0, self.vf, self.af);
        let (vm, am, jm) = (self.vm, self.am, self.jm);
        let dv = vf - v0;
        let dp = self.pf - self.p0;
        // Already at the target's state: no motion at all. At rest it can hold for any time; a
        // joint moving at its target velocity can only leave and come back (below, with the
        // durations in between blocked).
        let at_target = dp == 0.0 && dv == 0.0 && a0 == 0.0 && af == 0.0;
        if at_target && v0 == 0.0 {
            let pr = Profile::new(self.p0, v0, a0);
            return Some(Step1 {
                best: pr,
                t_min: 0.0,
                blocked: [(0.0, 0.0); 3],
                right: [pr; 3],
                n_blocked: 0,
            });
        }
        for d in [1.0f64, -1.0] {
            if c.n > 0 && touching {
                break;
            }
            let jd = d * jm;
            let a1 = d * am;
            let a2 = -d * am;
            // VEL
            if let (Some(h1), Some(h2)) = (
                velocity::min_time(v0, a0, d * vm, 0.0, am, jm),
                velocity::min_time(d * vm, 0.0, vf, af, am, jm),
            ) {
                let (mut p, mut v, mut a) = (0.0, v0, a0);
                for i in 0..3 {
                    (p, v, a) = integrate(h1.t[i], p, v, a, h1.j[i]);
                }
                let p1 = p;
                let (mut p, mut v2, mut a2x) = (0.0, d * vm, 0.0);
                for i in 0..3 {
                    (p, v2, a2x) = integrate(h2.t[i], p, v2, a2x, h2.j[i]);
                }
                let _ = (v, a, v2, a2x);
                let t4 = (dp - p1 - p) / (d * vm);
                let t = [h1.t[0], h1.t[1], h1.t[2], t4, h2.t[0], h2.t[1], h2.t[2]];
                let j = [h1.j[0], h1.j[1], h1.j[2], 0.0, h2.j[0], h2.j[1], h2.j[2]];
                // A valid cruise at the velocity limit in this direction
                // excludes the non-cruise families of the same direction.
                if self.add_raw(&mut c, &t, &j) && t4 > 0.0 {
                    continue;
                }
            }
            let js = [jd, 0.0, -jd, 0.0, jd];
            let ij = 1.0 / jd;
            // The position equations of the families below, expanded in
            // closed form (J = jd); they share
            // K1 = J(v0 + vf) − (a0² + af²)/2,
            // K2 = 2J²(p0 − pf) + 2J(af·vf − a0·v0) + 2(a0³ − af³)/3,
            // K3 = J²(vf² − v0²) + J(a0²·v0 − af²·vf) − (a0⁴ − af⁴)/4.
            let (a0s, afs) = (a0 * a0, af * af);
            let k1 = jd * (v0 + vf) - 0.5 * (a0s + afs);
            let k2 = 2.0 * jd * jd * (self.p0 - self.pf)
                + 2.0 * jd * (af * vf - a0 * v0)
                + (2.0 / 3.0) * (a0s * a0 - afs * af);
            let k3 =
                jd * jd * (vf * vf - v0 * v0) + jd * (a0s * v0 - afs * vf) - 0.25 * (a0s * a0s - afs * afs);
            // ACC0_ACC1: A1 t2 + A2 t6 = R.
            {
                let r = dv - (a1 * a1 - a0 * a0) / (2.0 * jd) - (af * af - a2 * a2) / (2.0 * jd);
                let ts = [
                    [(a1 - a0) / jd, 0.0, 0.0],
                    [0.0, 1.0, 0.0],
                    [(a1 - a2) / jd, 0.0, 0.0],
                    [r / a2, -a1 / a2, 0.0],
                    [(af - a2) / jd, 0.0, 0.0],
                ];
                // Position residual times 2·A·J² in x = t2 (A = A1 = −A2).
                let aa = a1 * a1;
                let poly = [
                    4.0 * aa * aa + aa * jd * (7.0 * v0 + vf) - aa * (3.5 * a0s + 0.5 * afs) + a1 * k2 - k3,
                    2.0 * a1 * jd * (3.0 * aa + 2.0 * jd * v0 - a0s),
                    2.0 * aa * jd * jd,
                ];
                // t2 = x >= 0 and t6 = x − R/A1 >= 0 (with a margin well
                // above the duration check's tolerance).
                let x0 = (r / a1).max(0.0);
                let lo = x0 - 1e-8 * (1.0 + 2.0 * x0 + (r / a1).abs() + 6.0 * am / jm);
                self.family_poly(&mut c, &poly, &ts, &js, 0, (lo, f64::INFINITY));
            }
            // ACC0: A1 = dA, x = A2, t6 = 0.
            {
                // t2 = (Δv − (2A1² − a0² + af²)/(2jd) + x²/jd) / A1
                let ts = [
                    [(a1 - a0) / jd, 0.0, 0.0],
                    [(dv - (2.0 * a1 * a1 - a0 * a0 + af * af) / (2.0 * jd)) / a1, 0.0, 1.0 / (jd * a1)],
                    [a1 / jd, -1.0 / jd, 0.0],
                    [0.0; 3],
                    [af / jd, -1.0 / jd, 0.0],
                ];
                // Prune: t2 is largest at x² = A²; t7 >= 0 needs d·x <= d·af.
                let t2_max = d * (dv + (a0 * a0 - af * af) / (2.0 * jd)) / am;
                let (lo, hi) = if d > 0.0 { (-am, af) } else { (af, am) };
                if t2_max >= -1e-12 * (1.0 + dv.abs()) {
                    let (lo, hi) = hold_window(&ts, 1, lo - 1e-12 * am, hi + 1e-12 * am, am, jm);
                    if lo <= hi {
                        // Position residual times 2·A1·J² in x = A2.
                        let w = 2.0 * jd * vf - afs;
                        let poly = [a1 * a1 * k1 + a1 * k2 + k3, -2.0 * a1 * w, a1 * a1 + w, -2.0 * a1, 1.0];
                        self.family_poly(&mut c, &poly, &ts, &js, 0, (lo, hi));
                    }
                }
            }
            // ACC1: A2 = −dA, x = A1, t2 = 0.
            {
                // t6 = (Δv − (−a0² − 2A2² + af²)/(2jd) − x²/jd) / A2
                let ts = [
                    [-a0 / jd, 1.0 / jd, 0.0],
                    [0.0; 3],
                    [-a2 / jd, 1.0 / jd, 0.0],
                    [(dv - (-a0 * a0 - 2.0 * a2 * a2 + af * af) / (2.0 * jd)) / a2, 0.0, -1.0 / (jd * a2)],
                    [(af - a2) / jd, 0.0, 0.0],
                ];
                // Prune: t6 is largest at x² = A²; t1 >= 0 needs d·x >= d·a0.
                let t6_max = d * ((af * af - a0 * a0) / (2.0 * jd) - dv) / am;
                let (lo, hi) = if d > 0.0 { (a0, am) } else { (-am, a0) };
                if t6_max >= -1e-12 * (1.0 + dv.abs()) {
                    let (lo, hi) = hold_window(&ts, 3, lo - 1e-12 * am, hi + 1e-12 * am, am, jm);
                    if lo <= hi {
                        // Position residual times −2·A2·J² in x = A1.
                        let w = 2.0 * jd * v0 - a0s;
                        let poly = [a2 * a2 * k1 - a2 * k2 - k3, -2.0 * a2 * w, a2 * a2 + w, -2.0 * a2, 1.0];
                        self.family_poly(&mut c, &poly, &ts, &js, 0, (lo, hi));
                    }
                }
            }
            // NONE: u = A1 − A2, A1 = (u + C/u)/2, A2 = (C/u − u)/2; the
            // durations times u are quadratics in u.
            {
                let cc = jd * dv + (a0 * a0 - af * af) / 2.0;
                let ts = [
                    [cc * 0.5 * ij, -a0 * ij, 0.5 * ij],
                    [0.0; 3],
                    [0.0, 0.0, ij],
                    [0.0; 3],
                    [-(cc * 0.5) * ij, af * ij, 0.5 * ij],
                ];
                // |A1|, |A2| <= A (with a margin above the limit check's
                // tolerance) bound |u| to [|C|/(A + √(A² − |C|)), A + √(A² − |C|)].
                let amt = am * (1.0 + 1e-8) + 1e-10 * (1.0 + am);
                let cabs = cc.abs();
                let mut umin = cabs / (amt + (amt * amt - cabs).max(0.0).sqrt()) * (1.0 - 1e-9);
                // t1 >= 0 (A1 >= a0) and t5 >= 0 (A2 <= af) in the direction's
                // frame (signs flipped for d < 0), with a margin above the
                // duration check's tolerance (durations are at most 6A/J):
                // for C <= 0, |u| >= a0 + √(a0² − C); for C >= 0, |u| >= √(af² + C) − af.
                let da = 1e-8 * (jm + 6.0 * am);
                let (a0d, afd) = (d * a0 - da, d * af + da);
                if cc <= 0.0 {
                    umin = umin.max((a0d + (a0d * a0d - cc).sqrt()) * (1.0 - 1e-9));
                }
                if cc >= 0.0 {
                    umin = umin.max(((afd * afd + cc).sqrt() - afd) * (1.0 - 1e-9));
                }
                let umax = (amt + (amt * amt - cabs).max(0.0).sqrt()).min(2.0 * am * (1.0 + 1e-9));
                let (lo, hi) = if d > 0.0 { (umin.max(1e-300), umax) } else { (-umax, -umin.max(1e-300)) };
                // A1² − A2² = C with |A1|, |A2| <= A needs |C| <= A².
                if cc.abs() <= am * am * (1.0 + 1e-9) && lo <= hi {
                    // The position residual times u³·J² is u²·q(u)/4 with the
                    // depressed quartic
                    // q(u) = u⁴ + 2(2J(v0 + vf) − a0² − af²)·u²
                    //        + 4(J²(p0 − pf) + J(af·vf − a0·v0) + (a0³ − af³)/3)·u − C²
                    // (derived by expanding the three-ramp integration), so
                    // only a quartic has to be solved.
                    // (= u⁴ + 4·K1·u² + 2·K2·u − C²)
                    let q = [-cc * cc, 2.0 * k2, 4.0 * k1, 0.0, 1.0];
                    self.family_poly(&mut c, &q, &ts, &js, 1, (lo, hi));
                }
            }
        }
        // A moving joint already at its target with no way back found: it ends at once, and
        // at no later time.
        let at_once = || {
            let pr = Profile::new(self.p0, v0, a0);
            Step1 {
                best: pr,
                t_min: 0.0,
                blocked: [(0.0, f64::INFINITY), (0.0, 0.0), (0.0, 0.0)],
                right: [pr; 3],
                n_blocked: 1,
            }
        };
        if c.n == 0 {
            return at_target.then(at_once);
        }
        // Sort by duration and merge duplicates (the same profile found by two families).
        let mut idx = [0usize; MAX_CAND];
        for (i, v) in idx.iter_mut().enumerate() {
            *v = i;
        }
        let idx = &mut idx[..c.n];
        idx.sort_unstable_by(|&a, &b| c.t[a].total_cmp(&c.t[b]));
        let mut u = [0usize; MAX_CAND];
        let mut nu = 0;
        for &i in idx.iter() {
            if nu == 0 || c.t[i] - c.t[u[nu - 1]] > 1e-9 * (1.0 + c.t[i]) {
                u[nu] = i;
                nu += 1;
            }
        }
        // The durations found are the ends of the feasible durations' intervals: the fastest,
        // then each blocked interval's two ends. An even count means the fastest is an
        // isolated point (a touching root: the profile exists at that duration alone), so the
        // durations up to the next are blocked (as Ruckig's block calculation reads two
        // profiles). A moving joint already at its target's state is such a point at 0 (the
        // families find it too): it cannot stay, only leave and come back.
        let first = if at_target {
            match u[..nu].iter().position(|&i| c.t[i] > 0.0) {
                Some(f) => f,
                None => return Some(at_once()),
            }
        } else {
            0
        };
        let list = &u[first..nu];
        let n = list.len();
        let best = c.get(self, list[0]);
        let mut out =
            Step1 { best, t_min: c.t[list[0]], blocked: [(0.0, 0.0); 3], right: [best; 3], n_blocked: 0 };
        if at_target {
            out.best = Profile::new(self.p0, v0, a0);
            out.t_min = 0.0;
            out.blocked[0] = (0.0, c.t[list[0]]);
            out.n_blocked = 1;
        }
        let mut k = if n % 2 == 0 { 0 } else { 1 };
        while k + 1 < n && out.n_blocked < 3 {
            out.blocked[out.n_blocked] = (c.t[list[k]], c.t[list[k + 1]]);
            out.right[out.n_blocked] = c.get(self, list[k + 1]);
            out.n_blocked += 1;
            k += 2;
        }
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn holds_families_match_the_laurent_assembly() {
        let mut s = 987654321u64;
        let mut rnd = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let (mut found, mut n) = (0, 0);
        while n < 4000 {
            let vm = 0.08 + 16.0 * rnd();
            let am = 0.08 + 16.0 * rnd();
            let jm = 0.08 + 16.0 * rnd();
            let a0 = (2.0 * rnd() - 1.0) * am;
            let af = (2.0 * rnd() - 1.0) * am;
            let v0 = (2.0 * rnd() - 1.0) * (vm - a0 * a0 / (2.0 * jm)).max(0.0);
            let vf = (2.0 * rnd() - 1.0) * (vm - af * af / (2.0 * jm)).max(0.0);
            let pb = Problem { p0: 0.0, v0, a0, pf: 8.0 * (rnd() - 0.5), vf, af, vm, am, jm };
            let Some(st) = pb.solve() else { continue };
            n += 1;
            for k in 0..3 {
                let tt = st.t_min * (1.0 + [1e-6, 0.01, 0.5][k] * rnd());
                let a = pb.with_duration_holds(tt);
                let b = pb.with_duration_holds_lp(tt);
                assert_eq!(a.is_some(), b.is_some(), "{pb:?} {tt}");
                if let (Some(a), Some(b)) = (a, b) {
                    found += 1;
                    assert!((a.duration() - b.duration()).abs() < 1e-9 * (1.0 + tt));
                    assert_eq!(a.n, b.n, "{pb:?} {tt}");
                    for i in 0..a.n {
                        assert!((a.t[i] - b.t[i]).abs() < 1e-7 * (1.0 + tt), "{pb:?} {tt} {a:?} {b:?}");
                    }
                }
            }
        }
        assert!(found > 1000, "{found}");
    }
}
