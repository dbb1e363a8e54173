//! The simulator's debris side, as a plain core: the debris world advanced with the plant,
//! the sensor that observes it, and the arm-link vs debris contact check of every tick.
//!
//! Frames: the world lives in the module's LVLH frame; the arm base sits at
//! `debris.base_lvlh` with its axes along LVLH, so a base-frame point is
//! `p_lvlh − base_lvlh` and attitudes are the same in both. Messages carry base-frame poses.
//! Time: the world starts at plant time 0 and advances exactly one control period per
//! plant tick, so the world time *is* the plant time.
//!
//! Allocation-free after construction: [`DebrisSide::tick`] and
//! [`DebrisSide::drain_observations`] (tested with the counting allocator).

use dkrrt_collision::{descriptor_of, proximity, ArmPoser, ContactPair, Obstacle, PosedCapsule};
use dkrrt_config::Scenario;
use dkrrt_debris::{DebrisWorld, ObsBuffer, Sensor};
use dkrrt_model::{ArmModel, NJ};
use dkrrt_msg::{DebrisObs, DebrisObservation, DebrisShape, DEBRIS_HAS_VELOCITY, MAX_DEBRIS};
use serde::Serialize;

/// The first contact of a run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Contact {
    /// Plant time, s.
    pub t_s: f64,
    /// Arm link (0 = first moving link).
    pub link: usize,
    /// Debris id.
    pub debris_id: u32,
    /// Separation (≤ the contact margin), m.
    pub distance_m: f64,
}

/// What the debris side reports.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct DebrisStats {
    /// Objects at the start.
    pub objects: usize,
    /// Ticks checked.
    pub ticks_checked: u64,
    /// Smallest link–debris distance seen, m (`null` without debris).
    pub min_distance_m: Option<f64>,
    /// Plant time, link and debris of the smallest distance.
    pub min_distance_t_s: f64,
    pub min_distance_link: usize,
    pub min_distance_debris: u32,
    /// Ticks with at least one pair within the contact margin.
    pub contact_ticks: u64,
    /// The first contact (any contact is a collision: the run failed).
    pub first_contact: Option<Contact>,
    /// Scheduled events fired (impulses, splits).
    pub events_fired: u32,
    /// Observation records produced by the sensor / frames they were sent in.
    pub observations: u64,
    pub observation_frames: u64,
}

impl DebrisStats {
    /// A collision happened.
    pub fn collided(&self) -> bool {
        self.first_contact.is_some()
    }
}

/// Debris world + sensor + contact check, stepped with the plant.
pub struct DebrisSide {
    world: DebrisWorld,
    sensor: Sensor,
    obs: ObsBuffer,
    base: [f64; 3],
    margin: f64,
    poser: ArmPoser,
    capsules: [PosedCapsule; NJ],
    obstacles: Vec<Obstacle>,
    /// The contract shape descriptor per world index (what a perception driver would report).
    shapes: Vec<(u32, DebrisShape)>,
    contacts: [ContactPair; 8],
    /// Running figures.
    pub stats: DebrisStats,
    /// Smallest arm–debris separation at the last check, m (infinite before the first).
    pub distance_now_m: f64,
}

impl DebrisSide {
    /// Builds the scenario's debris world and sensor (allocates; not in the loop). `model` is
    /// the arm whose links are checked.
    pub fn new(sc: &Scenario, model: &ArmModel) -> Result<DebrisSide, String> {
        let scene = sc.load_debris_scene().map_err(|e| e.to_string())?;
        let world =
            DebrisWorld::new(&scene).map_err(|e| format!("debris.scene {:?}: {e}", sc.debris.scene))?;
        let sensor =
            Sensor::new(sc.sensor_config(), sc.debris.seed).map_err(|e| format!("debris sensor: {e}"))?;
        let objects = world.debris().len();
        let mut sensor = sensor;
        let mut obs = ObsBuffer::new();
        // The sensor's sample grid starts at plant time 0.
        let first = sensor.poll(0.0, world.debris(), &mut obs) as u64;
        Ok(DebrisSide {
            world,
            sensor,
            obs,
            base: sc.debris.base_lvlh,
            margin: sc.debris.contact_margin_m,
            poser: ArmPoser::with_offset(model.clone(), sc.debris.base_lvlh),
            capsules: [PosedCapsule::default(); NJ],
            obstacles: Vec::with_capacity(MAX_DEBRIS),
            shapes: Vec::with_capacity(MAX_DEBRIS),
            contacts: [ContactPair::default(); 8],
            stats: DebrisStats { objects, observations: first, ..DebrisStats::default() },
            distance_now_m: f64::INFINITY,
        })
    }

    /// The true future of this world for `ticks` more ticks of `dt` (for `oracle-rrt`; see
    /// [`crate::oracle`]), kept every `sample_ticks` ticks. Allocates: start-up only.
    pub fn truth_table(&self, dt: f64, ticks: u64, sample_ticks: u64) -> crate::oracle::TruthTable {
        crate::oracle::TruthTable::record(&self.world, dt, ticks, sample_ticks, self.base)
    }

    /// Every object's id and true position in the arm's base frame.
    pub fn positions(&self, mut f: impl FnMut(u32, [f64; 3])) {
        let b = self.base;
        for d in self.world.debris() {
            f(d.id, [d.state.p.x - b[0], d.state.p.y - b[1], d.state.p.z - b[2]]);
        }
    }

    /// The world (read-only).
    pub fn world(&self) -> &DebrisWorld {
        &self.world
    }

    /// The arm's link capsules at joint positions `q`, in LVLH.
    pub fn arm_capsules(&mut self, q: &[f64; NJ]) -> &[PosedCapsule; NJ] {
        self.poser.pose(q, &mut self.capsules);
        &self.capsules
    }

    /// Checks the arm at `q` against the true debris shapes at plant time `t` (the world's
    /// current time), with the same code as the planner's predicted checks. Returns true if a
    /// pair is within the contact margin. A non-finite `q` is not a state: it is not checked.
    pub fn check(&mut self, q: &[f64; NJ]) -> bool {
        if !q.iter().all(|x| x.is_finite()) {
            return false;
        }
        let mut obstacles = std::mem::take(&mut self.obstacles);
        self.obstacles_into(&mut obstacles);
        let hit = self.check_against(q, &obstacles, self.world.time());
        self.obstacles = obstacles;
        hit
    }

    /// The true debris shapes now, posed in LVLH, into `out` (what [`DebrisSide::check`]
    /// checks the arm against; at most [`MAX_DEBRIS`]). Allocation-free with `out`'s capacity.
    pub fn obstacles_into(&self, out: &mut Vec<Obstacle>) {
        out.clear();
        for d in self.world.debris() {
            let p = [d.state.p.x, d.state.p.y, d.state.p.z];
            let qq = d.state.q.quaternion();
            let o = Obstacle::from_shape(
                d.id,
                &d.props.shape,
                d.props.bounding_radius,
                &p,
                &[qq.w, qq.i, qq.j, qq.k],
            );
            if out.len() < out.capacity().min(MAX_DEBRIS) {
                out.push(o);
            }
        }
    }

    /// [`DebrisSide::check`] against `obstacles` (the world's, from
    /// [`DebrisSide::obstacles_into`] at plant time `t`, possibly of another copy of this
    /// side stepped elsewhere): the same measure, the same figures.
    pub fn check_against(&mut self, q: &[f64; NJ], obstacles: &[Obstacle], t: f64) -> bool {
        if !q.iter().all(|x| x.is_finite()) {
            return false;
        }
        self.poser.pose(q, &mut self.capsules);
        let mut pr = proximity(&self.capsules, obstacles, self.margin, &mut self.contacts);
        // Reported distances are separations: 0 when touching or overlapping (the closed-form
        // primitives measure a penetration, parry's hulls do not; one convention in reports).
        pr.min_distance = pr.min_distance.max(0.0);
        self.distance_now_m = pr.min_distance;
        let s = &mut self.stats;
        s.ticks_checked += 1;
        if pr.min_distance.is_finite() && s.min_distance_m.is_none_or(|m| pr.min_distance < m) {
            s.min_distance_m = Some(pr.min_distance);
            s.min_distance_t_s = t;
            s.min_distance_link = pr.link;
            s.min_distance_debris = pr.id;
        }
        if pr.any_contact() {
            s.contact_ticks += 1;
            if s.first_contact.is_none() {
                let c = self.contacts[0];
                s.first_contact =
                    Some(Contact { t_s: t, link: c.link, debris_id: c.id, distance_m: c.distance.max(0.0) });
            }
            return true;
        }
        false
    }

    /// The contract descriptor of object `id`'s true shape and its bounding radius.
    pub fn shape_of(&mut self, id: u32) -> (DebrisShape, f64) {
        shape_entry(&self.world, &mut self.shapes, id)
    }

    /// Advances the world by `dt` and lets the sensor sample (the observations become
    /// available after the sensor latency; collect them with [`Self::drain_observations`]).
    pub fn step(&mut self, dt: f64) {
        self.world.step(dt);
        self.stats.events_fired = self.world.events_fired();
        let t = self.world.time();
        self.stats.observations += self.sensor.poll(t, self.world.debris(), &mut self.obs) as u64;
    }

    /// One world tick: advances the debris by `dt`, checks the arm at `q` against them, and
    /// hands the sensor's due observation frames to `send` (the simulator's tick, and a
    /// driver's simulated perception on the measured arm). Allocation-free.
    pub fn tick<E>(
        &mut self,
        dt: f64,
        q: &[f64; NJ],
        frame: &mut DebrisObservation,
        send: impl FnMut(&mut DebrisObservation) -> Result<(), E>,
    ) -> Result<crate::core::TickReport, E> {
        self.step(dt);
        let first_contact = self.check(q) && self.stats.contact_ticks == 1;
        let frames = self.drain_observations(frame, send)?;
        Ok(crate::core::TickReport { first_contact, frames })
    }

    /// Moves the available observations into frames of at most [`MAX_DEBRIS`] items, calling
    /// `send` for each filled frame (`stamp_ns` = plant time now). Returns the frames sent.
    pub fn drain_observations<E>(
        &mut self,
        frame: &mut DebrisObservation,
        mut send: impl FnMut(&mut DebrisObservation) -> Result<(), E>,
    ) -> Result<u32, E> {
        let now_ns = (self.world.time() * 1e9).round() as u64;
        let mut sent = 0;
        // A sample that saw nothing is sent as an empty frame (when nothing else is sent now):
        // the predictor can then say the sky is empty rather than wait for a word.
        if self.sensor.take_empty_delivery() && self.obs.as_slice().is_empty() {
            frame.header.stamp_ns = now_ns;
            frame.header.flags = 0;
            frame.count = 0;
            send(frame)?;
            sent += 1;
        }
        let all = self.obs.as_slice();
        for chunk in all.chunks(MAX_DEBRIS) {
            frame.header.stamp_ns = now_ns;
            frame.header.flags = 0;
            frame.count = chunk.len() as u32;
            for (item, o) in frame.items.iter_mut().zip(chunk) {
                let (shape, radius) = shape_entry(&self.world, &mut self.shapes, o.id);
                *item = DebrisObs {
                    id: o.id,
                    flags: if o.has_rates { DEBRIS_HAS_VELOCITY } else { 0 },
                    t_meas_ns: (o.t.max(0.0) * 1e9).round() as u64,
                    p: [o.p[0] - self.base[0], o.p[1] - self.base[1], o.p[2] - self.base[2]],
                    q: o.q,
                    v: o.v,
                    w: o.w,
                    bounding_radius: radius,
                    shape,
                };
            }
            send(frame)?;
            sent += 1;
        }
        self.obs.clear();
        self.stats.observation_frames += sent as u64;
        Ok(sent)
    }
}

/// Descriptor (cached per id: the hull's box is computed once) and bounding radius of `id`.
fn shape_entry(world: &DebrisWorld, cache: &mut Vec<(u32, DebrisShape)>, id: u32) -> (DebrisShape, f64) {
    let Some(i) = world.index_of(id) else { return (DebrisShape::default(), 0.0) };
    let d = &world.debris()[i];
    let r = d.props.bounding_radius;
    if let Some(e) = cache.iter().find(|e| e.0 == id) {
        return (e.1, r);
    }
    let desc = descriptor_of(d.props.shape.as_ref());
    if cache.len() < cache.capacity() {
        cache.push((id, desc));
    }
    (desc, r)
}
