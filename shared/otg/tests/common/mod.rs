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
    // Where the start state is beyond the limits (or makes exceeding the
    // velocity limit inevitable), the bound is relaxed to that excursion.
    let mut vhi = [0.0; N];
    let mut vlo = [0.0; N];
    let mut ab = [0.0; N];
    for j in 0..N {
        let (v0, a0, jm, vm) = (start.v[j], start.a[j], lim.j_max[j], lim.v_max[j]);
        let ex = v0 + a0 * a0.abs() / (2.0 * jm);
        (vlo[j], vhi[j]) = if skip_brake { ((-vm).min(v0).min(ex), vm.max(v0).max(ex)) } else { (-vm, vm) };
        ab[j] = if skip_brake { lim.a_max[j].max(a0.abs()) } else { lim.a_max[j] };
        vhi[j] += vhi[j].abs() * 1e-9 + 1e-9;
        vlo[j] -= vlo[j].abs() * 1e-9 + 1e-9;
        ab[j] = ab[j] * (1.0 + 1e-9) + 1e-9;
    }
    for j in 0..N {
        let segs = tr.joint_segments(j);
        let (vh, vl, at) = (vhi[j], vlo[j], ab[j]);
        let jt = lim.j_max[j] * (1.0 + 1e-12);
        let (mut p, mut v, mut a) = (start.p[j], start.v[j], start.a[j]);
        let mut t = 0.0;
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
            if s.v0 > vh || s.v0 < vl || s.a0.abs() > at {
                return Err(format!("joint {j} seg {k}: limit violated v={} a={}", s.v0, s.a0));
            }
            if s.jerk != 0.0 {
                let tz = -s.a0 / s.jerk;
                if tz > 0.0 && tz < s.t1 - s.t0 {
                    let (_, vz, _) = s.state_at(s.t0 + tz);
                    if vz > vh || vz < vl {
                        return Err(format!("joint {j} seg {k}: v extremum {vz} > {}", lim.v_max[j]));
                    }
                }
            }
            (p, v, a) = s.state_at(s.t1);
            t = s.t1;
            if v > vh || v < vl || a.abs() > at {
                return Err(format!("joint {j} seg {k} end: limit violated v={v} a={a}"));
            }
        }
        if !segs.is_empty() && (t - t_end).abs() > 1e-12 * (1.0 + t_end) {
            return Err(format!("joint {j}: ends at {t}, trajectory at {t_end}"));
        }
        let fin = tr.at(t_end);
        let (dp, dv, da) = ((p - target.p[j]).abs(), (v - target.v[j]).abs(), (a - target.a[j]).abs());
        // The end's acceleration to rounding in time of the jerk (1e-16 of the limit).
        if (check_p && dp >= 1e-8) || dv >= 1e-8 || da >= 1e-10 + 1e-14 * lim.a_max[j] {
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
            if s.v[j] > vhi[j] || s.v[j] < vlo[j] || s.a[j].abs() > ab[j] {
                return Err(format!("joint {j} t={t}: sampled limit violation v={} a={}", s.v[j], s.a[j]));
            }
        }
    }
    Ok(())
}
