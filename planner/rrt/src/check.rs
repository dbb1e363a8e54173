//! Checking configurations, motions and rests against the world in time.
//!
//! **Why sampled checks are safe here.** Between two check times `Δt` apart, any point of the
//! arm moves at most `V_arm·Δt`, with `V_arm = Σ_i v_max,i · lever_i` (the joint speed limits
//! of the motion and each joint's lever arm, [`ArmPoser::lever_arms`]), and any point of an
//! obstacle's inflated surface moves at most `V_obs·Δt` (its forecast's largest
//! `|v| + ω·R + dσ/dt`, [`WorldInTime::max_speed`]). The separation is 1-Lipschitz in that
//! relative motion, so at any instant between two samples it is at least the smaller sampled
//! separation minus `(V_arm + V_obs)·Δt / 2`. The checker picks `Δt = δ / (V_arm + V_obs)` and
//! requires every sample to clear the obstacles inflated by `δ/2` more: nothing, however thin
//! or fast, slips between two samples. At rest `V_arm = 0`, so waits are sampled more sparsely.
//!
//! **Broad phase over the stretch.** Before sampling, the tracks that cannot come within the
//! clearance cap of the arm during the whole stretch are set aside ([`WorldInTime::near`]
//! against the sphere holding every point the arm can reach, or holding the resting arm):
//! they change neither the verdict nor the (capped) clearance, and `V_obs` is the largest
//! speed of the tracks kept, so a fast object far away no longer shortens every sample step.
//!
//! **A start inside the inflation.** The obstacles are inflated by the forecast's bound plus a
//! margin, so a newer forecast can put the arm *inside* an inflated obstacle while the object
//! itself is still away. Refusing every motion from there leaves the arm where the object is
//! coming. So a motion (or message) whose start has clearance `c₀ < 0` is checked with a
//! *relief* ([`Checker::relieve_start`]): until `t₀ + within_s` its samples need clearance
//! `≥ c₀ − deeper_m` only (it may not go much deeper than where it starts), after that `≥ 0`
//! as always. Such a motion leaves the inflation within `within_s`; a rest inside it fails.

use dkrrt_collision::{clearance, ArmPoser, Obstacle, PosedCapsule};
use dkrrt_model::{ArmModel, NJ};
use dkrrt_msg::MAX_DEBRIS;

use crate::world::{Near, WorldInTime};

/// Result of checking a stretch of time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Check {
    pub ok: bool,
    /// Smallest sampled clearance (beyond the inflation), capped at the checker's cap, m.
    pub min_clearance: f64,
    /// First failing time (if not ok), s.
    pub t_fail: f64,
    /// Samples checked.
    pub samples: u32,
}

impl Check {
    fn pass(cap: f64) -> Check {
        Check { ok: true, min_clearance: cap, t_fail: f64::NAN, samples: 0 }
    }
}

/// Configuration / motion checker (preallocated; allocation-free).
#[derive(Debug, Clone)]
pub struct Checker {
    poser: ArmPoser,
    caps: [PosedCapsule; NJ],
    obs: Vec<Obstacle>,
    arm_speed: f64,
    delta: f64,
    q_min: [f64; NJ],
    q_max: [f64; NJ],
    /// Sphere (centre, radius) holding every arm point at any configuration.
    reach: ([f64; 3], f64),
    /// The relief (floor, until) for a start inside the inflation (see the module docs).
    relief: Option<(f64, f64)>,
    /// Clearances above this are not measured exactly (reported as the cap), m.
    pub cap: f64,
    /// Configurations checked so far.
    pub configs_checked: u64,
}

impl Checker {
    /// `v_max`: the joint speed limits the checked motions respect; `delta_m`: the largest
    /// relative motion between two samples (see the module docs).
    pub fn new(model: ArmModel, v_max: &[f64; NJ], delta_m: f64) -> Checker {
        let l = model.limits();
        let (q_min, q_max) = (l.q_min.into(), l.q_max.into());
        let poser = ArmPoser::new(model);
        let arm_speed = poser.max_point_speed(v_max);
        let reach = poser.reach_sphere();
        Checker {
            poser,
            caps: [PosedCapsule::default(); NJ],
            obs: Vec::with_capacity(MAX_DEBRIS),
            arm_speed,
            delta: delta_m.max(1e-4),
            q_min,
            q_max,
            reach,
            relief: None,
            cap: 1.0,
            configs_checked: 0,
        }
    }

    pub fn poser(&self) -> &ArmPoser {
        &self.poser
    }

    /// Upper bound on the speed of any arm point, m/s.
    pub fn arm_speed(&self) -> f64 {
        self.arm_speed
    }

    /// The δ of the module docs, m.
    pub fn delta(&self) -> f64 {
        self.delta
    }

    fn in_limits(&self, q: &[f64; NJ]) -> bool {
        (0..NJ).all(|i| q[i].is_finite() && q[i] >= self.q_min[i] - 1e-9 && q[i] <= self.q_max[i] + 1e-9)
    }

    /// Clearance of configuration `q` at time `t` against the world inflated by `extra` more
    /// (negative: in collision; returned early below `stop_below`).
    pub fn clearance_at(
        &mut self,
        world: &WorldInTime,
        q: &[f64; NJ],
        t: f64,
        extra: f64,
        stop_below: f64,
    ) -> f64 {
        self.clearance_masked(world, q, t, extra, stop_below, u64::MAX)
    }

    /// [`Checker::clearance_at`] against the tracks in `mask` only ([`WorldInTime::near`]).
    fn clearance_masked(
        &mut self,
        world: &WorldInTime,
        q: &[f64; NJ],
        t: f64,
        extra: f64,
        stop_below: f64,
        mask: u64,
    ) -> f64 {
        self.configs_checked += 1;
        if !self.in_limits(q) {
            return -1.0;
        }
        self.poser.pose(q, &mut self.caps);
        let (centre, radius) = bounding_sphere(&self.caps);
        let near = Near { arm: &self.caps, centre: &centre, radius, cap: self.cap };
        world.obstacles_within(t, extra, mask, Some(near), &mut self.obs);
        clearance(&self.caps, &self.obs, stop_below, self.cap)
    }

    /// Sets the relief for checks of motions that start at `q` at time `t0` (module docs): when
    /// `q` is inside the inflation there (clearance `c₀ < 0`, with the samples' δ/2), samples
    /// until `t0 + within_s` need only `c₀ − deeper_m`; else no relief. Returns `c₀`. Every
    /// check until [`Checker::end_relief`] uses it.
    pub fn relieve_start(
        &mut self,
        world: &WorldInTime,
        q: &[f64; NJ],
        t0: f64,
        deeper_m: f64,
        within_s: f64,
    ) -> f64 {
        let c = self.clearance_at(world, q, t0, 0.5 * self.delta, f64::NEG_INFINITY);
        self.relief = (c < 0.0 && c.is_finite()).then_some((c - deeper_m.max(0.0), t0 + within_s.max(0.0)));
        c
    }

    /// Back to plain checks (clearance `≥ 0` everywhere).
    pub fn end_relief(&mut self) {
        self.relief = None;
    }

    /// The smallest clearance a sample at time `t` may have.
    fn floor_at(&self, t: f64) -> f64 {
        match self.relief {
            Some((floor, until)) if t < until => floor,
            _ => 0.0,
        }
    }

    /// The obstacle nearest to configuration `q` at time `t` and its clearance (diagnostics).
    pub fn nearest_at(&mut self, world: &WorldInTime, q: &[f64; NJ], t: f64) -> Option<(u32, f64)> {
        self.poser.pose(q, &mut self.caps);
        world.obstacles_at(t, 0.0, &mut self.obs);
        self.obs
            .iter()
            .map(|o| (o.id, clearance(&self.caps, std::slice::from_ref(o), f64::NEG_INFINITY, self.cap)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// Checks the motion `at(t)` over `[t0, t1]` (times past `t_end` are not checked: beyond
    /// the look-ahead nothing is known). `moving = false` for a rest (`at` constant).
    pub fn check(
        &mut self,
        world: &WorldInTime,
        t0: f64,
        t1: f64,
        t_end: f64,
        moving: bool,
        mut at: impl FnMut(f64) -> [f64; NJ],
    ) -> Check {
        let mut out = Check::pass(self.cap);
        let t1c = t1.min(t_end);
        if t1c < t0 {
            return out;
        }
        let half = 0.5 * self.delta;
        // Broad phase: the tracks that can come within the cap of the arm in [t0, t1c].
        let (centre, radius) = if moving {
            self.reach
        } else {
            self.poser.pose(&at(t0), &mut self.caps);
            bounding_sphere(&self.caps)
        };
        let (mask, v_obs) = world.near(t0, t1c, &centre, radius + self.cap, half);
        let v = v_obs + if moving { self.arm_speed } else { 0.0 };
        let dt_min = if v <= 1e-9 { 0.5 } else { (self.delta / v).min(0.5) };
        let mut t = t0;
        loop {
            let floor = self.floor_at(t);
            let c = if moving || out.samples == 0 {
                let q = at(t);
                self.clearance_masked(world, &q, t, half, floor, mask)
            } else {
                // At rest the arm's pose is already computed.
                self.configs_checked += 1;
                let near = Near { arm: &self.caps, centre: &centre, radius, cap: self.cap };
                world.obstacles_within(t, half, mask, Some(near), &mut self.obs);
                clearance(&self.caps, &self.obs, floor, self.cap)
            };
            out.samples += 1;
            out.min_clearance = out.min_clearance.min(c);
            if c < floor {
                out.ok = false;
                out.t_fail = t;
                return out;
            }
            if t >= t1c {
                break;
            }
            // Conservative advancement: with clearance c (beyond the δ/2 inflation) nothing can
            // close the gap faster than v, so the next δ/2-margin sample may wait c / v longer.
            // Under a relief the gap is to its floor until it ends, then to 0: either the gap to
            // the floor runs out first, or the samples may skip to its end (or as far as c
            // allows past it).
            let step = if v > 1e-9 {
                let until = self.relief.map_or(t, |r| r.1) - t;
                let free = if (c - floor) / v < until { (c - floor) / v } else { until.max(c / v) };
                dt_min.max(free + dt_min)
            } else {
                dt_min
            };
            t = (t + step).min(t1c);
        }
        out
    }
}

/// A sphere holding every capsule (centre: the mean of their centres).
fn bounding_sphere(caps: &[PosedCapsule]) -> ([f64; 3], f64) {
    let n = caps.len().max(1) as f64;
    let mut c = [0.0; 3];
    for k in caps {
        (0..3).for_each(|i| c[i] += k.centre[i] / n);
    }
    let r = caps
        .iter()
        .map(|k| {
            let d =
                ((k.centre[0] - c[0]).powi(2) + (k.centre[1] - c[1]).powi(2) + (k.centre[2] - c[2]).powi(2))
                    .sqrt();
            d + k.bound
        })
        .fold(0.0, f64::max);
    (c, r)
}
