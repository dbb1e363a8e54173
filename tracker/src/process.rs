//! The `dkrrt tracker` process shell: the controller core at 1 kHz on
//! absolute CLOCK_MONOTONIC deadlines (realtime), or driven by each new state
//! (lockstep). Records wake latency, compute time and state-to-command
//! latency into preallocated histograms.

use serde::Serialize;
use std::path::Path;

use dkrrt_config::arm::contract_limits;
use dkrrt_config::{Mode, Scenario};
use dkrrt_msg::bus::{Bus, HeartbeatTx};
use dkrrt_msg::*;
use dkrrt_rt::clock::{mono_ns, Pacer, PhaseFollower};
use dkrrt_rt::hist::{LatencyHist, Percentiles};
use dkrrt_rt::rtsetup::{self, RtOptions, RtReport};
use dkrrt_rt::signals;

use crate::ctrl::{ModeEvent, Tracker, TrackerConfig};

/// Most mode events kept for the report (preallocated; more are counted only).
pub const MAX_EVENTS: usize = 256;

#[derive(Debug, Clone, Copy, Default, serde::Serialize)]
pub struct ErrorSummary {
    pub rms: f64,
    pub max: f64,
}

#[derive(Debug, Clone, Copy, Default, serde::Serialize)]
pub struct Rejected {
    pub state: u64,
    pub trajectory: u64,
}

/// What the tracker reports at exit (written as JSON to `--stats`).
#[derive(Debug, Clone, serde::Serialize)]
pub struct TrackerReport {
    pub mode: Mode,
    pub ticks: u64,
    pub deadline_misses: u64,
    pub wake_latency_us: Percentiles,
    /// The wake-up latency's percentile curve, `(nines, µs)` (`dkrrt latency` plots it).
    pub wake_latency_curve_us: Vec<(f64, f64)>,
    pub tick_compute_us: Percentiles,
    pub state_to_command_us: Percentiles,
    pub tracking_error_rad: ErrorSummary,
    /// Max |q - goal| over joints at the end (NaN if no trajectory was received).
    pub final_error_rad: f64,
    pub safe_hold_entries: u64,
    /// Times the reference was re-anchored where the arm measured (plant brakes engaged under a
    /// moving reference, or the arm left it by more than `tracker.max_track_error_rad`).
    pub reanchors: u64,
    pub stale_ticks: u64,
    pub trajectories_accepted: u64,
    pub rejected: Rejected,
    /// Trajectories ignored because they came from a publisher the run did not start (another
    /// `Source`, or a second publisher of the run's source).
    pub foreign_trajectories: u64,
    /// Robot states ignored because they came from a second publisher (not the run's plant).
    pub foreign_states: u64,
    /// Times the wake phase moved to follow the states' arrival (`tracker.follow_states`).
    pub phase_moves: u64,
    /// The wake phase at the end, µs after the monotonic grid.
    pub phase_us: f64,
    pub events: Vec<ModeEvent>,
    pub events_dropped: u64,
    pub end_of_run_seen: bool,
    pub stopped_by_signal: bool,
    pub rt: RtReport,
}

fn log_event(e: &ModeEvent) {
    let safe = e.reason.is_safe_hold();
    eprintln!(
        "tracker: {}{:?} -> {:?} ({:?}) at plant t = {:.3} s",
        if safe { "SAFE HOLD: " } else { "" },
        e.from,
        e.to,
        e.reason,
        e.plant_ns as f64 * 1e-9
    );
}

/// Logs a mode event and keeps it for the report (preallocated: no growth).
fn record(events: &mut Vec<ModeEvent>, dropped: &mut u64, e: ModeEvent) {
    if events.len() < MAX_EVENTS {
        events.push(e);
    } else {
        *dropped += 1;
    }
    log_event(&e);
}

/// Runs the tracker until the plant signals the end of the run, or SIGINT/SIGTERM.
/// One sample of the tracker's trace (`--trace FILE`; every [`TRACE_TICKS`] plant ticks):
/// the measured positions and the reference (none while idle).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct TraceSample {
    pub t_s: f64,
    pub q: [f64; NJ],
    pub q_des: Option<[f64; NJ]>,
    pub qd_des: Option<[f64; NJ]>,
    pub qdd_des: Option<[f64; NJ]>,
}

/// After a stop request: no state for this long means the plant is gone, ns.
pub const SIM_GONE_NS: u64 = 1_000_000_000;
/// After a stop request: the tracker answers the plant at most this long, ns.
pub const STOP_LIMIT_NS: u64 = 30_000_000_000;

/// Plant ticks between trace samples.
pub const TRACE_TICKS: u64 = 10;

/// Runs the tracker; with `trace`, keeps a [`TraceSample`] every [`TRACE_TICKS`] plant ticks
/// (room allocated up front for the scenario's duration) and writes them there as JSON at exit.
pub fn run(
    run: &str,
    sc: &Scenario,
    stats_path: Option<&Path>,
    trace: Option<&Path>,
) -> Result<TrackerReport, String> {
    signals::install();
    let period = sc.period_ns().max(1);
    let mut samples: Vec<TraceSample> =
        Vec::with_capacity(if trace.is_some() { (sc.ticks() / TRACE_TICKS + 16) as usize } else { 0 });
    let model = sc.load_arm().map_err(|e| e.to_string())?;
    let lim = contract_limits(&model);
    let rt = rtsetup::apply_if(
        sc.run.mode == Mode::Realtime,
        &RtOptions::new(sc.tracker.cpu, sc.tracker.fifo_priority, sc.tracker.mlockall),
    );
    for w in &rt.warnings {
        eprintln!("tracker: warning: {w}");
    }
    let bus = Bus::new(run, "tracker").map_err(|e| e.to_string())?;
    let mut state_sub = bus.subscriber::<RobotState>().map_err(|e| e.to_string())?;
    let mut traj_sub = bus.subscriber::<Trajectory>().map_err(|e| e.to_string())?;
    let mut cmd_pub = bus.publisher::<TorqueCommand>(Source::Tracker).map_err(|e| e.to_string())?;
    let mut hb = HeartbeatTx::new(&bus, Source::Tracker, sc.run.heartbeat_hz).map_err(|e| e.to_string())?;

    let mut ctrl = Tracker::new(model, TrackerConfig::from_scenario(sc));
    let mut state = <RobotState as Zeroed>::zeroed();
    let mut traj = Box::new(<Trajectory as Zeroed>::zeroed());
    let mut cmd = <TorqueCommand as Zeroed>::zeroed();
    let (mut wake, mut compute, mut s2c) = (LatencyHist::new(), LatencyHist::new(), LatencyHist::new());
    let mut events: Vec<ModeEvent> = Vec::with_capacity(MAX_EVENTS);
    let mut events_dropped = 0u64;
    let period_ns = sc.period_ns();
    let mut pacer = Pacer::new(period_ns, sc.tracker.phase_us * 1000, 2_000_000);
    let wait_ns = sc.tracker.state_wait_us * 1000;
    // Following the states' arrival phase (`tracker.follow_states`): wake `phase_us` before it.
    let mut follower = sc.tracker.follow_states.then(|| {
        PhaseFollower::new(period_ns, sc.tracker.phase_us * 1000, (sc.run.control_hz / 2.0).max(1.0) as u32)
    });
    let mut phase_moves = 0u64;
    let mut last_seq: Option<u64> = None;
    // The plant this run started: the first publisher of states. A second one (a rogue `sim`
    // on the run) is ignored and counted; if ours is gone from the service, the next one
    // takes over (a restarted driver).
    let mut state_lock = dkrrt_msg::bus::PublisherLock::default();
    let mut foreign_warned = false;
    let mut last_q = [f64::NAN; NJ];
    let mut end_of_run_seen = false;
    let mut stopped_by_signal = false;
    let mut traj_rejected_seen = 0u64;
    let expected_source = if sc.replans() { Source::Planner } else { Source::TrajectorySource };
    let mut source_lock: Option<u128> = None;
    let mut foreign_trajectories = 0u64;

    // A signal is a controlled stop: brake to rest, hold, and keep answering the plant until
    // it ends the run (its END_OF_RUN state) or is gone.
    let mut stop_at: Option<u64> = None;
    let mut last_fresh_ns = mono_ns();
    loop {
        // 1. Wait for this tick's state (a first stop request cuts the wait short).
        let mut fresh = false;
        let interrupt = || stop_at.is_none() && signals::stop_requested();
        match sc.run.mode {
            Mode::Realtime => {
                let w = pacer.wait(interrupt);
                wake.record_ns(w.latency_ns());
                let until = w.deadline_ns + wait_ns;
                loop {
                    if state_lock.latest(&bus, &mut state_sub, &mut state, &lim).map_err(|e| e.to_string())?
                        && last_seq.is_none_or(|s| state.header.seq > s)
                    {
                        fresh = true;
                    }
                    if fresh || mono_ns() >= until || interrupt() {
                        break;
                    }
                    core::hint::spin_loop();
                }
            }
            Mode::Lockstep => {
                let mut spins = 0u32;
                loop {
                    if state_lock.latest(&bus, &mut state_sub, &mut state, &lim).map_err(|e| e.to_string())?
                        && last_seq.is_none_or(|s| state.header.seq > s)
                    {
                        fresh = true;
                        break;
                    }
                    if interrupt() || (stop_at.is_some() && mono_ns() > last_fresh_ns + SIM_GONE_NS) {
                        break;
                    }
                    spins += 1;
                    if spins.is_multiple_of(64) {
                        std::thread::yield_now();
                    }
                    core::hint::spin_loop();
                }
            }
        }
        let now = mono_ns();
        if let (true, Some(f)) = (fresh && sc.run.mode == Mode::Realtime, follower.as_mut()) {
            if let Some(ph) = f.record(state.header.mono_ns) {
                let d = ph.abs_diff(pacer.phase_ns());
                if d.min(period_ns - d) > 20_000 {
                    pacer.set_phase(ph);
                    phase_moves += 1;
                }
            }
        }
        if fresh {
            last_fresh_ns = now;
        }
        if state_sub.foreign > 0 && !foreign_warned {
            foreign_warned = true;
            eprintln!("tracker: ignoring robot states from a publisher this run did not start");
        }
        // A stop: our own signal, or the plant's (FLAG_STOPPING in its state).
        let plant_stops = fresh && state.header.flags & FLAG_STOPPING != 0;
        if stop_at.is_none() && (signals::stop_requested() || plant_stops) {
            stop_at = Some(now);
            stopped_by_signal = signals::stop_requested();
            if let Some(e) = ctrl.stop() {
                record(&mut events, &mut events_dropped, e);
            }
            if last_seq.is_none() {
                break; // never controlled the arm: nothing to bring to rest
            }
        }
        if let Some(t) = stop_at {
            // The plant is gone (no state for a while), or it never ends: stop answering.
            if now > last_fresh_ns + SIM_GONE_NS || now > t + STOP_LIMIT_NS {
                break;
            }
        }
        let t_compute = mono_ns();

        // 2. New trajectory? Only from the run's own source: the `Source` the scenario's
        // method publishes with, and the first publisher of it (a rogue `goto` on the run is
        // ignored and counted).
        if traj_sub.latest(&mut traj, &lim).map_err(|e| e.to_string())? {
            let mut ours = traj.header.source == expected_source as u32
                && *source_lock.get_or_insert(traj_sub.origin) == traj_sub.origin;
            if !ours && traj.header.source == expected_source as u32 {
                // A second publisher of the run's source: the restarted source (the one we
                // followed is gone from the service) takes over; a rogue one (ours is still
                // there) does not.
                let gone = source_lock
                    .is_some_and(|l| bus.publisher_ids::<Trajectory>().is_ok_and(|ids| !ids.contains(&l)));
                if gone {
                    source_lock = Some(traj_sub.origin);
                    ours = true;
                }
            }
            if !ours {
                foreign_trajectories += 1;
                if foreign_trajectories == 1 {
                    eprintln!(
                        "tracker: ignoring a trajectory from a publisher this run did not start (source {})",
                        traj.header.source
                    );
                }
            } else if let Some(e) = ctrl.set_trajectory(&traj) {
                record(&mut events, &mut events_dropped, e);
            }
        }
        if traj_sub.rejected > traj_rejected_seen {
            traj_rejected_seen = traj_sub.rejected;
            if let Some(e) = ctrl.reject_trajectory(state.header.stamp_ns) {
                record(&mut events, &mut events_dropped, e);
            }
        }

        // 3. Control.
        let braked = state.header.flags & FLAG_BRAKE_ENGAGED != 0;
        let input = fresh.then_some((state.header.seq, state.header.stamp_ns, &state.q, &state.qd, braked));
        let out = ctrl.tick(input);
        if fresh
            && samples.len() < samples.capacity()
            && (state.header.stamp_ns / period).is_multiple_of(TRACE_TICKS)
        {
            let des = ctrl.desired(state.header.stamp_ns);
            samples.push(TraceSample {
                t_s: state.header.stamp_ns as f64 * 1e-9,
                q: state.q,
                q_des: des.map(|d| d.0),
                qd_des: des.map(|d| d.1),
                qdd_des: des.map(|d| d.2),
            });
        }
        if let Some(e) = out.event {
            record(&mut events, &mut events_dropped, e);
        }
        if fresh {
            last_seq = Some(state.header.seq);
            last_q = state.q;
        }
        if last_seq.is_some() {
            cmd.header.stamp_ns = out.plant_ns;
            cmd.tau = out.tau;
            cmd.q_set = out.q_set;
            cmd.qd_set = out.qd_set;
            cmd.state_seq = out.state_seq;
            cmd.mode = out.mode as u32;
            cmd.traj_id = ctrl.active_traj_id() as u32;
            cmd_pub.publish(&mut cmd).map_err(|e| e.to_string())?;
            let sent = mono_ns();
            compute.record_ns(sent - t_compute);
            if fresh {
                s2c.record_ns(sent.saturating_sub(state.header.mono_ns));
            }
        }
        let ps = match out.mode {
            ControllerMode::Brake => ProcessState::SafeHold,
            ControllerMode::Hold if ctrl.stats.safe_hold_entries > 0 => ProcessState::SafeHold,
            _ => ProcessState::Running,
        };
        hb.maybe_send(
            mono_ns(),
            false,
            out.plant_ns,
            ps,
            ctrl.stats.ticks,
            pacer.misses,
            state_sub.rejected + traj_sub.rejected,
            ctrl.stats.safe_hold_entries,
        )
        .map_err(|e| e.to_string())?;
        if fresh && state.header.flags & FLAG_END_OF_RUN != 0 {
            end_of_run_seen = true;
            break;
        }
    }
    let _ = hb.maybe_send(
        mono_ns(),
        true,
        0,
        ProcessState::Stopping,
        ctrl.stats.ticks,
        pacer.misses,
        state_sub.rejected + traj_sub.rejected,
        ctrl.stats.safe_hold_entries,
    );
    let final_error_rad = match ctrl.goal() {
        Some(g) => (0..NJ).map(|i| (g[i] - last_q[i]).abs()).fold(0.0, f64::max),
        None => f64::NAN,
    };
    let report = TrackerReport {
        mode: sc.run.mode,
        ticks: ctrl.stats.ticks,
        deadline_misses: if sc.run.mode == Mode::Realtime { pacer.misses } else { 0 },
        wake_latency_us: wake.percentiles_us(),
        wake_latency_curve_us: wake.curve_us(),
        tick_compute_us: compute.percentiles_us(),
        state_to_command_us: s2c.percentiles_us(),
        tracking_error_rad: ErrorSummary { rms: ctrl.stats.track.rms(), max: ctrl.stats.track.max_abs },
        final_error_rad,
        safe_hold_entries: ctrl.stats.safe_hold_entries,
        reanchors: ctrl.stats.reanchors,
        stale_ticks: ctrl.stats.stale_ticks,
        trajectories_accepted: ctrl.stats.trajectories_accepted,
        rejected: Rejected { state: state_sub.rejected, trajectory: traj_sub.rejected },
        foreign_trajectories,
        foreign_states: state_sub.foreign,
        phase_moves,
        phase_us: pacer.phase_ns() as f64 * 1e-3,
        events,
        events_dropped,
        end_of_run_seen,
        stopped_by_signal,
        rt,
    };
    dkrrt_rt::write_stats("tracker", stats_path, &report)?;
    if let Some(p) = trace {
        std::fs::write(p, serde_json::to_string(&samples).map_err(|e| e.to_string())?)
            .map_err(|e| format!("tracker: --trace {}: {e}", p.display()))?;
    }
    Ok(report)
}
