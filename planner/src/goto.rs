//! The trajectory source core: a joint-space goal becomes a time-optimal,
//! jerk-limited, synchronized trajectory (dkrrt-otg) in the fixed-size
//! [`Trajectory`] message the tracker samples.

use dkrrt_model::ArmModel;
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

/// The goal counts as reached within this joint distance, rad.
pub const GOAL_TOLERANCE_RAD: f64 = 1e-3;
/// At most one re-issue of the goal per this much plant time, ns.
pub const REISSUE_GAP_NS: u64 = 500_000_000;

/// The `straight` trajectory source as a core (the `dkrrt goto` process and the in-process
/// lockstep both step it): plan to the goal once the first state is known; on a new goal,
/// plan from the reference the arm is on (continuity); if the tracker holds short of the
/// goal (a safe hold after stale state or an invalid trajectory), re-issue the goal from
/// where the arm rests, at most once per [`REISSUE_GAP_NS`].
#[derive(Debug, Clone)]
pub struct Goto {
    limits: Limits<NJ>,
    period_s: f64,
    goal: [f64; NJ],
    pending: bool,
    restart_from_state: bool,
    last_reissue_ns: Option<u64>,
    /// Id of the last trajectory written (0: none yet).
    pub traj_id: u64,
    /// Goals re-issued after the tracker stopped short of them.
    pub reissues: u64,
}

impl Goto {
    /// A source that will plan to `goal` at its first step.
    pub fn new(limits: Limits<NJ>, period_s: f64, goal: [f64; NJ]) -> Self {
        Goto {
            limits,
            period_s,
            goal,
            pending: true,
            restart_from_state: false,
            last_reissue_ns: None,
            traj_id: 0,
            reissues: 0,
        }
    }

    /// The goal in force.
    pub fn goal(&self) -> &[f64; NJ] {
        &self.goal
    }

    /// A new goal: planned at the next step.
    pub fn set_goal(&mut self, goal: [f64; NJ]) {
        self.goal = goal;
        self.pending = true;
    }

    /// A new end-effector pose goal (`p` m, `q` (w, x, y, z), base frame): the IK solution
    /// nearest the arm's configuration `q_now` ([`dkrrt_rrt::goal`]; goto knows no debris).
    /// Returns false (the goal in force is kept) if no solution reaches the pose.
    pub fn set_pose_goal(&mut self, model: &ArmModel, p: &[f64; 3], q: &[f64; 4], q_now: &[f64; NJ]) -> bool {
        let sols = dkrrt_rrt::goal::ik_solutions(model, p, q, &[*q_now, self.goal]);
        match dkrrt_rrt::goal::choose(&sols, q_now, |_| 1.0) {
            Some(g) => {
                self.set_goal(g);
                true
            }
            None => false,
        }
    }

    /// One step at plant time `now_ns` with the measured joint positions; `holding`: the
    /// tracker holds (its newest command, for a recent state, is a hold). `out` is the caller's
    /// trajectory buffer and must keep the last trajectory written between calls. Returns the
    /// new trajectory's duration when one was written into `out` (publish it), its error when
    /// planning failed, `None` when there is nothing to do.
    pub fn step(
        &mut self,
        now_ns: u64,
        q_meas: &[f64; NJ],
        holding: bool,
        out: &mut Trajectory,
    ) -> Option<Result<f64, GotoError>> {
        if !self.pending && self.traj_id > 0 && holding {
            let off = (0..NJ).map(|i| (q_meas[i] - self.goal[i]).abs()).fold(0.0, f64::max);
            let due = self.last_reissue_ns.is_none_or(|t| now_ns > t + REISSUE_GAP_NS);
            if off > GOAL_TOLERANCE_RAD && due {
                self.last_reissue_ns = Some(now_ns);
                self.reissues += 1;
                self.pending = true;
                self.restart_from_state = true;
            }
        }
        if !std::mem::take(&mut self.pending) {
            return None;
        }
        // From the reference we published (continuity), or from the measured state at rest
        // (the first time, and after a hold).
        let from = if self.traj_id == 0 || std::mem::take(&mut self.restart_from_state) {
            KinState::rest(*q_meas)
        } else {
            let s = out.sample(out.time_of(now_ns));
            KinState { p: s.p, v: s.v, a: s.a }
        };
        self.traj_id += 1;
        Some(plan(&from, &self.goal, &self.limits, self.period_s, self.traj_id, now_ns, out))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pose_goal_is_solved_nearest_the_arm_or_refused() {
        let model = ArmModel::default_arm();
        let start = [0.0, -0.5, 1.0, 0.0, 0.5, 0.0];
        let want = [0.35, -0.2, 0.7, 0.3, 0.2, 0.4];
        let t = model.fk(&dkrrt_model::JVec::from_row_slice(&want));
        let (p, r) = ([t.translation.x, t.translation.y, t.translation.z], t.rotation);
        let q = [r.w, r.i, r.j, r.k];
        let mut g = Goto::new(limits(), 0.001, start);
        assert!(g.set_pose_goal(&model, &p, &q, &start));
        let f = model.fk(&dkrrt_model::JVec::from_row_slice(g.goal()));
        assert!((f.translation.vector - t.translation.vector).norm() < 1e-4);
        let mut out = <Trajectory as Zeroed>::zeroed();
        assert!(g.step(0, &start, false, &mut out).unwrap().is_ok());
        let before = *g.goal();
        assert!(!g.set_pose_goal(&model, &[10.0, 0.0, 0.0], &q, &start), "out of reach");
        assert_eq!(*g.goal(), before, "the goal in force is kept");
    }

    #[test]
    fn goto_plans_once_replans_on_a_new_goal_and_reissues_after_a_hold() {
        let start = [0.0, -0.5, 1.0, 0.0, 0.5, 0.0];
        let goal = [0.35, -0.2, 0.7, 0.3, 0.2, 0.4];
        let mut g = Goto::new(limits(), 0.001, goal);
        let mut out = <Trajectory as Zeroed>::zeroed();
        let d = g.step(0, &start, false, &mut out).unwrap().unwrap();
        assert!(d > 1.0 && out.traj_id == 1 && out.start_ns == 0);
        assert!(g.step(1_000_000, &start, false, &mut out).is_none(), "nothing new: nothing to do");
        // A new goal mid-motion: planned from the reference at that instant (continuity).
        let now = 1_000_000_000;
        let before = out.sample(out.time_of(now));
        g.set_goal(start);
        g.step(now, &before.p, false, &mut out).unwrap().unwrap();
        assert_eq!(out.traj_id, 2);
        let after = out.sample(0.0);
        for j in 0..NJ {
            assert!((after.p[j] - before.p[j]).abs() < 1e-12 && (after.v[j] - before.v[j]).abs() < 1e-12);
        }
        // Holding short of the goal: re-issued from the measured state at rest, at most every
        // 0.5 s; holding at the goal: nothing.
        let q = [0.1, -0.4, 0.9, 0.05, 0.4, 0.05];
        let t = 3_000_000_000;
        g.step(t, &q, true, &mut out).unwrap().unwrap();
        assert_eq!((g.reissues, out.traj_id), (1, 3));
        let s0 = out.sample(0.0);
        assert!(s0.v.iter().all(|v| *v == 0.0) && (0..NJ).all(|j| (s0.p[j] - q[j]).abs() < 1e-12));
        assert!(g.step(t + 100_000_000, &q, true, &mut out).is_none(), "too soon");
        assert!(g.step(t + 600_000_000, &q, true, &mut out).is_some());
        assert_eq!(g.reissues, 2);
        assert!(g.step(t + 2_000_000_000, &start, true, &mut out).is_none(), "at the goal");
    }

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
