//! The trajectory source core: a joint-space goal becomes a time-optimal,
//! jerk-limited, synchronized trajectory (dkrrt-otg) in the fixed-size
//! [`Trajectory`] message the tracker samples.

use dkrrt_msg::{JerkSegment, Trajectory, Zeroed, MAX_SEGMENTS, NJ};
use dkrrt_otg::{KinState, Limits, Options, OtgError};

#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum GotoError {
    #[error("trajectory generation failed: {0}")]
    Otg(#[from] OtgError),
    #[error("joint {joint} needs {needed} segments, the message carries {max}")]
    TooManySegments { joint: usize, needed: usize, max: usize },
}

/// Encodes a generated trajectory as a message starting at plant time `start_ns`.
pub fn to_message(
    t: &dkrrt_otg::Trajectory<NJ>,
    traj_id: u64,
    start_ns: u64,
    out: &mut Trajectory,
) -> Result<(), GotoError> {
    *out = <Trajectory as Zeroed>::zeroed();
    out.traj_id = traj_id;
    out.start_ns = start_ns;
    out.duration_s = t.duration();
    for j in 0..NJ {
        let segs = t.joint_segments(j);
        // Zero-length segments carry no motion; drop them so t0 strictly increases.
        let mut n = 0;
        for s in segs.iter().filter(|s| s.t1 > s.t0 || segs.len() == 1) {
            if n == MAX_SEGMENTS {
                return Err(GotoError::TooManySegments { joint: j, needed: segs.len(), max: MAX_SEGMENTS });
            }
            if n > 0 && s.t0 <= out.seg[j][n - 1].t0 {
                continue;
            }
            out.seg[j][n] = JerkSegment { t0: s.t0, p: s.p0, v: s.v0, a: s.a0, j: s.jerk };
            n += 1;
        }
        if n == 0 {
            let end = t.final_state();
            out.seg[j][0] = JerkSegment { t0: 0.0, p: end.p[j], v: 0.0, a: 0.0, j: 0.0 };
            n = 1;
        }
        out.seg[j][0].t0 = 0.0;
        out.n_seg[j] = n as u32;
    }
    Ok(())
}

/// Plans a rest-to-rest move from `from` (current position, velocity,
/// acceleration) to `goal` at rest, time-synchronized, with the duration a
/// whole number of control periods `period_s`.
pub fn plan(
    from: &KinState<NJ>,
    goal: &[f64; NJ],
    limits: &Limits<NJ>,
    period_s: f64,
    traj_id: u64,
    start_ns: u64,
    out: &mut Trajectory,
) -> Result<f64, GotoError> {
    let opts = Options { period: Some(period_s), ..Options::default() };
    let t = dkrrt_otg::Trajectory::calculate(from, &KinState::rest(*goal), limits, &opts)?;
    to_message(&t, traj_id, start_ns, out)?;
    Ok(t.duration())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits() -> Limits<NJ> {
        Limits { v_max: [0.1; NJ], a_max: [0.2; NJ], j_max: [1.0; NJ] }
    }

    #[test]
    fn message_reproduces_the_generated_trajectory() {
        let from = KinState::rest([0.0, -0.5, 1.0, 0.0, 0.5, 0.0]);
        let goal = [0.35, -0.2, 0.7, 0.3, 0.2, 0.4];
        let mut msg = <Trajectory as Zeroed>::zeroed();
        let d = plan(&from, &goal, &limits(), 1e-3, 1, 5_000_000, &mut msg).unwrap();
        // Duration is a whole number of periods.
        assert!(((d * 1e3).round() - d * 1e3).abs() < 1e-6, "{d}");
        let t = dkrrt_otg::Trajectory::calculate(
            &from,
            &KinState::rest(goal),
            &limits(),
            &Options { period: Some(1e-3), ..Options::default() },
        )
        .unwrap();
        for k in 0..=200 {
            let tt = d * k as f64 / 200.0;
            let a = t.at(tt);
            let b = msg.sample(tt);
            for j in 0..NJ {
                assert!((a.p[j] - b.p[j]).abs() < 1e-9, "t={tt} j={j}");
                assert!((a.v[j] - b.v[j]).abs() < 1e-9);
                assert!((a.a[j] - b.a[j]).abs() < 1e-9);
            }
        }
        let end = msg.sample(d + 1.0);
        for j in 0..NJ {
            assert!((end.p[j] - goal[j]).abs() < 1e-8);
            assert!(end.v[j].abs() < 1e-8);
        }
        assert_eq!(msg.start_ns, 5_000_000);
        let lim = dkrrt_msg::ContractLimits::symmetric(3.0, 0.2, 100.0);
        dkrrt_msg::Validate::validate(&msg, &lim).unwrap();
    }

    #[test]
    fn a_bad_goal_is_an_error_not_a_trajectory() {
        let mut msg = <Trajectory as Zeroed>::zeroed();
        let r = plan(&KinState::rest([0.0; NJ]), &[f64::NAN; NJ], &limits(), 1e-3, 1, 0, &mut msg);
        assert!(matches!(r, Err(GotoError::Otg(_))));
    }
}
