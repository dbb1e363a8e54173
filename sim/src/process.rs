//! The `dkrrt sim` process shell: wires the plant core to iceoryx2 and a clock.
//!
//! Realtime: ticks on absolute CLOCK_MONOTONIC deadlines at multiples of the
//! period. Lockstep: after publishing state `k` it waits for the command
//! answering `k`, so the run is deterministic and as fast as the loop allows.
//! Either way the timing contract of [`crate::plant`] holds.

use std::path::Path;

use dkrrt_config::arm::contract_limits;
use dkrrt_config::{Mode, Scenario};
use dkrrt_msg::bus::{Bus, HeartbeatTx};
use dkrrt_msg::*;
use dkrrt_rt::clock::{mono_ns, Pacer};
use dkrrt_rt::hist::{LatencyHist, Percentiles};
use dkrrt_rt::rtsetup::{self, RtOptions, RtReport};
use dkrrt_rt::signals;

use crate::core::SimCore;
use crate::debris::DebrisStats;
use crate::plant::PlantStats;

/// What the sim reports at exit (written as JSON to `--stats`).
#[derive(Debug, Clone, serde::Serialize)]
pub struct SimReport {
    pub mode: Mode,
    pub ticks: u64,
    pub deadline_misses: u64,
    pub wake_latency_us: Percentiles,
    pub plant: PlantStats,
    pub commands_received: u64,
    pub commands_rejected: u64,
    pub final_q: [f64; NJ],
    pub final_qd: [f64; NJ],
    /// Debris world figures (`null` without debris): closest approach, contacts.
    pub debris: Option<DebrisStats>,
    pub stopped_by_signal: bool,
    /// The controlled stop at the end of the run, if there was one.
    pub stop: Option<StopReport>,
    pub rt: RtReport,
    /// The depth camera's figures (`null` when off).
    pub camera: Option<crate::camera_proc::CameraReport>,
}

/// What the simulator waits for at tick 0 in lockstep (see [`run`]).
#[derive(Debug, Clone, Copy, Default)]
pub struct Gate {
    pub trajectory: bool,
    pub predictor: bool,
    /// Lockstep with the DK-RRT planner: at every planner cycle boundary (`planner.rate_hz`),
    /// hold until the planner's status for that tick is out (its plan, if any, is published
    /// before it), so plant time never runs ahead of the planner.
    pub planner: bool,
}

/// Runs the simulator until the scenario's duration has elapsed in plant
/// time, or SIGINT/SIGTERM. The last published state carries `FLAG_END_OF_RUN`.
///
/// `gate.trajectory` (lockstep only): hold at tick 0 until a trajectory has
/// been published, so plant time does not run ahead of a slow-starting
/// trajectory source; `gate.predictor` (lockstep, with debris): also until a
/// subscriber (the predictor) reads the debris observations, so that none of
/// them is published to nobody. The launcher sets both.
/// The sim's trace (`--trace FILE`; every [`TRACE_TICKS`] ticks): the true smallest
/// arm–debris distance and every object's true position in the base frame.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct SimTrace {
    /// `(t_s, distance_m)`.
    pub distance: Vec<(f64, f64)>,
    /// `(t_s, id, position)`.
    pub debris: Vec<(f64, u32, [f64; 3])>,
}

/// Ticks between trace samples.
pub const TRACE_TICKS: u64 = 10;

/// Lockstep stop phase: a tick waits this long for the tracker's command, then steps without
/// it, ns.
pub const STOP_WAIT_NS: u64 = 50_000_000;

use crate::stop::StopPolicy;
pub use crate::stop::{StopReport, REST_SPEED_RAD_S, REST_TICKS, STOP_BRAKE_AFTER_S, STOP_LIMIT_S};

/// Runs the simulator; with `trace`, keeps a [`SimTrace`] (room allocated up front for the
/// scenario's duration) and writes it there as JSON at exit.
pub fn run(
    run: &str,
    sc: &Scenario,
    gate: Gate,
    stats_path: Option<&Path>,
    trace: Option<&Path>,
) -> Result<SimReport, String> {
    signals::install();
    let n_trace = if trace.is_some() { (sc.ticks() / TRACE_TICKS + 16) as usize } else { 0 };
    let mut tr = SimTrace {
        distance: Vec::with_capacity(n_trace),
        debris: Vec::with_capacity(n_trace * (dkrrt_msg::MAX_DEBRIS + 2)),
    };
    let model = sc.load_arm().map_err(|e| e.to_string())?;
    let lim = contract_limits(&model);
    let rt = rtsetup::apply_if(
        sc.run.mode == Mode::Realtime,
        &RtOptions::new(sc.sim.cpu, sc.sim.fifo_priority, sc.sim.mlockall),
    );
    for w in &rt.warnings {
        eprintln!("sim: warning: {w}");
    }
    let bus = Bus::new(run, "sim").map_err(|e| e.to_string())?;
    let mut state_pub = bus.publisher::<RobotState>(Source::Sim).map_err(|e| e.to_string())?;
    let mut cmd_sub = bus.subscriber::<TorqueCommand>().map_err(|e| e.to_string())?;
    let mut traj_gate = if gate.trajectory && sc.run.mode == Mode::Lockstep {
        Some(bus.subscriber::<Trajectory>().map_err(|e| e.to_string())?)
    } else {
        None
    };
    let mut traj_seen = <Trajectory as Zeroed>::zeroed();
    let mut hb = HeartbeatTx::new(&bus, Source::Sim, sc.run.heartbeat_hz).map_err(|e| e.to_string())?;

    let mut core = SimCore::new(sc, model)?;
    let mut obs_pub = match core.debris {
        Some(_) => Some(bus.publisher::<DebrisObservation>(Source::Sim).map_err(|e| e.to_string())?),
        None => None,
    };
    let mut obs_msg = <DebrisObservation as Zeroed>::zeroed();
    let mut camera = crate::camera_proc::SimCamera::new(run, sc)?;
    let mut plan_gate = if gate.planner && sc.run.mode == Mode::Lockstep {
        Some(bus.subscriber::<PlanStatus>().map_err(|e| e.to_string())?)
    } else {
        None
    };
    let mut plan_status = <PlanStatus as Zeroed>::zeroed();
    let plan_cycle_ns = (1e9 / sc.planner.rate_hz).round() as u64;
    let mut next_plan_ns = 0u64;
    let mut obs_gate = gate.predictor && obs_pub.is_some() && sc.run.mode == Mode::Lockstep;
    // Lockstep with planner and predictor: before the state of a planner cycle goes out, the
    // predictor has read every frame published so far (and published what they made due), so
    // the cycle plans on the forecasts the in-process lockstep would give it.
    let mut prog_gate = if obs_gate && plan_gate.is_some() {
        Some(bus.subscriber::<PredictorProgress>().map_err(|e| e.to_string())?)
    } else {
        None
    };
    let mut prog = <PredictorProgress as Zeroed>::zeroed();
    let (mut prog_seen, mut plan_seen) = (false, false);

    let period_ns = sc.period_ns();
    let total = sc.ticks();
    let mut msg = <RobotState as Zeroed>::zeroed();
    let mut wake = LatencyHist::new();
    let mut pacer = Pacer::new(period_ns, 0, 2_000_000);
    let first_timeout_ns = 20_000_000_000u64;
    let timeout_ns = 2_000_000_000u64;

    let mut k = 0u64;
    // The controlled stop (crate::stop): asked for by a signal, or the duration is over with
    // the arm moving. The gates are dropped when it begins.
    // The rest test allows for the measurement noise the tracker's hold answers.
    let rest = crate::stop::scenario_rest_speed(sc);
    let mut policy = StopPolicy::new(sc.run.control_hz, total).with_rest_speed(rest);
    loop {
        if sc.run.mode == Mode::Realtime {
            let w = pacer.wait(|| policy.report().is_none() && signals::stop_requested());
            wake.record_ns(w.latency_ns());
        }
        let step = policy.tick(k, core.plant.max_speed(), signals::stop_requested());
        if step.began {
            (traj_gate, plan_gate, prog_gate, obs_gate) = (None, None, None, false);
            if policy.stopped_by_signal {
                eprintln!("sim: stop requested: bringing the arm to rest");
            }
        }
        if step.engage_brakes {
            core.plant.engage_brakes();
            eprintln!("sim: the arm is not at rest {STOP_BRAKE_AFTER_S} s after the stop: brakes engaged");
        }
        let (last, forced, stopping) = (step.last, step.forced, step.stopping);
        // The frames the predictor reads: the depth camera's with `predictor.input = "depth"`.
        let published = if sc.depth_input() {
            camera.as_ref().map_or(0, |c| c.published())
        } else {
            obs_pub.as_ref().map_or(0, |p| p.next_seq())
        };
        if let (false, Some(g)) = (last || published == 0 || k * period_ns < next_plan_ns, prog_gate.as_mut())
        {
            let t0 = mono_ns();
            let mut spins = 0u32;
            let mut gone = false;
            while !(prog.frames > 0 && prog.frame_seq + 1 >= published) {
                g.latest(&mut prog, &lim).map_err(|e| e.to_string())?;
                if signals::stop_requested() {
                    break;
                }
                if spins.is_multiple_of(256) {
                    // A predictor that died (its ports removed by the launcher) is not waited for.
                    let n = bus.publisher_count::<PredictorProgress>().map_err(|e| e.to_string())?;
                    prog_seen |= n > 0;
                    if prog_seen && n == 0 {
                        gone = true;
                        break;
                    }
                }
                if mono_ns() - t0 > timeout_ns {
                    return Err(format!(
                        "sim: lockstep: the predictor has not read observation frame {} at tick {k} within {} s",
                        published - 1,
                        timeout_ns / 1_000_000_000
                    ));
                }
                spins += 1;
                if spins.is_multiple_of(64) {
                    std::thread::yield_now();
                }
                core::hint::spin_loop();
            }
            if gone {
                eprintln!("sim: lockstep: the predictor is gone; no longer waiting for it");
                prog_gate = None;
            }
        }
        let m = core.plant.measured();
        msg.header.stamp_ns = k * period_ns;
        msg.header.flags = if m.brake_engaged { FLAG_BRAKE_ENGAGED } else { 0 }
            | if last { FLAG_END_OF_RUN } else { 0 }
            | if stopping { FLAG_STOPPING } else { 0 };
        msg.q = m.q;
        msg.qd = m.qd;
        msg.tau = m.tau;
        state_pub.publish(&mut msg).map_err(|e| e.to_string())?;
        if last {
            break;
        }
        let plant = &mut core.plant;
        // Brakes forced at the end of a stop: commands are read (and counted), not applied.
        match sc.run.mode {
            Mode::Realtime => {
                cmd_sub
                    .for_each(&lim, |c| {
                        if !forced {
                            plant.offer_command(c.state_seq, &c.tau)
                        }
                    })
                    .map_err(|e| e.to_string())?;
            }
            Mode::Lockstep => {
                let t0 = mono_ns();
                let limit = if k == 0 { first_timeout_ns } else { timeout_ns };
                let mut spins = 0u32;
                let stamp = k * period_ns;
                let mut plan_due = plan_gate.is_some() && stamp >= next_plan_ns;
                loop {
                    if plan_due && spins.is_multiple_of(256) {
                        // A planner that died (its ports removed by the launcher) is not waited for.
                        let n = bus.publisher_count::<PlanStatus>().map_err(|e| e.to_string())?;
                        plan_seen |= n > 0;
                        if plan_seen && n == 0 {
                            eprintln!("sim: lockstep: the planner is gone; no longer waiting for it");
                            plan_gate = None;
                            plan_due = false;
                        }
                    }
                    if plan_due {
                        if let Some(g) = plan_gate.as_mut() {
                            if g.latest(&mut plan_status, &lim).map_err(|e| e.to_string())?
                                && plan_status.header.stamp_ns >= stamp
                            {
                                plan_due = false;
                                next_plan_ns = stamp - stamp % plan_cycle_ns + plan_cycle_ns;
                            }
                        }
                    }
                    cmd_sub
                        .for_each(&lim, |c| {
                            if !forced {
                                plant.offer_command(c.state_seq, &c.tau)
                            }
                        })
                        .map_err(|e| e.to_string())?;
                    if let Some(g) = traj_gate.as_mut() {
                        if g.latest(&mut traj_seen, &lim).map_err(|e| e.to_string())? {
                            traj_gate = None;
                        }
                    }
                    let mut gated = k == 0 && traj_gate.is_some();
                    if k == 0 && !gated && obs_gate && spins.is_multiple_of(64) {
                        // The predictor is reading once its progress publisher is up (it
                        // subscribes to the observations first); another reader (a recorder)
                        // does not open the gate.
                        obs_gate =
                            bus.publisher_count::<PredictorProgress>().map_err(|e| e.to_string())? == 0;
                    }
                    gated |= k == 0 && obs_gate;
                    gated |= plan_due;
                    if (plant.has_command_for_current() && !gated) || (signals::stop_requested() && !stopping)
                    {
                        break;
                    }
                    // Stopping: a controller that does not answer within STOP_WAIT_NS is gone
                    // (the plant's watchdog then brakes).
                    if stopping && (forced || mono_ns() - t0 > STOP_WAIT_NS) {
                        break;
                    }
                    if mono_ns() - t0 > limit {
                        let waiting = if plan_due {
                            "no planner status for this cycle"
                        } else if traj_gate.is_some() && k == 0 {
                            "no trajectory published"
                        } else if obs_gate && k == 0 {
                            "no reader of the debris observations (predictor)"
                        } else {
                            "no command answering state"
                        };
                        return Err(format!(
                            "sim: lockstep: {waiting} at tick {k} within {} s",
                            limit / 1_000_000_000
                        ));
                    }
                    spins += 1;
                    if spins.is_multiple_of(64) {
                        // Late subscribers get the current state from history.
                        state_pub.update_connections().map_err(|e| e.to_string())?;
                        std::thread::yield_now();
                    }
                    core::hint::spin_loop();
                }
            }
        }
        k += 1;
        let rep = core
            .step(&mut obs_msg, |m| match obs_pub.as_mut() {
                Some(p) => p.publish(m).map(|_| ()),
                None => Ok(()),
            })
            .map_err(|e| e.to_string())?;
        if let (Some(cam), Some(d)) = (camera.as_mut(), core.debris.as_mut()) {
            let q = core.plant.true_state().0.into();
            cam.tick(d, &q, k * period_ns)?;
        }
        if n_trace > 0 && k.is_multiple_of(TRACE_TICKS) && tr.distance.len() < tr.distance.capacity() {
            if let Some(d) = core.debris.as_ref() {
                let t = k as f64 * period_ns as f64 * 1e-9;
                if d.distance_now_m.is_finite() {
                    tr.distance.push((t, d.distance_now_m));
                }
                let out = &mut tr.debris;
                d.positions(|id, p| {
                    if out.len() < out.capacity() {
                        out.push((t, id, p));
                    }
                });
            }
        }
        if rep.first_contact {
            let c = core.debris.as_ref().and_then(|d| d.stats.first_contact).unwrap();
            eprintln!(
                "sim: COLLISION: link {} hit debris {} at t = {:.3} s (distance {:.4} m)",
                c.link, c.debris_id, c.t_s, c.distance_m
            );
        }
        let plant = &mut core.plant;
        let state = if plant.brake_engaged() { ProcessState::SafeHold } else { ProcessState::Running };
        hb.maybe_send(
            mono_ns(),
            false,
            k * period_ns,
            state,
            k,
            pacer.misses,
            cmd_sub.rejected,
            plant.stats.brake_engagements,
        )
        .map_err(|e| e.to_string())?;
    }
    let plant = &core.plant;
    let _ = hb.maybe_send(
        mono_ns(),
        true,
        k * period_ns,
        ProcessState::Stopping,
        k,
        pacer.misses,
        cmd_sub.rejected,
        plant.stats.brake_engagements,
    );
    let (q, qd) = plant.true_state();
    let report = SimReport {
        mode: sc.run.mode,
        ticks: k,
        deadline_misses: if sc.run.mode == Mode::Realtime { pacer.misses } else { 0 },
        wake_latency_us: wake.percentiles_us(),
        plant: plant.stats,
        commands_received: cmd_sub.received,
        commands_rejected: cmd_sub.rejected,
        final_q: q.into(),
        final_qd: qd.into(),
        debris: core.debris.as_ref().map(|d| d.stats),
        stopped_by_signal: policy.stopped_by_signal,
        stop: policy.report(),
        rt,
        camera: camera.map(|c| c.finish()).transpose()?,
    };
    dkrrt_rt::write_stats("sim", stats_path, &report)?;
    if let Some(p) = trace {
        std::fs::write(p, serde_json::to_string(&tr).map_err(|e| e.to_string())?)
            .map_err(|e| format!("sim: --trace {}: {e}", p.display()))?;
    }
    Ok(report)
}
