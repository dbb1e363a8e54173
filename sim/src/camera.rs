//! The sim's depth camera, as a core: when a frame is due on the plant clock, what the camera
//! sees is taken as a [`Snapshot`] (the debris' true shapes and poses and the arm's link
//! capsules, a copy of a few kB with no allocation); a [`Renderer`] turns a snapshot into a
//! `DepthImage` message (the ray casting of `dkrrt_camera`, a few ms); the frame is delivered
//! `latency_s` after its capture ([`CameraSide::deliver`]).
//!
//! The snapshot splits the cheap part that belongs to the plant's tick from the expensive
//! part that must not run inside a 1 kHz loop: the in-process lockstep renders inline, a
//! real-time sim renders in a thread of its own. Both call these functions, so both deliver
//! the same frames at the same plant times.
//!
//! Frames: the world is in LVLH, the message in the arm's base frame (axes along LVLH), so
//! the camera at `camera.position_m` (base frame) sits at `position_m + debris.base_lvlh`.

use dkrrt_camera::scene::Object;
use dkrrt_camera::{Camera, CameraConfig, DepthFrame, Target};
use dkrrt_collision::PosedCapsule;
use dkrrt_model::NJ;
use dkrrt_msg::{DepthImage, Zeroed, DEPTH_MAX_INSTANCES, DEPTH_PIXELS};

use crate::debris::DebrisSide;

/// Objects a snapshot holds (the first ones of the world; more are not seen).
pub const MAX_SEEN: usize = 64;

/// What the camera sees at one capture: plant time, every object's shape and pose (LVLH),
/// the arm's capsules (LVLH).
#[derive(Clone)]
pub struct Snapshot {
    pub t_s: f64,
    /// (id, shape, position, attitude (w, x, y, z), bounding radius).
    pub objects: heapless::Vec<Object, MAX_SEEN>,
    /// The arm's link capsules (none: no arm in view).
    pub arm: heapless::Vec<PosedCapsule, NJ>,
}

impl Default for Snapshot {
    fn default() -> Self {
        Snapshot { t_s: f64::NAN, objects: heapless::Vec::new(), arm: heapless::Vec::new() }
    }
}

impl Snapshot {
    /// Takes the world's objects and the arm at `q` (the plant's true configuration) at the
    /// world's time. Shapes are shared (reference-counted), not copied: no allocation.
    pub fn take(&mut self, side: &mut DebrisSide, q: &[f64; NJ]) {
        self.of_world(side.world());
        self.arm.clear();
        for c in side.arm_capsules(q) {
            let _ = self.arm.push(*c);
        }
    }

    /// Takes the world's objects at its time, and no arm. No allocation.
    pub fn of_world(&mut self, world: &dkrrt_debris::DebrisWorld) {
        self.t_s = world.time();
        self.objects.clear();
        self.arm.clear();
        for d in world.debris().iter().take(MAX_SEEN) {
            let qq = d.state.q.quaternion();
            let _ = self.objects.push((
                d.id,
                d.props.shape.clone(),
                [d.state.p.x, d.state.p.y, d.state.p.z],
                [qq.w, qq.i, qq.j, qq.k],
                d.props.bounding_radius,
            ));
        }
    }
}

/// Renders snapshots into messages: the camera (placed in LVLH) and its scratch frame.
pub struct Renderer {
    camera: Camera,
    /// As configured: the pose in the arm's base frame.
    cfg: CameraConfig,
    frame: DepthFrame,
}

impl Renderer {
    /// A camera at `cfg`'s pose in the base frame, the base at `base_lvlh`. Allocates its
    /// buffers once.
    pub fn new(cfg: &CameraConfig, base_lvlh: [f64; 3]) -> Result<Renderer, String> {
        let p = cfg.position_m;
        let placed = CameraConfig {
            position_m: [p[0] + base_lvlh[0], p[1] + base_lvlh[1], p[2] + base_lvlh[2]],
            ..*cfg
        };
        let camera = Camera::new(placed).map_err(|e| e.to_string())?;
        Ok(Renderer { camera, cfg: *cfg, frame: DepthFrame::default() })
    }

    /// The renderers of `cfg`'s cameras ([`CameraConfig::rig`]: one, or a cube rig of six).
    pub fn rig(cfg: &CameraConfig, base_lvlh: [f64; 3]) -> Result<Vec<Renderer>, String> {
        cfg.rig().iter().map(|c| Renderer::new(c, base_lvlh)).collect()
    }

    /// Renders `snap` into `out` (stamped with the capture time; depth in mm, 0 = no return,
    /// farther than 65.535 m saturates). Allocation-free.
    pub fn render(&mut self, snap: &Snapshot, out: &mut DepthImage) {
        let mut targets: heapless::Vec<Target<'_>, MAX_SEEN> = heapless::Vec::new();
        for (id, shape, p, q, bound) in snap.objects.iter().take(DEPTH_MAX_INSTANCES) {
            let _ = targets.push(Target { id: *id, shape: shape.as_ref(), p: *p, q: *q, bound: *bound });
        }
        self.camera.render(&targets, &snap.arm, &mut self.frame);
        let f = &self.frame;
        let n = (f.width * f.height) as usize;
        out.header.stamp_ns = (snap.t_s.max(0.0) * 1e9).round() as u64;
        out.header.flags = 0;
        out.width = f.width;
        out.height = f.height;
        out.focal_px = self.camera.focal_px();
        (out.cx, out.cy) = self.camera.principal_point();
        out.position_m = self.cfg.position_m;
        out.orientation = self.cfg.orientation;
        out.range_min_m = self.cfg.range_min_m;
        out.range_max_m = self.cfg.range_max_m;
        out.n_instances = f.n_instances as u32;
        out.ids[..f.n_instances].copy_from_slice(&f.ids[..f.n_instances]);
        for (mm, &d) in out.depth_mm[..n].iter_mut().zip(&f.depth_m[..n]) {
            *mm = (d as f64 * 1000.0).round().clamp(0.0, u16::MAX as f64) as u16;
        }
        out.instance[..n].copy_from_slice(&f.instance[..n]);
        debug_assert!(n <= DEPTH_PIXELS);
    }
}

/// The capture times: every `1 / rate_hz` of plant time from 0 (a capture falls on the
/// first tick at or after its time).
#[derive(Debug, Clone, Copy)]
pub struct CaptureClock {
    rate_hz: f64,
    next: u64,
}

impl CaptureClock {
    pub fn new(rate_hz: f64) -> CaptureClock {
        CaptureClock { rate_hz, next: 0 }
    }

    /// Whether a capture is due at plant time `t_s`.
    pub fn due(&self, t_s: f64) -> bool {
        t_s + 1e-9 >= self.next as f64 / self.rate_hz
    }

    /// The capture due at `t_s` was taken: the next one is the first later grid time.
    pub fn taken(&mut self, t_s: f64) {
        while self.due(t_s) {
            self.next += 1;
        }
    }
}

/// The camera's frames in flight: each delivered `latency_s` after its capture, from a
/// preallocated ring; with [`CameraSide::tick`] the whole camera inline.
pub struct CameraSide {
    pub cfg: CameraConfig,
    pub clock: CaptureClock,
    /// Frames in flight: (delivery time, message), oldest at `head`.
    ring: Box<[(f64, DepthImage)]>,
    head: usize,
    len: usize,
    pub stats: CameraStats,
}

/// What the camera did.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct CameraStats {
    pub captured: u64,
    pub delivered: u64,
    /// Captures lost because more frames were in flight than the ring holds (never with a
    /// latency below the ring's span).
    pub overrun: u64,
}

impl CameraSide {
    /// The schedule of `cfg` (validated). Allocates the ring: `latency · rate + 2` captures
    /// of `faces` frames each.
    pub fn new(cfg: &CameraConfig) -> Result<CameraSide, String> {
        cfg.validate().map_err(|e| e.to_string())?;
        let slots = ((cfg.latency_s * cfg.rate_hz).ceil() as usize + 2) * cfg.faces as usize;
        let ring = (0..slots).map(|_| (f64::NAN, <DepthImage as Zeroed>::zeroed())).collect();
        Ok(CameraSide {
            cfg: *cfg,
            clock: CaptureClock::new(cfg.rate_hz),
            ring,
            head: 0,
            len: 0,
            stats: CameraStats::default(),
        })
    }

    /// The message the next capture renders into; `None` when the ring is full (an overrun is
    /// counted by [`CameraSide::captured`]).
    pub fn slot(&mut self) -> Option<&mut DepthImage> {
        if self.len == self.ring.len() {
            return None;
        }
        let i = (self.head + self.len) % self.ring.len();
        Some(&mut self.ring[i].1)
    }

    /// The capture at `t_s` is rendered into [`CameraSide::slot`] (or lost if there was
    /// none): it is delivered at `t_s + latency_s`.
    pub fn captured(&mut self, t_s: f64) {
        self.stats.captured += 1;
        if self.len == self.ring.len() {
            self.stats.overrun += 1;
            return;
        }
        let i = (self.head + self.len) % self.ring.len();
        self.ring[i].0 = t_s + self.cfg.latency_s;
        self.len += 1;
    }

    /// Hands every frame whose latency has elapsed by plant time `t_s` to `send`, oldest
    /// first. Returns how many.
    pub fn deliver<E>(
        &mut self,
        t_s: f64,
        mut send: impl FnMut(&mut DepthImage) -> Result<(), E>,
    ) -> Result<u32, E> {
        let mut n = 0;
        while self.len > 0 && self.ring[self.head].0 <= t_s + 1e-9 {
            let i = self.head;
            self.head = (self.head + 1) % self.ring.len();
            self.len -= 1;
            self.stats.delivered += 1;
            n += 1;
            send(&mut self.ring[i].1)?;
        }
        Ok(n)
    }

    /// The whole camera inline (the in-process lockstep, a lockstep sim): at the world's time
    /// with the arm at `q`, captures and renders (one frame per camera of the rig) if due,
    /// then delivers what is due. Allocation-free.
    pub fn tick<E>(
        &mut self,
        side: &mut DebrisSide,
        q: &[f64; NJ],
        snap: &mut Snapshot,
        renderers: &mut [Renderer],
        send: impl FnMut(&mut DepthImage) -> Result<(), E>,
    ) -> Result<u32, E> {
        let t = side.world().time();
        if self.clock.due(t) {
            self.clock.taken(t);
            snap.take(side, q);
            for r in renderers.iter_mut() {
                if let Some(out) = self.slot() {
                    r.render(snap, out);
                }
                self.captured(t);
            }
        }
        self.deliver(t, send)
    }
}
