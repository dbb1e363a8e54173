//! The controller core: computed-torque tracking of a [`Trajectory`] message,
//! with safe hold (brake to rest within the limits, then hold) when the state
//! goes stale or the trajectory is invalid.
//!
//! τ = M(q)(q̈d + Kd ė + Kp e) + C(q, q̇) q̇ + g(q)
//!
//! Delay compensation: a command computed from state `k` acts from tick `k+1`
//! to `k+2` (see the plant's timing contract). With `predict` on, the law is
//! evaluated at the model's prediction of state `k+1` (forward dynamics under
//! the previous command), against the reference at `t_{k+1}`, with the mean
//! reference acceleration over the interval the torque acts.

use dkrrt_model::{ArmModel, JVec, NJ};
use dkrrt_msg::{ControllerMode, Trajectory, Zeroed};
use dkrrt_otg::{KinState, Limits, Options};

/// Controller options (from the scenario's `[tracker]` and `[motion]` tables).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackerConfig {
    pub kp: [f64; NJ],
    pub kd: [f64; NJ],
    /// A state older than this many ticks is stale.
    pub stale_ticks: u32,
    /// Tick length, s.
    pub dt: f64,
    pub predict: bool,
    /// Limits the brake-to-rest respects.
    pub limits: Limits<NJ>,
    /// A new trajectory must start within this distance of the current reference, rad.
    pub max_start_jump: f64,
    /// A spliced trajectory (one whose `start_ns` lies ahead) must continue the reference it
    /// replaces at `start_ns` within these tolerances: position (rad), velocity (rad/s),
    /// acceleration (rad/s²).
    pub splice_tol: [f64; 3],
    /// A measured position further than this from the reference (any joint, rad) means the
    /// arm is not where the reference is (a plant brake, a push, a stall): the controller
    /// re-anchors a brake to rest at the measured state instead of pulling the arm back.
    pub max_track_error: f64,
}

impl TrackerConfig {
    pub fn from_scenario(sc: &dkrrt_config::Scenario) -> Self {
        TrackerConfig {
            kp: sc.tracker.kp,
            kd: sc.tracker.kd,
            stale_ticks: sc.tracker.stale_ticks,
            dt: sc.period_ns() as f64 * 1e-9,
            predict: sc.tracker.predict,
            limits: Limits { v_max: sc.motion.v_max, a_max: sc.motion.a_max, j_max: sc.motion.j_max },
            max_start_jump: 0.05,
            splice_tol: SPLICE_TOL,
            max_track_error: sc.tracker.max_track_error_rad,
        }
    }
}

/// Default splice tolerances (p rad, v rad/s, a rad/s²): a planner splices at the exact state of
/// the current reference, so only floating-point differences are allowed.
pub const SPLICE_TOL: [f64; 3] = [1e-6, 1e-6, 1e-5];

/// Why the controller changed mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Reason {
    FirstState,
    NewTrajectory,
    TrajectoryComplete,
    StaleState,
    InvalidTrajectory,
    BrakeComplete,
    /// A queued trajectory took over at its `start_ns`.
    Splice,
    /// A queued trajectory did not continue the reference at its `start_ns` (not followed).
    SpliceRejected,
    /// A controlled stop of the run ([`Tracker::stop`]): brake to rest, then hold.
    Stop,
    /// The plant's brakes engaged while the reference moved (its command watchdog fired):
    /// brake to rest from where the arm is, then hold there.
    PlantBrake,
    /// The measured position left the reference by more than `max_track_error`: brake to
    /// rest from where the arm is, then hold there.
    TrackingError,
}

impl Reason {
    /// A safe-hold reason: the controller braked because something went wrong (not a normal
    /// switch such as a new trajectory, its completion or a controlled stop).
    pub fn is_safe_hold(self) -> bool {
        matches!(
            self,
            Reason::StaleState
                | Reason::InvalidTrajectory
                | Reason::SpliceRejected
                | Reason::PlantBrake
                | Reason::TrackingError
        )
    }
}

/// A mode switch, reported by the tick that made it.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ModeEvent {
    pub tick: u64,
    pub plant_ns: u64,
    #[serde(serialize_with = "ser_mode")]
    pub from: ControllerMode,
    #[serde(serialize_with = "ser_mode")]
    pub to: ControllerMode,
    pub reason: Reason,
}

fn ser_mode<S: serde::Serializer>(m: &ControllerMode, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(match m {
        ControllerMode::Idle => "idle",
        ControllerMode::Track => "track",
        ControllerMode::Brake => "brake",
        ControllerMode::Hold => "hold",
    })
}

/// A measured state handed to [`Tracker::tick`]: `(seq, stamp_ns, q, qd, brakes_engaged)`,
/// the last being the plant's `FLAG_BRAKE_ENGAGED`.
pub type StateIn<'a> = (u64, u64, &'a [f64; NJ], &'a [f64; NJ], bool);

/// The command of one tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TickOutput {
    pub tau: [f64; NJ],
    /// The reference position and velocity for the tick the command acts in (servo-mode arms
    /// track these with their own servo); the measured position at rest when idle.
    pub q_set: [f64; NJ],
    pub qd_set: [f64; NJ],
    pub mode: ControllerMode,
    /// Seq of the state this answers (the newest received).
    pub state_seq: u64,
    /// Plant time the command was computed for, ns.
    pub plant_ns: u64,
    pub event: Option<ModeEvent>,
}

/// Tracking-error accumulators (over ticks with a fresh state and a reference).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ErrorStats {
    pub sum_sq: f64,
    pub n: u64,
    pub max_abs: f64,
    pub last_abs: f64,
}

impl ErrorStats {
    /// RMS over joints and ticks, rad.
    pub fn rms(&self) -> f64 {
        if self.n == 0 {
            0.0
        } else {
            (self.sum_sq / (self.n as f64 * NJ as f64)).sqrt()
        }
    }
}

/// Counters of the controller.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CtrlStats {
    pub ticks: u64,
    pub stale_ticks: u64,
    pub safe_hold_entries: u64,
    pub trajectories_accepted: u64,
    pub trajectories_rejected: u64,
    /// Trajectories queued for a later `start_ns`, and how many of them took over.
    pub splices_queued: u64,
    pub splices_taken: u64,
    /// Trajectories offered after a controlled stop (not followed).
    pub ignored_after_stop: u64,
    /// Times the reference was re-anchored at the measured state (plant brakes, tracking
    /// error); those that interrupted a tracked motion also count as safe holds.
    pub reanchors: u64,
    pub track: ErrorStats,
}

/// The computed-torque controller. All state is preallocated at construction;
/// [`Tracker::tick`] and [`Tracker::set_trajectory`] allocate nothing.
pub struct Tracker {
    model: ArmModel,
    cfg: TrackerConfig,
    mode: ControllerMode,
    traj: Box<Trajectory>,
    brake: dkrrt_otg::Trajectory<NJ>,
    brake_start_ns: u64,
    hold_q: [f64; NJ],
    last_state: Option<(u64, u64, JVec, JVec)>, // (seq, stamp_ns, q, qd)
    /// `traj` arrived before the first state: its start is checked on the tick after it.
    traj_pending: bool,
    /// A trajectory whose `start_ns` lies ahead: it takes over then (splice).
    queued: Box<Trajectory>,
    ticks_since_state: u32,
    prev_tau: JVec,
    tick: u64,
    /// A controlled stop was asked for: brake to rest, hold, follow nothing new.
    stopping: bool,
    /// The newest state said the plant's brakes are engaged (they are at power-up).
    plant_braked: bool,
    /// The brakes engaged under a moving reference and are still engaged: the reference
    /// follows the measured arm until they release.
    follow_brake: bool,
    pub stats: CtrlStats,
}

impl Tracker {
    pub fn new(model: ArmModel, cfg: TrackerConfig) -> Tracker {
        Tracker {
            model,
            cfg,
            mode: ControllerMode::Idle,
            traj: Box::new(<Trajectory as Zeroed>::zeroed()),
            brake: dkrrt_otg::Trajectory::hold(&KinState::rest([0.0; NJ])),
            brake_start_ns: 0,
            hold_q: [0.0; NJ],
            last_state: None,
            traj_pending: false,
            queued: Box::new(<Trajectory as Zeroed>::zeroed()),
            ticks_since_state: 0,
            prev_tau: JVec::zeros(),
            tick: 0,
            stopping: false,
            plant_braked: true,
            follow_brake: false,
            stats: CtrlStats::default(),
        }
    }

    pub fn mode(&self) -> ControllerMode {
        self.mode
    }

    pub fn active_traj_id(&self) -> u64 {
        if self.mode == ControllerMode::Track {
            self.traj.traj_id
        } else {
            0
        }
    }

    /// End position of the last accepted trajectory (the goal), if any.
    pub fn goal(&self) -> Option<[f64; NJ]> {
        (self.traj.traj_id != 0 && !self.traj_pending).then(|| self.traj.sample(self.traj.duration_s).p)
    }

    /// Plant time of the current tick (extrapolated while the state is stale).
    fn plant_ns(&self) -> u64 {
        match self.last_state {
            Some((_, stamp, _, _)) => {
                stamp + (self.ticks_since_state as f64 * self.cfg.dt * 1e9).round() as u64
            }
            None => 0,
        }
    }

    /// The desired (p, v, a) at plant time `ns` in the current mode.
    fn reference(&self, ns: u64) -> ([f64; NJ], [f64; NJ], [f64; NJ]) {
        match self.mode {
            ControllerMode::Track => {
                let s = self.traj.sample(self.traj.time_of(ns));
                (s.p, s.v, s.a)
            }
            ControllerMode::Brake => {
                let t = (ns as i128 - self.brake_start_ns as i128) as f64 * 1e-9;
                let s = self.brake.at(t.max(0.0));
                (s.p, s.v, s.a)
            }
            ControllerMode::Hold | ControllerMode::Idle => (self.hold_q, [0.0; NJ], [0.0; NJ]),
        }
    }

    /// The desired joint positions, velocities and accelerations at plant time `ns` (the
    /// trajectory, the brake or the hold), or `None` while idle (no reference yet).
    pub fn desired(&self, ns: u64) -> Option<([f64; NJ], [f64; NJ], [f64; NJ])> {
        (self.mode != ControllerMode::Idle).then(|| self.reference(ns))
    }

    fn switch(&mut self, to: ControllerMode, reason: Reason, ns: u64) -> ModeEvent {
        let ev = ModeEvent { tick: self.tick, plant_ns: ns, from: self.mode, to, reason };
        self.mode = to;
        ev
    }

    /// A controlled stop (the run is ending: a signal, the launcher's shutdown): a moving
    /// reference brakes to rest within the motion limits and then holds (the same brake
    /// as a safe hold, not counted as one); a held or idle arm stays held. From now on no
    /// trajectory is followed. Returns the mode switch, if any.
    pub fn stop(&mut self) -> Option<ModeEvent> {
        if self.stopping {
            return None;
        }
        self.stopping = true;
        self.queued.traj_id = 0;
        let ns = self.plant_ns();
        match self.mode {
            ControllerMode::Track => Some(self.brake_to_rest(Reason::Stop, ns)),
            _ => None,
        }
    }

    /// Whether [`Tracker::stop`] was called.
    pub fn stopping(&self) -> bool {
        self.stopping
    }

    /// Enters safe hold: brake from the current reference to rest within the
    /// limits, then hold where it stops.
    fn enter_safe_hold(&mut self, reason: Reason, ns: u64) -> ModeEvent {
        self.stats.safe_hold_entries += 1;
        self.brake_to_rest(reason, ns)
    }

    /// Brakes from the current reference to rest within the limits, then holds where it stops.
    fn brake_to_rest(&mut self, reason: Reason, ns: u64) -> ModeEvent {
        let (p, v, a) = match (self.mode, self.last_state) {
            (ControllerMode::Idle, Some((_, _, q, _))) => (q.into(), [0.0; NJ], [0.0; NJ]),
            _ => self.reference(ns),
        };
        self.brake_from(p, v, a, reason, ns)
    }

    /// Re-anchors the reference at the measured state: a brake to rest from where the arm
    /// is and how fast it moves (the arm is not where the reference is, and pulling it back
    /// would yank it). Interrupting a tracked motion counts as a safe hold.
    fn reanchor(&mut self, q: &JVec, qd: &JVec, reason: Reason, ns: u64) -> ModeEvent {
        self.stats.reanchors += 1;
        if self.mode == ControllerMode::Track {
            self.stats.safe_hold_entries += 1;
        }
        self.brake_from((*q).into(), (*qd).into(), [0.0; NJ], reason, ns)
    }

    /// Brakes from (p, v, a) to rest within the limits (from `ns`), then holds where it stops.
    fn brake_from(&mut self, p: [f64; NJ], v: [f64; NJ], a: [f64; NJ], reason: Reason, ns: u64) -> ModeEvent {
        if self.plan_brake(p, v, a, ns) {
            self.switch(ControllerMode::Brake, reason, ns)
        } else {
            // Cannot happen for a clamped finite state; hold where we are.
            self.hold_q = p;
            self.switch(ControllerMode::Hold, reason, ns)
        }
    }

    /// Plans the brake from (p, v, a) to rest (starting at `ns`) and the hold where it ends;
    /// false if no brake could be planned (the mode is left to the caller).
    fn plan_brake(&mut self, p: [f64; NJ], v: [f64; NJ], a: [f64; NJ], ns: u64) -> bool {
        // Clamp the start into the generator's domain (a reference never
        // exceeds the limits, but a measured state might).
        let mut cur = KinState { p, v, a };
        for i in 0..NJ {
            cur.v[i] = cur.v[i].clamp(-self.cfg.limits.v_max[i], self.cfg.limits.v_max[i]);
            cur.a[i] = cur.a[i].clamp(-self.cfg.limits.a_max[i], self.cfg.limits.a_max[i]);
        }
        match dkrrt_otg::Trajectory::calculate_velocity(
            &cur,
            &[0.0; NJ],
            &[0.0; NJ],
            &self.cfg.limits,
            &Options::default(),
        ) {
            Ok(b) => {
                self.brake = b;
                self.brake_start_ns = ns;
                self.hold_q = b.final_state().p;
                true
            }
            Err(_) => false,
        }
    }

    /// Offers a new (already validated) trajectory. Accepted if it is new and
    /// starts at the current reference; otherwise rejected and, while
    /// tracking, the controller brakes (an invalid trajectory is not followed).
    /// Before the first state, where the arm is is not known: the trajectory is
    /// kept and its start checked against the first state (on the tick after it).
    ///
    /// A trajectory whose `start_ns` lies ahead of the current tick is queued instead (a newer
    /// queued one replaces it): it takes over at `start_ns` if it continues the reference there
    /// in position, velocity and acceleration (within `splice_tol`; at rest, the position may
    /// differ by up to `max_start_jump`), else it is rejected (and a tracked motion brakes).
    pub fn set_trajectory(&mut self, t: &Trajectory) -> Option<ModeEvent> {
        if self.stopping {
            if t.traj_id != self.traj.traj_id {
                self.stats.ignored_after_stop += 1;
            }
            return None;
        }
        if t.traj_id != 0 && (t.traj_id == self.traj.traj_id || t.traj_id == self.queued.traj_id) {
            return None;
        }
        if t.traj_id != 0 && self.last_state.is_some() && t.start_ns > self.plant_ns() {
            *self.queued = *t;
            self.stats.splices_queued += 1;
            return None;
        }
        if t.traj_id != 0 && self.last_state.is_none() {
            *self.traj = *t;
            self.traj_pending = true;
            return None;
        }
        let ns = self.plant_ns();
        let start = t.sample(t.time_of(ns)).p;
        if t.traj_id == 0 || !self.starts_at_reference(&start, ns) {
            self.stats.trajectories_rejected += 1;
            return self.reject_trajectory(ns);
        }
        *self.traj = *t;
        self.stats.trajectories_accepted += 1;
        Some(self.switch(ControllerMode::Track, Reason::NewTrajectory, ns))
    }

    /// Whether `start` lies within `max_start_jump` of the current reference (the measured
    /// position when idle).
    fn starts_at_reference(&self, start: &[f64; NJ], ns: u64) -> bool {
        let cur: [f64; NJ] = match (self.mode, &self.last_state) {
            (ControllerMode::Idle, Some((_, _, q, _))) => (*q).into(),
            _ => self.reference(ns).0,
        };
        let jump = (0..NJ).map(|i| (start[i] - cur[i]).abs()).fold(0.0, f64::max);
        jump <= self.cfg.max_start_jump
    }

    /// Splices the queued trajectory in at its `start_ns`, if it continues the reference there.
    fn take_queued(&mut self) -> Option<ModeEvent> {
        let start_ns = self.queued.start_ns;
        let ns = self.plant_ns();
        let (p, v, a) = match self.mode {
            ControllerMode::Idle => match self.last_state {
                Some((_, _, q, _)) => (q.into(), [0.0; NJ], [0.0; NJ]),
                None => return None,
            },
            _ => self.reference(start_ns),
        };
        let s = self.queued.sample(0.0);
        let moving = matches!(self.mode, ControllerMode::Track | ControllerMode::Brake);
        let tol = self.cfg.splice_tol;
        let p_tol = if moving { tol[0] } else { self.cfg.max_start_jump };
        let ok = (0..NJ).all(|i| {
            (s.p[i] - p[i]).abs() <= p_tol
                && (s.v[i] - v[i]).abs() <= tol[1]
                && (s.a[i] - a[i]).abs() <= tol[2]
        });
        // A brake in progress is a safe hold: only a plan from rest (after it) replaces it.
        if ok && self.mode != ControllerMode::Brake {
            *self.traj = *self.queued;
            self.queued.traj_id = 0;
            self.stats.trajectories_accepted += 1;
            self.stats.splices_taken += 1;
            Some(self.switch(ControllerMode::Track, Reason::Splice, ns))
        } else {
            self.queued.traj_id = 0;
            self.stats.trajectories_rejected += 1;
            if self.mode == ControllerMode::Track {
                Some(self.enter_safe_hold(Reason::SpliceRejected, ns))
            } else {
                None
            }
        }
    }

    /// The trajectory waiting for its `start_ns` (id 0: none).
    pub fn queued_traj_id(&self) -> u64 {
        self.queued.traj_id
    }

    /// Records that a trajectory message failed validation.
    pub fn reject_trajectory(&mut self, ns: u64) -> Option<ModeEvent> {
        if self.mode == ControllerMode::Track {
            Some(self.enter_safe_hold(Reason::InvalidTrajectory, ns))
        } else {
            None
        }
    }

    /// One control tick. `state` is the newest valid state if one arrived
    /// since the last tick. Returns the command to publish.
    /// See [`StateIn`] for what a state carries.
    pub fn tick(&mut self, state: Option<StateIn<'_>>) -> TickOutput {
        self.tick += 1;
        self.stats.ticks += 1;
        let mut event = None;
        let mut brakes_engaged = false;
        match state {
            Some((seq, stamp, q, qd, braked)) if self.last_state.is_none_or(|(s, ..)| seq > s) => {
                let first = self.last_state.is_none();
                self.last_state = Some((seq, stamp, JVec::from_row_slice(q), JVec::from_row_slice(qd)));
                self.ticks_since_state = 0;
                brakes_engaged = braked && !self.plant_braked;
                self.follow_brake &= braked;
                self.plant_braked = braked;
                if first {
                    self.hold_q = *q;
                    event = Some(ModeEvent {
                        tick: self.tick,
                        plant_ns: stamp,
                        from: self.mode,
                        to: self.mode,
                        reason: Reason::FirstState,
                    });
                }
            }
            _ => self.ticks_since_state = self.ticks_since_state.saturating_add(1),
        }
        let Some((seq, _, q, qd)) = self.last_state else {
            return TickOutput {
                tau: [0.0; NJ],
                q_set: [0.0; NJ],
                qd_set: [0.0; NJ],
                mode: self.mode,
                state_seq: 0,
                plant_ns: 0,
                event,
            };
        };
        let ns = self.plant_ns();
        let stale = self.ticks_since_state >= self.cfg.stale_ticks;
        if stale {
            self.stats.stale_ticks += 1;
        }
        // A trajectory that arrived before the first state: check its start now (the tick
        // after the first state, whose event this tick may already carry).
        if self.traj_pending && event.is_none() && !stale {
            self.traj_pending = false;
            let start = self.traj.sample(self.traj.time_of(ns)).p;
            if self.starts_at_reference(&start, ns) {
                self.stats.trajectories_accepted += 1;
                event = Some(self.switch(ControllerMode::Track, Reason::NewTrajectory, ns));
            } else {
                // Nothing was accepted before it: forget it (as a rejected offer is).
                self.stats.trajectories_rejected += 1;
                self.traj.traj_id = 0;
            }
        }

        // A queued trajectory takes over at its start.
        if self.queued.traj_id != 0 && ns >= self.queued.start_ns && !stale {
            if let Some(e) = self.take_queued() {
                event = Some(e);
            }
        }

        // Mode transitions.
        if stale && matches!(self.mode, ControllerMode::Track | ControllerMode::Idle) {
            event = Some(self.enter_safe_hold(Reason::StaleState, ns));
        } else if self.mode == ControllerMode::Track && self.traj.time_of(ns) >= self.traj.duration_s {
            self.hold_q = self.traj.sample(self.traj.duration_s).p;
            event = Some(self.switch(ControllerMode::Hold, Reason::TrajectoryComplete, ns));
        } else if self.mode == ControllerMode::Brake {
            let t = (ns as i128 - self.brake_start_ns as i128) as f64 * 1e-9;
            if t >= self.brake.duration() {
                event = Some(self.switch(ControllerMode::Hold, Reason::BrakeComplete, ns));
            }
        }

        // Tracking error of the measured state against the reference at its stamp.
        let dt_ns = (self.cfg.dt * 1e9).round() as u64;
        let fresh = !stale && self.ticks_since_state == 0;
        if fresh && self.mode != ControllerMode::Idle {
            let (pd, _, _) = self.reference(ns);
            let e = &mut self.stats.track;
            let mut m: f64 = 0.0;
            for i in 0..NJ {
                let d = pd[i] - q[i];
                e.sum_sq += d * d;
                m = m.max(d.abs());
            }
            e.n += 1;
            e.max_abs = e.max_abs.max(m);
            e.last_abs = m;

            // The arm is not where the reference is: the plant's brakes engaged under a
            // moving reference (and hold it while they stay engaged), or it left the
            // reference. Re-anchor at the measured state; never pull it back.
            let moving = matches!(self.mode, ControllerMode::Track | ControllerMode::Brake);
            if brakes_engaged && moving {
                self.follow_brake = true;
                event = Some(self.reanchor(&q, &qd, Reason::PlantBrake, ns));
            } else if self.follow_brake {
                // Still braked by the plant: the reference keeps following the arm.
                match self.mode {
                    ControllerMode::Brake => {
                        self.plan_brake(q.into(), qd.into(), [0.0; NJ], ns);
                    }
                    _ => self.hold_q = q.into(),
                }
            } else if m > self.cfg.max_track_error {
                event = Some(self.reanchor(&q, &qd, Reason::TrackingError, ns));
            }
        }

        let tau = if stale {
            // No measurement: feed-forward along the reference only.
            let (pd, vd, ad) = self.reference(ns + dt_ns);
            let (pd, vd, ad) = (JVec::from(pd), JVec::from(vd), JVec::from(ad));
            self.model.rnea(&pd, &vd, &ad)
        } else {
            let (qc, qdc, t_ref) = if self.cfg.predict {
                let acc = self.model.forward_dynamics(&q, &qd, &self.prev_tau);
                let h = self.cfg.dt;
                (q + qd * h + acc * (0.5 * h * h), qd + acc * h, ns + dt_ns)
            } else {
                (q, qd, ns)
            };
            let (pd, vd, _) = self.reference(t_ref);
            // Mean reference acceleration over the interval the torque acts.
            let (_, _, ad) = self.reference(t_ref + dt_ns / 2);
            let mut qdd = JVec::zeros();
            for i in 0..NJ {
                qdd[i] = ad[i] + self.cfg.kd[i] * (vd[i] - qdc[i]) + self.cfg.kp[i] * (pd[i] - qc[i]);
            }
            // M(q) q̈ + h(q, q̇) in one recursive Newton–Euler pass.
            self.model.rnea(&qc, &qdc, &qdd)
        };
        // Never command beyond the actuators' limits.
        let lim = &self.model.limits().tau_max;
        let mut out = [0.0; NJ];
        for i in 0..NJ {
            out[i] = tau[i].clamp(-lim[i], lim[i]);
        }
        self.prev_tau = JVec::from(out);
        let (q_set, qd_set) = match self.mode {
            ControllerMode::Idle => (q.into(), [0.0; NJ]),
            _ => {
                let (p, v, _) = self.reference(ns + dt_ns);
                (p, v)
            }
        };
        TickOutput { tau: out, q_set, qd_set, mode: self.mode, state_seq: seq, plant_ns: ns, event }
    }
}
