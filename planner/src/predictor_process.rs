//! The `dkrrt predictor` process shell: fits the scenario's models at start-up (before its
//! node appears on the bus, so the launcher's readiness check covers the fit), then
//! subscribes to `dkrrt/debris/observation`, feeds [`PredictorCore`] and publishes
//! `dkrrt/debris/forecast`.
//!
//! Cadence: realtime — paced on absolute CLOCK_MONOTONIC deadlines at `predictor.rate_hz`,
//! one forecast per wake (from the newest estimates); lockstep — one forecast each time the
//! plant clock (observation stamps) passes the next `1/rate_hz` boundary, so the result does
//! not depend on the machine's speed. Ends with the run (the sim's end-of-run flag) or on
//! SIGINT/SIGTERM.

use std::path::Path;

use dkrrt_config::arm::contract_limits;
use dkrrt_config::{Mode, Scenario};
use dkrrt_msg::bus::{Bus, HeartbeatTx};
use dkrrt_msg::*;
use dkrrt_predictor::GateStats;
use dkrrt_rt::clock::{mono_ns, Pacer};
use dkrrt_rt::hist::{LatencyHist, Percentiles};
use dkrrt_rt::signals;

use crate::predict::{fit_models, ObsCounters, PredictorCore};

/// What the predictor reports at exit (JSON via `--stats`).
#[derive(Debug, Clone, serde::Serialize)]
pub struct PredictorReport {
    pub method: String,
    /// Start-up fit time, s.
    pub fit_s: f64,
    pub forecasts: u64,
    /// Forecasts per second (wall clock in realtime, plant clock in lockstep) between the
    /// first and the last forecast.
    pub forecast_rate_hz: f64,
    /// Time of one forecast (all tracks, roll-out + message), µs; in lockstep it includes the
    /// observation of the frame that made the forecast due.
    pub forecast_compute_us: Percentiles,
    /// Tracks in the last forecast.
    pub tracks: u32,
    pub observations: ObsCounters,
    /// Observation items rejected (contract check + predictor gate + whole bad frames).
    pub rejected_observations: u64,
    pub gate: GateStats,
    pub deadline_misses: u64,
    pub stopped_by_signal: bool,
}

/// Runs the predictor until the end of the run or a signal.
pub fn run(run: &str, sc: &Scenario, stats_path: Option<&Path>) -> Result<PredictorReport, String> {
    signals::install();
    if !sc.has_debris() {
        return Err("predictor: the scenario has no debris (debris.scene is empty)".into());
    }
    let model = sc.load_arm().map_err(|e| e.to_string())?;
    let lim = contract_limits(&model);
    let t_fit = mono_ns();
    let models = fit_models(sc)?;
    let fit_s = (mono_ns() - t_fit) as f64 * 1e-9;
    eprintln!("predictor: {} models fitted in {fit_s:.2} s", sc.predictor_method());
    let mut core = PredictorCore::for_scenario(models, sc)?;
    if sc.depth_input() {
        eprintln!(
            "predictor: depth front end {}",
            if core.learned_front_end() { "learned (f_θ)" } else { "classical" }
        );
    }

    let bus = Bus::new(run, "predictor").map_err(|e| e.to_string())?;
    let mut obs_sub = bus.subscriber::<DebrisObservation>().map_err(|e| e.to_string())?;
    // `predictor.input = "depth"`: the depth camera's frames, through the front end
    // (`predictor.front_end`: classical or learned), in place of the pose sensor's observations.
    let mut img_sub = match sc.depth_input() {
        true => Some(bus.subscriber::<DepthImage>().map_err(|e| e.to_string())?),
        false => None,
    };
    let mut state_sub = bus.subscriber::<RobotState>().map_err(|e| e.to_string())?;
    let mut state_lock = dkrrt_msg::bus::PublisherLock::default();
    let mut fc_pub = bus.publisher::<DebrisForecast>(Source::Predictor).map_err(|e| e.to_string())?;
    let mut prog_pub = bus.publisher::<PredictorProgress>(Source::Predictor).map_err(|e| e.to_string())?;
    let mut prog = <PredictorProgress as Zeroed>::zeroed();
    let mut hb = HeartbeatTx::new(&bus, Source::Predictor, sc.run.heartbeat_hz).map_err(|e| e.to_string())?;
    let mut msg = Box::new(<DebrisForecast as Zeroed>::zeroed());
    let mut state = <RobotState as Zeroed>::zeroed();

    let period_ns = (1e9 / sc.predictor.rate_hz).round() as u64;
    let realtime = sc.run.mode == Mode::Realtime;
    let mut pacer = Pacer::new(period_ns, 0, 0);
    let mut compute = LatencyHist::new();
    let mut forecasts = 0u64;
    let mut tracks = 0u32;
    let (mut first_fc, mut last_fc) = (None::<f64>, 0.0f64);
    let mut end = false;
    let mut stopped_by_signal = false;
    while !end {
        if realtime {
            pacer.wait(signals::stop_requested);
        } else {
            std::thread::sleep(std::time::Duration::from_micros(200));
        }
        if signals::stop_requested() {
            stopped_by_signal = true;
            break;
        }
        // The end of the run first: the sim publishes its last frames before the state with
        // END_OF_RUN, so the drain below still gets them (and counts a gap before them).
        if state_lock.latest(&bus, &mut state_sub, &mut state, &lim).map_err(|e| e.to_string())? {
            end = state.header.flags & FLAG_END_OF_RUN != 0;
        }
        // The core checks each frame and then each item (and counts what it drops).
        // Realtime: all new frames, then one forecast per wake. Lockstep: frame by frame,
        // a forecast at every plant-clock boundary a frame passes (however the frames were
        // batched on the bus).
        let mut publish_err = None;
        let mut publish = |msg: &mut DebrisForecast, n: usize, t0: u64, t: f64| {
            if let Err(e) = fc_pub.publish(msg) {
                publish_err.get_or_insert(e.to_string());
            }
            compute.record_ns(mono_ns() - t0);
            forecasts += 1;
            tracks = n as u32;
            first_fc.get_or_insert(t);
            last_fc = t;
        };
        let mut newest = None::<Header>;
        if realtime {
            match img_sub.as_mut() {
                Some(s) => s.for_each_checked(
                    |m| m.validate(&lim),
                    |img| {
                        newest = Some(img.header);
                        core.observe_depth(img, &lim)
                    },
                ),
                None => obs_sub.for_each_checked(
                    |_| Ok(()),
                    |f| {
                        newest = Some(f.header);
                        core.observe_frame(f, &lim)
                    },
                ),
            }
            .map_err(|e| e.to_string())?;
            let t0 = mono_ns();
            let n = core.forecast_into(&mut msg);
            if core.publishable(n) {
                publish(&mut msg, n, t0, mono_ns() as f64 * 1e-9);
            }
        } else {
            let rate_hz = sc.predictor.rate_hz;
            let mut step =
                |core: &mut PredictorCore,
                 h: Header,
                 observe: &dyn Fn(&mut PredictorCore, &mut DebrisForecast) -> Option<usize>| {
                    newest = Some(h);
                    let t0 = mono_ns();
                    if let Some(n) = observe(core, &mut msg) {
                        let t = core.newest_t;
                        publish(&mut msg, n, t0, t);
                    }
                };
            match img_sub.as_mut() {
                Some(s) => s.for_each_checked(
                    |m| m.validate(&lim),
                    |img| {
                        step(&mut core, img.header, &|c, m| {
                            c.observe_depth_then_forecast(img, &lim, rate_hz, m)
                        })
                    },
                ),
                None => obs_sub.for_each_checked(
                    |_| Ok(()),
                    |f| step(&mut core, f.header, &|c, m| c.observe_then_forecast(f, &lim, rate_hz, m)),
                ),
            }
            .map_err(|e| e.to_string())?;
        }
        if let Some(e) = publish_err {
            return Err(e);
        }
        // After the forecasts the frames made due: how far the predictor has read.
        if let Some(h) = newest {
            prog.header.stamp_ns = h.stamp_ns;
            prog.frame_seq = h.seq;
            prog.frames = core.counters.frames;
            prog.forecasts = forecasts;
            prog_pub.publish(&mut prog).map_err(|e| e.to_string())?;
        }
        core.counters.frames_lost = img_sub.as_ref().map_or(obs_sub.lost, |s| s.lost);
        hb.maybe_send(
            mono_ns(),
            false,
            (core.newest_t.max(0.0) * 1e9) as u64,
            ProcessState::Running,
            forecasts,
            pacer.misses,
            core.counters.rejected(),
            0,
        )
        .map_err(|e| e.to_string())?;
    }
    let _ = hb.maybe_send(mono_ns(), true, 0, ProcessState::Stopping, forecasts, pacer.misses, 0, 0);
    let span = first_fc.map_or(0.0, |f| last_fc - f);
    let report = PredictorReport {
        method: sc.predictor_method().to_string(),
        fit_s,
        forecasts,
        forecast_rate_hz: if span > 0.0 { (forecasts - 1) as f64 / span } else { 0.0 },
        forecast_compute_us: compute.percentiles_us(),
        tracks,
        observations: core.counters,
        rejected_observations: core.counters.rejected(),
        gate: *core.gate(),
        deadline_misses: if realtime { pacer.misses } else { 0 },
        stopped_by_signal,
    };
    dkrrt_rt::write_stats("predictor", stats_path, &report)?;
    Ok(report)
}
