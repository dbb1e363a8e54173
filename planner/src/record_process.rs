//! The `dkrrt record` process shell: subscribes to `dkrrt/debris_observation` on a run and
//! writes every valid item to a file in the format of [`dkrrt_predictor::recorded`]
//! (`dkrrt train --observations FILE` trains on it). Frames are checked like the
//! predictor checks them (the frame, then item by item); bad ones are counted, not written.
//! Ends with the run (the robot state's end-of-run flag), after `max_wall_s`, or on
//! SIGINT/SIGTERM.

use std::io::Write;
use std::path::Path;

use dkrrt_config::arm::contract_limits;
use dkrrt_config::Scenario;
use dkrrt_debris::Observation;
use dkrrt_msg::bus::Bus;
use dkrrt_msg::*;
use dkrrt_rt::clock::mono_ns;
use dkrrt_rt::signals;

/// What the recorder saw.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct RecordReport {
    pub frames: u64,
    pub frames_rejected: u64,
    /// Frames the bus overwrote before they were read.
    pub frames_lost: u64,
    pub items_written: u64,
    pub items_invalid: u64,
    pub stopped_by_signal: bool,
}

/// A recording's wall-clock limit: a finite number of seconds > 0.
pub fn check_seconds(s: f64) -> Result<f64, String> {
    if s.is_finite() && s > 0.0 {
        Ok(s)
    } else {
        Err(format!("{s}: must be a finite number of seconds > 0"))
    }
}

/// Records until the end of the run, `max_wall_s` seconds, or a signal.
pub fn run(run: &str, sc: &Scenario, out: &Path, max_wall_s: Option<f64>) -> Result<RecordReport, String> {
    signals::install();
    if let Some(s) = max_wall_s {
        check_seconds(s).map_err(|e| format!("record: --seconds {e}"))?;
    }
    let lim = contract_limits(&sc.load_arm().map_err(|e| e.to_string())?);
    let file = std::fs::File::create(out).map_err(|e| format!("record: create {}: {e}", out.display()))?;
    let mut w = std::io::BufWriter::new(file);
    let bus = Bus::new(run, "record").map_err(|e| e.to_string())?;
    let mut obs_sub = bus.subscriber::<DebrisObservation>().map_err(|e| e.to_string())?;
    let mut state_sub = bus.subscriber::<RobotState>().map_err(|e| e.to_string())?;
    let mut state = <RobotState as Zeroed>::zeroed();
    let mut rep = RecordReport::default();
    let t_end = max_wall_s.map(|s| mono_ns().saturating_add((s * 1e9) as u64));
    let mut io_err = None;
    loop {
        // The end of the run first: frames published before the last state are still read.
        let end = state_sub.latest(&mut state, &lim).map_err(|e| e.to_string())?
            && state.header.flags & FLAG_END_OF_RUN != 0;
        obs_sub
            .for_each_checked(
                |_| Ok(()),
                |f| {
                    rep.frames += 1;
                    if f.validate_frame().is_err() {
                        rep.frames_rejected += 1;
                        return;
                    }
                    for (i, it) in f.items[..f.count as usize].iter().enumerate() {
                        if it.validate_item(&lim, i).is_err() {
                            rep.items_invalid += 1;
                            continue;
                        }
                        let o = Observation {
                            id: it.id,
                            t: it.t_meas_ns as f64 * 1e-9,
                            t_avail: f.header.stamp_ns as f64 * 1e-9,
                            p: it.p,
                            q: it.q,
                            v: it.v,
                            w: it.w,
                            has_rates: it.flags & DEBRIS_HAS_VELOCITY != 0,
                            partial: it.flags & DEBRIS_PARTIAL != 0,
                            restart: it.flags & DEBRIS_RESTART != 0,
                            axis_only: it.flags & DEBRIS_AXIS_ONLY != 0,
                            seq: f.header.seq as u32,
                        };
                        match dkrrt_predictor::recorded::write_observation(&mut w, &o) {
                            Ok(()) => rep.items_written += 1,
                            Err(e) => {
                                io_err.get_or_insert(e);
                            }
                        }
                    }
                },
            )
            .map_err(|e| e.to_string())?;
        rep.frames_lost = obs_sub.lost;
        if let Some(e) = io_err {
            return Err(format!("record: write {}: {e}", out.display()));
        }
        if signals::stop_requested() {
            rep.stopped_by_signal = true;
            break;
        }
        if end || t_end.is_some_and(|t| mono_ns() >= t) {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    w.flush().map_err(|e| format!("record: write {}: {e}", out.display()))?;
    Ok(rep)
}
