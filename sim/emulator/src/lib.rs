//! The arm emulator's core: the simulated plant (`dkrrt_sim::plant`) behind the arm side of
//! dkrrt's UDP protocol (docs/udp-protocol.md), as a real arm controller behaves:
//!
//! * every tick it sends a state with its own sequence number and its own clock (an epoch of
//!   its own: a driver must map it, never assume it);
//! * it applies the newest valid command that answers a state it sent, from its next tick on
//!   (the plant's timing contract), in torque mode (Franka FCI style), servo mode (positions and
//!   velocities tracked by the arm's own computed-torque servo, UR `servoj` style) or hold (brakes);
//! * after `abort_after` ticks without a valid command it aborts to its brakes (`BRAKES |
//!   ABORTED` in the state, FCI uses 20); commands flowing again release them.
//!
//! Plain step functions over preallocated state: [`ArmEmulator::state`],
//! [`ArmEmulator::receive`], [`ArmEmulator::step`] allocate nothing. The process shell (sockets,
//! clock, packet loss and delay) is separate: [`net`] is the emulated network (delay, jitter,
//! loss, duplication, reordering) and [`process`] the `dkrrt arm-emulator` process.

pub mod net;
pub mod process;

use dkrrt_model::{ArmModel, JVec, NJ};
use dkrrt_sim::plant::{Plant, PlantConfig};
use dkrrt_udp::{status, CommandPacket, Mode, PacketError, StatePacket, STATE_LEN};

/// How the emulated arm behaves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EmulatorConfig {
    /// Ticks without a valid command before the arm aborts to its brakes.
    pub abort_after: u32,
    /// The arm's own servo for [`Mode::Servo`] commands: computed torque with these gains
    /// (1/s², 1/s).
    pub servo_kp: [f64; NJ],
    pub servo_kd: [f64; NJ],
    /// The arm's clock at its tick 0, ns.
    pub clock_epoch_ns: u64,
    /// Tick length, ns.
    pub period_ns: u64,
}

impl EmulatorConfig {
    /// FCI-like defaults at the given tick length: abort after 20 missed ticks, a 20 rad/s
    /// critically damped servo, the clock starting at an arbitrary epoch (1 h).
    pub fn new(period_ns: u64) -> Self {
        EmulatorConfig {
            abort_after: 20,
            servo_kp: [400.0; NJ],
            servo_kd: [40.0; NJ],
            clock_epoch_ns: 3_600_000_000_000,
            period_ns,
        }
    }
}

/// Counters of the emulated arm.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct EmulatorStats {
    pub states_sent: u64,
    /// Valid command packets received.
    pub commands_received: u64,
    /// Datagrams that were not valid command packets (length, checksum, version, …).
    pub commands_invalid: u64,
    /// Valid commands not used: answering a state not sent yet, or older than the one kept.
    pub commands_stale: u64,
    /// Commands applied (one per tick at most).
    pub commands_applied: u64,
    /// Times the watchdog aborted to the brakes.
    pub aborts: u64,
}

/// Why a datagram was not taken.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Rejected {
    /// Not a valid command packet.
    Invalid(PacketError),
    /// It answers a state the arm has not sent, or an older one than the command kept.
    Stale,
}

/// The emulated arm.
pub struct ArmEmulator {
    plant: Plant,
    model: ArmModel,
    cfg: EmulatorConfig,
    /// The newest valid command, applied at the next step.
    next: Option<CommandPacket>,
    /// `state_seq` of the last command applied (a command may not go back in time).
    applied_state_seq: Option<u32>,
    last_command_seq: u32,
    missed: u32,
    aborted: bool,
    /// The last command applied asked to hold (brakes on request: silence is no abort).
    holding: bool,
    pub stats: EmulatorStats,
}

impl ArmEmulator {
    /// An arm at `q0`, at rest, brakes engaged until commands flow. The plant's watchdog is
    /// the arm's abort (`plant.command_timeout_ticks` is set to `cfg.abort_after`).
    pub fn new(model: ArmModel, plant: PlantConfig, q0: &[f64; NJ], cfg: EmulatorConfig) -> ArmEmulator {
        let pc = PlantConfig { command_timeout_ticks: cfg.abort_after, ..plant };
        ArmEmulator {
            plant: Plant::new(model.clone(), pc, q0),
            model,
            cfg,
            next: None,
            applied_state_seq: None,
            last_command_seq: 0,
            missed: 0,
            aborted: false,
            holding: false,
            stats: EmulatorStats::default(),
        }
    }

    /// The simulated plant (true state, statistics).
    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// The arm's clock now, ns.
    pub fn clock_ns(&self) -> u64 {
        self.cfg.clock_epoch_ns + self.plant.tick() * self.cfg.period_ns
    }

    /// The state of the current tick, encoded into `buf`; returns its length.
    pub fn state(&mut self, buf: &mut [u8; STATE_LEN]) -> usize {
        let m = self.plant.measured();
        let mut st = 0;
        if m.brake_engaged {
            st |= status::BRAKES;
        }
        if self.aborted {
            st |= status::ABORTED;
        }
        self.stats.states_sent += 1;
        StatePacket {
            seq: m.tick as u32,
            arm_time_ns: self.clock_ns(),
            q: m.q,
            qd: m.qd,
            tau: m.tau,
            status: st,
            missed: self.missed,
            last_command_seq: self.last_command_seq,
            abort_after: self.cfg.abort_after,
        }
        .encode(buf)
    }

    /// A datagram from the driver: kept for the next tick if it is a valid command answering a
    /// state already sent and no older than the command kept or applied; returns the `seq` of
    /// the state it answers.
    pub fn receive(&mut self, datagram: &[u8]) -> Result<u32, Rejected> {
        let c = CommandPacket::decode(datagram).map_err(|e| {
            self.stats.commands_invalid += 1;
            Rejected::Invalid(e)
        })?;
        self.stats.commands_received += 1;
        let future = u64::from(c.state_seq) > self.plant.tick();
        let older = self.next.is_some_and(|n| c.state_seq < n.state_seq)
            || self.applied_state_seq.is_some_and(|a| c.state_seq < a);
        if future || older {
            self.stats.commands_stale += 1;
            return Err(Rejected::Stale);
        }
        self.next = Some(c);
        Ok(c.state_seq)
    }

    /// Power off: the brakes engage and the arm coasts to rest on them; steps the plant (as
    /// fast as it computes, nobody listens any more) until every joint has been slower than
    /// `rest_speed` for 50 ticks or `limit_ticks` have passed. Returns the ticks it took.
    pub fn power_off(&mut self, rest_speed: f64, limit_ticks: u64) -> u64 {
        if self.plant.max_speed() >= rest_speed {
            self.plant.engage_brakes();
        } else {
            self.plant.hold();
        }
        let (mut n, mut rest) = (0u64, 0u64);
        while rest < 50 && n < limit_ticks {
            self.plant.step();
            n += 1;
            rest = if self.plant.max_speed() < rest_speed { rest + 1 } else { 0 };
        }
        n
    }

    /// The servo's torque for a position/velocity setpoint, from the arm's own measurement.
    fn servo(&mut self, c: &CommandPacket) -> [f64; NJ] {
        let m = self.plant.measured();
        let (q, qd) = (JVec::from(m.q), JVec::from(m.qd));
        let mut acc = JVec::zeros();
        for i in 0..NJ {
            acc[i] = self.cfg.servo_kp[i] * (c.q[i] - q[i]) + self.cfg.servo_kd[i] * (c.qd[i] - qd[i]);
        }
        (self.model.mass_matrix(&q) * acc + self.model.nonlinear_effects(&q, &qd)).into()
    }

    /// One arm tick: the kept command (if any) is handed to the plant, the plant steps, the
    /// watchdog counts.
    pub fn step(&mut self) {
        match self.next.take() {
            Some(c) => {
                match c.mode {
                    Mode::Torque => self.plant.offer_command(u64::from(c.state_seq), &c.tau),
                    Mode::Servo => {
                        let tau = self.servo(&c);
                        self.plant.offer_command(u64::from(c.state_seq), &tau);
                    }
                    Mode::Hold => self.plant.hold(),
                }
                self.holding = c.mode == Mode::Hold;
                self.applied_state_seq = Some(c.state_seq);
                self.last_command_seq = c.seq;
                self.stats.commands_applied += 1;
                self.missed = 0;
                self.aborted = false;
            }
            None => self.missed = self.missed.saturating_add(1),
        }
        self.plant.step();
        // An abort is commands that stopped flowing: not the silence before the first command
        // (the arm is braked at power-up), nor after a hold was asked for.
        let flowed = self.stats.commands_applied > 0 && !self.holding;
        if flowed && !self.aborted && self.missed > self.cfg.abort_after && self.plant.brake_engaged() {
            self.aborted = true;
            self.stats.aborts += 1;
        }
    }
}
