//! Step 2: a profile of one joint with a prescribed duration (so that all
//! joints finish together).
//!
//! Primary family: a time-optimal velocity profile to a cruise velocity `vc`
//! (acceleration 0), a cruise, and a time-optimal velocity profile to the
//! target; the cruise time follows from the duration, and `vc` is the root of
//! the remaining position equation, found by safeguarded Newton with the
//! analytic derivative (`by_cruise_newton`). Fallbacks for the rare durations
//! this family cannot realize: the hold families (`Problem::with_duration_holds`),
//! more thorough searches of the cruise family, and the time-optimal profile
//! under a reduced jerk, acceleration or velocity limit whose minimum duration
//! equals the prescribed one.

#[allow(unused_imports)]
use crate::profile::raw_within_limits;
use crate::profile::{integrate, Profile};
use crate::step1::Problem;
use crate::velocity::{self, VelProfile};

fn vel_end(h: &VelProfile, v: f64, a: f64) -> f64 {
    let (mut p, mut v, mut a) = (0.0, v, a);
    for i in 0..3 {
        (p, v, a) = integrate(h.t[i], p, v, a, h.j[i]);
    }
    p
}

/// Cruise family residual at cruise velocity `vc`.
fn cruise(pb: &Problem, tt: f64, vc: f64) -> Option<(f64, VelProfile, f64, VelProfile)> {
    let h1 = velocity::min_time(pb.v0, pb.a0, vc, 0.0, pb.am, pb.jm)?;
    let h2 = velocity::min_time(vc, 0.0, pb.vf, pb.af, pb.am, pb.jm)?;
    let t4 = tt - h1.duration() - h2.duration();
    if t4 < -1e-12 * (1.0 + tt) {
        return None;
    }
    let f = vel_end(&h1, pb.v0, pb.a0) + vel_end(&h2, vc, 0.0) + vc * t4.max(0.0) - (pb.pf - pb.p0);
    Some((f, h1, t4.max(0.0), h2))
}

/// The time-optimal velocity ramp between a state with zero acceleration
/// and `(v, a)`: its jerk sign `s`, peak acceleration `ap` (or the plateau
/// at `±am` with hold `th`). `from_rest` (zero acceleration at the start):
/// `(vz, 0) → (v, a)`, else `(v, a) → (vz, 0)`. The sign follows from the
/// velocity reached by ramping the acceleration straight to its end value.
#[inline(always)]
fn ramp(v: f64, a: f64, vz: f64, from_rest: bool, am: f64, jm: f64) -> (f64, f64, f64) {
    // Velocity change from the zero-acceleration end towards the other end.
    let (dv, free) = if from_rest {
        (v - vz, v - vz - a * a.abs() / (2.0 * jm))
    } else {
        (vz - v, vz - v - a * a.abs() / (2.0 * jm))
    };
    let s = if free >= 0.0 { 1.0 } else { -1.0 };
    let sj = s * jm;
    let sq = (sj * dv + 0.5 * a * a).max(0.0);
    let ap = sq.sqrt();
    if ap > am {
        let ap = s * am;
        (s, ap, (dv - (2.0 * am * am - a * a) / (2.0 * sj)) / ap)
    } else {
        (s, s * ap, 0.0)
    }
}

/// Cruise family at cruise velocity `vc` (cruise time allowed negative):
/// position residual `f`, its derivative `df/dvc = t4 + (r1 + r2)/2` (`r1`,
/// `r2`: the ramps next to the cruise; from `d(P − vc·T)/dvc = −T + r/2` for
/// each velocity profile), phase durations and jerks.
#[inline]
fn cruise_newton(pb: &Problem, tt: f64, vc: f64) -> (f64, f64, [f64; 7], [f64; 7]) {
    let (am, jm) = (pb.am, pb.jm);
    let (s1, ap1, h1) = ramp(pb.v0, pb.a0, vc, false, am, jm);
    let (s2, ap2, h2) = ramp(pb.vf, pb.af, vc, true, am, jm);
    let (ij1, ij2) = (s1 / jm, s2 / jm);
    let t = [(ap1 - pb.a0) * ij1, h1, ap1 * ij1, 0.0, ap2 * ij2, h2, (ap2 - pb.af) * ij2];
    let j = [s1 * jm, 0.0, -s1 * jm, 0.0, s2 * jm, 0.0, -s2 * jm];
    let t4 = tt - (t[0] + t[1] + t[2]) - (t[4] + t[5] + t[6]);
    let (mut p, mut v, mut a) = (0.0, pb.v0, pb.a0);
    for k in 0..3 {
        (p, v, a) = integrate(t[k], p, v, a, j[k]);
    }
    let _ = (v, a);
    let p1 = p;
    let (mut p, mut v, mut a) = (0.0, vc, 0.0);
    for k in 4..7 {
        (p, v, a) = integrate(t[k], p, v, a, j[k]);
    }
    let _ = (v, a);
    let f = p1 + p + vc * t4 - (pb.pf - pb.p0);
    let mut t = t;
    t[3] = t4;
    (f, t4 + 0.5 * (t[2] + t[4]), t, j)
}

/// Fast path: safeguarded Newton on the cruise residual (increasing in `vc`
/// wherever the cruise time is not negative) from the mean velocity.
fn by_cruise_newton(pb: &Problem, tt: f64, lo: f64, hi: f64) -> Option<Profile> {
    let (mut a, mut b) = (lo, hi);
    let dp = pb.pf - pb.p0;
    let mut x = (dp / tt).clamp(a, b);
    let ftol = 1e-15 * (1.0 + dp.abs());
    let mut res = cruise_newton(pb, tt, x);
    for _ in 0..40 {
        let (f, df, ..) = res;
        if !f.is_finite() {
            return None;
        }
        if f.abs() <= ftol {
            break;
        }
        if f < 0.0 {
            a = x;
        } else {
            b = x;
        }
        let xn = x - f / df;
        let next = if df > 0.0 && xn > a && xn < b { xn } else { 0.5 * (a + b) };
        if (next - x).abs() <= 1e-15 * (1.0 + x.abs()) {
            break;
        }
        x = next;
        res = cruise_newton(pb, tt, x);
    }
    let (_, _, mut t, j) = res;
    if t[3] < -1e-12 * (1.0 + tt) {
        return None;
    }
    t[3] = t[3].max(0.0);
    let pr = pb.build(&t, &j)?;
    pb.accept(&pr).then_some(pr)
}

/// Cruise family residual at cruise velocity `vc` with the cruise time
/// allowed to be negative (continuous over the whole velocity range).
#[inline]
fn cruise_ext(pb: &Problem, tt: f64, vc: f64) -> Option<(f64, VelProfile, f64, VelProfile)> {
    let h1 = velocity::min_time(pb.v0, pb.a0, vc, 0.0, pb.am, pb.jm)?;
    let h2 = velocity::min_time(vc, 0.0, pb.vf, pb.af, pb.am, pb.jm)?;
    let t4 = tt - h1.duration() - h2.duration();
    let f = vel_end(&h1, pb.v0, pb.a0) + vel_end(&h2, vc, 0.0) + vc * t4 - (pb.pf - pb.p0);
    Some((f, h1, t4, h2))
}

/// Fast path: Illinois on the extended residual over `[lo, hi]`; the root is
/// returned as a profile if its cruise time is not negative and it verifies.
fn by_cruise_ext(pb: &Problem, tt: f64, lo: f64, hi: f64) -> Option<Profile> {
    let (mut a, mut b) = (lo, hi);
    let (mut fa, mut fb) = (cruise_ext(pb, tt, a)?.0, cruise_ext(pb, tt, b)?.0);
    if (fa <= 0.0) == (fb <= 0.0) {
        return None;
    }
    let ftol = 1e-14 * (1.0 + (pb.pf - pb.p0).abs());
    let mut side = 0i8;
    let mut best = if fa.abs() < fb.abs() { a } else { b };
    for _ in 0..100 {
        let mut m = (a * fb - b * fa) / (fb - fa);
        if !(m > a.min(b) && m < a.max(b)) {
            m = 0.5 * (a + b);
        }
        let (fm, ..) = cruise_ext(pb, tt, m)?;
        best = m;
        if (fm <= 0.0) == (fa <= 0.0) {
            a = m;
            fa = fm;
            if side == -1 {
                fb *= 0.5;
            }
            side = -1;
        } else {
            b = m;
            fb = fm;
            if side == 1 {
                fa *= 0.5;
            }
            side = 1;
        }
        if fm.abs() <= ftol || (b - a).abs() <= 1e-15 * (a.abs() + b.abs()) {
            break;
        }
    }
    for x in [best, a, b] {
        let (_, h1, t4, h2) = cruise_ext(pb, tt, x)?;
        if t4 < -1e-12 * (1.0 + tt) {
            return None;
        }
        if let Some(pr) = cruise_profile(pb, &h1, t4.max(0.0), &h2) {
            if pb.accept(&pr) {
                return Some(pr);
            }
        }
    }
    None
}

fn cruise_profile(pb: &Problem, h1: &VelProfile, t4: f64, h2: &VelProfile) -> Option<Profile> {
    let t = [h1.t[0], h1.t[1], h1.t[2], t4, h2.t[0], h2.t[1], h2.t[2]];
    let j = [h1.j[0], h1.j[1], h1.j[2], 0.0, h2.j[0], h2.j[1], h2.j[2]];
    pb.build(&t, &j)
}

/// Cruise velocities reachable within the duration `tt`.
fn cruise_range(pb: &Problem, tt: f64) -> Option<(f64, f64)> {
    let reach = pb.am * tt + pb.a0.abs() * pb.a0.abs() / pb.jm;
    let lo0 = (-pb.vm).max(pb.v0.min(pb.vf) - reach);
    let hi0 = pb.vm.min(pb.v0.max(pb.vf) + reach);
    (lo0 <= hi0).then_some((lo0, hi0))
}

/// The cruise family by the slower, more thorough searches (see
/// [`by_cruise_newton`] for the fast path).
fn by_cruise(pb: &Problem, tt: f64) -> Option<Profile> {
    const K: usize = 24;
    let (lo0, hi0) = cruise_range(pb, tt)?;
    if let Some(pr) = by_cruise_ext(pb, tt, lo0, hi0) {
        return Some(pr);
    }
    // The window where the two velocity profiles fit into the duration:
    // g(vc) = T1 + T2 <= tt. Golden-section search for the minimum of g, then
    // bisection for both window edges.
    let g = |vc: f64| -> f64 {
        velocity::min_time_duration(pb.v0, pb.a0, vc, 0.0, pb.am, pb.jm)
            + velocity::min_time_duration(vc, 0.0, pb.vf, pb.af, pb.am, pb.jm)
    };
    // A cruise velocity inside the window: the golden-section search for the
    // minimum of g stops at the first point with g <= tt.
    let (mut a, mut b) = (lo0, hi0);
    let gr = 0.618_033_988_749_895;
    let (mut c1, mut c2) = (b - gr * (b - a), a + gr * (b - a));
    let (mut g1, mut g2) = (g(c1), g(c2));
    let mut inside = None;
    for _ in 0..64 {
        if g1 <= tt {
            inside = Some(c1);
            break;
        }
        if g2 <= tt {
            inside = Some(c2);
            break;
        }
        if g1 < g2 {
            b = c2;
            c2 = c1;
            g2 = g1;
            c1 = b - gr * (b - a);
            g1 = g(c1);
        } else {
            a = c1;
            c1 = c2;
            g1 = g2;
            c2 = a + gr * (b - a);
            g2 = g(c2);
        }
        if b - a <= 1e-13 * (1.0 + a.abs() + b.abs()) {
            break;
        }
    }
    let (vbest, gbest) = match inside {
        Some(v) => (v, if v == c1 { g1 } else { g2 }),
        None => {
            let v = 0.5 * (a + b);
            let gv = g(v);
            if gv > tt {
                return None;
            }
            (v, gv)
        }
    };
    // Window edge between `inside` (g <= tt) and `outside`: Illinois on
    // g − tt (g is continuous), bisection where it stalls.
    let edge = |mut inside: f64, outside: f64| -> f64 {
        let mut go = g(outside);
        if go <= tt {
            return outside;
        }
        let mut outside = outside;
        let mut gi = gbest - tt;
        go -= tt;
        let mut side = 0i8;
        for it in 0..100 {
            let mut m = if go.is_finite() && it % 8 != 7 {
                inside - gi * (outside - inside) / (go - gi)
            } else {
                0.5 * (inside + outside)
            };
            let (l, h) = if inside < outside { (inside, outside) } else { (outside, inside) };
            if !(m > l && m < h) {
                m = 0.5 * (inside + outside);
                if !(m > l && m < h) {
                    break;
                }
            }
            let gm = g(m) - tt;
            if gm <= 0.0 {
                inside = m;
                gi = gm;
                if side == -1 {
                    go *= 0.5;
                }
                side = -1;
            } else {
                outside = m;
                go = gm;
                if side == 1 {
                    gi *= 0.5;
                }
                side = 1;
            }
            if (outside - inside).abs() <= 1e-14 * (1.0 + inside.abs()) {
                break;
            }
        }
        inside
    };
    // Illinois (modified regula falsi) on a sign change of the residual,
    // which is continuous where it is defined.
    let bracket = |x0: f64, f0: f64, x1: f64, f1: f64| -> Option<Profile> {
        let (mut a, mut b, mut fa, mut fb) = (x0, x1, f0, f1);
        let mut side = 0i8;
        for _ in 0..100 {
            let mut m = (a * fb - b * fa) / (fb - fa);
            if !(m > a && m < b) {
                m = 0.5 * (a + b);
            }
            let Some((fm, ..)) = cruise(pb, tt, m) else { break };
            if (fm <= 0.0) == (fa <= 0.0) {
                a = m;
                fa = fm;
                if side == -1 {
                    fb *= 0.5;
                }
                side = -1;
            } else {
                b = m;
                fb = fm;
                if side == 1 {
                    fa *= 0.5;
                }
                side = 1;
            }
            if fm.abs() <= 1e-14 * (1.0 + (pb.pf - pb.p0).abs()) || b - a <= 1e-15 * (a.abs() + b.abs()) {
                break;
            }
        }
        for x in [a, b] {
            if let Some((_, h1, t4, h2)) = cruise(pb, tt, x) {
                if let Some(pr) = cruise_profile(pb, &h1, t4, &h2) {
                    if pb.accept(&pr) {
                        return Some(pr);
                    }
                }
            }
        }
        None
    };
    // Usually the residual changes sign between the window point and the
    // edge it points to (it mostly grows with the cruise velocity): try that
    // edge first, then the other, then scan the whole window.
    let fbest = cruise(pb, tt, vbest).map(|r| r.0);
    let (mut lo, mut hi) = (f64::NAN, f64::NAN);
    let mut ends = (None, None);
    if let Some(fv) = fbest {
        for low_side in if fv > 0.0 { [true, false] } else { [false, true] } {
            if low_side {
                lo = edge(vbest, lo0);
                ends.0 = cruise(pb, tt, lo).map(|r| r.0);
                if let Some(f0) = ends.0 {
                    if lo < vbest && ((f0 <= 0.0) != (fv <= 0.0) || fv == 0.0) {
                        if let Some(pr) = bracket(lo, f0, vbest, fv) {
                            return Some(pr);
                        }
                    }
                }
            } else {
                hi = edge(vbest, hi0);
                ends.1 = cruise(pb, tt, hi).map(|r| r.0);
                if let Some(f1) = ends.1 {
                    if vbest < hi && ((fv <= 0.0) != (f1 <= 0.0) || f1 == 0.0) {
                        if let Some(pr) = bracket(vbest, fv, hi, f1) {
                            return Some(pr);
                        }
                    }
                }
            }
        }
    }
    if lo.is_nan() {
        lo = edge(vbest, lo0);
        ends.0 = cruise(pb, tt, lo).map(|r| r.0);
    }
    if hi.is_nan() {
        hi = edge(vbest, hi0);
        ends.1 = cruise(pb, tt, hi).map(|r| r.0);
    }
    let mut prev: Option<(f64, f64)> = None;
    for i in 0..=K {
        let vc = lo + (hi - lo) * i as f64 / K as f64;
        let cur = if i == 0 {
            ends.0.map(|f| (vc, f))
        } else if i == K {
            ends.1.map(|f| (hi, f))
        } else {
            cruise(pb, tt, vc).map(|(f, ..)| (vc, f))
        };
        if let (Some((x0, f0)), Some((x1, f1))) = (prev, cur) {
            if (f0 <= 0.0) != (f1 <= 0.0) || f1 == 0.0 {
                if let Some(pr) = bracket(x0, f0, x1, f1) {
                    return Some(pr);
                }
            }
        }
        prev = cur;
    }
    None
}

/// Reduce the jerk (`which = 0`), acceleration (`1`) or velocity (`2`) limit until the
/// time-optimal duration equals `tt`.
fn by_reduced_limit(pb: &Problem, tt: f64, which: usize) -> Option<Profile> {
    let full = [pb.jm, pb.am, pb.vm][which];
    let floor = [
        0.0,
        pb.a0.abs().max(pb.af.abs()),
        pb.v0
            .abs()
            .max(pb.vf.abs() + pb.af * pb.af / (2.0 * pb.jm))
            .max(pb.v0 + pb.a0 * pb.a0.abs() / (2.0 * pb.jm)),
    ][which];
    let make = |x: f64| {
        let mut q = Problem { ..*pb };
        match which {
            0 => q.jm = x,
            1 => q.am = x,
            _ => q.vm = x,
        }
        q
    };
    let (mut lo, mut hi) = (floor, full);
    let mut best: Option<Profile> = None;
    for _ in 0..100 {
        let m = 0.5 * (lo + hi);
        if m <= lo || m >= hi {
            break;
        }
        match make(m).solve() {
            Some(s) if s.t_min > tt => lo = m,
            Some(s) => {
                hi = m;
                best = Some(s.best);
                if (s.t_min - tt).abs() <= 1e-13 * (1.0 + tt) {
                    break;
                }
            }
            None => lo = m,
        }
    }
    let pr = best?;
    // Re-check against the original limits.
    let pr = pb.build(&pr.t[..pr.n.min(7)], &pr.j[..pr.n.min(7)])?;
    ((pr.duration() - tt).abs() <= 1e-10 * (1.0 + tt) && pb.accept(&pr)).then_some(pr)
}

/// A valid profile of duration `tt` (not shorter than the minimum), if found.
pub(crate) fn with_duration(pb: &Problem, tt: f64) -> Option<Profile> {
    if let Some((lo0, hi0)) = cruise_range(pb, tt) {
        if let Some(p) = by_cruise_newton(pb, tt, lo0, hi0) {
            return Some(p);
        }
    }
    // Where the fast path fails the cruise family has (practically) never
    // had a solution: the hold families first, then the thorough cruise
    // searches.
    if let Some(p) = pb.with_duration_holds(tt) {
        return Some(p);
    }
    if let Some(p) = by_cruise(pb, tt) {
        return Some(p);
    }
    by_reduced_limit(pb, tt, 0)
        .or_else(|| by_reduced_limit(pb, tt, 1))
        .or_else(|| by_reduced_limit(pb, tt, 2))
}
