//! The `dkrrt udp-driver` process: the arm's states in, commands out, paced by the arm.
//!
//! It sleeps on its socket until a state datagram arrives (`ppoll`, no clock of its own: the
//! arm's cycle is the plant's), publishes it as a `RobotState` (plant time = the arm's clock
//! since its first state; `Source::Driver`), then polls the bus for the tracker's command
//! answering it and sends it to the arm within the tick. The session's controlled stop is
//! [`dkrrt_sim::stop::StopPolicy`], the simulator's: `FLAG_STOPPING`, rest, `FLAG_END_OF_RUN`,
//! then a hold command (the arm's brakes). With debris in the scenario it also runs the
//! simulated debris world and its sensor on the arm's clock (the perception a real set-up gets
//! from its own driver), checking contacts against the *measured* arm.

use std::net::{SocketAddr, UdpSocket};
use std::path::Path;

use dkrrt_config::arm::contract_limits;
use dkrrt_config::{Mode, Scenario};
use dkrrt_msg::bus::{Bus, HeartbeatTx};
use dkrrt_msg::*;
use dkrrt_rt::clock::mono_ns;
use dkrrt_rt::hist::{LatencyHist, Percentiles};
use dkrrt_rt::poll::wait_readable;
use dkrrt_rt::rtsetup::{self, RtOptions, RtReport};
use dkrrt_rt::signals;
use dkrrt_sim::debris::{DebrisSide, DebrisStats};
use dkrrt_sim::stop::{StopPolicy, StopReport};
use dkrrt_udp::{Mode as ArmMode, COMMAND_LEN};

use crate::core::{DriverCore, Dropped, LinkStats};

/// Before the first state: how long the driver waits for the arm, ns.
pub const FIRST_STATE_NS: u64 = 10_000_000_000;
/// After states have flowed: silence this long means the arm is gone (a fault), ns.
pub const ARM_SILENT_NS: u64 = 1_000_000_000;
/// After publishing a state, how long the driver waits for the command answering it, as a
/// fraction of the period (then it goes back to the socket; a later command is still sent).
pub const COMMAND_WAIT_FRACTION: f64 = 0.9;
/// Between two polls of the bus for that command the driver sleeps this long, µs.
pub const COMMAND_POLL_US: u64 = 15;

/// The arm as the driver measured it: the simulator's `PlantStats` figures a real arm can give
/// (same names, so the launcher's checks read either; hard-stop hits are the arm's to report).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct MeasuredStats {
    /// States published.
    pub ticks: u64,
    /// Rising edges of the arm's `BRAKES` after commands had been flowing.
    pub brake_engagements: u64,
    /// States with the brakes engaged.
    pub brake_ticks: u64,
    /// Largest measured |q̇ᵢ| / the arm's velocity limit.
    pub max_velocity_ratio: f64,
    /// States with some joint faster than its limit.
    pub velocity_limit_ticks: u64,
    /// Not measurable through the protocol: always 0 (the arm enforces its hard stops).
    pub limit_hits: u64,
    /// Datagrams refused for a non-finite number (never published).
    pub non_finite_steps: u64,
}

/// The link's figures in the driver's report.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct LinkReport {
    #[serde(flatten)]
    pub stats: LinkStats,
    /// Command sent → the first state that says the arm applied it, µs (includes the wait for
    /// the arm's next tick).
    pub command_echo_us: Percentiles,
    /// Between consecutive new states, µs (the arm's cycle as seen through the network).
    pub state_interval_us: Percentiles,
    /// State datagram received → the command answering it sent, µs (bus + tracker + bus).
    pub turnaround_us: Percentiles,
    /// Hold commands sent (the end of the session, forced brakes).
    pub holds_sent: u64,
    /// Datagrams that could not be sent (the arm's port closed, …).
    pub send_errors: u64,
}

/// What the driver reports at exit (`--stats`): the simulator's report's fields, plus the link.
#[derive(Debug, Clone, serde::Serialize)]
pub struct DriverReport {
    pub mode: Mode,
    /// States published.
    pub ticks: u64,
    /// Paced by the arm: the driver has no deadlines of its own.
    pub deadline_misses: u64,
    pub plant: MeasuredStats,
    pub commands_received: u64,
    pub commands_rejected: u64,
    pub final_q: [f64; NJ],
    pub final_qd: [f64; NJ],
    pub debris: Option<DebrisStats>,
    /// The simulated depth camera's figures (`[camera] enabled` or `predictor.input =
    /// "depth"`; `null` when off).
    pub camera: Option<dkrrt_sim::camera_proc::CameraReport>,
    pub stopped_by_signal: bool,
    pub stop: Option<StopReport>,
    pub link: LinkReport,
    pub arm: SocketAddr,
    pub rt: RtReport,
}

/// Where the driver talks.
#[derive(Debug, Clone, Copy)]
pub struct Endpoints {
    /// The driver's own UDP address (the arm sends states here).
    pub listen: SocketAddr,
    /// The arm's address (commands go there).
    pub arm: SocketAddr,
}

/// Runs the driver until the session ends (its duration in arm time, a stop request, or the
/// arm falling silent: an error).
pub fn run(
    run: &str,
    sc: &Scenario,
    ep: Endpoints,
    stats_path: Option<&Path>,
) -> Result<DriverReport, String> {
    signals::install();
    if sc.run.mode != Mode::Realtime {
        return Err("udp-driver: run.mode must be \"realtime\": the arm keeps its own time".into());
    }
    if ep.listen == ep.arm {
        return Err(format!(
            "udp-driver: --listen and --arm are both {}: the driver would send its commands to itself",
            ep.listen
        ));
    }
    let model = sc.load_arm().map_err(|e| e.to_string())?;
    let lim = contract_limits(&model);
    let v_lim = model.limits().v_max;
    let rt = rtsetup::apply_if(true, &RtOptions::new(sc.sim.cpu, sc.sim.fifo_priority, sc.sim.mlockall));
    for w in &rt.warnings {
        eprintln!("udp-driver: warning: {w}");
    }
    let sock = UdpSocket::bind(ep.listen).map_err(|e| format!("udp-driver: bind {}: {e}", ep.listen))?;
    sock.set_nonblocking(true).map_err(|e| format!("udp-driver: {e}"))?;
    let bus = Bus::new(run, Source::Driver.name()).map_err(|e| e.to_string())?;
    let mut state_pub = bus.publisher::<RobotState>(Source::Driver).map_err(|e| e.to_string())?;
    let mut cmd_sub = bus.subscriber::<TorqueCommand>().map_err(|e| e.to_string())?;
    let mut hb = HeartbeatTx::new(&bus, Source::Driver, sc.run.heartbeat_hz).map_err(|e| e.to_string())?;
    let mut debris = if sc.has_debris() { Some(DebrisSide::new(sc, &model)?) } else { None };
    let mut obs_pub = match debris {
        Some(_) => Some(bus.publisher::<DebrisObservation>(Source::Driver).map_err(|e| e.to_string())?),
        None => None,
    };
    let mut obs_msg = <DebrisObservation as Zeroed>::zeroed();
    // The simulated depth camera, rendering the same world on the arm's clock as the sim
    // process does on its own (a thread of its own; `dkrrt_sim::camera_proc`).
    let mut camera = dkrrt_sim::camera_proc::SimCamera::new(run, sc)?;
    let dt_s = sc.period_ns() as f64 * 1e-9;
    let cmd_wait_ns = (sc.period_ns() as f64 * COMMAND_WAIT_FRACTION) as u64;
    // What the arm takes (`tracker.command`): torques, or setpoints for its own servo.
    let arm_mode = if sc.tracker.command == "servo" { ArmMode::Servo } else { ArmMode::Torque };

    let mut core = DriverCore::new();
    // The rest test allows for the arm's measurement noise (the scenario's `sim.noise_*`,
    // which the emulator measures with) as the sim's does.
    let rest = dkrrt_sim::stop::scenario_rest_speed(sc);
    let mut policy = StopPolicy::new(sc.run.control_hz, sc.ticks()).with_rest_speed(rest);
    let mut msg = <RobotState as Zeroed>::zeroed();
    let mut meas = MeasuredStats::default();
    let (mut interval, mut turnaround) = (LatencyHist::new(), LatencyHist::new());
    let (mut holds_sent, mut send_errors) = (0u64, 0u64);
    let mut rbuf = [0u8; 2048];
    let mut cbuf = [0u8; COMMAND_LEN];
    let t_start = mono_ns();
    let mut last_state_ns: Option<u64> = None;
    let mut last_tick = 0u64;
    let mut forced = false;
    let mut brakes_before = true;
    let mut commands_flowed = false;
    // The newest state published: bus seq, when its datagram arrived.
    let mut pending: Option<(u64, u64)> = None;
    let mut final_q = [f64::NAN; NJ];
    let mut final_qd = [f64::NAN; NJ];
    let mut ended = false;
    while !ended {
        // 1. Sleep on the socket until a state arrives (or the heartbeat is due).
        let readable = wait_readable(&sock, 50_000_000);
        let now = mono_ns();
        if policy.report().is_none() && signals::stop_requested() && last_state_ns.is_none() {
            eprintln!("udp-driver: stop requested before the arm's first state");
            break;
        }
        match last_state_ns {
            None if now > t_start + FIRST_STATE_NS => {
                return Err(format!(
                    "udp-driver: no state from the arm at {} within {} s (listening on {})",
                    ep.arm,
                    FIRST_STATE_NS / 1_000_000_000,
                    ep.listen
                ));
            }
            Some(t) if now > t + ARM_SILENT_NS => {
                let _ = hb.maybe_send(
                    now,
                    true,
                    msg.header.stamp_ns,
                    ProcessState::Fault,
                    meas.ticks,
                    0,
                    cmd_sub.rejected,
                    meas.brake_engagements,
                );
                return Err(format!(
                    "udp-driver: the arm at {} fell silent for {} s",
                    ep.arm,
                    ARM_SILENT_NS / 1_000_000_000
                ));
            }
            _ => {}
        }
        // 2. Every datagram waiting: new states are published in arrival order.
        // (A loop inside an if: the loop ends on `break`, never on its condition.)
        if readable {
            loop {
                let n = match sock.recv_from(&mut rbuf) {
                    Ok((n, _)) => n,
                    Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => break,
                    Err(_) => break,
                };
                let now = mono_ns();
                let s = match core.on_datagram(now, &rbuf[..n]) {
                    Ok(s) => s,
                    Err(Dropped::Invalid(dkrrt_udp::PacketError::NonFinite(_))) => {
                        meas.non_finite_steps += 1;
                        continue;
                    }
                    Err(_) => continue,
                };
                if let Some(t) = last_state_ns {
                    interval.record_ns(now - t);
                }
                last_state_ns = Some(now);
                let max_speed = s.qd.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                let step = policy.tick(s.tick, max_speed, signals::stop_requested() || s.stopping);
                if step.began && policy.stopped_by_signal {
                    eprintln!("udp-driver: stop requested: bringing the arm to rest");
                }
                if step.engage_brakes {
                    eprintln!("udp-driver: the arm is not at rest 5 s after the stop: brakes engaged");
                }
                forced = step.forced;
                // The simulated perception, on the arm's clock: the world steps every tick the arm
                // advanced (lost states too), checked against the measured arm.
                if let (Some(d), Some(p)) = (debris.as_mut(), obs_pub.as_mut()) {
                    if meas.ticks == 0 {
                        d.check(&s.q);
                    }
                    let n = if meas.ticks == 0 { 0 } else { s.tick.saturating_sub(last_tick) };
                    for i in 0..n {
                        let q = if i + 1 == n { &s.q } else { &final_q };
                        let rep = d
                            .tick(dt_s, q, &mut obs_msg, |m| p.publish(m).map(|_| ()))
                            .map_err(|e| e.to_string())?;
                        if let Some(cam) = camera.as_mut() {
                            cam.tick(d, q, (last_tick + i + 1) * sc.period_ns())?;
                        }
                        if let (true, Some(c)) = (rep.first_contact, d.stats.first_contact) {
                            eprintln!(
                            "udp-driver: COLLISION: link {} hit debris {} at t = {:.3} s (distance {:.4} m)",
                            c.link, c.debris_id, c.t_s, c.distance_m
                        );
                        }
                    }
                }
                last_tick = s.tick;
                // Measured figures.
                meas.ticks += 1;
                let mut ratio = 0.0f64;
                for i in 0..NJ {
                    ratio = ratio.max(s.qd[i].abs() / v_lim[i]);
                }
                meas.max_velocity_ratio = meas.max_velocity_ratio.max(ratio);
                meas.velocity_limit_ticks += u64::from(ratio > 1.0);
                meas.brake_ticks += u64::from(s.brakes);
                if s.brakes && !brakes_before && commands_flowed {
                    meas.brake_engagements += 1;
                }
                commands_flowed |= !s.brakes;
                brakes_before = s.brakes;
                (final_q, final_qd) = (s.q, s.qd);
                msg.header.stamp_ns = s.plant_ns;
                msg.header.flags = if s.brakes { FLAG_BRAKE_ENGAGED } else { 0 }
                    | if step.stopping { FLAG_STOPPING } else { 0 }
                    | if step.last { FLAG_END_OF_RUN } else { 0 };
                msg.q = s.q;
                msg.qd = s.qd;
                msg.tau = s.tau;
                let seq = state_pub.publish(&mut msg).map_err(|e| e.to_string())?;
                core.published(seq, s.arm_seq);
                pending = Some((seq, now));
                if forced || step.last {
                    // Brakes: the arm holds; the tracker's commands are read, not sent.
                    let n = core.hold(now, &mut cbuf);
                    send_errors += u64::from(sock.send_to(&cbuf[..n], ep.arm).is_err());
                    holds_sent += 1;
                }
                if step.last {
                    ended = true;
                    break;
                }
            }
        }
        // 3. The tracker's command answering the newest state, within the tick.
        if let Some((seq, t_recv)) = pending {
            loop {
                let mut answered = false;
                let t = mono_ns();
                cmd_sub
                    .for_each(&lim, |c| {
                        if c.state_seq >= seq {
                            answered = true;
                        }
                        if forced || ended {
                            return;
                        }
                        if let Some(n) =
                            core.command(t, c.state_seq, arm_mode, &c.tau, &c.q_set, &c.qd_set, &mut cbuf)
                        {
                            if sock.send_to(&cbuf[..n], ep.arm).is_err() {
                                send_errors += 1;
                            }
                            if c.state_seq == seq {
                                turnaround.record_ns(mono_ns() - t_recv);
                            }
                        }
                    })
                    .map_err(|e| e.to_string())?;
                if answered
                    || ended
                    || mono_ns() > t_recv + cmd_wait_ns
                    || signals::stop_requested() && policy.report().is_none()
                {
                    break;
                }
                // Sleep between polls: a spinning SCHED_FIFO driver beside a spinning tracker
                // would starve the rest and trip the kernel's real-time throttling.
                std::thread::sleep(std::time::Duration::from_micros(COMMAND_POLL_US));
            }
            pending = None;
        }
        let state = if brakes_before { ProcessState::SafeHold } else { ProcessState::Running };
        hb.maybe_send(
            mono_ns(),
            false,
            msg.header.stamp_ns,
            state,
            meas.ticks,
            0,
            cmd_sub.rejected,
            meas.brake_engagements,
        )
        .map_err(|e| e.to_string())?;
    }
    let _ = hb.maybe_send(
        mono_ns(),
        true,
        msg.header.stamp_ns,
        ProcessState::Stopping,
        meas.ticks,
        0,
        cmd_sub.rejected,
        meas.brake_engagements,
    );
    let report = DriverReport {
        mode: sc.run.mode,
        ticks: meas.ticks,
        deadline_misses: 0,
        plant: meas,
        commands_received: cmd_sub.received,
        commands_rejected: cmd_sub.rejected,
        final_q,
        final_qd,
        debris: debris.as_ref().map(|d| d.stats),
        camera: camera.map(|c| c.finish()).transpose()?,
        stopped_by_signal: policy.stopped_by_signal,
        stop: policy.report(),
        link: LinkReport {
            stats: core.stats,
            command_echo_us: core.command_echo_us(),
            state_interval_us: interval.percentiles_us(),
            turnaround_us: turnaround.percentiles_us(),
            holds_sent,
            send_errors,
        },
        arm: ep.arm,
        rt,
    };
    dkrrt_rt::write_stats("udp-driver", stats_path, &report)?;
    Ok(report)
}
