//! The driver side of the arm protocol as plain step functions (no socket, no bus, no clock of
//! its own: the caller passes `now_ns`):
//!
//! * [`DriverCore::on_datagram`]: a datagram from the arm → the state to publish (the arm's
//!   clock mapped to plant time: its first state is time zero), or why not (invalid, late,
//!   duplicate, the arm's clock going back);
//! * [`DriverCore::published`]: which bus `seq` a state went out with, so that a command
//!   answering it (`TorqueCommand::state_seq`, a bus seq) can name the arm's `seq`;
//! * [`DriverCore::command`] / [`DriverCore::hold`]: the command datagram to send;
//! * the link's figures: states lost/late/duplicated, invalid datagrams, the command echo
//!   (command sent → the arm's echo of its `seq` in a state received), the arm's aborts.
//!
//! Nothing allocates after [`DriverCore::new`].

use dkrrt_rt::hist::{LatencyHist, Percentiles};
use dkrrt_udp::link::{Arrival, SeqStats, SeqTracker};
use dkrrt_udp::{status, CommandPacket, Mode, PacketError, StatePacket, COMMAND_LEN, NJ};

/// States (and commands) remembered for matching, at 1 kHz: 64 ms.
pub const WINDOW: usize = 64;

/// A state from the arm, ready to publish.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmState {
    /// The arm's `seq`.
    pub arm_seq: u32,
    /// Arm ticks since its first state (gaps are lost states).
    pub tick: u64,
    /// The arm's clock since its first state, ns: the plant time of the sample.
    pub plant_ns: u64,
    pub q: [f64; NJ],
    pub qd: [f64; NJ],
    pub tau: [f64; NJ],
    pub brakes: bool,
    pub aborted: bool,
    /// The arm's own stop request (a stop button).
    pub stopping: bool,
}

/// Why a datagram gave no state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Dropped {
    /// Not a valid state packet (counted in `invalid`).
    Invalid(PacketError),
    /// Older than the newest state (reordered or delayed): not used.
    Late,
    /// Seen before.
    Duplicate,
    /// Newer `seq` but the arm's clock went back (an arm restart): not used.
    ClockBack,
}

/// The link's figures as the driver sees them.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct LinkStats {
    /// States from the arm: received, lost, late (out of order), duplicated.
    pub states: SeqStats,
    /// Datagrams that were not valid state packets (length, magic, version, checksum, NaN…).
    pub invalid: u64,
    /// The most recent reason a datagram was invalid.
    #[serde(skip)]
    pub last_invalid: Option<PacketError>,
    /// States whose arm clock was not after the newest one's.
    pub clock_back: u64,
    pub commands_sent: u64,
    /// Commands that answered a state no longer (or never) in the window: not sent.
    pub commands_unmatched: u64,
    /// Times the arm reported an abort (rising `ABORTED`).
    pub aborts: u64,
    /// The longest run of ticks the arm reported without a valid command.
    pub arm_missed_max: u32,
}

/// The driver side of one arm session.
pub struct DriverCore {
    epoch_ns: Option<u64>,
    first_seq: u32,
    newest_time_ns: u64,
    seqs: SeqTracker,
    /// `(bus seq, arm seq)` of the last states published, ring.
    map: [(u64, u32); WINDOW],
    map_n: u64,
    newest_arm_seq: u32,
    cmd_seq: u32,
    /// `(command seq, sent at)` ring, for the round trip.
    sent: [(u32, u64); WINDOW],
    echoed: Option<u32>,
    aborted: bool,
    rtt: LatencyHist,
    pub stats: LinkStats,
}

impl Default for DriverCore {
    fn default() -> Self {
        Self::new()
    }
}

impl DriverCore {
    pub fn new() -> DriverCore {
        DriverCore {
            epoch_ns: None,
            first_seq: 0,
            newest_time_ns: 0,
            seqs: SeqTracker::new(),
            map: [(u64::MAX, 0); WINDOW],
            map_n: 0,
            newest_arm_seq: 0,
            cmd_seq: 0,
            sent: [(0, 0); WINDOW],
            echoed: None,
            aborted: false,
            rtt: LatencyHist::new(),
            stats: LinkStats::default(),
        }
    }

    /// A datagram from the arm, received at `now_ns`.
    pub fn on_datagram(&mut self, now_ns: u64, d: &[u8]) -> Result<ArmState, Dropped> {
        let p = StatePacket::decode(d).map_err(|e| {
            self.stats.invalid += 1;
            self.stats.last_invalid = Some(e);
            Dropped::Invalid(e)
        })?;
        let arrival = self.seqs.on_packet(p.seq);
        self.stats.states = self.seqs.stats;
        // The echo: the first state that says the arm applied a command we sent.
        if self.echoed.is_none_or(|e| p.last_command_seq.wrapping_sub(e) as i32 > 0)
            && p.last_command_seq != 0
        {
            let slot = self.sent[p.last_command_seq as usize % WINDOW];
            if slot.0 == p.last_command_seq && slot.1 > 0 {
                self.rtt.record_ns(now_ns.saturating_sub(slot.1));
            }
            self.echoed = Some(p.last_command_seq);
        }
        match arrival {
            Arrival::Late => return Err(Dropped::Late),
            Arrival::Duplicate => return Err(Dropped::Duplicate),
            Arrival::New => {}
        }
        let epoch = *self.epoch_ns.get_or_insert_with(|| {
            self.first_seq = p.seq;
            p.arm_time_ns
        });
        if p.arm_time_ns < epoch || (self.stats.states.received > 1 && p.arm_time_ns <= self.newest_time_ns) {
            self.stats.clock_back += 1;
            return Err(Dropped::ClockBack);
        }
        self.newest_time_ns = p.arm_time_ns;
        self.newest_arm_seq = p.seq;
        let aborted = p.status & status::ABORTED != 0;
        if aborted && !self.aborted {
            self.stats.aborts += 1;
        }
        self.aborted = aborted;
        self.stats.arm_missed_max = self.stats.arm_missed_max.max(p.missed);
        Ok(ArmState {
            arm_seq: p.seq,
            tick: u64::from(p.seq.wrapping_sub(self.first_seq)),
            plant_ns: p.arm_time_ns - epoch,
            q: p.q,
            qd: p.qd,
            tau: p.tau,
            brakes: p.status & status::BRAKES != 0,
            aborted,
            stopping: p.status & status::STOPPING != 0,
        })
    }

    /// The state of arm `seq` went out on the bus as `bus_seq`.
    pub fn published(&mut self, bus_seq: u64, arm_seq: u32) {
        self.map[(bus_seq % WINDOW as u64) as usize] = (bus_seq, arm_seq);
        self.map_n += 1;
    }

    fn encode(
        &mut self,
        now_ns: u64,
        state_seq: u32,
        mode: Mode,
        tau: &[f64; NJ],
        q: &[f64; NJ],
        qd: &[f64; NJ],
        buf: &mut [u8; COMMAND_LEN],
    ) -> usize {
        self.cmd_seq = self.cmd_seq.wrapping_add(1).max(1);
        self.sent[self.cmd_seq as usize % WINDOW] = (self.cmd_seq, now_ns.max(1));
        self.stats.commands_sent += 1;
        CommandPacket { seq: self.cmd_seq, state_seq, mode, tau: *tau, q: *q, qd: *qd }.encode(buf)
    }

    /// The datagram for a command answering bus state `state_seq`: torques (`Mode::Torque`) or
    /// setpoints (`Mode::Servo`); `None` (counted) if that state is not in the window.
    #[allow(clippy::too_many_arguments)]
    pub fn command(
        &mut self,
        now_ns: u64,
        state_seq: u64,
        mode: Mode,
        tau: &[f64; NJ],
        q: &[f64; NJ],
        qd: &[f64; NJ],
        buf: &mut [u8; COMMAND_LEN],
    ) -> Option<usize> {
        let (bus, arm) = self.map[(state_seq % WINDOW as u64) as usize];
        if bus != state_seq {
            self.stats.commands_unmatched += 1;
            return None;
        }
        Some(self.encode(now_ns, arm, mode, tau, q, qd, buf))
    }

    /// A hold command (brakes) answering the newest state.
    pub fn hold(&mut self, now_ns: u64, buf: &mut [u8; COMMAND_LEN]) -> usize {
        let z = [0.0; NJ];
        self.encode(now_ns, self.newest_arm_seq, Mode::Hold, &z, &z, &z, buf)
    }

    /// Command sent → the arm's first state that says it applied it, µs.
    pub fn command_echo_us(&self) -> Percentiles {
        self.rtt.percentiles_us()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dkrrt_udp::STATE_LEN;

    fn state(seq: u32, t: u64, last_cmd: u32) -> [u8; STATE_LEN] {
        let mut b = [0u8; STATE_LEN];
        StatePacket {
            seq,
            arm_time_ns: t,
            q: [0.1; NJ],
            qd: [0.0; NJ],
            tau: [0.0; NJ],
            status: 0,
            missed: 0,
            last_command_seq: last_cmd,
            abort_after: 20,
        }
        .encode(&mut b);
        b
    }

    #[test]
    fn the_arm_clock_becomes_plant_time_and_commands_name_the_arm_seq() {
        let mut d = DriverCore::new();
        let s = d.on_datagram(10, &state(1000, 5_000_000_000, 0)).unwrap();
        assert_eq!((s.tick, s.plant_ns), (0, 0));
        d.published(0, 1000);
        let s = d.on_datagram(20, &state(1002, 5_002_000_000, 0)).unwrap();
        assert_eq!((s.tick, s.plant_ns), (2, 2_000_000));
        d.published(1, 1002);
        assert_eq!(d.stats.states.lost, 1);
        let mut buf = [0u8; COMMAND_LEN];
        let n = d.command(30, 1, Mode::Torque, &[1.0; NJ], &[0.0; NJ], &[0.0; NJ], &mut buf).unwrap();
        let c = CommandPacket::decode(&buf[..n]).unwrap();
        assert_eq!((c.state_seq, c.seq, c.mode), (1002, 1, Mode::Torque));
        // A command for a state never published is not sent.
        assert!(d.command(30, 7, Mode::Torque, &[1.0; NJ], &[0.0; NJ], &[0.0; NJ], &mut buf).is_none());
        assert_eq!(d.stats.commands_unmatched, 1);
        // The arm echoes command 1 at 1 030 ns: a round trip of 1 000 ns.
        d.on_datagram(1_030, &state(1003, 5_003_000_000, 1)).unwrap();
        assert_eq!(d.command_echo_us().count, 1);
        assert!((d.command_echo_us().p50 - 1.0).abs() < 0.01);
    }

    #[test]
    fn late_duplicate_corrupt_and_clock_back_states_are_dropped_and_counted() {
        let mut d = DriverCore::new();
        d.on_datagram(0, &state(10, 1_000, 0)).unwrap();
        d.on_datagram(0, &state(12, 3_000, 0)).unwrap();
        assert_eq!(d.on_datagram(0, &state(11, 2_000, 0)), Err(Dropped::Late));
        assert_eq!(d.on_datagram(0, &state(12, 3_000, 0)), Err(Dropped::Duplicate));
        let mut bad = state(13, 4_000, 0);
        bad[40] ^= 0x10;
        assert!(matches!(d.on_datagram(0, &bad), Err(Dropped::Invalid(PacketError::Checksum { .. }))));
        assert!(matches!(d.on_datagram(0, &bad[..100]), Err(Dropped::Invalid(PacketError::Length { .. }))));
        assert_eq!(d.on_datagram(0, &state(14, 2_500, 0)), Err(Dropped::ClockBack));
        let st = d.stats;
        assert_eq!((st.states.late, st.states.duplicates, st.invalid, st.clock_back), (1, 1, 2, 1));
    }
}
