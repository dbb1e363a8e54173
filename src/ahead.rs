//! The debris side run ahead: in a lockstep run on the pose sensor, the debris world, its
//! sensor and the debris predictor do not depend on the arm (the sensor observes the debris,
//! never the arm), so other threads can step them ahead of the plant, tracker and planner,
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
//! Two stages, a thread each, as a pipeline: the world's (step, sensor, posed obstacles; it
//! keeps the sensor's frames and the planner's next cycle per tick) and the predictor's (feeds
//! each tick's frames as the serial lockstep does at that tick, copies the forecasts). In a
//! dense scene the predictor's work is about twice the world's, and the arm's side about as
//! much as both: one thread for both stages kept the arm's side waiting for it (dense 47–49×
//! real time, 60× with the two stages; docs/architecture.md). Without a predictor the world's
//! stage alone runs.
//!
//! Ticks travel in batches of [`BATCH`] through queues between the threads ([`Pipe`]: a
//! mutex, a condition variable and room for every batch, so handing a batch over never
//! allocates, where `std::sync::mpsc` allocates the first time a thread blocks on a channel,
//! at a moment that depends on the timing); batches, their frames and forecast copies are
//! recycled, so after warm-up nothing is allocated. Dropping the [`Ahead`] stops and joins the
//! threads.

use std::collections::VecDeque;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;

use dkrrt_collision::Obstacle;
use dkrrt_msg::{DebrisForecast, DebrisObs, DebrisObservation, Zeroed, MAX_DEBRIS};
use dkrrt_planner::predict::{Cadence, ObsCounters};
use dkrrt_predictor::GateStats;
use dkrrt_rrt::CycleClock;
use dkrrt_sim::debris::DebrisSide;

use crate::lockstep::PredictorLoop;

/// Ticks per batch.
pub const BATCH: usize = 25;
/// Batches the debris side may run ahead by (the pool holds two more, for the one being
/// filled and the one being read): 0.2 s of plant time at 1 kHz, so it keeps working through
/// a long planning cycle (32 did no better in dense).
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
    /// This tick's observation frames: `frames[first..first + count]` of the batch.
    frames_first: usize,
    frames_count: usize,
    /// The tick's stamp after the step and the planner's next cycle then (the predictor's
    /// read decision).
    now_ns: u64,
    next_cycle: Option<u64>,
    latest_deferred: bool,
    predictor: Option<PredictorSnapshot>,
}

struct Batch {
    ticks: Vec<WorldTick>,
    /// The observation frames the sensor sent during the batch (the world's thread to the
    /// predictor's), packed: each frame's header and its range of `items`.
    frames: Vec<(dkrrt_msg::Header, std::ops::Range<usize>)>,
    items: Vec<DebrisObs>,
    /// The frame the sensor's observations are drained into, and the predictor reads.
    scratch: Box<DebrisObservation>,
    forecasts: Vec<Box<DebrisForecast>>,
    used: usize,
    /// Each thread's allocations so far (the world's, the predictor's), when it handed the
    /// batch on (with the counting allocator installed; else 0).
    allocs: [u64; 2],
}

impl Batch {
    /// A batch with room for `frames` observation frames of `items` observations in all, and
    /// `forecasts` forecast copies (more are allocated if ever needed).
    fn new((frames, items): (usize, usize), forecasts: usize) -> Batch {
        let ticks = (0..BATCH)
            .map(|_| WorldTick {
                obstacles: Vec::with_capacity(MAX_DEBRIS),
                t: 0.0,
                observations: 0,
                observation_frames: 0,
                events_fired: 0,
                forecast: None,
                frames_first: 0,
                frames_count: 0,
                now_ns: 0,
                next_cycle: None,
                latest_deferred: false,
                predictor: None,
            })
            .collect();
        let forecasts = (0..forecasts).map(|_| Box::new(<DebrisForecast as Zeroed>::zeroed())).collect();
        Batch {
            ticks,
            frames: Vec::with_capacity(frames),
            items: Vec::with_capacity(items),
            scratch: Box::new(<DebrisObservation as Zeroed>::zeroed()),
            forecasts,
            used: 0,
            allocs: [0; 2],
        }
    }
}

/// A queue of batches from one thread to another, with room for every batch there is (no
/// allocation after [`Pipe::new`]). Closed, it hands out nothing more and takes nothing.
struct Pipe {
    q: Mutex<(VecDeque<Batch>, bool)>,
    ready: Condvar,
}

impl Pipe {
    fn new(room: usize) -> Arc<Pipe> {
        Arc::new(Pipe { q: Mutex::new((VecDeque::with_capacity(room), false)), ready: Condvar::new() })
    }

    fn lock(&self) -> MutexGuard<'_, (VecDeque<Batch>, bool)> {
        self.q.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Hands `b` on; `false` when closed.
    fn send(&self, b: Batch) -> bool {
        let mut g = self.lock();
        if g.1 {
            return false;
        }
        g.0.push_back(b);
        drop(g);
        self.ready.notify_one();
        true
    }

    /// The next batch, waiting for it; `None` when closed.
    fn recv(&self) -> Option<Batch> {
        let mut g = self.lock();
        loop {
            if g.1 {
                return None;
            }
            if let Some(b) = g.0.pop_front() {
                return Some(b);
            }
            g = self.ready.wait(g).unwrap_or_else(|e| e.into_inner());
        }
    }

    fn close(&self) {
        self.lock().1 = true;
        self.ready.notify_all();
    }
}

/// Closes its pipes when dropped: when a stage ends, returning or panicking, the stages
/// waiting on it stop too (and the arm's side reports it).
struct Closer(Vec<Arc<Pipe>>);

impl Drop for Closer {
    fn drop(&mut self) {
        self.0.iter().for_each(|p| p.close());
    }
}

/// The arm's side of a run ahead: the ticks in order, and the predictor's output as the
/// planner reads it.
pub struct Ahead {
    full: Arc<Pipe>,
    empty: Arc<Pipe>,
    mid: Arc<Pipe>,
    threads: Vec<JoinHandle<()>>,
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
    /// The threads' allocations as of the last batch read (allocation tests).
    pub thread_allocs: u64,
}

/// Frames and observations a batch has room for from the start: the sensor samples at most
/// 100 times a second (checked at start-up, [`dkrrt_debris::Sensor::new`]) at most
/// [`dkrrt_debris::MAX_DEBRIS`] objects (fragments included); a latency jitter releases a
/// sample's observations over several ticks (a frame each), and may release two samples' in
/// one tick.
fn room_per_batch(period_ns: u64) -> (usize, usize) {
    let samples = (BATCH as f64 * period_ns as f64 * 1e-9 * 100.0).ceil() as usize + 2;
    let per_tick = 2 * dkrrt_debris::MAX_DEBRIS.div_ceil(MAX_DEBRIS);
    (BATCH * per_tick, samples * dkrrt_debris::MAX_DEBRIS)
}

impl Ahead {
    /// Starts the threads with a debris side fresh from the scenario (at plant time 0), the
    /// predictor (if any), the planner's cadence (`None`: no planner reads forecasts) and the
    /// tick period.
    pub fn start(
        side: DebrisSide,
        predictor: Option<PredictorLoop>,
        cadence: Option<CycleClock>,
        period_ns: u64,
    ) -> Result<Ahead, String> {
        let pool = IN_FLIGHT + 2;
        let (full, empty, mid) = (Pipe::new(pool), Pipe::new(pool), Pipe::new(pool));
        // At most one forecast per `1 / rate` of plant time, so a batch holds at most this many
        // (one more for the rounding): allocated here, not while running.
        let per_batch = predictor
            .as_ref()
            .map_or(0, |p| (BATCH as f64 * period_ns as f64 * 1e-9 * p.rate_hz).ceil() as usize + 1);
        let room = if predictor.is_some() { room_per_batch(period_ns) } else { (0, 0) };
        for _ in 0..pool {
            empty.send(Batch::new(room, per_batch));
        }
        let spawn = |name: &str, f: Box<dyn FnOnce() + Send>| {
            std::thread::Builder::new()
                .name(name.into())
                .spawn(f)
                .map_err(|e| format!("lockstep: the {name} thread: {e}"))
        };
        let all = || Closer(vec![full.clone(), empty.clone(), mid.clone()]);
        // With a predictor, two stages: the world (step, sensor, posed obstacles) hands each
        // batch to the predictor, which hands it to the arm's side. A stage that ends closes
        // every pipe.
        let threads = (|| -> Result<Vec<JoinHandle<()>>, String> {
            Ok(match predictor {
                Some(p) => {
                    let (c1, c2) = (all(), all());
                    let (e, m1, m2, f) = (empty.clone(), mid.clone(), mid.clone(), full.clone());
                    vec![
                        spawn(
                            "debris-world",
                            Box::new(move || world(side, cadence, period_ns, true, &m1, &e, c1)),
                        )?,
                        spawn("debris-predict", Box::new(move || predict(p, &m2, &f, c2)))?,
                    ]
                }
                None => {
                    let (c, e, f) = (all(), empty.clone(), full.clone());
                    vec![spawn(
                        "debris-world",
                        Box::new(move || world(side, None, period_ns, false, &f, &e, c)),
                    )?]
                }
            })
        })();
        // A thread that could not start: the others stop at the closed pipes.
        let threads = threads.inspect_err(|_| drop(all()))?;
        Ok(Ahead {
            full,
            empty,
            mid,
            threads,
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

    /// The next tick (blocking until the threads have stepped it); its forecast, if one was
    /// written, becomes the fresh one.
    pub fn next_tick(&mut self) -> &WorldTick {
        if self.pos >= BATCH {
            if let Some(b) = self.cur.take() {
                self.empty.send(b);
            }
            self.cur =
                Some(self.full.recv().unwrap_or_else(|| panic!("lockstep: the debris thread stopped")));
            self.pos = 0;
        }
        let b = self.cur.as_ref().expect("a batch");
        self.thread_allocs = b.allocs[0] + b.allocs[1];
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
        // Closed pipes end the threads wherever they wait.
        for p in [&self.full, &self.empty, &self.mid] {
            p.close();
        }
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

/// The world's stage: steps the debris side tick by tick, poses the obstacles and, with
/// `frames`, keeps the sensor's frames and the planner's cadence for the predictor's stage.
fn world(
    mut side: DebrisSide,
    mut cadence: Option<CycleClock>,
    period_ns: u64,
    frames: bool,
    out: &Pipe,
    empty: &Pipe,
    _closer: Closer,
) {
    let dt = period_ns as f64 * 1e-9;
    let mut tick: u64 = 0;
    while let Some(mut b) = empty.recv() {
        (b.frames.clear(), b.items.clear());
        for w in b.ticks.iter_mut() {
            // The planner's cycle at this tick's stamp comes before the sim's step, as in
            // `Lockstep::tick`.
            let stamp = tick * period_ns;
            w.next_cycle = cadence.as_mut().map(|c| {
                c.due(stamp);
                c.next_ns
            });
            w.now_ns = stamp + period_ns;
            side.step(dt);
            side.obstacles_into(&mut w.obstacles);
            w.t = side.world().time();
            w.frames_first = b.frames.len();
            let _ = side.drain_observations::<()>(&mut b.scratch, |f| {
                if frames {
                    let first = b.items.len();
                    b.items.extend_from_slice(&f.items[..(f.count as usize).min(MAX_DEBRIS)]);
                    b.frames.push((f.header, first..b.items.len()));
                }
                Ok(())
            });
            w.frames_count = b.frames.len() - w.frames_first;
            (w.observations, w.observation_frames, w.events_fired) =
                (side.stats.observations, side.stats.observation_frames, side.stats.events_fired);
            w.forecast = None;
            w.latest_deferred = false;
            w.predictor = None;
            tick += 1;
        }
        b.allocs[0] = dkrrt_rt::alloc_count::AllocStats::now().allocs;
        if !out.send(b) {
            return;
        }
    }
}

/// The predictor's stage: feeds each tick's frames, as the serial lockstep does at that tick,
/// and keeps a copy of every forecast written.
fn predict(mut p: PredictorLoop, input: &Pipe, out: &Pipe, _closer: Closer) {
    while let Some(mut b) = input.recv() {
        b.used = 0;
        let Batch { ticks, frames, items, scratch, forecasts, used, .. } = &mut b;
        for w in ticks.iter_mut() {
            let mut written = false;
            for (header, range) in &frames[w.frames_first..w.frames_first + w.frames_count] {
                (scratch.header, scratch.count) = (*header, range.len() as u32);
                scratch.items[..range.len()].copy_from_slice(&items[range.clone()]);
                written |= matches!(p.feed(scratch, w.now_ns, w.next_cycle), Cadence::Written(_));
            }
            if written {
                if *used == forecasts.len() {
                    forecasts.push(Box::new(<DebrisForecast as Zeroed>::zeroed()));
                }
                *forecasts[*used] = *p.forecast;
                w.forecast = Some(*used);
                *used += 1;
            }
            w.latest_deferred = p.latest_deferred;
            w.predictor = Some(PredictorSnapshot {
                forecasts: p.forecasts,
                tracks: p.tracks,
                deferred: p.deferred,
                counters: p.core.counters,
                gate: *p.core.gate(),
            });
        }
        b.allocs[1] = dkrrt_rt::alloc_count::AllocStats::now().allocs;
        if !out.send(b) {
            return;
        }
    }
}
