//! The plant core: the arm's rigid-body dynamics integrated under commanded
//! joint torques, with torque saturation, hard joint stops, joint brakes on a
//! command watchdog, and optional measurement noise and delay.
//!
//! Timing contract (the same for the simulator and a real driver): the plant
//! publishes state `k` at tick `k`; a command answering state `k`
//! (`state_seq = k`) is applied from tick `k + 1` to `k + 2` (one tick of
//! transport delay, as on a real 1 kHz fieldbus). [`Plant::offer_command`]
//! takes commands in any order; [`Plant::step`] applies the newest eligible one.

use dkrrt_model::{ArmModel, JVec, NJ};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

/// Plant options (from the scenario's `[sim]` table).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantConfig {
    /// Tick length, s.
    pub dt: f64,
    /// RK4 substeps per tick (more while the brakes are engaged, see [`Plant::step`]).
    pub substeps: u32,
    pub noise_q_std: f64,
    pub noise_qd_std: f64,
    /// Measurement delay, ticks (≤ [`MAX_DELAY`]).
    pub delay_ticks: u32,
    /// Brakes engage after this many ticks without a new eligible command.
    pub command_timeout_ticks: u32,
    /// Brake damping, N·m·s/rad (saturated at the torque limits).
    pub brake_damping: f64,
    pub seed: u64,
}

impl PlantConfig {
    pub fn from_scenario(sc: &dkrrt_config::Scenario) -> Self {
        PlantConfig {
            dt: sc.period_ns() as f64 * 1e-9,
            substeps: sc.sim.substeps,
            noise_q_std: sc.sim.noise_q_std,
            noise_qd_std: sc.sim.noise_qd_std,
            delay_ticks: sc.sim.delay_ticks.min(MAX_DELAY as u32),
            command_timeout_ticks: sc.sim.command_timeout_ticks,
            brake_damping: sc.sim.brake_damping,
            seed: sc.sim.seed,
        }
    }
}

/// Largest supported measurement delay, ticks.
pub const MAX_DELAY: usize = 1000;

/// A measured state as the plant reports it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measured {
    pub tick: u64,
    pub q: [f64; NJ],
    pub qd: [f64; NJ],
    /// Torque applied over the last tick.
    pub tau: [f64; NJ],
    pub brake_engaged: bool,
}

#[derive(Debug, Clone, Copy)]
struct Cmd {
    state_seq: u64,
    tau: JVec,
}

/// Below this speed an engaged joint brake locks the joint, rad/s.
pub const BRAKE_LOCK_RAD_S: f64 = 1e-3;

/// Counters of the plant.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct PlantStats {
    pub ticks: u64,
    /// Commands accepted for application.
    pub commands_applied: u64,
    /// Commands that arrived too late to be applied (a newer one was already active).
    pub commands_late: u64,
    /// Commands whose torque exceeded the limit and was saturated.
    pub saturations: u64,
    /// Times the brake watchdog engaged after commands had been flowing.
    pub brake_engagements: u64,
    /// Times the controller asked the arm to hold on its brakes (not a fault).
    pub holds: u64,
    /// Ticks spent with brakes engaged.
    pub brake_ticks: u64,
    /// Substeps in which a joint hit its hard stop.
    pub limit_hits: u64,
    /// Largest true |q̇ᵢ| / the arm's velocity limit over the run (> 1: a limit was exceeded).
    pub max_velocity_ratio: f64,
    /// Ticks in which some joint moved faster than its velocity limit.
    pub velocity_limit_ticks: u64,
    /// Substeps whose integration gave a non-finite state (the state before it was kept and
    /// the brakes engaged: a NaN never becomes a state).
    pub non_finite_steps: u64,
}

/// The plant. Constructed once; [`Plant::step`] allocates nothing.
pub struct Plant {
    model: ArmModel,
    cfg: PlantConfig,
    q: JVec,
    qd: JVec,
    tick: u64,
    active: Option<Cmd>,
    pending: Option<Cmd>,
    ticks_without_command: u32,
    brake: bool,
    tau_applied: JVec,
    rng: SmallRng,
    /// Ring of past true states for the measurement delay.
    history: Vec<(JVec, JVec, JVec)>,
    pub stats: PlantStats,
}

impl Plant {
    pub fn new(model: ArmModel, cfg: PlantConfig, q0: &[f64; NJ]) -> Plant {
        let q = JVec::from_row_slice(q0);
        let zero = JVec::zeros();
        let n = cfg.delay_ticks as usize + 1;
        Plant {
            model,
            cfg,
            q,
            qd: zero,
            tick: 0,
            active: None,
            pending: None,
            ticks_without_command: 0,
            brake: true, // brakes hold the arm until commands flow
            tau_applied: zero,
            rng: SmallRng::seed_from_u64(cfg.seed),
            history: vec![(q, zero, zero); n],
            stats: PlantStats::default(),
        }
    }

    pub fn model(&self) -> &ArmModel {
        &self.model
    }

    /// Current tick (index of the state [`Plant::measured`] reports).
    pub fn tick(&self) -> u64 {
        self.tick
    }

    /// True joint position and velocity (no noise, no delay).
    pub fn true_state(&self) -> (JVec, JVec) {
        (self.q, self.qd)
    }

    pub fn brake_engaged(&self) -> bool {
        self.brake
    }

    /// Forgets the commands offered and applied (an arm told to hold: what it was sent
    /// before is not applied after). Until a new command arrives the brakes (engaged by the
    /// caller, or by the watchdog) hold the arm.
    fn drop_commands(&mut self) {
        self.pending = None;
        self.active = None;
    }

    /// The controller asks the arm to hold on its brakes (a driver's end of session): commands
    /// are forgotten and the brakes engaged, counted in `holds`, not as a brake engagement
    /// (which is the arm acting against a failing controller).
    pub fn hold(&mut self) {
        self.drop_commands();
        if !self.brake {
            self.brake = true;
            self.stats.holds += 1;
        }
    }

    /// Engages the joint brakes now (the watchdog, a non-finite step, the end of a controlled
    /// stop whose controller did not bring the arm to rest, an emulated arm told to hold);
    /// commands flowing again release them. Counted once per engagement.
    pub fn engage_brakes(&mut self) {
        if !self.brake {
            self.brake = true;
            self.stats.brake_engagements += 1;
        }
    }

    /// Largest true joint speed now, rad/s.
    pub fn max_speed(&self) -> f64 {
        self.qd.iter().fold(0.0f64, |m, v| m.max(v.abs()))
    }

    /// Offers a command answering state `state_seq`. It becomes eligible at
    /// tick `state_seq + 1`. Stale commands (older than the active one) are
    /// counted and dropped.
    pub fn offer_command(&mut self, state_seq: u64, tau: &[f64; NJ]) {
        let cmd = Cmd { state_seq, tau: JVec::from_row_slice(tau) };
        if let Some(a) = self.active {
            if state_seq <= a.state_seq {
                self.stats.commands_late += 1;
                return;
            }
        }
        if let Some(p) = self.pending {
            if p.state_seq >= state_seq {
                self.stats.commands_late += 1;
                return;
            }
        }
        // A held command that is already eligible is promoted before it is replaced.
        self.promote_eligible();
        self.pending = Some(cmd);
    }

    /// Moves the pending command to active if it answers a state before this tick.
    fn promote_eligible(&mut self) {
        if let Some(p) = self.pending {
            if p.state_seq < self.tick {
                self.active = Some(p);
                self.pending = None;
                self.stats.commands_applied += 1;
                self.ticks_without_command = 0;
                self.brake = false;
            }
        }
    }

    /// True if a command answering the current state has been offered.
    pub fn has_command_for_current(&self) -> bool {
        self.pending.is_some_and(|p| p.state_seq >= self.tick)
            || self.active.is_some_and(|a| a.state_seq >= self.tick)
    }

    fn saturate(&self, tau: &JVec) -> (JVec, bool) {
        let lim = &self.model.limits().tau_max;
        let mut out = *tau;
        let mut sat = false;
        for i in 0..NJ {
            if out[i].abs() > lim[i] {
                out[i] = out[i].clamp(-lim[i], lim[i]);
                sat = true;
            }
        }
        (out, sat)
    }

    fn brake_torque(&self, qd: &JVec) -> JVec {
        let lim = &self.model.limits().tau_max;
        let mut t = JVec::zeros();
        for i in 0..NJ {
            t[i] = (-self.cfg.brake_damping * qd[i]).clamp(-lim[i], lim[i]);
        }
        t
    }

    fn accel(&self, q: &JVec, qd: &JVec, tau_cmd: &JVec) -> JVec {
        let tau = if self.brake { self.brake_torque(qd) } else { *tau_cmd };
        self.model.forward_dynamics(q, qd, &tau)
    }

    /// Substeps while braked: the viscous brake is stiff (rate `c / λ_min(M(q))`, ~3000 /s on
    /// the default arm), and RK4 is stable for `h·rate` up to ~2.8: at least
    /// `dt·c / (1.4·λ_min)` substeps (half that limit), and never fewer than configured.
    fn brake_substeps(&self) -> u32 {
        if self.qd.iter().all(|v| *v == 0.0) {
            return self.cfg.substeps.max(1); // held at rest: no brake torque, nothing stiff
        }
        let m = self.model.mass_matrix(&self.q).symmetric_eigenvalues().min();
        let need = if m > 0.0 { (self.cfg.dt * self.cfg.brake_damping / (1.4 * m)).ceil() } else { 100.0 };
        (need.clamp(1.0, 100.0) as u32).max(self.cfg.substeps)
    }

    /// Advances one tick: applies the newest eligible command (or the brakes),
    /// integrates with RK4 substeps (`substeps`; the free arm's dynamics are slow next to a
    /// 1 ms tick: one step stays within 1e-9 rad of 16 over 2 s, test
    /// `one_rk4_step_per_tick_matches_a_fine_integration_and_the_brake_stays_stable`),
    /// enforces hard stops.
    pub fn step(&mut self) {
        // Eligible: commands answering states up to tick - 1.
        self.promote_eligible();
        self.ticks_without_command = self.ticks_without_command.saturating_add(1);
        if self.ticks_without_command > self.cfg.command_timeout_ticks {
            self.engage_brakes();
        }
        let (tau, sat) = match (&self.active, self.brake) {
            (Some(c), false) => self.saturate(&c.tau),
            _ => (JVec::zeros(), false),
        };
        if sat {
            self.stats.saturations += 1;
        }
        let n = if self.brake { self.brake_substeps() } else { self.cfg.substeps.max(1) };
        let h = self.cfg.dt / n as f64;
        let lim = *self.model.limits();
        for _ in 0..n {
            let (q, qd) = (self.q, self.qd);
            let k1v = qd;
            let k1a = self.accel(&q, &qd, &tau);
            let k2v = qd + k1a * (h / 2.0);
            let k2a = self.accel(&(q + k1v * (h / 2.0)), &k2v, &tau);
            let k3v = qd + k2a * (h / 2.0);
            let k3a = self.accel(&(q + k2v * (h / 2.0)), &k3v, &tau);
            let k4v = qd + k3a * h;
            let k4a = self.accel(&(q + k3v * h), &k4v, &tau);
            let q_next = q + (k1v + k2v * 2.0 + k3v * 2.0 + k4v) * (h / 6.0);
            let qd_next = qd + (k1a + k2a * 2.0 + k3a * 2.0 + k4a) * (h / 6.0);
            if !(q_next.iter().all(|x| x.is_finite()) && qd_next.iter().all(|x| x.is_finite())) {
                self.stats.non_finite_steps += 1;
                self.engage_brakes();
                continue;
            }
            self.q = q_next;
            self.qd = qd_next;
            for i in 0..NJ {
                if self.q[i] < lim.q_min[i] {
                    self.q[i] = lim.q_min[i];
                    self.qd[i] = self.qd[i].max(0.0);
                    self.stats.limit_hits += 1;
                } else if self.q[i] > lim.q_max[i] {
                    self.q[i] = lim.q_max[i];
                    self.qd[i] = self.qd[i].min(0.0);
                    self.stats.limit_hits += 1;
                }
            }
        }
        // An engaged brake is a friction brake: once a joint has all but stopped, it is
        // locked (held at rest), not left creeping at the viscous model's tail.
        if self.brake {
            for i in 0..NJ {
                if self.qd[i].abs() < BRAKE_LOCK_RAD_S {
                    self.qd[i] = 0.0;
                }
            }
        }
        let mut ratio = 0.0f64;
        for i in 0..NJ {
            ratio = ratio.max(self.qd[i].abs() / lim.v_max[i]);
        }
        if ratio > 1.0 {
            self.stats.velocity_limit_ticks += 1;
        }
        self.stats.max_velocity_ratio = self.stats.max_velocity_ratio.max(ratio);
        self.tau_applied = if self.brake { self.brake_torque(&self.qd) } else { tau };
        if self.brake {
            self.stats.brake_ticks += 1;
        }
        self.tick += 1;
        self.stats.ticks += 1;
        let n = self.history.len();
        self.history[(self.tick as usize) % n] = (self.q, self.qd, self.tau_applied);
    }

    fn gauss(&mut self) -> f64 {
        // Box–Muller; allocation-free.
        let u1: f64 = self.rng.random::<f64>().max(1e-300);
        let u2: f64 = self.rng.random::<f64>();
        (-2.0 * u1.ln()).sqrt() * (2.0 * core::f64::consts::PI * u2).cos()
    }

    /// The state as measured at the current tick (delayed and noisy as configured).
    pub fn measured(&mut self) -> Measured {
        // Slot (t + 1) mod n holds the state of tick t - delay (the ring is
        // pre-filled with the initial state for the first ticks).
        let n = self.history.len();
        let (q, qd, tau) = self.history[(self.tick as usize + 1) % n];
        let mut m = Measured {
            tick: self.tick,
            q: [0.0; NJ],
            qd: [0.0; NJ],
            tau: [0.0; NJ],
            brake_engaged: self.brake,
        };
        for i in 0..NJ {
            m.q[i] = q[i];
            m.qd[i] = qd[i];
            m.tau[i] = tau[i];
        }
        if self.cfg.noise_q_std > 0.0 || self.cfg.noise_qd_std > 0.0 {
            for i in 0..NJ {
                m.q[i] += self.cfg.noise_q_std * self.gauss();
                m.qd[i] += self.cfg.noise_qd_std * self.gauss();
            }
        }
        m
    }
}
