//! `dkrrt latency`: the latency and jitter suite. In one run, side by side:
//!
//! * a cyclictest-style **baseline** thread: the tracker's period and priority
//!   (`tracker.fifo_priority`, mlockall, 1 ns timer slack), absolute CLOCK_MONOTONIC deadlines,
//!   nothing else to do: what the machine gives a periodic thread;
//! * the **real process set** (`dkrrt launch` on the scenario, for the same duration): the
//!   tracker's wake-up latency and its state→command latency;
//! * a cross-process **iceoryx2 ping-pong** at 1 kHz for each message type we send
//!   (`RobotState`, `TorqueCommand`, `Trajectory`, `DebrisForecast`): through dkrrt's bus
//!   (`dkrrt_msg::bus`: validation, sequence bookkeeping, one copy each way) and through raw
//!   iceoryx2 publish-subscribe with the same payload types (`send_copy`, `receive`) as the
//!   reference. A child process (`dkrrt latency-echo`) answers every ping; one-way latency is
//!   the time from publishing to the reader seeing the sample (both busy-poll, as iceoryx2's
//!   own benchmarks do), on the one CLOCK_MONOTONIC both processes share;
//! * optional load: `cpu` (a busy thread per core, normal priority) or `io` (4 MiB writes with
//!   fsync, in a loop).
//!
//! Prints p50/p99/p99.9/max, writes `latency.json` and HdrHistogram-style percentile plots
//! (`latency-wake`, `latency-ipc`, SVG and PNG) into `--out`, says which real-time settings
//! were granted, and checks the targets (tracker wake p99.9 ≤ 1.1 × the baseline's; bus
//! one-way p50 ≤ 2 µs and p99 ≤ 2 × raw for the same type).

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use dkrrt_config::Scenario;
use dkrrt_msg::bus::{remove_run_leftovers, run_config, Bus, Pub, Sub, Topic};
use dkrrt_msg::*;
use dkrrt_rt::clock::{mono_ns, sleep_until, Pacer};
use dkrrt_rt::hist::{LatencyHist, Percentiles};
use dkrrt_rt::rtsetup::{self, RtOptions, RtReport};
use dkrrt_rt::signals;
use iceoryx2::node::Node;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::{ipc, ServiceName};
use serde_json::{json, Value};

/// Load to run beside the measurement.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Load {
    None,
    Cpu,
    Io,
}

impl Load {
    pub fn parse(s: &str) -> Result<Load, String> {
        match s {
            "none" => Ok(Load::None),
            "cpu" => Ok(Load::Cpu),
            "io" => Ok(Load::Io),
            _ => Err(format!("--load {s:?}: must be none, cpu or io")),
        }
    }
    fn name(self) -> &'static str {
        match self {
            Load::None => "none",
            Load::Cpu => "cpu",
            Load::Io => "io",
        }
    }
}

/// The ping-pong round starts at this phase of the millisecond, µs (after the plant's tick at
/// 0 and the tracker's at 50); its eight pings follow one another.
const FIRST_SLOT_US: u64 = 150;
/// A ping not answered within this long is a timeout (counted; the next leg is pinged), µs,
/// plus [`PONG_NS_PER_BYTE`] per byte of the message.
const PONG_TIMEOUT_US: u64 = 90;
/// A round trip copies its message four times (into the ping, out of it, into the pong, out
/// of it): allowed 2 ns per byte on top of [`PONG_TIMEOUT_US`] (0.5 GB/s, a debug build's
/// copies on a loaded VM). A 94 kB `DebrisForecast` answered in 91 µs, typical on this VM,
/// was counted unanswered with a flat 90 µs: 90 % of its raw round trips in one test run.
const PONG_NS_PER_BYTE: u64 = 2;

/// The message sizes, bytes, in [`TYPES`] order.
const SIZES: [usize; 4] = [
    std::mem::size_of::<RobotState>(),
    std::mem::size_of::<TorqueCommand>(),
    std::mem::size_of::<Trajectory>(),
    std::mem::size_of::<DebrisForecast>(),
];

/// How long the pinger waits for the pong of a message of `bytes`, ns.
const fn pong_timeout_ns(bytes: usize) -> u64 {
    PONG_TIMEOUT_US * 1000 + PONG_NS_PER_BYTE * bytes as u64
}
/// The echo starts polling this long before the round (its wake-up latency), µs.
const ECHO_LEAD_US: u64 = 40;
/// The echo stops polling at this phase of the millisecond if the round is not complete, µs.
const ROUND_END_US: u64 = 950;

/// The leg a round starts with: rotates every millisecond (the first ping of a round meets
/// cold caches; no leg should always be first). Both processes derive it from the shared
/// CLOCK_MONOTONIC grid.
fn first_leg(ms_deadline_ns: u64) -> usize {
    (ms_deadline_ns / 1_000_000 % (2 * TYPES.len() as u64)) as usize
}

/// The ping-pong threads run SCHED_FIFO this far below the tracker (when it has a priority):
/// they measure the transport, not the scheduler.
const PINGPONG_BELOW_TRACKER: u32 = 20;

/// The message types measured, in order.
pub const TYPES: [&str; 4] = ["RobotState", "TorqueCommand", "Trajectory", "DebrisForecast"];

/// One valid sample of each type (the bus validates what it carries).
fn samples(
    sc: &Scenario,
) -> Result<(RobotState, TorqueCommand, Box<Trajectory>, Box<DebrisForecast>), String> {
    let mut st = <RobotState as Zeroed>::zeroed();
    st.q = sc.sim.initial_q;
    let cmd = <TorqueCommand as Zeroed>::zeroed();
    let mut traj = Box::new(<Trajectory as Zeroed>::zeroed());
    let goal = sc.goal.q.unwrap_or(sc.sim.initial_q);
    let limits = dkrrt_otg::Limits { v_max: sc.motion.v_max, a_max: sc.motion.a_max, j_max: sc.motion.j_max };
    dkrrt_planner::goto::plan(
        &dkrrt_otg::KinState::rest(sc.sim.initial_q),
        &goal,
        &limits,
        1e-3,
        1,
        0,
        &mut traj,
    )
    .map_err(|e| format!("latency: a sample trajectory: {e:?}"))?;
    Ok((st, cmd, traj, sample_forecast(forecast_tracks(sc))))
}

/// Bytes of each measured sample the bus moves ([`UsedPart::used_bytes`]), in [`TYPES`] order.
fn used_sizes(sc: &Scenario) -> Result<[usize; 4], String> {
    let (st, cmd, traj, fc) = samples(sc)?;
    Ok([st.used_bytes(), cmd.used_bytes(), traj.used_bytes(), fc.used_bytes()])
}

/// Tracks in the measured forecast: one per object of the scenario's debris scene, as its
/// run's forecasts carry (the bus moves only the tracks a forecast uses); all 32 without debris.
fn forecast_tracks(sc: &Scenario) -> usize {
    let objects =
        if sc.has_debris() { sc.load_debris_scene().map_or(MAX_DEBRIS, |s| s.debris.len()) } else { 0 };
    if objects == 0 {
        MAX_DEBRIS
    } else {
        objects.min(MAX_DEBRIS)
    }
}

/// A valid forecast of `tracks` balls, every step of each filled.
fn sample_forecast(tracks: usize) -> Box<DebrisForecast> {
    let mut fc = Box::new(<DebrisForecast as Zeroed>::zeroed());
    (fc.count, fc.steps, fc.dt_s) = (tracks as u32, FORECAST_STEPS as u32, 0.1);
    for (i, tr) in fc.tracks.iter_mut().enumerate().take(tracks) {
        (tr.id, tr.bounding_radius, tr.shape) = (i as u32, 0.3, DebrisShape::sphere(0.3));
        for (k, st) in tr.steps.iter_mut().enumerate() {
            let p = [3.0 + i as f64, -2.0 + 0.01 * k as f64, 0.5];
            *st = ForecastStep {
                p,
                q: [1.0, 0.0, 0.0, 0.0],
                sigma_m: 0.01 * (k + 1) as f64,
                sigma_pos_m: 0.01 * (k + 1) as f64,
            };
        }
    }
    fc
}

// ---------------------------------------------------------------- legs

/// One ping-pong pair on the pinger's side.
trait PingLeg {
    /// Sends a ping; returns its send time.
    fn ping(&mut self) -> Result<u64, String>;
    /// Polls for the pong; `Some(publish time of the pong)`.
    fn pong(&mut self) -> Result<Option<u64>, String>;
}

/// One ping-pong pair on the echo's side.
trait EchoLeg {
    /// Polls for a ping; if there was one, answers it and returns the ping's publish time and
    /// when it was read (before the answer went out).
    fn echo(&mut self) -> Result<Option<(u64, u64)>, String>;
}

fn e(x: impl std::fmt::Display) -> String {
    x.to_string()
}

/// Through dkrrt's bus: `Pub::publish` / `Sub::latest` (validated).
struct BusLeg<T: Topic> {
    msg: Box<T>,
    tx: Pub<T>,
    rx: Sub<T>,
    lim: ContractLimits,
}

impl<T: Topic> PingLeg for BusLeg<T> {
    fn ping(&mut self) -> Result<u64, String> {
        self.tx.publish(&mut self.msg).map_err(e)?;
        Ok(self.msg.header().mono_ns)
    }
    fn pong(&mut self) -> Result<Option<u64>, String> {
        Ok(self.rx.latest(&mut self.msg, &self.lim).map_err(e)?.then(|| self.msg.header().mono_ns))
    }
}

impl<T: Topic> EchoLeg for BusLeg<T> {
    fn echo(&mut self) -> Result<Option<(u64, u64)>, String> {
        if !self.rx.latest(&mut self.msg, &self.lim).map_err(e)? {
            return Ok(None);
        }
        let got = (self.msg.header().mono_ns, mono_ns());
        self.tx.publish(&mut self.msg).map_err(e)?;
        Ok(Some(got))
    }
}

/// Raw iceoryx2: `send_copy` / `receive`, the same payload types, no validation.
struct RawLeg<T: Topic> {
    msg: Box<T>,
    tx: Publisher<ipc::Service, T, ()>,
    rx: Subscriber<ipc::Service, T, ()>,
}

impl<T: Topic> RawLeg<T> {
    fn send(&mut self) -> Result<u64, String> {
        let t = mono_ns();
        self.msg.header_mut().mono_ns = t;
        self.tx.send_copy(*self.msg).map_err(e)?;
        Ok(t)
    }
    fn recv(&mut self) -> Result<Option<u64>, String> {
        let mut got = None;
        while let Some(s) = self.rx.receive().map_err(e)? {
            *self.msg = *s.payload();
            got = Some(self.msg.header().mono_ns);
        }
        Ok(got)
    }
}

impl<T: Topic> PingLeg for RawLeg<T> {
    fn ping(&mut self) -> Result<u64, String> {
        self.send()
    }
    fn pong(&mut self) -> Result<Option<u64>, String> {
        self.recv()
    }
}

impl<T: Topic> EchoLeg for RawLeg<T> {
    fn echo(&mut self) -> Result<Option<(u64, u64)>, String> {
        let Some(sent) = self.recv()? else { return Ok(None) };
        let got = (sent, mono_ns());
        self.send()?;
        Ok(Some(got))
    }
}

fn raw_service<T: Topic>(
    node: &Node<ipc::Service>,
    dir: &str,
) -> Result<iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, T, ()>, String> {
    let name = ServiceName::new(&format!("dkrrt/latency/raw/{dir}/{}", T::SERVICE)).map_err(e)?;
    node.service_builder(&name)
        .publish_subscribe::<T>()
        .history_size(0)
        .subscriber_max_buffer_size(T::BUFFER)
        .enable_safe_overflow(true)
        .open_or_create()
        .map_err(e)
}

/// The legs of one side: (bus, raw) per type. `out` is the direction this side publishes in
/// (`ping` for the pinger), `ping_run`/`pong_run` the two bus runs (one service name per type
/// and run, so each direction needs its own run).
struct Side {
    bus: Vec<Box<dyn Both>>,
    raw: Vec<Box<dyn Both>>,
    _buses: (Bus, Bus),
}

trait Both: PingLeg + EchoLeg {}
impl<X: PingLeg + EchoLeg> Both for X {}

fn side(sc: &Scenario, ping_run: &str, pong_run: &str, pinger: bool) -> Result<Side, String> {
    let node = if pinger { "latency-ping" } else { "latency-echo" };
    let ping_bus = Bus::new(ping_run, node).map_err(e)?;
    let pong_bus = Bus::new(pong_run, node).map_err(e)?;
    let (tx_bus, rx_bus) = if pinger { (&ping_bus, &pong_bus) } else { (&pong_bus, &ping_bus) };
    let (tx_dir, rx_dir) = if pinger { ("ping", "pong") } else { ("pong", "ping") };
    let model = sc.load_arm().map_err(e)?;
    let lim = dkrrt_config::arm::contract_limits(&model);
    let (st, cmd, traj, fc) = samples(sc)?;
    fn bus_leg<T: Topic>(
        tx: &Bus,
        rx: &Bus,
        msg: Box<T>,
        lim: ContractLimits,
    ) -> Result<Box<dyn Both>, String> {
        msg.validate(&lim).map_err(|v| format!("latency: the {} sample is invalid: {v}", T::SERVICE))?;
        Ok(Box::new(BusLeg {
            msg,
            tx: tx.publisher::<T>(Source::User).map_err(e)?,
            rx: rx.subscriber::<T>().map_err(e)?,
            lim,
        }))
    }
    fn raw_leg<T: Topic>(
        node: &Node<ipc::Service>,
        tx: &str,
        rx: &str,
        msg: Box<T>,
    ) -> Result<Box<dyn Both>, String> {
        Ok(Box::new(RawLeg {
            msg,
            tx: raw_service::<T>(node, tx)?.publisher_builder().create().map_err(e)?,
            rx: raw_service::<T>(node, rx)?.subscriber_builder().create().map_err(e)?,
        }))
    }
    let bus = vec![
        bus_leg(tx_bus, rx_bus, Box::new(st), lim)?,
        bus_leg(tx_bus, rx_bus, Box::new(cmd), lim)?,
        bus_leg(tx_bus, rx_bus, traj.clone(), lim)?,
        bus_leg(tx_bus, rx_bus, fc.clone(), lim)?,
    ];
    let n = &ping_bus.node;
    let raw = vec![
        raw_leg(n, tx_dir, rx_dir, Box::new(st))?,
        raw_leg(n, tx_dir, rx_dir, Box::new(cmd))?,
        raw_leg(n, tx_dir, rx_dir, traj)?,
        raw_leg(n, tx_dir, rx_dir, fc)?,
    ];
    Ok(Side { bus, raw, _buses: (ping_bus, pong_bus) })
}

/// Figures of one leg.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize, Default)]
pub struct LegFigures {
    pub one_way_us: Percentiles,
    pub one_way_curve_us: Vec<(f64, f64)>,
    pub round_trip_us: Percentiles,
    pub timeouts: u64,
}

struct LegHists {
    one_way: LatencyHist,
    round_trip: LatencyHist,
    timeouts: u64,
}

impl LegHists {
    fn new() -> Self {
        LegHists { one_way: LatencyHist::new(), round_trip: LatencyHist::new(), timeouts: 0 }
    }
    fn figures(&self) -> LegFigures {
        LegFigures {
            one_way_us: self.one_way.percentiles_us(),
            one_way_curve_us: self.one_way.curve_us(),
            round_trip_us: self.round_trip.percentiles_us(),
            timeouts: self.timeouts,
        }
    }
}

/// What the echo process writes at exit: the one-way latency of the pings, per leg
/// (`bus` then `raw`, in [`TYPES`] order).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize, Default)]
pub struct EchoReport {
    pub bus: Vec<LegFigures>,
    pub raw: Vec<LegFigures>,
    pub echoed: u64,
    /// Pings answered but not measured: sent before the echo was polling for them.
    pub missed: u64,
}

/// The echo's bookkeeping of one round: which leg to poll, and when the round is over.
#[derive(Debug, Clone, Copy)]
struct EchoRound {
    /// When the echo started polling this round, ns.
    since: u64,
    legs: usize,
    /// This round's pings answered.
    n: usize,
    /// The leg whose ping should come next.
    expect: usize,
    turn: u64,
}

impl EchoRound {
    fn new(since: u64, first: usize, legs: usize) -> EchoRound {
        EchoRound { since, legs, n: 0, expect: first % legs, turn: 0 }
    }

    /// Every leg of the round answered.
    fn done(&self) -> bool {
        self.n >= self.legs
    }

    /// The legs to poll this turn: the expected one, and every 8th turn all of them (a lost
    /// ping or pong puts the two sides out of step).
    fn to_poll(&mut self) -> impl Iterator<Item = usize> {
        self.turn += 1;
        let (sweep, expect) = (self.turn.is_multiple_of(8), self.expect);
        (0..self.legs).filter(move |k| sweep || *k == expect)
    }

    /// A ping of leg `k` sent at `sent` was answered; whether it is this round's (to be
    /// measured). A stale one (a late ping of an earlier round) is answered, not measured, and
    /// does not count towards the round's end: counted, it would end the round one ping
    /// early, leave that ping to the next round, and so on every round after.
    fn answered(&mut self, k: usize, sent: u64) -> bool {
        if sent < self.since {
            return false;
        }
        self.n += 1;
        self.expect = (k + 1) % self.legs;
        true
    }
}

/// The `dkrrt latency-echo` process: answers every ping until SIGTERM or `seconds`.
pub fn echo(sc: &Scenario, ping_run: &str, pong_run: &str, seconds: f64, stats: &Path) -> Result<(), String> {
    signals::install();
    let rt = pingpong_rt(sc);
    for w in &rt.warnings {
        eprintln!("latency-echo: warning: {w}");
    }
    let mut s = side(sc, ping_run, pong_run, false)?;
    let mut bus: Vec<LegHists> = (0..TYPES.len()).map(|_| LegHists::new()).collect();
    let mut raw: Vec<LegHists> = (0..TYPES.len()).map(|_| LegHists::new()).collect();
    let mut pacer = Pacer::new(1_000_000, 0, 1_000_000);
    let end = mono_ns() + (seconds * 1e9) as u64;
    let (mut echoed, mut missed) = (0u64, 0u64);
    let legs = 2 * TYPES.len();
    while !signals::stop_requested() && mono_ns() < end {
        let ms = pacer.wait(signals::stop_requested).deadline_ns;
        // The round's pings come one after the other from FIRST_SLOT_US on. Poll the leg that
        // should be next, and every 8th turn all of them (a lost ping or pong puts the two
        // sides out of step). A ping sent before this window (a late echo) measures our sleep,
        // not the transport: answered (the pinger drops the answer), not recorded.
        sleep_until(ms + (FIRST_SLOT_US - ECHO_LEAD_US) * 1000, signals::stop_requested);
        let mut round = EchoRound::new(mono_ns(), first_leg(ms), legs);
        let window_end = ms + ROUND_END_US * 1000;
        while !round.done() && mono_ns() < window_end {
            for k in round.to_poll() {
                let (i, raw_leg) = (k / 2, k % 2 == 1);
                let (l, h) =
                    if raw_leg { (&mut s.raw[i], &mut raw[i]) } else { (&mut s.bus[i], &mut bus[i]) };
                if let Some((sent, read)) = l.echo()? {
                    echoed += 1;
                    if round.answered(k, sent) {
                        h.one_way.record_ns(read.saturating_sub(sent));
                    } else {
                        missed += 1;
                    }
                }
            }
        }
    }
    let rep = EchoReport {
        bus: bus.iter().map(LegHists::figures).collect(),
        raw: raw.iter().map(LegHists::figures).collect(),
        echoed,
        missed,
    };
    dkrrt_rt::write_stats("latency-echo", Some(stats), &rep)
}

/// The pinger: every millisecond from [`FIRST_SLOT_US`] on, one ping per leg in turn, each
/// waiting for its pong. Returns (bus, raw) figures: round trip and the pongs' one-way latency.
fn pinger(
    sc: &Scenario,
    ping_run: &str,
    pong_run: &str,
    stop: &AtomicBool,
) -> Result<(Vec<LegHists>, Vec<LegHists>, RtReport), String> {
    let rt = pingpong_rt(sc);
    let mut s = side(sc, ping_run, pong_run, true)?;
    let mut bus: Vec<LegHists> = (0..TYPES.len()).map(|_| LegHists::new()).collect();
    let mut raw: Vec<LegHists> = (0..TYPES.len()).map(|_| LegHists::new()).collect();
    let mut pacer = Pacer::new(1_000_000, 0, 2_000_000);
    // Rounds are measured once every leg has been answered in one round (the echo is up,
    // connected and in step); until then they only warm up.
    let (t0, mut warm) = (mono_ns(), false);
    while !stop.load(Ordering::Relaxed) {
        let ms = pacer.wait(|| stop.load(Ordering::Relaxed)).deadline_ns;
        if !warm && mono_ns() > t0 + 20_000_000_000 {
            return Err("latency: the echo process did not answer within 20 s".into());
        }
        let mut all = true;
        sleep_until(ms + FIRST_SLOT_US * 1000, || stop.load(Ordering::Relaxed));
        for j in 0..2 * TYPES.len() {
            let k = (first_leg(ms) + j) % (2 * TYPES.len());
            let (i, raw_leg) = (k / 2, k % 2 == 1);
            let (l, h) = if raw_leg { (&mut s.raw[i], &mut raw[i]) } else { (&mut s.bus[i], &mut bus[i]) };
            // A late pong of an earlier ping is not this ping's answer.
            while l.pong()?.is_some() {}
            let sent = l.ping()?;
            let mut got = false;
            while !got && mono_ns() < sent + pong_timeout_ns(SIZES[i]) {
                if let Some(pong_sent) = l.pong()?.filter(|p| *p >= sent) {
                    let now = mono_ns();
                    if warm {
                        h.round_trip.record_ns(now - sent);
                        h.one_way.record_ns(now - pong_sent);
                    }
                    got = true;
                }
            }
            if warm && !got {
                h.timeouts += 1;
            }
            all &= got;
        }
        warm |= all;
    }
    Ok((bus, raw, rt))
}

/// The ping-pong threads' real-time settings: SCHED_FIFO [`PINGPONG_BELOW_TRACKER`] below the
/// tracker's priority (normal scheduling if the tracker has none), 1 ns timer slack.
fn pingpong_rt(sc: &Scenario) -> RtReport {
    let prio = sc
        .tracker
        .fifo_priority
        .saturating_sub(PINGPONG_BELOW_TRACKER)
        .max(u32::from(sc.tracker.fifo_priority > 0));
    rtsetup::apply(&RtOptions::new(-1, prio, false))
}

/// The cyclictest-style baseline: wakes every `period` at `phase` with the given RT settings
/// until `stop`; returns its wake-up latencies and what was granted.
fn baseline(period_ns: u64, phase_ns: u64, rt: RtOptions, stop: &AtomicBool) -> (LatencyHist, RtReport) {
    let granted = rtsetup::apply(&rt);
    let mut h = LatencyHist::new();
    let mut pacer = Pacer::new(period_ns, phase_ns, 2_000_000);
    while !stop.load(Ordering::Relaxed) {
        let w = pacer.wait(|| stop.load(Ordering::Relaxed));
        h.record_ns(w.latency_ns());
    }
    (h, granted)
}

/// The load threads (normal priority) until `stop`.
fn start_load(load: Load, dir: &Path, stop: Arc<AtomicBool>) -> Vec<std::thread::JoinHandle<()>> {
    let mut v = Vec::new();
    match load {
        Load::None => {}
        Load::Cpu => {
            let n = std::thread::available_parallelism().map_or(2, |n| n.get());
            for i in 0..n {
                let stop = stop.clone();
                v.push(std::thread::spawn(move || {
                    let mut x = 1.0f64 + i as f64;
                    while !stop.load(Ordering::Relaxed) {
                        for _ in 0..10_000 {
                            x = (x * 1.000_001).sin() + 1.5;
                        }
                        std::hint::black_box(x);
                    }
                }));
            }
        }
        Load::Io => {
            let p = dir.join("load-io.tmp");
            v.push(std::thread::spawn(move || {
                use std::io::Write;
                let block = vec![0x5au8; 4 << 20];
                while !stop.load(Ordering::Relaxed) {
                    if let Ok(mut f) = std::fs::File::create(&p) {
                        for _ in 0..4 {
                            let _ = f.write_all(&block);
                        }
                        let _ = f.sync_all();
                    }
                }
                let _ = std::fs::remove_file(&p);
            }));
        }
    }
    v
}

fn row(name: &str, p: &Percentiles) -> String {
    format!(
        "  {name:<50} {:>9.1} {:>9.1} {:>9.1} {:>9.1}   ({} samples)",
        p.p50, p.p99, p.p999, p.max, p.count
    )
}

fn pct(v: &Value) -> Percentiles {
    serde_json::from_value(v.clone()).unwrap_or_default()
}

/// Runs the suite; returns the JSON written to `out/latency.json` and whether every target
/// was met.
pub fn run(sc: &Scenario, duration_s: f64, load: Load, out: &Path) -> Result<(Value, bool), String> {
    signals::install();
    std::fs::create_dir_all(out).map_err(|x| format!("--out {}: {x}", out.display()))?;
    if !(duration_s.is_finite() && duration_s >= 1.0 && duration_s <= 24.0 * 3600.0) {
        return Err(format!("--duration {duration_s}: must be within [1, 86400] s"));
    }
    let mut sc = sc.clone();
    sc.run.duration_s = duration_s;
    sc.run.mode = dkrrt_config::Mode::Realtime;
    if let Some(ep) = sc.episode.as_mut() {
        ep.duration_s = Some(duration_s);
    }
    let tag = crate::launch::random_hex(6);
    let (ping_run, pong_run) = (format!("lat{tag}a"), format!("lat{tag}b"));
    for r in [&ping_run, &pong_run] {
        run_config(r).map_err(e)?;
    }
    let dir = crate::launch::private_dir(&format!("lat{tag}"))?;
    let sc_path = dir.join("scenario.toml");
    // The echo needs the real-time settings only: without the episode it starts at once
    // (regenerating an episode can take seconds).
    let echo_sc = Scenario { episode: None, ..sc.clone() };
    crate::launch::write_private(&sc_path, &echo_sc.to_toml())?;
    let echo_stats = dir.join("echo.json");
    let exe = std::env::current_exe().map_err(e)?;
    let mut echo_child = std::process::Command::new(&exe)
        .arg("latency-echo")
        .arg("--scenario")
        .arg(&sc_path)
        .args(["--ping-run", &ping_run, "--pong-run", &pong_run])
        .arg("--seconds")
        .arg(format!("{}", duration_s + 60.0))
        .arg("--stats")
        .arg(&echo_stats)
        .stdin(std::process::Stdio::null())
        .spawn()
        .map_err(|x| format!("latency: start the echo process: {x}"))?;

    let stop = Arc::new(AtomicBool::new(false));
    let period = sc.period_ns();
    let rt_opts = RtOptions::new(sc.tracker.cpu, sc.tracker.fifo_priority, sc.tracker.mlockall);
    let base = {
        let stop = stop.clone();
        let phase = sc.tracker.phase_us * 1000;
        std::thread::spawn(move || baseline(period, phase, rt_opts, &stop))
    };
    let ping = {
        let (stop, sc, a, b) = (stop.clone(), sc.clone(), ping_run.clone(), pong_run.clone());
        std::thread::spawn(move || {
            let r = pinger(&sc, &a, &b, &stop);
            if r.is_err() {
                stop.store(true, Ordering::Relaxed);
            }
            r
        })
    };
    let loads = start_load(load, out, stop.clone());
    let set_report = dir.join("process-set.json");
    let launched = crate::launch::launch(crate::launch::LaunchOptions {
        scenario: sc.clone(),
        report: set_report.clone(),
        run: None,
        quiet: true,
        figures: None,
        record: None,
        driver: crate::launch::Driver::Sim,
    });
    stop.store(true, Ordering::Relaxed);
    for l in loads {
        let _ = l.join();
    }
    let (base_h, base_rt) = base.join().map_err(|_| "latency: the baseline thread panicked".to_string())?;
    let pinged = ping.join().map_err(|_| "latency: the ping thread panicked".to_string())?;
    // SAFETY: SIGTERM to our own child.
    unsafe { libc::kill(echo_child.id() as i32, libc::SIGTERM) };
    let _ = echo_child.wait();
    let echo_rep: EchoReport = std::fs::read_to_string(&echo_stats)
        .ok()
        .and_then(|t| serde_json::from_str(&t).ok())
        .ok_or_else(|| "latency: the echo process left no statistics".to_string())?;
    for r in [&ping_run, &pong_run] {
        if let Ok(c) = run_config(r) {
            let _ = Bus::remove_stale(&c);
        }
        remove_run_leftovers(r);
    }
    let _ = std::fs::remove_dir_all(&dir);
    let (set, set_ok) = launched?;
    let (ping_bus, ping_raw, ping_rt) = pinged?;
    if signals::stop_requested() {
        return Err("latency: stopped by a signal".into());
    }

    // Figures.
    let used = used_sizes(&sc)?;
    let label = |i: usize| {
        if used[i] == SIZES[i] {
            format!("{} ({} B)", TYPES[i], SIZES[i])
        } else {
            format!("{} ({} B, {} used)", TYPES[i], SIZES[i], used[i])
        }
    };
    let base_p = base_h.percentiles_us();
    let tr = &set["tracker"];
    let tr_wake = pct(&tr["wake_latency_us"]);
    let s2c = pct(&tr["state_to_command_us"]);
    let curve = |v: &Value| -> Vec<(f64, f64)> {
        v.as_array()
            .map(|a| a.iter().filter_map(|p| Some((p[0].as_f64()?, p[1].as_f64()?))).collect())
            .unwrap_or_default()
    };
    let mut ipc = Vec::new();
    for (i, name) in TYPES.iter().enumerate() {
        let leg = |echo: &LegFigures, ping: &LegHists| {
            json!({
                "one_way_us": echo.one_way_us,
                "one_way_back_us": ping.one_way.percentiles_us(),
                "round_trip_us": ping.round_trip.percentiles_us(),
                "timeouts": ping.timeouts,
                "one_way_curve_us": echo.one_way_curve_us,
            })
        };
        ipc.push(json!({
            "type": name,
            "bytes": SIZES[i],
            "used_bytes": used[i],
            "bus": leg(&echo_rep.bus[i], &ping_bus[i]),
            "raw": leg(&echo_rep.raw[i], &ping_raw[i]),
        }));
    }
    // Targets.
    let mut targets = Vec::new();
    let ratio = if base_p.p999 > 0.0 { tr_wake.p999 / base_p.p999 } else { f64::INFINITY };
    targets.push(json!({
        "name": "tracker wake p99.9 <= 1.1 x baseline p99.9",
        "value": ratio, "limit": 1.1, "met": ratio <= 1.1,
        "detail": format!("tracker {:.1} us vs baseline {:.1} us", tr_wake.p999, base_p.p999),
    }));
    for (i, name) in TYPES.iter().enumerate() {
        let (b, r) = (&echo_rep.bus[i].one_way_us, &echo_rep.raw[i].one_way_us);
        targets.push(json!({
            "name": format!("{name} one-way p50 <= 2 us"),
            "value": b.p50, "limit": 2.0, "met": b.p50 <= 2.0 && b.count > 0,
            "detail": format!("bus {:.2} us (raw {:.2} us)", b.p50, r.p50),
        }));
        let q = if r.p99 > 0.0 { b.p99 / r.p99 } else { f64::INFINITY };
        targets.push(json!({
            "name": format!("{name} one-way p99 <= 2 x raw"),
            "value": q, "limit": 2.0, "met": q <= 2.0 && b.count > 0,
            "detail": format!("bus {:.2} us vs raw {:.2} us", b.p99, r.p99),
        }));
    }
    let all_met = targets.iter().all(|t| t["met"] == true);
    let mut figures = Vec::new();
    let wake_panel = dkrrt_figures::CurvePanel {
        title: "wake-up latency (1 kHz, same priority)".into(),
        y_label: "latency [us]".into(),
        curves: vec![
            dkrrt_figures::Curve {
                name: "baseline thread".into(),
                points: base_h.curve_us(),
                color: 7,
                dashed: false,
            },
            dkrrt_figures::Curve {
                name: "tracker".into(),
                points: curve(&tr["wake_latency_curve_us"]),
                color: 0,
                dashed: false,
            },
        ],
    };
    let title = format!("dkrrt latency, {duration_s} s, load {}", load.name());
    figures.extend(dkrrt_figures::percentile_curves(&out.join("latency-wake"), &title, &[wake_panel])?);
    let ipc_panels: Vec<dkrrt_figures::CurvePanel> = (0..TYPES.len())
        .map(|i| dkrrt_figures::CurvePanel {
            title: format!("{} one-way", label(i)),
            y_label: "latency [us]".into(),
            curves: vec![
                dkrrt_figures::Curve {
                    name: "dkrrt bus".into(),
                    points: echo_rep.bus[i].one_way_curve_us.clone(),
                    color: 0,
                    dashed: false,
                },
                dkrrt_figures::Curve {
                    name: "raw iceoryx2".into(),
                    points: echo_rep.raw[i].one_way_curve_us.clone(),
                    color: 1,
                    dashed: false,
                },
            ],
        })
        .collect();
    figures.extend(dkrrt_figures::percentile_curves(
        &out.join("latency-ipc"),
        &format!("{title}: IPC"),
        &ipc_panels,
    )?);

    let report = json!({
        "duration_s": duration_s,
        "load": load.name(),
        "period_us": period as f64 / 1000.0,
        "rt": { "baseline": base_rt, "tracker": tr["rt"], "sim": set["sim"]["rt"], "ping_pong": ping_rt },
        "baseline_wake_us": base_p,
        "baseline_wake_curve_us": base_h.curve_us(),
        "tracker_wake_us": tr_wake,
        "state_to_command_us": s2c,
        "ipc": ipc,
        "targets": targets,
        "all_targets_met": all_met,
        "process_set": {
            "scenario": sc.name,
            "ok": set_ok,
            "stop_reason": set["stop_reason"],
            "ticks": set["ticks"],
            "deadline_misses": set["deadline_misses"],
        },
        "figures": figures.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
        "machine": { "cpus": std::thread::available_parallelism().map_or(0, |n| n.get()) },
    });
    let json_path = out.join("latency.json");
    std::fs::write(&json_path, serde_json::to_string_pretty(&report).map_err(e)?)
        .map_err(|x| format!("write {}: {x}", json_path.display()))?;

    // The printout.
    let granted = |r: &Value| {
        format!(
            "SCHED_FIFO {}, mlockall {}, timer slack 1 ns {}",
            if r["fifo"] == true { "granted" } else { "NOT granted" },
            if r["mlockall"] == true { "granted" } else { "NOT granted" },
            if r["timer_slack_1ns"] == true { "set" } else { "NOT set" }
        )
    };
    println!("dkrrt latency: {duration_s} s, load {}, period {} us", load.name(), period / 1000);
    println!("  real-time settings: baseline {}; tracker {}", granted(&json!(base_rt)), granted(&tr["rt"]));
    println!("  {:<50} {:>9} {:>9} {:>9} {:>9}", "latency [us]", "p50", "p99", "p99.9", "max");
    println!("{}", row("baseline thread wake-up", &base_p));
    println!("{}", row("tracker wake-up (process set)", &tr_wake));
    println!("{}", row("state -> command (process set)", &s2c));
    for (i, name) in TYPES.iter().enumerate() {
        println!("{}", row(&format!("{} one-way, bus", label(i)), &echo_rep.bus[i].one_way_us));
        println!("{}", row(&format!("{name} ({} B) one-way, raw", SIZES[i]), &echo_rep.raw[i].one_way_us));
        println!("{}", row(&format!("{name} round trip, bus"), &ping_bus[i].round_trip.percentiles_us()));
        println!("{}", row(&format!("{name} round trip, raw"), &ping_raw[i].round_trip.percentiles_us()));
    }
    let timeouts: u64 = ping_bus.iter().chain(&ping_raw).map(|h| h.timeouts).sum();
    if timeouts > 0 {
        println!("  unanswered pings (> {PONG_TIMEOUT_US} us + {PONG_NS_PER_BYTE} ns per byte): {timeouts}");
    }
    println!("  process set: {}", set["stop_reason"].as_str().unwrap_or("?"));
    let met = targets.iter().filter(|t| t["met"] == true).count();
    for t in &targets {
        println!(
            "  target {:<44} {}  ({})",
            t["name"].as_str().unwrap_or("?"),
            if t["met"] == true { "met" } else { "NOT met" },
            t["detail"].as_str().unwrap_or("")
        );
    }
    println!(
        "latency: {met} of {} targets met; tracker wake p99.9 {:.1} us vs baseline {:.1} us; RobotState one-way p50 {:.2} us (raw {:.2} us); {} and {} figures in {}",
        targets.len(),
        tr_wake.p999,
        base_p.p999,
        echo_rep.bus[0].one_way_us.p50,
        echo_rep.raw[0].one_way_us.p50,
        json_path.display(),
        figures.len(),
        out.display()
    );
    Ok((report, all_met))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stale_ping_neither_counts_nor_ends_the_round_early() {
        let mut r = EchoRound::new(1_000, 6, 8);
        // The expected leg first; all of them every 8th turn.
        assert_eq!(r.to_poll().collect::<Vec<_>>(), [6]);
        for _ in 0..6 {
            r.to_poll().for_each(drop);
        }
        assert_eq!(r.to_poll().count(), 8);
        // Last round's late ping of leg 5 turns up first: answered, not this round's.
        assert!(!r.answered(5, 999));
        assert_eq!(r.expect, 6);
        // This round's eight, in the pinger's order from leg 6.
        for j in 0..8 {
            assert!(!r.done(), "ended after {j}");
            assert!(r.answered((6 + j) % 8, 2_000 + j as u64));
        }
        assert!(r.done());
    }
}
