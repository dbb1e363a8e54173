//! The debris world: fixed-capacity set of rigid bodies, allocation-free stepping, events.

use crate::body::{attitude_rk4, BodyProps, RigidState};
use crate::orbit::{ChiefState, RefOrbit};
use crate::scene::{EventSpec, PerturbationConfig, Scene, SceneError};
use crate::MAX_DEBRIS;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

/// One debris object in the world.
#[derive(Debug, Clone)]
pub struct Debris {
    /// Unique id.
    pub id: u32,
    /// Shape, mass, inertia.
    pub props: BodyProps,
    /// Current state.
    pub state: RigidState,
    /// Constant unmodelled acceleration (LVLH) [m/s²].
    pub bias_accel: Vector3<f64>,
    /// Current Gauss–Markov unmodelled acceleration (LVLH) [m/s²].
    pub noise_accel: Vector3<f64>,
}

/// A scheduled event, prepared at construction (fragment shapes pre-built: firing never allocates).
#[derive(Debug, Clone)]
enum Prepared {
    Impulse { id: u32, dv: Vector3<f64>, dw: Vector3<f64> },
    Split { id: u32, new_id: u32, props: BodyProps, offset: Vector3<f64>, dv: Vector3<f64>, w: Vector3<f64> },
}

/// Kind of an event that has fired.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FiredKind {
    /// Velocity / rate impulse.
    Impulse,
    /// Fragment split (with the new fragment's id).
    Split {
        /// Id of the new fragment.
        new_id: u32,
    },
}

/// Record of the last event that fired.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FiredEvent {
    /// World time at which it was applied [s].
    pub t: f64,
    /// Target (parent) id.
    pub id: u32,
    /// What happened.
    pub kind: FiredKind,
}

/// Debris world: reference orbit, up to [`MAX_DEBRIS`] bodies, scheduled events and
/// perturbations. [`DebrisWorld::step`] never allocates.
#[derive(Debug, Clone)]
pub struct DebrisWorld {
    orbit: RefOrbit,
    t: f64,
    max_substep: f64,
    debris: Vec<Debris>,
    events: Vec<(f64, Prepared)>,
    next_event: usize,
    perturb: PerturbationConfig,
    rng: SmallRng,
    fired: u32,
    last_fired: Option<FiredEvent>,
    /// Step only the object with this id ([`DebrisWorld::set_only`]).
    only: Option<u32>,
    /// Attitudes held where no split needs them ([`DebrisWorld::set_translation_only`]).
    translation_only: bool,
    /// The frame's state where it does not change with time: a circular reference orbit
    /// without J2 (radius, rates; the relative dynamics need nothing else then).
    steady_frame: Option<ChiefState>,
}

fn v3(a: [f64; 3]) -> Vector3<f64> {
    Vector3::new(a[0], a[1], a[2])
}

/// Standard normal sample (Box–Muller), allocation-free.
fn gauss(rng: &mut SmallRng) -> f64 {
    let u1: f64 = rng.random::<f64>().max(1e-300);
    let u2: f64 = rng.random::<f64>();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

impl DebrisWorld {
    /// Build a world from a (validated) scene at t = 0.
    pub fn new(scene: &Scene) -> Result<Self, SceneError> {
        scene.validate()?;
        let mut rng = SmallRng::seed_from_u64(scene.seed);
        let mut debris = Vec::with_capacity(MAX_DEBRIS);
        for (i, d) in scene.debris.iter().enumerate() {
            let props = BodyProps::new(&d.shape, d.mass, d.inertia).map_err(|e| SceneError::Invalid {
                field: format!("debris[{i}].{}", e.field),
                reason: e.reason,
            })?;
            let q = UnitQuaternion::new_normalize(Quaternion::new(d.q[0], d.q[1], d.q[2], d.q[3]));
            let s = scene.perturbation.accel_bias_sigma;
            let bias = Vector3::new(gauss(&mut rng), gauss(&mut rng), gauss(&mut rng)) * s;
            let n0 = scene.perturbation.accel_noise_sigma;
            let noise = Vector3::new(gauss(&mut rng), gauss(&mut rng), gauss(&mut rng)) * n0;
            debris.push(Debris {
                id: d.id,
                props,
                state: RigidState { p: v3(d.p), v: v3(d.v), q, w: v3(d.w) },
                bias_accel: bias,
                noise_accel: noise,
            });
        }
        let mut events = Vec::with_capacity(scene.events.len());
        for (i, e) in scene.events.iter().enumerate() {
            let p = match e {
                EventSpec::Impulse { id, dv, dw, .. } => {
                    Prepared::Impulse { id: *id, dv: v3(*dv), dw: v3(*dw) }
                }
                EventSpec::Split { id, new_id, fragment, mass, inertia, offset, dv, w, .. } => {
                    Prepared::Split {
                        id: *id,
                        new_id: *new_id,
                        props: BodyProps::new(fragment, *mass, *inertia).map_err(|e| {
                            SceneError::Invalid {
                                field: format!("events[{i}].fragment.{}", e.field),
                                reason: e.reason,
                            }
                        })?,
                        offset: v3(*offset),
                        dv: v3(*dv),
                        w: v3(*w),
                    }
                }
            };
            events.push((e.time(), p));
        }
        events.sort_by(|a, b| a.0.total_cmp(&b.0));
        Ok(DebrisWorld {
            orbit: RefOrbit::from_config(&scene.orbit),
            t: 0.0,
            max_substep: scene.integrator.max_substep,
            debris,
            events,
            next_event: 0,
            perturb: scene.perturbation,
            rng,
            fired: 0,
            last_fired: None,
            only: None,
            translation_only: false,
            steady_frame: {
                let o = RefOrbit::from_config(&scene.orbit);
                (o.e == 0.0 && !o.j2).then(|| o.at(0.0))
            },
        })
    }

    /// Current time [s].
    pub fn time(&self) -> f64 {
        self.t
    }
    /// Reference orbit of the module.
    pub fn orbit(&self) -> &RefOrbit {
        &self.orbit
    }
    /// Reference-orbit (LVLH frame) state now.
    pub fn chief(&self) -> ChiefState {
        self.orbit.at(self.t)
    }
    /// All debris objects (active ones only; fragments are appended when they split off).
    pub fn debris(&self) -> &[Debris] {
        &self.debris
    }
    /// Mutable access (e.g. to set states in tests or resets).
    pub fn debris_mut(&mut self) -> &mut [Debris] {
        &mut self.debris
    }
    /// Index of the object with `id`.
    pub fn index_of(&self, id: u32) -> Option<usize> {
        self.debris.iter().position(|d| d.id == id)
    }
    /// Maximum RK4 substep [s].
    pub fn max_substep(&self) -> f64 {
        self.max_substep
    }
    /// Set the maximum RK4 substep [s] (clamped to > 0).
    pub fn set_max_substep(&mut self, h: f64) {
        self.max_substep = h.max(1e-6);
    }
    /// Steps only the object `id` from now on (`None`: all of them, the default); the others
    /// keep their states. What the object does is exactly what it does in the whole world:
    /// no object acts on another, every random stream advances as if all were stepped (the
    /// others' draws are taken and dropped), and events fire as scheduled. For what depends
    /// on one object's motion alone (aiming it), at a fraction of the cost.
    pub fn set_only(&mut self, id: Option<u32>) {
        self.only = id;
    }
    /// Steps positions and velocities only, from now on (`false`: attitudes too, the
    /// default): the translation reads no attitude, so positions and velocities are exactly
    /// those of the whole world — except for an object a split event involves (the fragment is
    /// placed by its parent's attitude), whose attitude is still stepped. For what needs an
    /// object's position alone (aiming it), at about half the cost of a step.
    pub fn set_translation_only(&mut self, on: bool) {
        self.translation_only = on;
    }
    /// Number of events that have fired.
    pub fn events_fired(&self) -> u32 {
        self.fired
    }
    /// The most recent fired event.
    pub fn last_fired(&self) -> Option<FiredEvent> {
        self.last_fired
    }

    /// Apply an instantaneous impulse now (velocity change in LVLH, body-rate change in body axes).
    /// Returns false if `id` does not exist.
    pub fn apply_impulse(&mut self, id: u32, dv: Vector3<f64>, dw: Vector3<f64>) -> bool {
        match self.index_of(id) {
            Some(i) => {
                self.debris[i].state.v += dv;
                self.debris[i].state.w += dw;
                true
            }
            None => false,
        }
    }

    /// Inertial angular momentum of object `i`, ECI axes [kg m²/s] (conserved when torque-free).
    pub fn angular_momentum_eci(&self, i: usize) -> Vector3<f64> {
        let d = &self.debris[i];
        let c = self.chief();
        c.lvlh_to_eci * (d.state.q * (d.props.inertia * d.state.w))
    }

    fn fire_due_events(&mut self) {
        while self.next_event < self.events.len() && self.events[self.next_event].0 <= self.t + 1e-12 {
            let (_, ev) = &self.events[self.next_event];
            self.next_event += 1;
            match ev {
                Prepared::Impulse { id, dv, dw } => {
                    if let Some(i) = self.debris.iter().position(|d| d.id == *id) {
                        self.debris[i].state.v += dv;
                        self.debris[i].state.w += dw;
                        self.fired += 1;
                        self.last_fired = Some(FiredEvent { t: self.t, id: *id, kind: FiredKind::Impulse });
                    }
                }
                Prepared::Split { id, new_id, props, offset, dv, w } => {
                    let Some(i) = self.debris.iter().position(|d| d.id == *id) else { continue };
                    if self.debris.len() >= MAX_DEBRIS || props.mass >= self.debris[i].props.mass {
                        continue;
                    }
                    let parent = &mut self.debris[i];
                    let m_old = parent.props.mass;
                    let m_f = props.mass;
                    let m_new = m_old - m_f;
                    let r_off = parent.state.q * offset;
                    let frag_state = RigidState {
                        p: parent.state.p + r_off * (m_new / m_old),
                        v: parent.state.v + dv * (m_new / m_old),
                        q: parent.state.q,
                        w: *w,
                    };
                    // Centre of mass and linear momentum are conserved.
                    parent.state.p -= r_off * (m_f / m_old);
                    parent.state.v -= dv * (m_f / m_old);
                    // Parent keeps its shape; its mass and inertia scale with the mass lost.
                    parent.props.mass = m_new;
                    parent.props.inertia *= m_new / m_old;
                    parent.props.inv_inertia *= m_old / m_new;
                    let frag = Debris {
                        id: *new_id,
                        props: props.clone(), // Arc clone of the pre-built shape: no allocation
                        state: frag_state,
                        bias_accel: parent.bias_accel,
                        noise_accel: parent.noise_accel,
                    };
                    self.debris.push(frag); // capacity MAX_DEBRIS reserved: no reallocation
                    self.fired += 1;
                    self.last_fired =
                        Some(FiredEvent { t: self.t, id: *id, kind: FiredKind::Split { new_id: *new_id } });
                }
            }
        }
    }

    /// Advance by `dt` seconds with RK4 substeps of at most `max_substep`. Allocation-free.
    pub fn step(&mut self, dt: f64) {
        if !(dt > 0.0 && dt.is_finite()) {
            return;
        }
        let n = ((dt / self.max_substep).ceil() as usize).max(1);
        let h = dt / n as f64;
        for _ in 0..n {
            self.fire_due_events();
            self.substep(h);
        }
        self.fire_due_events();
    }

    fn substep(&mut self, h: f64) {
        // On a circular orbit without J2, r, ν̇ and ν̈ are the same at every time (ṙ = 0), and
        // the relative dynamics read nothing else: one state for all.
        let (c0, c1, c2) = match self.steady_frame {
            Some(c) => (c, c, c),
            None => (self.orbit.at(self.t), self.orbit.at(self.t + 0.5 * h), self.orbit.at(self.t + h)),
        };
        // Gauss–Markov update of the unmodelled accelerations (held constant over the substep).
        let sig = self.perturb.accel_noise_sigma;
        if sig > 0.0 {
            let phi = (-h / self.perturb.accel_noise_tau).exp();
            let s = sig * (1.0 - phi * phi).sqrt();
            for d in self.debris.iter_mut() {
                // Drawn for every object, so the stream is the same whichever are stepped.
                let g = Vector3::new(gauss(&mut self.rng), gauss(&mut self.rng), gauss(&mut self.rng));
                if self.only.is_some_and(|id| id != d.id) {
                    continue;
                }
                d.noise_accel = d.noise_accel * phi + g * s;
            }
        }
        let orbit = &self.orbit;
        for d in self.debris.iter_mut() {
            if self.only.is_some_and(|id| id != d.id) {
                continue;
            }
            let extra = d.bias_accel + d.noise_accel;
            let acc =
                |c: &ChiefState, p: &Vector3<f64>, v: &Vector3<f64>| orbit.relative_accel(c, p, v) + extra;
            let (p0, v0) = (d.state.p, d.state.v);
            let a1 = acc(&c0, &p0, &v0);
            let (p2, v2) = (p0 + v0 * (0.5 * h), v0 + a1 * (0.5 * h));
            let a2 = acc(&c1, &p2, &v2);
            let (p3, v3_) = (p0 + v2 * (0.5 * h), v0 + a2 * (0.5 * h));
            let a3 = acc(&c1, &p3, &v3_);
            let (p4, v4) = (p0 + v3_ * h, v0 + a3 * h);
            let a4 = acc(&c2, &p4, &v4);
            d.state.p = p0 + (v0 + v2 * 2.0 + v3_ * 2.0 + v4) * (h / 6.0);
            d.state.v = v0 + (a1 + a2 * 2.0 + a3 * 2.0 + a4) * (h / 6.0);
            let split = |e: &(f64, Prepared)| matches!(e.1, Prepared::Split { id, .. } if id == d.id);
            if !self.translation_only || self.events.iter().any(split) {
                attitude_rk4(&d.props, &mut d.state.q, &mut d.state.w, [c0.nu_dot, c1.nu_dot, c2.nu_dot], h);
            }
        }
        self.t += h;
    }
}
