//! Step 2: a profile of one joint with a prescribed duration (used to make
//! all joints finish together).

use crate::step1::ramp;

/// Rest-to-rest over `dist` in exactly `tt` (>= the minimum duration): the
/// cruise velocity `vc` and cruise time, found on the decreasing branch of
/// `g(vc) = Tacc(vc) + d/vc`.
pub(crate) fn rest_to_rest_with_duration(
    dist: f64,
    tt: f64,
    vc_max: f64,
    am: f64,
    jm: f64,
) -> Option<(f64, f64)> {
    let d = dist.abs();
    if d == 0.0 {
        return Some((0.0, tt));
    }
    let tacc = |vc: f64| {
        let (tj, tc) = ramp(vc, am, jm);
        2.0 * tj + tc
    };
    let g = |vc: f64| tacc(vc) + d / vc;
    if g(vc_max) >= tt {
        let t4 = (d / vc_max - tacc(vc_max)).max(0.0);
        return Some((vc_max, t4));
    }
    // Bracket: g(lo) > tt > g(hi) with g decreasing.
    let (mut lo, mut hi) = (d / tt * 0.5, vc_max);
    if g(lo) < tt {
        lo = f64::MIN_POSITIVE;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if g(mid) > tt {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let vc = 0.5 * (lo + hi);
    let t4 = tt - 2.0 * tacc(vc);
    Some((vc, t4.max(0.0)))
}
