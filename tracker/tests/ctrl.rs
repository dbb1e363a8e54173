//! The controller core in closed loop with the plant core (no IPC).

use dkrrt_config::Scenario;
use dkrrt_model::{ArmModel, NJ};
use dkrrt_msg::{ControllerMode, Trajectory, Zeroed};
use dkrrt_otg::KinState;
use dkrrt_sim::plant::{Plant, PlantConfig};
use dkrrt_tracker::ctrl::{Reason, Tracker, TrackerConfig};

#[global_allocator]
static ALLOC: dkrrt_rt::alloc_count::CountingAlloc = dkrrt_rt::alloc_count::CountingAlloc;

struct Loop {
    plant: Plant,
    ctrl: Tracker,
    traj: Box<Trajectory>,
    cfg: TrackerConfig,
}

fn setup(predict: bool) -> Loop {
    let sc = Scenario::default_scenario();
    let model = ArmModel::default_arm();
    let mut cfg = TrackerConfig::from_scenario(&sc);
    cfg.predict = predict;
    let plant = Plant::new(model.clone(), PlantConfig::from_scenario(&sc), &sc.sim.initial_q);
    let ctrl = Tracker::new(model, cfg);
    let mut traj = Box::new(<Trajectory as Zeroed>::zeroed());
    dkrrt_planner::goto::plan(
        &KinState::rest(sc.sim.initial_q),
        &sc.goal.q.expect("a joint goal"),
        &cfg.limits,
        1e-3,
        1,
        0,
        &mut traj,
    )
    .unwrap();
    Loop { plant, ctrl, traj, cfg }
}

impl Loop {
    /// One tick; returns the controller output.
    fn tick(&mut self, deliver: bool) -> dkrrt_tracker::ctrl::TickOutput {
        let m = self.plant.measured();
        let out =
            self.ctrl.tick(deliver.then_some((m.tick, m.tick * 1_000_000, &m.q, &m.qd, m.brake_engaged)));
        if deliver {
            self.plant.offer_command(out.state_seq, &out.tau);
        }
        self.plant.step();
        out
    }
}

/// The closed loop 1.5 s into tracking the straight trajectory (moving at full speed).
fn mid_motion() -> Loop {
    let mut l = setup(true);
    l.tick(true);
    l.ctrl.set_trajectory(&l.traj);
    for _ in 0..1500 {
        l.tick(true);
    }
    l
}

#[test]
fn tracks_a_jerk_limited_trajectory_to_the_goal() {
    let mut l = setup(true);
    l.tick(true);
    let ev = l.ctrl.set_trajectory(&l.traj).expect("accepted");
    assert_eq!(ev.to, ControllerMode::Track);
    let n = (l.traj.duration_s * 1000.0) as usize + 500;
    let mut saw_complete = false;
    for _ in 0..n {
        let out = l.tick(true);
        if let Some(e) = out.event {
            assert_eq!(e.reason, Reason::TrajectoryComplete);
            saw_complete = true;
        }
    }
    assert!(saw_complete);
    assert_eq!(l.ctrl.mode(), ControllerMode::Hold);
    let st = l.ctrl.stats;
    assert!(st.track.rms() < 1e-5, "rms {}", st.track.rms());
    assert!(st.track.max_abs < 1e-4, "max {}", st.track.max_abs);
    let (q, _) = l.plant.true_state();
    let goal = l.traj.sample(l.traj.duration_s).p;
    for i in 0..NJ {
        assert!((q[i] - goal[i]).abs() < 1e-6, "joint {i}: {} vs {}", q[i], goal[i]);
    }
    assert_eq!(st.safe_hold_entries, 0);
}

#[test]
fn delay_compensation_reduces_the_tracking_error() {
    let run = |predict: bool| {
        let mut l = setup(predict);
        l.tick(true);
        l.ctrl.set_trajectory(&l.traj);
        for _ in 0..3000 {
            l.tick(true);
        }
        l.ctrl.stats.track.rms()
    };
    let with = run(true);
    let without = run(false);
    assert!(without < 1e-3, "{without}");
    assert!(with < without / 2.0, "with {with}, without {without}");
}

#[test]
fn stale_state_brakes_to_rest_then_holds() {
    let mut l = setup(true);
    l.tick(true);
    l.ctrl.set_trajectory(&l.traj);
    for _ in 0..1500 {
        l.tick(true); // mid-motion, moving
    }
    // States stop arriving.
    let mut brake_at = None;
    let mut hold_at = None;
    for k in 1..3000u32 {
        let out = l.tick(false);
        if let Some(e) = out.event {
            match e.reason {
                Reason::StaleState => brake_at = Some(k),
                Reason::BrakeComplete => hold_at = Some(k),
                r => panic!("unexpected {r:?}"),
            }
        }
        assert!(out.tau.iter().all(|t| t.is_finite()));
    }
    assert_eq!(brake_at, Some(l.cfg.stale_ticks), "safe hold after exactly stale_ticks ticks");
    assert!(hold_at.is_some(), "brake ends in hold");
    assert_eq!(l.ctrl.mode(), ControllerMode::Hold);
    assert_eq!(l.ctrl.stats.safe_hold_entries, 1);
}

#[test]
fn invalid_trajectory_while_tracking_brakes() {
    let mut l = setup(true);
    l.tick(true);
    assert!(l.ctrl.reject_trajectory(0).is_none(), "nothing to stop when idle");
    l.ctrl.set_trajectory(&l.traj);
    for _ in 0..1000 {
        l.tick(true);
    }
    let e = l.ctrl.reject_trajectory(1_000_000_000).expect("brakes");
    assert_eq!((e.to, e.reason), (ControllerMode::Brake, Reason::InvalidTrajectory));
    // The arm comes to rest.
    for _ in 0..3000 {
        l.tick(true);
    }
    assert_eq!(l.ctrl.mode(), ControllerMode::Hold);
    assert!(l.plant.true_state().1.norm() < 1e-3);
}

#[test]
fn a_trajectory_that_does_not_start_at_the_reference_is_rejected() {
    let mut l = setup(true);
    l.tick(true);
    let mut far = Trajectory::hold(&[0.5; NJ]);
    far.traj_id = 9;
    far.duration_s = 1.0;
    assert!(l.ctrl.set_trajectory(&far).is_none());
    assert_eq!(l.ctrl.stats.trajectories_rejected, 1);
    assert_eq!(l.ctrl.mode(), ControllerMode::Idle);
    // While tracking, such a trajectory makes it brake.
    l.ctrl.set_trajectory(&l.traj).unwrap();
    for _ in 0..1000 {
        l.tick(true);
    }
    let q_at = l.plant.true_state().0;
    let e = l.ctrl.set_trajectory(&far).expect("brake");
    assert_eq!(e.reason, Reason::InvalidTrajectory);
    // The arm did not follow it: it braked to rest near where it was, within the limits,
    // nowhere near the rejected trajectory's [0.5; 6].
    for _ in 0..3000 {
        l.tick(true);
        let qd = l.plant.true_state().1;
        assert!((0..NJ).all(|j| qd[j].abs() <= l.cfg.limits.v_max[j] * 1.01), "{qd}");
    }
    assert_eq!(l.ctrl.mode(), ControllerMode::Hold);
    let (q, qd) = l.plant.true_state();
    assert!(qd.amax() < 1e-6, "{qd}");
    assert!((q - q_at).amax() < 0.05, "moved {} rad after the rejection", (q - q_at).amax());
    assert!((0..NJ).any(|j| (q[j] - 0.5).abs() > 0.1), "{q}");
}

#[test]
fn a_trajectory_before_the_first_state_is_checked_against_it() {
    // Offered before any state: kept, not followed; accepted the tick after the first state
    // because it starts where the arm is.
    let mut l = setup(true);
    assert!(l.ctrl.set_trajectory(&l.traj).is_none());
    assert_eq!(l.ctrl.mode(), ControllerMode::Idle);
    assert_eq!(l.ctrl.goal(), None, "not accepted yet");
    let first = l.tick(true).event.expect("first state");
    assert_eq!(
        (first.reason, first.from, first.to),
        (Reason::FirstState, ControllerMode::Idle, ControllerMode::Idle)
    );
    let e = l.tick(true).event.expect("accepted on the next tick");
    assert_eq!((e.reason, e.to), (Reason::NewTrajectory, ControllerMode::Track));
    assert_eq!(l.ctrl.stats.trajectories_accepted, 1);
    assert!(l.ctrl.goal().is_some());
    // One that starts away from the arm: rejected at the first state, the arm stays idle
    // (no torque towards the far start), and the same id offered later is judged again.
    let mut l = setup(true);
    let mut far = Trajectory::hold(&[0.5; NJ]);
    far.traj_id = 9;
    far.duration_s = 1.0;
    assert!(l.ctrl.set_trajectory(&far).is_none());
    l.tick(true);
    let out = l.tick(true);
    assert!(out.event.is_none(), "{:?}", out.event);
    assert_eq!(l.ctrl.mode(), ControllerMode::Idle);
    assert_eq!(l.ctrl.stats.trajectories_rejected, 1);
    assert_eq!(l.ctrl.stats.trajectories_accepted, 0);
    assert_eq!(l.ctrl.goal(), None);
    assert!(l.ctrl.set_trajectory(&far).is_none());
    assert_eq!(l.ctrl.stats.trajectories_rejected, 2);
    for _ in 0..200 {
        assert_eq!(l.tick(true).mode, ControllerMode::Idle);
    }
}

#[test]
fn tick_and_set_trajectory_allocate_nothing() {
    let mut l = setup(true);
    l.tick(true);
    let traj = l.traj.clone();
    let (_, s) = dkrrt_rt::alloc_count::count(|| {
        l.ctrl.set_trajectory(&traj);
        for k in 0..2000 {
            l.tick(k % 500 != 0);
        }
    });
    assert_eq!(s.allocs, 0, "{s:?}");
}

/// A plan spliced into `base` at plant time `at_ns` from `base`'s exact state there: to
/// `goal` at rest (or, with `jump`, from a state off by `jump` rad in joint 0).
fn spliced(base: &Trajectory, at_ns: u64, goal: &[f64; NJ], id: u64, jump: f64) -> Box<Trajectory> {
    let s = base.sample(base.time_of(at_ns));
    let mut from = KinState { p: s.p, v: s.v, a: s.a };
    from.p[0] += jump;
    let lim = dkrrt_otg::Limits {
        v_max: [0.1, 0.1, 0.1, 0.18, 0.18, 0.18],
        a_max: [0.2, 0.2, 0.2, 0.4, 0.4, 0.4],
        j_max: [1.0, 1.0, 1.0, 2.0, 2.0, 2.0],
    };
    let mut t = Box::new(<Trajectory as Zeroed>::zeroed());
    dkrrt_planner::goto::plan(&from, goal, &lim, 1e-3, id, at_ns, &mut t).unwrap();
    t
}

#[test]
fn a_trajectory_starting_ahead_is_queued_and_spliced_in_at_its_start() {
    let mut l = setup(true);
    l.tick(true);
    l.ctrl.set_trajectory(&l.traj).expect("accepted");
    for _ in 0..1500 {
        l.tick(true);
    }
    // At 1.5 s: a new plan to another goal, starting 60 ms ahead from the exact reference.
    let now_ns = 1_500_000_000;
    let goal = [0.2, -0.4, 0.9, 0.1, 0.4, 0.1];
    let next = spliced(&l.traj, now_ns + 60_000_000, &goal, 2, 0.0);
    assert!(l.ctrl.set_trajectory(&next).is_none(), "queued, not switched");
    assert_eq!(l.ctrl.queued_traj_id(), 2);
    assert_eq!(l.ctrl.active_traj_id(), 1);
    let mut spliced_at = None;
    for _ in 0..80 {
        let out = l.tick(true);
        if let Some(e) = out.event {
            assert_eq!(e.reason, Reason::Splice);
            spliced_at = Some(e.plant_ns);
        }
    }
    assert_eq!(spliced_at, Some(now_ns + 60_000_000), "takes over exactly at its start");
    assert_eq!(l.ctrl.active_traj_id(), 2);
    assert_eq!(l.ctrl.stats.splices_taken, 1);
    // The arm follows through the splice with the error of ordinary tracking, then arrives.
    let n = (next.duration_s * 1000.0) as usize + 300;
    for _ in 0..n {
        l.tick(true);
    }
    let (q, _) = l.plant.true_state();
    for j in 0..NJ {
        assert!((q[j] - goal[j]).abs() < 1e-5, "joint {j}: {}", q[j]);
    }
    assert!(l.ctrl.stats.track.max_abs < 1e-5, "{}", l.ctrl.stats.track.max_abs);
    assert_eq!(l.ctrl.stats.safe_hold_entries, 0);
}

#[test]
fn a_splice_that_does_not_continue_the_reference_is_rejected_and_the_arm_brakes() {
    let mut l = setup(true);
    l.tick(true);
    l.ctrl.set_trajectory(&l.traj).expect("accepted");
    for _ in 0..1500 {
        l.tick(true);
    }
    let now_ns = 1_500_000_000;
    let goal = [0.2, -0.4, 0.9, 0.1, 0.4, 0.1];
    // 1 mrad off in position: beyond the splice tolerance while moving.
    let bad = spliced(&l.traj, now_ns + 60_000_000, &goal, 2, 1e-3);
    assert!(l.ctrl.set_trajectory(&bad).is_none());
    let mut reasons = Vec::new();
    for _ in 0..2000 {
        if let Some(e) = l.tick(true).event {
            reasons.push(e.reason);
        }
    }
    assert_eq!(reasons.first(), Some(&Reason::SpliceRejected), "{reasons:?}");
    assert!(reasons.contains(&Reason::BrakeComplete), "{reasons:?}");
    assert_eq!(l.ctrl.stats.splices_taken, 0);
    assert_eq!(l.ctrl.stats.trajectories_rejected, 1);
    // The arm never followed the rejected plan: it stopped on the old path, at rest.
    let (q, qd) = l.plant.true_state();
    assert!(qd.iter().all(|v| v.abs() < 1e-4), "{qd:?}");
    let on_old = l.traj.sample(l.traj.time_of(now_ns + 60_000_000)).p;
    assert!((0..NJ).all(|j| (q[j] - on_old[j]).abs() < 0.05), "{q:?} vs {on_old:?}");
    assert!((0..NJ).any(|j| (q[j] - goal[j]).abs() > 0.05));
}

#[test]
fn a_controlled_stop_brakes_to_rest_within_the_limits_and_follows_nothing_after() {
    let mut l = mid_motion();
    let (_, qd0) = l.plant.true_state();
    assert!(qd0.amax() > 0.01, "moving when the stop comes: {qd0}");
    let e = l.ctrl.stop().expect("a tracked motion brakes");
    assert_eq!((e.from, e.to, e.reason), (ControllerMode::Track, ControllerMode::Brake, Reason::Stop));
    assert!(l.ctrl.stop().is_none(), "a second stop request changes nothing");
    assert_eq!(l.ctrl.stats.safe_hold_entries, 0, "a controlled stop is not a safe hold");
    // The brake's reference respects the motion limits (velocity, acceleration, jerk), and
    // the arm follows it to rest.
    let lim = l.cfg.limits;
    let mut prev_a: Option<[f64; NJ]> = None;
    let mut done = None;
    for k in 0..3000u64 {
        let ns = l.plant.tick() * 1_000_000;
        let (_, v, a) = l.ctrl.desired(ns).unwrap();
        for i in 0..NJ {
            assert!(v[i].abs() <= lim.v_max[i] + 1e-9, "v[{i}] = {}", v[i]);
            assert!(a[i].abs() <= lim.a_max[i] + 1e-9, "a[{i}] = {}", a[i]);
            if let Some(pa) = prev_a {
                let j = (a[i] - pa[i]) / 1e-3;
                assert!(j.abs() <= lim.j_max[i] * (1.0 + 1e-6) + 1e-6, "jerk[{i}] = {j}");
            }
        }
        prev_a = Some(a);
        // A valid new trajectory offered during the stop is not followed.
        if k == 100 {
            let mut t = l.traj.clone();
            t.traj_id += 100;
            assert!(l.ctrl.set_trajectory(&t).is_none());
        }
        if let Some(e) = l.tick(true).event {
            assert_eq!(e.reason, Reason::BrakeComplete);
            done = Some(k);
        }
    }
    assert!(done.is_some(), "the brake ended");
    assert_eq!(l.ctrl.mode(), ControllerMode::Hold);
    assert_eq!(l.ctrl.stats.ignored_after_stop, 1);
    assert!(l.ctrl.stopping());
    let (_, qd) = l.plant.true_state();
    assert!(qd.amax() < 1e-6, "at rest: {qd}");
}

/// Largest |qd_i| / v_max_i of the plant's true state.
fn speed_ratio(l: &Loop) -> f64 {
    let (_, qd) = l.plant.true_state();
    (0..NJ).map(|i| qd[i].abs() / l.cfg.limits.v_max[i]).fold(0.0, f64::max)
}

#[test]
fn plant_brakes_under_a_stalled_tracker_reanchor_the_reference_where_the_arm_stopped() {
    // A loaded machine: the tracker misses 200 ticks mid-motion, the plant's watchdog brakes
    // the arm to rest while the reference runs on. When the tracker wakes up, pulling the arm
    // back onto the reference would drive it far beyond its velocity limit; it must instead
    // brake from where the arm is (and follow it while the brakes hold), then hold there.
    let mut l = mid_motion();
    assert!(speed_ratio(&l) > 0.5, "moving at full speed when the stall comes");
    for _ in 0..200 {
        l.plant.step(); // the tracker does not run
    }
    assert!(l.plant.brake_engaged(), "the watchdog braked the arm");
    let (q_wake, qd_wake) = l.plant.true_state();
    let (pd, _, _) = l.ctrl.desired(l.plant.tick() * 1_000_000).unwrap();
    let behind = (0..NJ).map(|i| (pd[i] - q_wake[i]).abs()).fold(0.0, f64::max);
    assert!(behind > 0.01, "the reference ran {behind} rad ahead of the braked arm");

    let mut reasons = Vec::new();
    let mut peak: f64 = 0.0;
    for _ in 0..3000 {
        if let Some(e) = l.tick(true).event {
            reasons.push(e.reason);
        }
        peak = peak.max(speed_ratio(&l));
    }
    assert_eq!(reasons.first(), Some(&Reason::PlantBrake), "events: {reasons:?}");
    assert_eq!(l.ctrl.mode(), ControllerMode::Hold, "events: {reasons:?}");
    assert!(peak <= 1.0, "peak joint speed {peak} x its limit after the stall");
    assert_eq!(l.ctrl.stats.safe_hold_entries, 1);
    let (q, qd) = l.plant.true_state();
    assert!(qd.amax() < 1e-6, "at rest: {qd}");
    // Held where a brake within the limits from the arm's state at wake-up ends (not pulled
    // back to the reference): no further than that brake's distance.
    let lim = l.cfg.limits;
    for i in 0..NJ {
        let v = qd_wake[i].abs();
        let reach = v * v / (2.0 * lim.a_max[i]) + v * lim.a_max[i] / lim.j_max[i] + 1e-3;
        let moved = (q[i] - q_wake[i]).abs();
        assert!(
            moved <= reach,
            "joint {i} moved {moved} rad after waking at {v} rad/s (brake reach {reach})"
        );
    }
    // A plan from there is accepted.
    let mut t = Box::new(<Trajectory as Zeroed>::zeroed());
    dkrrt_planner::goto::plan(
        &KinState::rest(q.into()),
        &l.traj.sample(l.traj.duration_s).p,
        &l.cfg.limits,
        1e-3,
        77,
        (l.plant.tick() - 1) * 1_000_000,
        &mut t,
    )
    .unwrap();
    let e = l.ctrl.set_trajectory(&t).expect("a plan from where the arm is");
    assert_eq!(e.to, ControllerMode::Track);
}

#[test]
fn a_measured_state_off_the_reference_reanchors_a_brake_there() {
    // The arm measured 0.03 rad off a moving reference (a push, a slipped joint): brake to
    // rest from the measured state, do not pull it back.
    let mut l = mid_motion();
    let m = l.plant.measured();
    let mut q = m.q;
    q[2] += 3.0 * l.cfg.max_track_error;
    let out = l.ctrl.tick(Some((m.tick, m.tick * 1_000_000, &q, &m.qd, false)));
    let e = out.event.expect("re-anchored");
    assert_eq!(
        (e.from, e.to, e.reason),
        (ControllerMode::Track, ControllerMode::Brake, Reason::TrackingError)
    );
    assert_eq!((l.ctrl.stats.reanchors, l.ctrl.stats.safe_hold_entries), (1, 1));
    // The brake starts at the measured state, within the limits.
    let (p, v, _) = l.ctrl.desired(m.tick * 1_000_000).unwrap();
    for i in 0..NJ {
        assert!((p[i] - q[i]).abs() < 1e-12, "starts at the measured position");
        assert!((v[i] - m.qd[i]).abs() <= 1e-12 || v[i].abs() == l.cfg.limits.v_max[i]);
    }
    // Within the threshold nothing happens.
    let mut l = mid_motion();
    let m = l.plant.measured();
    let mut q = m.q;
    q[2] += 0.5 * l.cfg.max_track_error;
    assert!(l.ctrl.tick(Some((m.tick, m.tick * 1_000_000, &q, &m.qd, false))).event.is_none());
    assert_eq!(l.ctrl.mode(), ControllerMode::Track);
}

#[test]
fn brakes_engaged_at_power_up_are_not_a_fault() {
    // The plant starts braked (until commands flow): a trajectory accepted then is tracked.
    let mut l = setup(true);
    assert!(l.plant.brake_engaged());
    l.tick(true);
    l.ctrl.set_trajectory(&l.traj);
    for _ in 0..100 {
        l.tick(true);
    }
    assert_eq!(l.ctrl.mode(), ControllerMode::Track);
    assert_eq!(l.ctrl.stats.reanchors, 0);
}

#[test]
fn every_command_carries_the_setpoints_of_the_tick_it_acts_in() {
    // Idle: hold where the arm is.
    let mut l = setup(true);
    let out = l.tick(true);
    let q0 = l.plant.true_state().0;
    assert_eq!(out.qd_set, [0.0; NJ]);
    assert!(out.q_set.iter().zip(q0.iter()).all(|(a, b)| (a - b).abs() < 1e-9), "{:?}", out.q_set);
    // Tracking: the trajectory's position and velocity one tick after the state's stamp.
    let mut l = mid_motion();
    let m = l.plant.measured();
    let out = l.tick(true);
    let s = l.traj.sample(l.traj.time_of((m.tick + 1) * 1_000_000));
    for j in 0..NJ {
        assert!((out.q_set[j] - s.p[j]).abs() < 1e-9, "joint {j}: {} vs {}", out.q_set[j], s.p[j]);
        assert!((out.qd_set[j] - s.v[j]).abs() < 1e-9, "joint {j}");
    }
    assert!(out.qd_set.iter().any(|v| v.abs() > 0.01), "moving: {:?}", out.qd_set);
}
