//! Checking configurations, motions and rests against the world in time.
//!
//! **Why sampled checks are safe here.** Between two check times `Δt` apart, any point of the
//! arm moves at most `V_arm·Δt`, with `V_arm = Σ_i v_max,i · lever_i` (the joint speed limits
//! of the motion and each joint's lever arm, [`ArmPoser::lever_arms`]), and any point of an
//! obstacle's inflated surface moves at most `V_obs·Δt` (its forecast's largest
//! `|v| + ω·ℓ + dσ/dt`, ℓ the farthest its points lie from the turn's axis,
//! [`WorldInTime::max_speed`]). The separation is 1-Lipschitz in that
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
//! **Speeds from where the samples are.** No step is longer than `MAX_STEP_S` (0.5 s), so at
//! each sample a track's speeds are bounded over the next 0.5 s only (the forecast intervals
//! that window overlaps), not over the whole stretch: a fast interval elsewhere (a forecast
//! bound that jumps at some step, a problem obstacle's fast leg) spaces only the samples near
//! it. The broad phase still uses the whole stretch's. A check never takes more than
//! [`Checker::max_samples`] samples (200 000): one that would is not clear, so a check ends
//! whatever the obstacles' speeds.
//!
//! **Conservative advancement, per track and capsule, with two gaps.** Each sample gives, per
//! track and arm capsule, a lower bound on the gap to the track's inflated shape and one on
//! the gap to its bounding ball (about its centre, of radius its bounding radius plus `σ_pos`
//! plus the inflation: every obstacle built for it lies in that ball). The first closes at
//! most at the track's surface speed (its turn included) plus the capsule's speed
//! ([`ArmPoser::capsule_speeds`]: only the joints before it move it); the second at
//! `|v| + dσ_pos/dt` plus the capsule's ([`WorldInTime::ball_speed_within`]): a ball about the
//! centre turns into itself. The separation stays above both bounds, so the next sample may
//! wait for whichever lasts longer (then `δ / v` more, as above), over the pair that needs it
//! soonest. A tumbling rod whose ball stays clear of the arm no longer spaces the samples by
//! its spin, nor a track near the upper arm by the hand's speed.
//!
//! **A start inside the inflation.** The obstacles are inflated by the forecast's bound plus a
//! margin, so a newer forecast can put the arm *inside* an inflated obstacle while the object
//! itself is still away. Refusing every motion from there leaves the arm where the object is
//! coming. So a motion (or message) whose start has clearance `c₀ < 0` is checked with a
//! *relief* ([`Checker::relieve_start`]): until `t₀ + within_s` its samples need clearance
//! `≥ c₀ − deeper_m` only (it may not go much deeper than where it starts), after that `≥ 0`
//! as always. Such a motion leaves the inflation within `within_s`; a rest inside it fails.

use dkrrt_collision::{clearance, clearance_pairs, ArmPoser, Obstacle, PosedCapsule};
use dkrrt_model::{ArmModel, NJ};

use crate::world::{Gaps, Near, WorldInTime, MAX_TRACKS};

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
    /// The most samples one check takes: a motion that would need more is not clear (a
    /// guarantee that a check ends, whatever the obstacles' speeds; realistic checks take a
    /// few hundred).
    pub max_samples: u32,
    /// Checks that reached `max_samples` (not clear for that reason alone).
    pub capped: u64,
    /// A wall-clock time past which a check ends, not clear (looked at every
    /// [`DEADLINE_EVERY`] samples; `None`, the default: never, so that a run is the same
    /// whatever the machine's speed). For a search against a wall-clock time limit (`dkrrt
    /// plan`), whose checks of very slow motions can each take a long time.
    pub deadline: Option<std::time::Instant>,
    /// The last sample's gap per track ([`WorldInTime::obstacles_gapped`]).
    gaps: Gaps,
    /// The last sample's gap per track and capsule to its inflated shape (a lower bound; at
    /// least the ball's, [`Gaps::ball`]).
    pairs: [[f64; NJ]; MAX_TRACKS],
    /// The joint speed limits the checked motions respect (`check` of a moving arm), rad/s.
    v_max: [f64; NJ],
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
            obs: Vec::with_capacity(MAX_TRACKS),
            arm_speed,
            delta: delta_m.max(1e-4),
            q_min,
            q_max,
            reach,
            relief: None,
            cap: 1.0,
            configs_checked: 0,
            max_samples: MAX_SAMPLES,
            capped: 0,
            deadline: None,
            gaps: Gaps::default(),
            pairs: [[f64::INFINITY; NJ]; MAX_TRACKS],
            v_max: *v_max,
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
    /// the look-ahead nothing is known). `moving = false` for a rest (`at` constant). A moving
    /// arm is bounded by the joint speed limits ([`Checker::arm_speed`]); a motion known to be
    /// slower is better checked with [`Checker::check_motion`].
    pub fn check(
        &mut self,
        world: &WorldInTime,
        t0: f64,
        t1: f64,
        t_end: f64,
        moving: bool,
        at: impl FnMut(f64) -> [f64; NJ],
    ) -> Check {
        let v_max = self.v_max;
        self.check_joint_motion(world, t0, t1, t_end, moving.then_some(&v_max), at)
    }

    /// The speed bound of a motion whose joints move at most at `speed[j]` (rad/s): `Σ_j
    /// speed[j] · lever_j`, never above [`Checker::arm_speed`].
    pub fn motion_speed(&self, speed: &[f64; NJ]) -> f64 {
        self.poser.max_point_speed(speed).min(self.arm_speed)
    }

    /// The sphere (centre, radius) holding every arm point at any configuration.
    pub fn reach(&self) -> ([f64; 3], f64) {
        self.reach
    }

    /// The speed bound of any arm point when joint `j` moves at most at `speed[j]` (rad/s):
    /// `Σ_j speed[j] · lever_j`, whatever the joint speed limits.
    pub fn point_speed(&self, speed: &[f64; NJ]) -> f64 {
        self.poser.max_point_speed(speed)
    }

    /// [`Checker::check`] of a motion no point of which moves faster than `v_arm` m/s (`None`:
    /// a rest). The samples are spaced by `δ / (v_arm + V_obs)` (the module docs), and the
    /// broad phase holds the arm in its start pose's bounding sphere grown by `v_arm` times
    /// the stretch, when that is smaller than the sphere of all its reach.
    pub fn check_motion(
        &mut self,
        world: &WorldInTime,
        t0: f64,
        t1: f64,
        t_end: f64,
        v_arm: Option<f64>,
        at: impl FnMut(f64) -> [f64; NJ],
    ) -> Check {
        let v = v_arm.map(|v| v.clamp(0.0, self.arm_speed));
        self.check_inner(world, t0, t1, t_end, v.map(|v| (v, [v; NJ])), at)
    }

    /// [`Checker::check_motion`] of a motion whose joints move at most at `speed[j]` rad/s
    /// (`None`: a rest): each capsule's points at most at their own bound
    /// ([`ArmPoser::capsule_speeds`]), the whole arm at [`Checker::motion_speed`]. A capsule
    /// near the base moves slower than the hand: the samples near it are spaced by its speed.
    pub fn check_joint_motion(
        &mut self,
        world: &WorldInTime,
        t0: f64,
        t1: f64,
        t_end: f64,
        speed: Option<&[f64; NJ]>,
        at: impl FnMut(f64) -> [f64; NJ],
    ) -> Check {
        let arm = speed.map(|sp| {
            let v = self.motion_speed(sp);
            (v, self.poser.capsule_speeds(sp).map(|c| c.min(v)))
        });
        self.check_inner(world, t0, t1, t_end, arm, at)
    }

    /// The check, the arm moving at most at `arm.0` m/s and capsule `k` at `arm.1[k]`
    /// (`None`: at rest).
    fn check_inner(
        &mut self,
        world: &WorldInTime,
        t0: f64,
        t1: f64,
        t_end: f64,
        arm: Option<(f64, [f64; NJ])>,
        mut at: impl FnMut(f64) -> [f64; NJ],
    ) -> Check {
        let mut out = Check::pass(self.cap);
        let t1c = t1.min(t_end);
        if t1c < t0 {
            return out;
        }
        let moving = arm.is_some();
        let (v_arm, v_caps) = arm.unwrap_or((0.0, [0.0; NJ]));
        let half = 0.5 * self.delta;
        // Broad phase: the tracks that can come within the cap of the arm in [t0, t1c].
        self.poser.pose(&at(t0), &mut self.caps);
        let (mut centre, mut radius) = bounding_sphere(&self.caps);
        if moving {
            radius += v_arm * (t1c - t0);
            if radius >= self.reach.1 {
                (centre, radius) = self.reach;
            }
        }
        // Per track kept, how fast its surface and its bounding ball (no rotation: slower for
        // a tumbling shape) move; a gap to capsule `k` closes at most at that plus the
        // capsule's speed. The broad phase bounds them over the whole stretch; each step
        // below bounds them again over its own window.
        let mut closing = [0.0f64; MAX_TRACKS];
        let mask = world.near_speeds(t0, t1c, &centre, radius + self.cap, half, &mut closing);
        let mut closing_ball = [0.0f64; MAX_TRACKS];
        let mut t = t0;
        loop {
            let floor = self.floor_at(t);
            // At rest the arm's pose is computed once.
            let q = (moving || out.samples == 0).then(|| at(t));
            let c = self.sample(world, q.as_ref(), t, half, floor, mask);
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
            // Conservative advancement, per track: with clearance c (beyond the δ/2 inflation)
            // nothing closes that track's gap faster than its closing speed v, so the next
            // δ/2-margin sample may wait c / v + δ / v. Under a relief the gap is to its floor
            // until it ends, then to 0: either the gap to the floor runs out first, or the
            // samples may skip to its end (or as far as c allows past it). The nearest track
            // in time sets the step; a track far away no longer does, however fast.
            let until = self.relief.map_or(t, |r| r.1) - t;
            // The next step is at most `MAX_STEP_S`: the tracks' speeds over that window
            // bound them over it (a fast interval elsewhere in the stretch does not count).
            let ahead = (t + MAX_STEP_S).min(t1c);
            let mut m = mask;
            while m != 0 {
                let i = m.trailing_zeros() as usize;
                m &= m - 1;
                closing[i] = world.speed_within(i, t, ahead);
                closing_ball[i] = world.ball_speed_within(i, t, ahead);
            }
            let step = self.next_step(mask, &closing, &closing_ball, &v_caps, floor, until);
            if out.samples >= self.max_samples {
                // Not verified within the samples a check may take: not clear.
                self.capped += 1;
                out.ok = false;
                out.t_fail = t;
                return out;
            }
            if out.samples.is_multiple_of(DEADLINE_EVERY)
                && self.deadline.is_some_and(|d| std::time::Instant::now() >= d)
            {
                out.ok = false;
                out.t_fail = t;
                return out;
            }
            t = (t + step).min(t1c);
        }
        out
    }

    /// The step to the next sample of [`Checker::check_motion`] (its conservative advancement)
    /// from each track's gaps to each capsule at the last sample (to its inflated shape, and
    /// to its bounding ball) and their closing speeds: the track's surface's (`closing`) or
    /// ball's (`closing_ball`) plus the capsule's (`v_caps`).
    fn next_step(
        &self,
        mask: u64,
        closing: &[f64; MAX_TRACKS],
        closing_ball: &[f64; MAX_TRACKS],
        v_caps: &[f64; NJ],
        floor: f64,
        until: f64,
    ) -> f64 {
        // How long a gap `c` closing at `v` keeps the separation at or above the floor (0
        // after the relief ends `until` from now).
        let free = |c: f64, v: f64| {
            if v <= 1e-12 {
                return if c < floor {
                    0.0
                } else if c >= 0.0 {
                    f64::INFINITY
                } else {
                    until
                };
            }
            if (c - floor) / v < until {
                (c - floor) / v
            } else {
                until.max(c / v)
            }
        };
        let mut step = MAX_STEP_S;
        let mut m = mask;
        while m != 0 {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            for (k, vk) in v_caps.iter().enumerate() {
                let v = closing[i] + vk;
                if v <= 1e-9 {
                    continue;
                }
                // The separation stays above either gap's bound, whichever lasts longer.
                let vb = closing_ball[i] + vk;
                let f = free(self.pairs[i][k], v).max(free(self.gaps.ball[i][k], vb));
                step = step.min(f.max(0.0) + self.delta / v);
            }
        }
        step
    }

    /// One sample of [`Checker::check_motion`] at time `t`: the arm at `q` (posed anew; `None`:
    /// as posed last), its clearance from the tracks in `mask` inflated by `extra` more (below
    /// `floor`: returned as soon as found), and in `self.gaps` each track's gap to it.
    fn sample(
        &mut self,
        world: &WorldInTime,
        q: Option<&[f64; NJ]>,
        t: f64,
        extra: f64,
        floor: f64,
        mask: u64,
    ) -> f64 {
        self.configs_checked += 1;
        if let Some(q) = q {
            if !self.in_limits(q) {
                return -1.0;
            }
            self.poser.pose(q, &mut self.caps);
        }
        let (centre, radius) = bounding_sphere(&self.caps);
        let near = Near { arm: &self.caps, centre: &centre, radius, cap: self.cap };
        world.obstacles_gapped(t, extra, mask, Some(near), &mut self.obs, Some(&mut self.gaps));
        let mut m = mask;
        while m != 0 {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            self.pairs[i] = self.gaps.ball[i];
        }
        let mut c = self.cap;
        let mut per = [0.0; NJ];
        for (k, o) in self.obs.iter().enumerate() {
            let ck = clearance_pairs(&self.caps, o, floor, self.cap, &mut per);
            let i = self.gaps.track[k] as usize;
            for (p, d) in self.pairs[i].iter_mut().zip(per) {
                *p = p.max(d);
            }
            c = c.min(ck);
            if ck < floor {
                break;
            }
        }
        c
    }
}

/// The longest step between two samples of a check, s.
const MAX_STEP_S: f64 = 0.5;
/// A check looks at its [`Checker::deadline`] every this many samples.
pub const DEADLINE_EVERY: u32 = 4096;
/// The most samples one check takes by default ([`Checker::max_samples`]).
pub const MAX_SAMPLES: u32 = 200_000;

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
