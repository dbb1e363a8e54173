//! The debris side run ahead: in a lockstep run on the pose sensor, the debris world, its
//! sensor and the debris predictor do not depend on the arm (the sensor observes the debris,
//! never the arm), so a second thread can step them ahead of the plant, tracker and planner,
//! tick for tick, and hand over what the arm's side reads of them:
//!
//! * every tick, the true debris as posed obstacles for the true contact check
//!   ([`dkrrt_sim::debris::DebrisSide::obstacles_into`]) and the world's counters;
//! * every forecast the predictor writes (a copy), and its figures.
//!
//! The predictor decides which forecasts to build from the planner's cycle cadence
//! ([`dkrrt_rrt::CycleClock`]), a copy of which this thread advances with the same stamps: the
//! run is the same, tick for tick, as the serial lockstep (test
//! `tests/lockstep.rs::a_run_ahead_is_the_serial_run`). It needs every state delivered (the
//! planner's cadence then depends on the stamps alone).
//!
//! Ticks travel in batches of [`BATCH`] through a bounded channel; batches and their forecast
//! copies are recycled, so after warm-up nothing is allocated. Dropping the [`Ahead`] stops
//! and joins the thread.

use std::sync::mpsc::{sync_channel, Receiver, SyncSender};
use std::thread::JoinHandle;

use dkrrt_collision::Obstacle;
use dkrrt_msg::{DebrisForecast, DebrisObservation, Zeroed, MAX_DEBRIS};
use dkrrt_planner::predict::{Cadence, ObsCounters};
use dkrrt_predictor::GateStats;
use dkrrt_rrt::CycleClock;
use dkrrt_sim::debris::DebrisSide;

use crate::lockstep::PredictorLoop;

/// Ticks per batch.
pub const BATCH: usize = 25;
/// Batches the thread may run ahead by (plus the one being filled and the one being read):
/// 0.2 s of plant time at 1 kHz, so the debris side keeps working through a long planning
/// cycle.
const IN_FLIGHT: usize = 8;

/// The predictor's running figures after a tick.
#[derive(Debug, Clone, Copy, Default)]
pub struct PredictorSnapshot {
    pub forecasts: u64,
    pub tracks: u32,
    pub deferred: u64,
    pub counters: ObsCounters,
    pub gate: GateStats,
}

/// One tick of the debris side, as the arm's side reads it.
pub struct WorldTick {
    /// The true debris, posed (LVLH), after this tick's step.
    pub obstacles: Vec<Obstacle>,
    /// Plant time after the step, s.
    pub t: f64,
    pub observations: u64,
    pub observation_frames: u64,
    pub events_fired: u32,
    /// The forecast written during this tick (index into the batch's copies).
    forecast: Option<usize>,
    latest_deferred: bool,
    predictor: Option<PredictorSnapshot>,
}

struct Batch {
    ticks: Vec<WorldTick>,
    forecasts: Vec<Box<DebrisForecast>>,
    used: usize,
    /// The thread's allocations so far, when the batch was filled (with the counting
    /// allocator installed; else 0).
    allocs: u64,
}

impl Batch {
    /// A batch with room for `forecasts` forecast copies (more are allocated if ever needed).
    fn new(forecasts: usize) -> Batch {
        let ticks = (0..BATCH)
            .map(|_| WorldTick {
                obstacles: Vec::with_capacity(MAX_DEBRIS),
                t: 0.0,
                observations: 0,
                observation_frames: 0,
                events_fired: 0,
                forecast: None,
                latest_deferred: false,
                predictor: None,
            })
            .collect();
        let forecasts = (0..forecasts).map(|_| Box::new(<DebrisForecast as Zeroed>::zeroed())).collect();
        Batch { ticks, forecasts, used: 0, allocs: 0 }
    }
}

/// The arm's side of a run ahead: the ticks in order, and the predictor's output as the
/// planner reads it.
pub struct Ahead {
    full: Option<Receiver<Batch>>,
    empty: Option<SyncSender<Batch>>,
    thread: Option<JoinHandle<()>>,
    cur: Option<Batch>,
    pos: usize,
    /// The newest forecast written, and whether the planner has not read it yet.
    pub forecast: Box<DebrisForecast>,
    pub fresh: bool,
    /// The newest due forecast was deferred ([`PredictorLoop`]'s `stale_reads`).
    pub latest_deferred: bool,
    pub stale_reads: u64,
    /// The predictor's figures after the last tick read (`None`: no predictor).
    pub predictor: Option<PredictorSnapshot>,
    /// The thread's allocations as of the last batch read (allocation tests).
    pub thread_allocs: u64,
}

impl Ahead {
    /// Starts the thread with a debris side fresh from the scenario (at plant time 0), the
    /// predictor (if any), the planner's cadence (`None`: no planner reads forecasts) and the
    /// tick period.
    pub fn start(
        side: DebrisSide,
        predictor: Option<PredictorLoop>,
        cadence: Option<CycleClock>,
        period_ns: u64,
    ) -> Result<Ahead, String> {
        let (full_tx, full) = sync_channel::<Batch>(IN_FLIGHT);
        let (empty, empty_rx) = sync_channel::<Batch>(IN_FLIGHT + 2);
        // At most one forecast per `1 / rate` of plant time, so a batch holds at most this many
        // (one more for the rounding): allocated here, not while running.
        let per_batch = predictor
            .as_ref()
            .map_or(0, |p| (BATCH as f64 * period_ns as f64 * 1e-9 * p.rate_hz).ceil() as usize + 1);
        for _ in 0..IN_FLIGHT + 2 {
            empty.send(Batch::new(per_batch)).map_err(|e| e.to_string())?;
        }
        let thread = std::thread::Builder::new()
            .name("debris-ahead".into())
            .spawn(move || run(side, predictor, cadence, period_ns, full_tx, empty_rx))
            .map_err(|e| format!("lockstep: the debris thread: {e}"))?;
        Ok(Ahead {
            full: Some(full),
            empty: Some(empty),
            thread: Some(thread),
            cur: None,
            pos: BATCH,
            forecast: Box::new(<DebrisForecast as Zeroed>::zeroed()),
            fresh: false,
            latest_deferred: false,
            stale_reads: 0,
            predictor: None,
            thread_allocs: 0,
        })
    }

    /// The next tick (blocking until the thread has stepped it); its forecast, if one was
    /// written, becomes the fresh one.
    pub fn next_tick(&mut self) -> &WorldTick {
        if self.pos >= BATCH {
            if let (Some(b), Some(empty)) = (self.cur.take(), self.empty.as_ref()) {
                let _ = empty.send(b);
            }
            let full = self.full.as_ref().expect("running");
            self.cur = Some(full.recv().unwrap_or_else(|_| panic!("lockstep: the debris thread stopped")));
            self.pos = 0;
        }
        let b = self.cur.as_ref().expect("a batch");
        self.thread_allocs = b.allocs;
        let w = &b.ticks[self.pos];
        self.pos += 1;
        if let Some(i) = w.forecast {
            *self.forecast = *b.forecasts[i];
            self.fresh = true;
        }
        self.latest_deferred = w.latest_deferred;
        self.predictor = w.predictor;
        w
    }
}

impl Drop for Ahead {
    fn drop(&mut self) {
        // Closing both channels ends the thread wherever it waits.
        self.full.take();
        self.empty.take();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn run(
    mut side: DebrisSide,
    mut predictor: Option<PredictorLoop>,
    mut cadence: Option<CycleClock>,
    period_ns: u64,
    full: SyncSender<Batch>,
    empty: Receiver<Batch>,
) {
    let dt = period_ns as f64 * 1e-9;
    let mut frame = Box::new(<DebrisObservation as Zeroed>::zeroed());
    let mut tick: u64 = 0;
    while let Ok(mut b) = empty.recv() {
        b.used = 0;
        for w in b.ticks.iter_mut() {
            // The planner's cycle at this tick's stamp comes before the sim's step, as in
            // `Lockstep::tick`.
            let stamp = tick * period_ns;
            let next_cycle = cadence.as_mut().map(|c| {
                c.due(stamp);
                c.next_ns
            });
            let now_ns = stamp + period_ns;
            side.step(dt);
            side.obstacles_into(&mut w.obstacles);
            w.t = side.world().time();
            let mut written = false;
            let _ = side.drain_observations::<()>(&mut frame, |f| {
                if let Some(p) = predictor.as_mut() {
                    written |= matches!(p.feed(f, now_ns, next_cycle), Cadence::Written(n) if n > 0);
                }
                Ok(())
            });
            w.forecast = None;
            if let (true, Some(p)) = (written, predictor.as_ref()) {
                if b.used == b.forecasts.len() {
                    b.forecasts.push(Box::new(<DebrisForecast as Zeroed>::zeroed()));
                }
                *b.forecasts[b.used] = *p.forecast;
                w.forecast = Some(b.used);
                b.used += 1;
            }
            (w.observations, w.observation_frames, w.events_fired) =
                (side.stats.observations, side.stats.observation_frames, side.stats.events_fired);
            w.latest_deferred = predictor.as_ref().is_some_and(|p| p.latest_deferred);
            w.predictor = predictor.as_ref().map(|p| PredictorSnapshot {
                forecasts: p.forecasts,
                tracks: p.tracks,
                deferred: p.deferred,
                counters: p.core.counters,
                gate: *p.core.gate(),
            });
            tick += 1;
        }
        b.allocs = dkrrt_rt::alloc_count::AllocStats::now().allocs;
        if full.send(b).is_err() {
            return;
        }
    }
}
