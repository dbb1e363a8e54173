//! 10 000 ticks of the tracker hot loop, in process, over real iceoryx2
//! services (sim side and tracker side in one thread), under a counting
//! global allocator: allocations per tick must be constant and bounded, and
//! nothing may accumulate.
//!
//! iceoryx2 0.10 allocates one small block per loaned sample (freed on
//! send); that is what the bound counts, exactly: every tick publishes the state and the
//! command (2), plus a debris observation frame when the sensor samples (every 20 ticks at
//! 50 Hz) and a heartbeat at 10 Hz: allocations per tick = samples published that tick, all
//! freed in the same tick.

use dkrrt::lockstep::{Lockstep, TrajSource};
use dkrrt_config::arm::contract_limits;
use dkrrt_config::Scenario;
use dkrrt_msg::bus::Bus;
use dkrrt_msg::*;
use dkrrt_rt::alloc_count::{count, CountingAlloc};

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc;

#[test]
fn hot_loop_allocations_per_tick_are_constant_and_bounded() {
    let mut sc = Scenario::default_scenario();
    sc.planner.method = "straight".into();
    let run = format!("alloc-{}", std::process::id());
    // Dropped after the buses and ports below: removes the run's files from /dev/shm.
    struct Leftovers(String);
    impl Drop for Leftovers {
        fn drop(&mut self) {
            dkrrt_msg::bus::remove_run_leftovers(&self.0);
        }
    }
    let _clean = Leftovers(run.clone());
    let mut ls = Lockstep::new(&sc).unwrap();
    let lim = contract_limits(ls.sim.plant.model());
    let TrajSource::Straight { traj: straight, .. } = &ls.source else { panic!("straight source") };
    let straight = straight.clone();
    let sim_bus = Bus::new(&run, "sim").unwrap();
    let tr_bus = Bus::new(&run, "tracker").unwrap();
    let mut state_pub = sim_bus.publisher::<RobotState>(Source::Sim).unwrap();
    let mut cmd_sub = sim_bus.subscriber::<TorqueCommand>().unwrap();
    let mut state_sub = tr_bus.subscriber::<RobotState>().unwrap();
    let mut traj_sub = tr_bus.subscriber::<Trajectory>().unwrap();
    let mut cmd_pub = tr_bus.publisher::<TorqueCommand>(Source::Tracker).unwrap();
    let mut obs_pub = sim_bus.publisher::<DebrisObservation>(Source::Sim).unwrap();
    let mut obs_sub = tr_bus.subscriber::<DebrisObservation>().unwrap();
    let mut hb = dkrrt_msg::bus::HeartbeatTx::new(&sim_bus, Source::Sim, sc.run.heartbeat_hz).unwrap();
    let mut frame = Box::new(<DebrisObservation as Zeroed>::zeroed());
    assert!(ls.sim.debris.is_some(), "the default scene's debris is stepped and observed");
    state_pub.update_connections().unwrap();
    cmd_pub.update_connections().unwrap();

    let mut state = <RobotState as Zeroed>::zeroed();
    let mut got = <RobotState as Zeroed>::zeroed();
    let mut cmd = <TorqueCommand as Zeroed>::zeroed();
    let mut traj = Box::new(<Trajectory as Zeroed>::zeroed());
    let mut started = false;

    // Returns the samples published this tick: (all, frames, heartbeats).
    let mut tick = |ls: &mut Lockstep| -> (u64, u64, u64) {
        let mut sent = 0;
        // sim side: publish the measured state
        let m = ls.sim.plant.measured();
        state.header.stamp_ns = m.tick * 1_000_000;
        state.q = m.q;
        state.qd = m.qd;
        state.tau = m.tau;
        state.header.flags = if m.brake_engaged { dkrrt_msg::FLAG_BRAKE_ENGAGED } else { 0 };
        state_pub.publish(&mut state).unwrap();
        sent += 1;
        // tracker side: receive, control, publish
        assert!(state_sub.latest(&mut got, &lim).unwrap());
        let _ = traj_sub.latest(&mut traj, &lim).unwrap();
        let out = ls.tracker.tick(Some((
            got.header.seq,
            got.header.stamp_ns,
            &got.q,
            &got.qd,
            got.header.flags & dkrrt_msg::FLAG_BRAKE_ENGAGED != 0,
        )));
        if !started {
            ls.tracker.set_trajectory(&straight);
            started = true;
        }
        cmd.tau = out.tau;
        cmd.state_seq = out.state_seq;
        cmd.mode = out.mode as u32;
        cmd_pub.publish(&mut cmd).unwrap();
        sent += 1;
        // sim side: take the command, step plant and debris world, publish the sensor's frames
        cmd_sub.for_each(&lim, |c| ls.sim.plant.offer_command(c.state_seq, &c.tau)).unwrap();
        let rep = ls.sim.step(&mut frame, |f| obs_pub.publish(f).map(|_| ())).unwrap();
        let frames = rep.frames as u64;
        obs_sub.for_each_checked(|_| Ok(()), |_| {}).unwrap();
        let t = ls.sim.plant.tick() * 1_000_000;
        let beat = hb.maybe_send(t, false, t, ProcessState::Running, 0, 0, 0, 0).unwrap() as u64;
        (sent + frames + beat, frames, beat)
    };

    // Warm up (first connections, lazily created buffers).
    for _ in 0..100 {
        tick(&mut ls);
    }
    let mut per_tick = Vec::with_capacity(10_000);
    let mut total = dkrrt_rt::alloc_count::AllocStats::default();
    let (mut frames, mut beats) = (0u64, 0u64);
    for _ in 0..10_000 {
        let ((sent, f, b), s) = count(|| tick(&mut ls));
        // Exactly one allocation per published sample (the iceoryx2 loan), none else.
        assert_eq!(s.allocs, sent, "allocations vs samples published this tick");
        frames += f;
        beats += b;
        per_tick.push(s.allocs - f - b);
        total.allocs += s.allocs;
        total.deallocs += s.deallocs;
        total.reallocs += s.reallocs;
    }
    let first = per_tick[0];
    assert!(per_tick.iter().all(|&a| a == first), "allocations per tick vary: {:?}", {
        let mut v = per_tick.clone();
        v.sort();
        v.dedup();
        v
    });
    assert_eq!(first, 2, "state and command: one loan each");
    // 10 s of plant time: the sensor's frames (50 Hz samples, released as their latency
    // elapses, so often more frames than samples) and heartbeats at 10 Hz were in it.
    assert!(frames >= 480, "{frames} frames");
    assert!((99..=101).contains(&beats), "{beats} heartbeats");
    assert_eq!(total.reallocs, 0);
    assert_eq!(total.allocs, total.deallocs, "allocations accumulate: {total:?}");
    eprintln!("allocations per tick: {first} (iceoryx2 sample loans), all freed within the tick");
    // The loop did real work: the arm tracked its trajectory.
    assert!(ls.tracker.stats.track.n > 9_000);
    assert!(ls.tracker.stats.track.rms() < 1e-6, "{}", ls.tracker.stats.track.rms());
}

#[test]
fn the_counting_allocator_sees_allocations() {
    // Guards the test above against a counter that silently reads zero.
    let (v, s) = count(|| vec![1u8; 64]);
    assert_eq!(v.len(), 64);
    assert!(s.allocs >= 1);
}

#[test]
fn a_lockstep_run_ahead_allocates_nothing_per_tick_after_warm_up() {
    // The default threat episode with the planner, the debris side and the predictor stepped
    // ahead on their own thread: after warm-up neither thread allocates.
    let mut sc = Scenario::default_scenario();
    dkrrt_episodes::resolve(&mut sc).unwrap();
    let mut ls = Lockstep::new(&sc).unwrap();
    assert!(ls.run_ahead(&sc).unwrap());
    for _ in 0..3000 {
        ls.tick(true);
    }
    let before = ls.ahead_allocs().unwrap();
    let mut total = dkrrt_rt::alloc_count::AllocStats::default();
    for _ in 0..8000 {
        let ((), s) = count(|| ls.tick(true));
        total.allocs += s.allocs;
        total.reallocs += s.reallocs;
    }
    assert_eq!((total.allocs, total.reallocs), (0, 0), "the arm's side allocated");
    assert_eq!(ls.ahead_allocs().unwrap(), before, "the debris thread allocated");
    assert!(ls.goal_reached_s.is_some() && !ls.collided(), "the run did its work");
}
