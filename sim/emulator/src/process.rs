//! The `dkrrt arm-emulator` process: the "hardware" of a hardware-in-the-loop run. The plant
//! core behind the UDP protocol ([`crate::ArmEmulator`]) on its own 1 kHz clock (absolute
//! CLOCK_MONOTONIC deadlines), with the emulated network ([`crate::net`]) between it and the
//! driver in both directions. It runs until SIGINT/SIGTERM (power off), like an arm does not
//! end with its client's session; at power off a moving arm coasts to rest on its brakes.

use std::net::{SocketAddr, UdpSocket};
use std::path::Path;

use dkrrt_config::Scenario;
use dkrrt_model::NJ;
use dkrrt_rt::clock::{align_up, mono_ns};
use dkrrt_rt::hist::{LatencyHist, Percentiles};
use dkrrt_rt::poll::wait_readable;
use dkrrt_rt::rtsetup::{self, RtOptions, RtReport};
use dkrrt_rt::signals;
use dkrrt_sim::plant::{PlantConfig, PlantStats};
use dkrrt_sim::stop::{REST_SPEED_RAD_S, STOP_LIMIT_S};
use dkrrt_udp::STATE_LEN;

use crate::net::{DelayLine, Impairment, NetStats, MAX_DATAGRAM};
use crate::{ArmEmulator, EmulatorConfig, EmulatorStats};

/// What the emulator reports at exit (`--stats`).
#[derive(Debug, Clone, serde::Serialize)]
pub struct EmulatorReport {
    /// Arm ticks.
    pub ticks: u64,
    /// Ticks that began more than one period late (the clock skipped them).
    pub deadline_misses: u64,
    /// The arm tick's wake-up latency, µs.
    pub wake_latency_us: Percentiles,
    /// The round trip on the arm's clock: a state sent → the command answering it received
    /// (both network directions, the driver, the bus and the tracker), µs.
    pub round_trip_us: Percentiles,
    pub arm: EmulatorStats,
    /// The true plant (what a real arm would not tell you): the launcher's limit checks use it.
    pub plant: PlantStats,
    /// The arm was moving when powered off (SIGTERM): its brakes engaged then.
    pub moving_at_power_off: bool,
    /// Plant time the brakes took to bring it to rest after power off, s.
    pub brake_settle_s: f64,
    /// The arm's true state at the end (at rest after power off, or `brake_settle_s` ran out).
    pub final_q: [f64; NJ],
    pub final_qd: [f64; NJ],
    /// The emulated network, arm → driver (states) and driver → arm (commands).
    pub to_driver: NetStats,
    pub from_driver: NetStats,
    pub delay_ms: f64,
    pub jitter_ms: f64,
    pub loss: f64,
    pub duplicate: f64,
    pub reorder: f64,
    pub send_errors: u64,
    pub rt: RtReport,
}

/// Runs the emulated arm at `listen`, sending its states to `driver`, until a stop signal.
pub fn run(
    sc: &Scenario,
    listen: SocketAddr,
    driver: SocketAddr,
    stats: Option<&Path>,
) -> Result<EmulatorReport, String> {
    signals::install();
    if listen == driver {
        return Err(format!(
            "arm-emulator: --listen and --driver are both {listen}: the arm would send its states to itself"
        ));
    }
    let model = sc.load_arm().map_err(|e| e.to_string())?;
    let rt = rtsetup::apply_if(true, &RtOptions::new(sc.sim.cpu, sc.sim.fifo_priority, sc.sim.mlockall));
    for w in &rt.warnings {
        eprintln!("arm-emulator: warning: {w}");
    }
    let sock = UdpSocket::bind(listen).map_err(|e| format!("arm-emulator: bind {listen}: {e}"))?;
    sock.set_nonblocking(true).map_err(|e| format!("arm-emulator: {e}"))?;
    let period = sc.period_ns();
    let cfg = EmulatorConfig { abort_after: sc.udp.abort_after, ..EmulatorConfig::new(period) };
    let mut arm = ArmEmulator::new(model, PlantConfig::from_scenario(sc), &sc.sim.initial_q, cfg);
    let imp = Impairment::from_scenario(&sc.udp, period);
    let mut out = DelayLine::new(imp, sc.udp.seed);
    let mut inl = DelayLine::new(imp, sc.udp.seed ^ 0x9e37_79b9_7f4a_7c15);
    let mut sbuf = [0u8; STATE_LEN];
    let mut buf = [0u8; MAX_DATAGRAM];
    let mut rbuf = [0u8; 2048];
    let (mut wake, mut rtt) = (LatencyHist::new(), LatencyHist::new());
    // When each of the last states was sent: `(seq, mono ns)`, ring.
    let mut sent_at = [(u32::MAX, 0u64); 64];
    let (mut ticks, mut misses, mut send_errors) = (0u64, 0u64, 0u64);
    let mut next_tick = align_up(mono_ns() + 2_000_000, period, 0);
    while !signals::stop_requested() {
        let now = mono_ns();
        if now >= next_tick {
            wake.record_ns(now - next_tick);
            if ticks > 0 {
                arm.step();
            }
            ticks += 1;
            let n = arm.state(&mut sbuf);
            let seq = (arm.plant().tick() & u64::from(u32::MAX)) as u32;
            sent_at[seq as usize % sent_at.len()] = (seq, now);
            out.push(now, &sbuf[..n]);
            next_tick += period;
            if now > next_tick {
                // More than a period late: the arm's clock skips (its tick is its own).
                let behind = (now - next_tick) / period + 1;
                misses += behind;
                next_tick += behind * period;
            }
        }
        let now = mono_ns();
        while let Some(n) = out.pop_due(now, &mut buf) {
            send_errors += u64::from(sock.send_to(&buf[..n], driver).is_err());
        }
        loop {
            match sock.recv_from(&mut rbuf) {
                Ok((n, _)) => inl.push(mono_ns(), &rbuf[..n]),
                Err(_) => break,
            }
        }
        let now = mono_ns();
        while let Some(n) = inl.pop_due(now, &mut buf) {
            if let Ok(seq) = arm.receive(&buf[..n]) {
                let (s, t) = sent_at[seq as usize % sent_at.len()];
                if s == seq {
                    sent_at[seq as usize % sent_at.len()].0 = u32::MAX; // the first answer counts
                    rtt.record_ns(now.saturating_sub(t));
                }
            }
        }
        // Sleep until the next tick, the next datagram due, or a datagram from the driver.
        let due = [Some(next_tick), out.next_due(), inl.next_due()]
            .into_iter()
            .flatten()
            .min()
            .unwrap_or(next_tick);
        let now = mono_ns();
        if due > now {
            wait_readable(&sock, due - now);
        }
    }
    // Powered off: a moving arm (its driver gone) coasts to rest on its brakes.
    let moving = arm.plant().max_speed() >= REST_SPEED_RAD_S;
    let settle = arm.power_off(REST_SPEED_RAD_S, (STOP_LIMIT_S * sc.run.control_hz) as u64);
    let (q, qd) = arm.plant().true_state();
    let report = EmulatorReport {
        moving_at_power_off: moving,
        brake_settle_s: settle as f64 * period as f64 * 1e-9,
        ticks,
        deadline_misses: misses,
        wake_latency_us: wake.percentiles_us(),
        round_trip_us: rtt.percentiles_us(),
        arm: arm.stats,
        plant: arm.plant().stats,
        final_q: q.into(),
        final_qd: qd.into(),
        to_driver: out.stats,
        from_driver: inl.stats,
        delay_ms: sc.udp.delay_ms,
        jitter_ms: sc.udp.jitter_ms,
        loss: sc.udp.loss,
        duplicate: sc.udp.duplicate,
        reorder: sc.udp.reorder,
        send_errors,
        rt,
    };
    dkrrt_rt::write_stats("arm-emulator", stats, &report)?;
    Ok(report)
}
