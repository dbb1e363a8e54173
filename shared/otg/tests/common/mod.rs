//! Shared checks for the integration tests.
#![allow(dead_code)]

use dkrrt_otg::{KinState, Limits, Trajectory};

/// Check every segment of every joint: continuity, limits at boundaries and at
/// interior velocity extrema, and a dense sampling (`samples` points); the end
/// state equals `target` (per joint where `check_p/v/a`).
pub fn check_traj<const N: usize>(
    tr: &Trajectory<N>,
    start: &KinState<N>,
    target: &KinState<N>,
    lim: &Limits<N>,
    check_p: bool,
    samples: usize,
    skip_brake: bool,
) -> Result<(), String> {
    let t_end = tr.duration();
    if !(t_end.is_finite() && t_end >= 0.0) {
        return Err(format!("bad duration {t_end}"));
    }
    for j in 0..N {
        let segs = tr.joint_segments(j);
        let vt = lim.v_max[j] * (1.0 + 1e-9) + 1e-9;
        let at = lim.a_max[j] * (1.0 + 1e-9) + 1e-9;
        let jt = lim.j_max[j] * (1.0 + 1e-12);
        let (mut p, mut v, mut a) = (start.p[j], start.v[j], start.a[j]);
        let mut t = 0.0;
        // In braking segments the state may be beyond the limits; the state after
        // the brake must be inside.
        let mut braking = skip_brake;
        for (k, s) in segs.iter().enumerate() {
            if (s.t0 - t).abs() > 1e-12 * (1.0 + t) {
                return Err(format!("joint {j} seg {k}: gap t0={} expected {t}", s.t0));
            }
            let tol = 1e-9 * (1.0 + p.abs() + v.abs() + a.abs());
            if (s.p0 - p).abs() > tol || (s.v0 - v).abs() > tol || (s.a0 - a).abs() > tol {
                return Err(format!("joint {j} seg {k}: discontinuity"));
            }
            if s.jerk.abs() > jt {
                return Err(format!("joint {j} seg {k}: jerk {} > {}", s.jerk, lim.j_max[j]));
            }
            if braking && s.v0.abs() <= vt && s.a0.abs() <= at && k > 0 {
                braking = false;
            }
            if braking && k == 0 {
                let outside = s.a0.abs() > lim.a_max[j]
                    || s.v0.abs() > lim.v_max[j]
                    || (s.a0 > 0.0 && s.v0 + s.a0 * s.a0 / (2.0 * lim.j_max[j]) > lim.v_max[j])
                    || (s.a0 < 0.0 && s.v0 - s.a0 * s.a0 / (2.0 * lim.j_max[j]) < -lim.v_max[j]);
                braking = outside;
            }
            if !braking {
                if s.v0.abs() > vt || s.a0.abs() > at {
                    return Err(format!("joint {j} seg {k}: limit violated v={} a={}", s.v0, s.a0));
                }
                if s.jerk != 0.0 {
                    let tz = -s.a0 / s.jerk;
                    if tz > 0.0 && tz < s.t1 - s.t0 {
                        let (_, vz, _) = s.state_at(s.t0 + tz);
                        if vz.abs() > vt {
                            return Err(format!("joint {j} seg {k}: v extremum {vz} > {}", lim.v_max[j]));
                        }
                    }
                }
            }
            (p, v, a) = s.state_at(s.t1);
            t = s.t1;
            if !braking && (v.abs() > vt || a.abs() > at) {
                return Err(format!("joint {j} seg {k} end: limit violated v={v} a={a}"));
            }
        }
        if !segs.is_empty() && (t - t_end).abs() > 1e-12 * (1.0 + t_end) {
            return Err(format!("joint {j}: ends at {t}, trajectory at {t_end}"));
        }
        let fin = tr.at(t_end);
        let (dp, dv, da) = ((p - target.p[j]).abs(), (v - target.v[j]).abs(), (a - target.a[j]).abs());
        if (check_p && dp >= 1e-8) || dv >= 1e-8 || da >= 1e-10 {
            return Err(format!("joint {j}: final state off by dp={dp:e} dv={dv:e} da={da:e}"));
        }
        if (check_p && (fin.p[j] - target.p[j]).abs() >= 1e-8)
            || (fin.v[j] - target.v[j]).abs() >= 1e-8
            || (fin.a[j] - target.a[j]).abs() >= 1e-10
        {
            return Err(format!("joint {j}: sampled final state differs"));
        }
    }
    // Dense sampling of all joints.
    for i in 0..=samples {
        let t = t_end * i as f64 / samples.max(1) as f64;
        let s = tr.at(t);
        for j in 0..N {
            let vt = lim.v_max[j] * (1.0 + 1e-9) + 1e-9;
            let at = lim.a_max[j] * (1.0 + 1e-9) + 1e-9;
            let in_brake = skip_brake
                && tr.joint_segments(j).first().is_some_and(|s0| {
                    let brake_end = tr.joint_segments(j).iter().take(2).map(|s| s.t1).fold(0.0, f64::max);
                    s0.t0 <= t && t <= brake_end
                });
            if !in_brake && (s.v[j].abs() > vt || s.a[j].abs() > at) {
                return Err(format!("joint {j} t={t}: sampled limit violation v={} a={}", s.v[j], s.a[j]));
            }
        }
    }
    Ok(())
}
