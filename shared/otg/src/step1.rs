//! Step 1: the time-optimal profile of a single joint (minimum duration).

use crate::profile::Profile;

/// Acceleration ramp from rest to cruise velocity `vc` (>= 0): jerk time and
/// constant-acceleration time.
#[inline]
pub(crate) fn ramp(vc: f64, am: f64, jm: f64) -> (f64, f64) {
    if vc * jm >= am * am {
        (am / jm, vc / am - am / jm)
    } else {
        ((vc / jm).sqrt(), 0.0)
    }
}

/// Append a symmetric rest-to-rest profile with cruise velocity `vc`, jerk
/// direction `d` and cruise time `t4`.
pub(crate) fn push_rest_profile(prof: &mut Profile, d: f64, vc: f64, t4: f64, am: f64, jm: f64) {
    let (tj, tc) = ramp(vc, am, jm);
    prof.push(tj, d * jm);
    prof.push(tc, 0.0);
    prof.push(tj, -d * jm);
    prof.push(t4, 0.0);
    prof.push(tj, -d * jm);
    prof.push(tc, 0.0);
    prof.push(tj, d * jm);
}

/// Minimum-time rest-to-rest motion over distance `dist` (any sign):
/// returns `(cruise velocity, cruise time)`.
pub(crate) fn rest_to_rest(dist: f64, vm: f64, am: f64, jm: f64) -> (f64, f64) {
    let d = dist.abs();
    if d == 0.0 {
        return (0.0, 0.0);
    }
    let (tj, tc) = ramp(vm, am, jm);
    let tacc = 2.0 * tj + tc;
    if vm * tacc <= d {
        return (vm, d / vm - tacc);
    }
    // Velocity limit not reached: vc·Tacc(vc) = d.
    let k = am / jm;
    let vc = (-k + (k * k + 4.0 * d / am).sqrt()) * am / 2.0;
    if vc * jm >= am * am {
        return (vc.min(vm), 0.0);
    }
    ((d * jm.sqrt() / 2.0).powf(2.0 / 3.0).min(vm), 0.0)
}
