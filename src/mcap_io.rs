//! `dkrrt recorder` (started by `dkrrt launch --record FILE`) and `dkrrt replay FILE`: the
//! process shells around [`dkrrt_recording`].
//!
//! The recorder is a separate process reading the bus (never in a hot loop of the run): it
//! polls every service each millisecond, writes every sample it sees (valid or not: a
//! recording is for finding out what went wrong) and counts what the bus overwrote before it
//! read it. Memory stays bounded: one write buffer, flushed every 100 ms.
//!
//! Replay republishes the payloads the predictor and the planner consume from the arm side
//! (`robot_state`, `torque_command`, `debris_observation`, `goal`) on a new run id, at the
//! recorded pace times `speed` (0: as fast as possible), so `dkrrt predictor` and
//! `dkrrt planner` can be re-run on recorded data.

use std::collections::BTreeMap;
use std::path::Path;

use dkrrt_msg::bus::{Bus, Sub, Topic};
use dkrrt_msg::*;
use dkrrt_recording::{read, topic_of, Recordable, Recorder, FLUSH_NS};
use dkrrt_rt::clock::mono_ns;
use dkrrt_rt::signals;

/// What the recorder wrote.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct RecorderReport {
    pub messages: u64,
    /// Per service: samples written and samples lost (overwritten before the recorder read them).
    pub per_service: BTreeMap<&'static str, (u64, u64)>,
    pub stopped_by_signal: bool,
}

fn drain<T: Recordable>(sub: &mut Sub<T>, rec: &mut Recorder, n: &mut u64) -> Result<Option<T>, String> {
    let mut last = None;
    let mut err = None;
    sub.for_each_checked(
        |_| Ok(()),
        |m| {
            if let Err(e) = rec.record(m, mono_ns()) {
                err.get_or_insert(e);
            }
            *n += 1;
            last = Some(*m);
        },
    )
    .map_err(|e| e.to_string())?;
    match err {
        Some(e) => Err(e),
        None => Ok(last),
    }
}

/// Records every service of run `run` into `out` until the end of the run (the plant's
/// END_OF_RUN state) or a signal.
pub fn record(run: &str, out: &Path) -> Result<RecorderReport, String> {
    signals::install();
    let mut rec = Recorder::create(out).map_err(|e| format!("recorder: {e}"))?;
    let bus = Bus::new(run, "recorder").map_err(|e| e.to_string())?;
    let e = |e: dkrrt_msg::bus::BusError| e.to_string();
    let mut state = bus.subscriber::<RobotState>().map_err(e)?;
    let mut cmd = bus.subscriber::<TorqueCommand>().map_err(e)?;
    let mut traj = bus.subscriber::<Trajectory>().map_err(e)?;
    let mut goal = bus.subscriber::<Goal>().map_err(e)?;
    let mut hb = bus.subscriber::<Heartbeat>().map_err(e)?;
    let mut obs = bus.subscriber::<DebrisObservation>().map_err(e)?;
    let mut fc = bus.subscriber::<DebrisForecast>().map_err(e)?;
    let mut status = bus.subscriber::<PlanStatus>().map_err(e)?;
    let mut prog = bus.subscriber::<PredictorProgress>().map_err(e)?;
    let mut counts = [0u64; 9];
    let mut last_flush = mono_ns();
    let mut rep = RecorderReport::default();
    loop {
        let end = drain(&mut state, &mut rec, &mut counts[0])?
            .is_some_and(|s| s.header.flags & FLAG_END_OF_RUN != 0);
        drain(&mut cmd, &mut rec, &mut counts[1])?;
        drain(&mut traj, &mut rec, &mut counts[2])?;
        drain(&mut goal, &mut rec, &mut counts[3])?;
        drain(&mut hb, &mut rec, &mut counts[4])?;
        drain(&mut obs, &mut rec, &mut counts[5])?;
        drain(&mut fc, &mut rec, &mut counts[6])?;
        drain(&mut status, &mut rec, &mut counts[7])?;
        drain(&mut prog, &mut rec, &mut counts[8])?;
        let now = mono_ns();
        if now - last_flush >= FLUSH_NS {
            rec.flush().map_err(|e| format!("recorder: {}: {e}", out.display()))?;
            last_flush = now;
        }
        if end {
            break;
        }
        if signals::stop_requested() {
            rep.stopped_by_signal = true;
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    let lost =
        [state.lost, cmd.lost, traj.lost, goal.lost, hb.lost, obs.lost, fc.lost, status.lost, prog.lost];
    let names = [
        RobotState::SERVICE,
        TorqueCommand::SERVICE,
        Trajectory::SERVICE,
        Goal::SERVICE,
        Heartbeat::SERVICE,
        DebrisObservation::SERVICE,
        DebrisForecast::SERVICE,
        PlanStatus::SERVICE,
        PredictorProgress::SERVICE,
    ];
    for i in 0..names.len() {
        rep.per_service.insert(names[i], (counts[i], lost[i]));
    }
    rep.messages = rec.finish().map_err(|e| format!("recorder: {}: {e}", out.display()))?;
    Ok(rep)
}

/// What a replay published.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct ReplayReport {
    pub published: BTreeMap<String, u64>,
    /// Recorded topics not replayed (view-only payloads, e.g. forecasts and plans: the
    /// processes re-run on the replay make their own).
    pub skipped: BTreeMap<String, u64>,
    /// Messages that did not decode.
    pub undecodable: u64,
    /// The recording ended in a broken record (interrupted): replayed up to there.
    pub interrupted: bool,
}

/// Republishes the arm-side payloads of recording `file` on run `run` at `speed` × the
/// recorded pace (0: as fast as possible).
pub fn replay(file: &Path, run: &str, speed: f64) -> Result<ReplayReport, String> {
    signals::install();
    if !(speed >= 0.0 && speed.is_finite()) {
        return Err(format!("--speed {speed}: must be a finite number >= 0"));
    }
    let (msgs, complete) = read(file)?;
    let bus = Bus::new(run, "replay").map_err(|e| e.to_string())?;
    let e = |e: dkrrt_msg::bus::BusError| e.to_string();
    let mut state = bus.publisher::<RobotState>(Source::Sim).map_err(e)?;
    let mut cmd = bus.publisher::<TorqueCommand>(Source::Tracker).map_err(e)?;
    let mut obs = bus.publisher::<DebrisObservation>(Source::Sim).map_err(e)?;
    let mut goal = bus.publisher::<Goal>(Source::User).map_err(e)?;
    let mut rep = ReplayReport { interrupted: !complete, ..ReplayReport::default() };
    let t0_rec = msgs.first().map_or(0, |m| m.log_time_ns);
    let t0 = mono_ns();
    for m in &msgs {
        if signals::stop_requested() {
            break;
        }
        if speed > 0.0 {
            let due = t0 + ((m.log_time_ns.saturating_sub(t0_rec)) as f64 / speed) as u64;
            while mono_ns() < due && !signals::stop_requested() {
                std::thread::sleep(std::time::Duration::from_micros(200));
            }
        }
        macro_rules! republish {
            ($t:ty, $p:expr) => {{
                match <$t>::from_json(&m.json) {
                    Some(mut x) => {
                        $p.publish(&mut x).map_err(e)?;
                        *rep.published.entry(m.topic.clone()).or_default() += 1;
                    }
                    None => rep.undecodable += 1,
                }
            }};
        }
        let t = m.topic.as_str();
        if t == topic_of(RobotState::SERVICE) {
            republish!(RobotState, state)
        } else if t == topic_of(TorqueCommand::SERVICE) {
            republish!(TorqueCommand, cmd)
        } else if t == topic_of(DebrisObservation::SERVICE) {
            republish!(DebrisObservation, obs)
        } else if t == topic_of(Goal::SERVICE) {
            republish!(Goal, goal)
        } else {
            *rep.skipped.entry(m.topic.clone()).or_default() += 1;
        }
    }
    Ok(rep)
}
