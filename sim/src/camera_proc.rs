//! The sim process's camera (`[camera] enabled`): frames on `dkrrt/depth_image`.
//!
//! Real time: rendering a frame takes milliseconds, so it never runs in the 1 kHz loop. At a
//! due capture the loop leaves a [`Snapshot`] in a mailbox (`try_lock`: the loop never waits
//! for the camera; if the camera thread holds the mailbox that instant, the capture is taken
//! at the next tick) and publishes the plant time; the camera thread, with a node and
//! publisher of its own (ports are not `Send`), renders the snapshot and publishes each frame
//! once the plant clock passes its capture time + `latency_s`. The thread leaves the loop's
//! SCHED_FIFO priority and CPU pinning (it would inherit them) for the normal scheduler.
//!
//! Lockstep: the loop renders and publishes inline ([`CameraSide::tick`]), so the frames come
//! at the same plant times as in the in-process lockstep.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use dkrrt_config::{Mode, Scenario};
use dkrrt_model::NJ;
use dkrrt_msg::bus::{Bus, Pub};
use dkrrt_msg::{DepthImage, Source};
use dkrrt_rt::clock::mono_ns;
use dkrrt_rt::hist::{LatencyHist, Percentiles};

use crate::camera::{CameraSide, CameraStats, CaptureClock, Renderer, Snapshot};
use crate::debris::DebrisSide;

/// What the camera did in a run (the sim's report, `camera`).
#[derive(Debug, Clone, Copy, Default, serde::Serialize)]
pub struct CameraReport {
    pub rate_hz: f64,
    pub stats: CameraStats,
    /// Wall time to render one capture (every camera of the rig), µs.
    pub render_us: Percentiles,
}

/// The latest snapshot for the camera thread.
pub struct Mailbox {
    fresh: bool,
    snap: Snapshot,
}

/// The sim loop's side of the camera (one per process: the variants' sizes do not matter).
#[allow(clippy::large_enum_variant)]
pub enum SimCamera {
    /// Real time: a thread renders and publishes.
    Thread {
        clock: CaptureClock,
        mailbox: Arc<Mutex<Mailbox>>,
        plant_ns: Arc<AtomicU64>,
        stop: Arc<AtomicBool>,
        handle: JoinHandle<Result<CameraReport, String>>,
    },
    /// Lockstep: inline (the port is dropped before its node).
    Inline {
        side: CameraSide,
        renderers: Vec<Renderer>,
        snap: Box<Snapshot>,
        publ: Pub<DepthImage>,
        bus: Bus,
        render: Box<LatencyHist>,
    },
}

impl SimCamera {
    /// The camera of `sc` for run `run` (`None` when off or without debris). Allocates and
    /// starts the thread: start-up only.
    pub fn new(run: &str, sc: &Scenario) -> Result<Option<SimCamera>, String> {
        if !sc.camera_on() {
            return Ok(None);
        }
        let cfg = sc.camera;
        let base = sc.debris.base_lvlh;
        let side = CameraSide::new(&cfg)?;
        let renderers = Renderer::rig(&cfg, base)?;
        if sc.run.mode == Mode::Lockstep {
            let bus = Bus::new(run, "sim-camera").map_err(|e| e.to_string())?;
            let publ = bus.publisher::<DepthImage>(Source::Sim).map_err(|e| e.to_string())?;
            return Ok(Some(SimCamera::Inline {
                side,
                renderers,
                snap: Box::default(),
                publ,
                bus,
                render: Box::new(LatencyHist::new()),
            }));
        }
        let mailbox = Arc::new(Mutex::new(Mailbox { fresh: false, snap: Snapshot::default() }));
        let plant_ns = Arc::new(AtomicU64::new(0));
        let stop = Arc::new(AtomicBool::new(false));
        let (mb, pn, st, run) = (mailbox.clone(), plant_ns.clone(), stop.clone(), run.to_string());
        let handle = std::thread::Builder::new()
            .name("sim-camera".into())
            .spawn(move || camera_thread(&run, side, renderers, mb, pn, st))
            .map_err(|e| format!("sim: camera thread: {e}"))?;
        Ok(Some(SimCamera::Thread { clock: CaptureClock::new(cfg.rate_hz), mailbox, plant_ns, stop, handle }))
    }

    /// After the plant tick that reached plant time `t_ns`, with the arm at `q`.
    pub fn tick(&mut self, debris: &mut DebrisSide, q: &[f64; NJ], t_ns: u64) -> Result<(), String> {
        let t = t_ns as f64 * 1e-9;
        match self {
            SimCamera::Thread { clock, mailbox, plant_ns, .. } => {
                plant_ns.store(t_ns, Ordering::Release);
                if clock.due(t) {
                    if let Ok(mut m) = mailbox.try_lock() {
                        m.snap.take(debris, q);
                        m.fresh = true;
                        clock.taken(t);
                    }
                }
                Ok(())
            }
            SimCamera::Inline { side, renderers, snap, publ, render, .. } => {
                let t0 = mono_ns();
                let due = side.clock.due(t);
                side.tick(debris, q, snap, renderers, |m| publ.publish(m).map(|_| ()))
                    .map_err(|e| e.to_string())?;
                if due {
                    render.record_ns(mono_ns().saturating_sub(t0));
                }
                Ok(())
            }
        }
    }

    /// Frames published so far (lockstep: the gate waits until the predictor has read them;
    /// real time: not counted here, 0).
    pub fn published(&self) -> u64 {
        match self {
            SimCamera::Inline { publ, .. } => publ.next_seq(),
            SimCamera::Thread { .. } => 0,
        }
    }

    /// Stops the camera and reports what it did.
    pub fn finish(self) -> Result<CameraReport, String> {
        match self {
            SimCamera::Thread { stop, handle, .. } => {
                stop.store(true, Ordering::Release);
                handle.join().map_err(|_| "sim: the camera thread panicked".to_string())?
            }
            SimCamera::Inline { side, render, .. } => Ok(CameraReport {
                rate_hz: side.cfg.rate_hz,
                stats: side.stats,
                render_us: render.percentiles_us(),
            }),
        }
    }
}

fn camera_thread(
    run: &str,
    mut side: CameraSide,
    mut renderers: Vec<Renderer>,
    mailbox: Arc<Mutex<Mailbox>>,
    plant_ns: Arc<AtomicU64>,
    stop: Arc<AtomicBool>,
) -> Result<CameraReport, String> {
    // Spawned by the real-time loop: not at its priority, not on its CPU.
    dkrrt_rt::rtsetup::demote_current_thread();
    let bus = Bus::new(run, "sim-camera").map_err(|e| e.to_string())?;
    let mut publ = bus.publisher::<DepthImage>(Source::Sim).map_err(|e| e.to_string())?;
    let mut snap = Box::<Snapshot>::default();
    let mut render = LatencyHist::new();
    while !stop.load(Ordering::Acquire) {
        let fresh = {
            let mut m = mailbox.lock().map_err(|_| "sim: camera mailbox poisoned".to_string())?;
            let f = m.fresh;
            if f {
                m.fresh = false;
                (*snap).clone_from(&m.snap);
            }
            f
        };
        if fresh {
            let t0 = mono_ns();
            for r in renderers.iter_mut() {
                if let Some(out) = side.slot() {
                    r.render(&snap, out);
                }
                side.captured(snap.t_s);
            }
            render.record_ns(mono_ns().saturating_sub(t0));
        }
        let now = plant_ns.load(Ordering::Acquire) as f64 * 1e-9;
        side.deliver(now, |m| publ.publish(m).map(|_| ())).map_err(|e| e.to_string())?;
        std::thread::sleep(std::time::Duration::from_micros(500));
    }
    Ok(CameraReport { rate_hz: side.cfg.rate_hz, stats: side.stats, render_us: render.percentiles_us() })
}
