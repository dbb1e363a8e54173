//! The emulated arm in closed loop with the tracker core over the wire format (no sockets):
//! tracking to the goal as the simulator does, the watchdog abort and recovery, servo mode,
//! bad and stale datagrams, and no allocation.

use dkrrt_config::Scenario;
use dkrrt_emulator::{ArmEmulator, EmulatorConfig, Rejected};
use dkrrt_model::{ArmModel, NJ};
use dkrrt_msg::{ControllerMode, Trajectory, Zeroed};
use dkrrt_otg::KinState;
use dkrrt_sim::plant::PlantConfig;
use dkrrt_tracker::ctrl::{Tracker, TrackerConfig};
use dkrrt_udp::{status, CommandPacket, Mode, StatePacket, COMMAND_LEN, STATE_LEN};

#[global_allocator]
static ALLOC: dkrrt_rt::alloc_count::CountingAlloc = dkrrt_rt::alloc_count::CountingAlloc;

struct Rig {
    arm: ArmEmulator,
    ctrl: Tracker,
    traj: Box<Trajectory>,
    epoch: Option<u64>,
    seq: u32,
    sb: [u8; STATE_LEN],
    cb: [u8; COMMAND_LEN],
    last: Option<StatePacket>,
}

fn rig() -> Rig {
    let sc = Scenario::default_scenario();
    let model = ArmModel::default_arm();
    let cfg = TrackerConfig::from_scenario(&sc);
    let arm = ArmEmulator::new(
        model.clone(),
        PlantConfig::from_scenario(&sc),
        &sc.sim.initial_q,
        EmulatorConfig::new(sc.period_ns()),
    );
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
    Rig {
        arm,
        ctrl: Tracker::new(model, cfg),
        traj,
        epoch: None,
        seq: 0,
        sb: [0; STATE_LEN],
        cb: [0; COMMAND_LEN],
        last: None,
    }
}

impl Rig {
    /// One tick: the arm sends its state; if `answer`, the driver (tracker core) answers it
    /// with a torque command over the wire; the arm steps.
    fn tick(&mut self, answer: bool) {
        let n = self.arm.state(&mut self.sb);
        let s = StatePacket::decode(&self.sb[..n]).unwrap();
        self.last = Some(s);
        if answer {
            // The driver maps the arm's clock to plant time (its first state is time zero).
            let epoch = *self.epoch.get_or_insert(s.arm_time_ns);
            let out = self.ctrl.tick(Some((
                u64::from(s.seq),
                s.arm_time_ns - epoch,
                &s.q,
                &s.qd,
                s.status & status::BRAKES != 0,
            )));
            self.seq += 1;
            let c = CommandPacket {
                seq: self.seq,
                state_seq: out.state_seq as u32,
                mode: Mode::Torque,
                tau: out.tau,
                q: [0.0; NJ],
                qd: [0.0; NJ],
            };
            let len = c.encode(&mut self.cb);
            self.arm.receive(&self.cb[..len]).unwrap();
        }
        self.arm.step();
    }
}

#[test]
fn the_tracker_drives_the_emulated_arm_to_the_goal_over_the_wire() {
    let mut r = rig();
    r.tick(true);
    r.ctrl.set_trajectory(&r.traj).expect("accepted");
    let n = (r.traj.duration_s * 1000.0) as usize + 500;
    let mut peak: f64 = 0.0;
    for _ in 0..n {
        r.tick(true);
        let (_, qd) = r.arm.plant().true_state();
        let lim = ArmModel::default_arm().limits().v_max;
        peak = peak.max((0..NJ).map(|i| qd[i].abs() / lim[i]).fold(0.0, f64::max));
    }
    assert_eq!(r.ctrl.mode(), ControllerMode::Hold);
    let goal = r.traj.sample(r.traj.duration_s).p;
    let (q, qd) = r.arm.plant().true_state();
    let err = (0..NJ).map(|i| (q[i] - goal[i]).abs()).fold(0.0, f64::max);
    // The same loop as the simulator's (one tick of command delay): the same accuracy.
    assert!(err < 1e-9, "final error {err}");
    assert!(qd.amax() < 1e-9);
    assert!(peak <= 1.0, "peak speed {peak} x the limit");
    assert_eq!(r.ctrl.stats.safe_hold_entries, 0);
    let st = r.arm.stats;
    assert_eq!((st.commands_invalid, st.commands_stale, st.aborts), (0, 0, 0));
    assert_eq!(st.commands_applied, st.states_sent);
    let last = r.last.unwrap();
    assert_eq!((last.status, last.missed, last.last_command_seq), (0, 0, r.seq - 1));
}

#[test]
fn missed_commands_abort_to_the_brakes_and_commands_release_them() {
    let mut r = rig();
    r.tick(true);
    r.ctrl.set_trajectory(&r.traj).unwrap();
    for _ in 0..1500 {
        r.tick(true);
    }
    let s = r.last.unwrap();
    assert_eq!(s.status & (status::BRAKES | status::ABORTED), 0, "moving under commands");
    // The driver goes silent: after abort_after (20) ticks the arm brakes and says so.
    for _ in 0..20 {
        r.tick(false);
    }
    assert_eq!(r.last.unwrap().status & status::ABORTED, 0, "not before the limit");
    // The brakes are viscous (sim.brake_damping) and the arm heavy: seconds to rest.
    for _ in 0..8000 {
        r.tick(false);
    }
    let s = r.last.unwrap();
    assert_eq!(s.status & (status::BRAKES | status::ABORTED), status::BRAKES | status::ABORTED, "{s:?}");
    assert!(s.missed > 20 && s.abort_after == 20, "{s:?}");
    assert_eq!(r.arm.stats.aborts, 1);
    let (_, qd) = r.arm.plant().true_state();
    assert!(qd.amax() < 1e-3, "the brakes stopped the arm: {qd}");
    // Commands again: the brakes release, the tracker (which saw the brakes engage under its
    // moving reference) holds the arm where it stopped.
    for _ in 0..1000 {
        r.tick(true);
    }
    let s = r.last.unwrap();
    assert_eq!(s.status & (status::BRAKES | status::ABORTED), 0, "{s:?}");
    assert_eq!(s.missed, 0);
    let (_, qd) = r.arm.plant().true_state();
    assert!(qd.amax() < 1e-6, "held at rest: {qd}");
}

#[test]
fn servo_mode_tracks_position_setpoints_with_the_arms_own_servo() {
    let mut r = rig();
    let mut target = r.arm.plant().true_state().0;
    target[1] += 0.02;
    target[4] -= 0.02;
    for k in 0..3000u32 {
        let n = r.arm.state(&mut r.sb);
        let s = StatePacket::decode(&r.sb[..n]).unwrap();
        let c = CommandPacket {
            seq: k + 1,
            state_seq: s.seq,
            mode: Mode::Servo,
            tau: [0.0; NJ],
            q: target.into(),
            qd: [0.0; NJ],
        };
        let len = c.encode(&mut r.cb);
        r.arm.receive(&r.cb[..len]).unwrap();
        r.arm.step();
    }
    let (q, qd) = r.arm.plant().true_state();
    assert!((q - target).amax() < 1e-6 && qd.amax() < 1e-6, "{q} vs {target}");
    // Hold: the brakes engage and the state says so.
    let n = r.arm.state(&mut r.sb);
    let s = StatePacket::decode(&r.sb[..n]).unwrap();
    let c = CommandPacket {
        seq: 9999,
        state_seq: s.seq,
        mode: Mode::Hold,
        tau: [0.0; NJ],
        q: [0.0; NJ],
        qd: [0.0; NJ],
    };
    let len = c.encode(&mut r.cb);
    r.arm.receive(&r.cb[..len]).unwrap();
    r.arm.step();
    let n = r.arm.state(&mut r.sb);
    assert_ne!(StatePacket::decode(&r.sb[..n]).unwrap().status & status::BRAKES, 0);
}

#[test]
fn bad_and_stale_datagrams_are_refused_and_counted() {
    let mut r = rig();
    for _ in 0..10 {
        r.tick(true);
    }
    let c = CommandPacket {
        seq: 50,
        state_seq: 5,
        mode: Mode::Torque,
        tau: [0.0; NJ],
        q: [0.0; NJ],
        qd: [0.0; NJ],
    };
    let len = c.encode(&mut r.cb);
    // Answers a state older than the one already applied.
    assert_eq!(r.arm.receive(&r.cb[..len]), Err(Rejected::Stale));
    // Answers a state the arm has not sent.
    let c = CommandPacket { state_seq: 1000, ..c };
    let len = c.encode(&mut r.cb);
    assert_eq!(r.arm.receive(&r.cb[..len]), Err(Rejected::Stale));
    // Damaged in transit.
    r.cb[30] ^= 0x10;
    assert!(matches!(r.arm.receive(&r.cb[..len]), Err(Rejected::Invalid(_))));
    assert!(matches!(r.arm.receive(b"hello"), Err(Rejected::Invalid(_))));
    assert_eq!((r.arm.stats.commands_stale, r.arm.stats.commands_invalid), (2, 2));
}

#[test]
fn state_receive_and_step_allocate_nothing() {
    let mut r = rig();
    r.tick(true);
    r.ctrl.set_trajectory(&r.traj).unwrap();
    for _ in 0..10 {
        r.tick(true);
    }
    let ((), st) = dkrrt_rt::alloc_count::count(|| {
        for k in 0..2000 {
            r.tick(k % 7 != 0);
        }
    });
    assert_eq!((st.allocs, st.reallocs), (0, 0));
}
