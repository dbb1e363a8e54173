//! dkrrt-udp: the wire protocol between `dkrrt udp-driver` and an arm (or the arm emulator),
//! as docs/udp-protocol.md specifies it. Two fixed-size datagrams, little-endian, each
//! ending in a CRC-32 (ISO-HDLC, as zlib/Ethernet) of everything before it:
//!
//! * [`StatePacket`], arm → driver, once per arm tick (1 kHz): the arm's sequence number and
//!   its own clock, joint positions, velocities and applied torques, status bits;
//! * [`CommandPacket`], driver → arm, one per state: the state it answers, the mode (torque
//!   streaming like Franka's FCI, or position+velocity streaming like UR's RTDE `servoj`, or
//!   hold), the setpoints.
//!
//! Encoding writes into a caller's fixed buffer and decoding reads from a slice: nothing
//! allocates. Decoding checks length, magic, version, kind, checksum and that every number is
//! finite, and says which failed ([`PacketError`]).

use std::fmt;

pub mod link;

/// Joints per arm.
pub const NJ: usize = 6;
/// `b"DKRA"` read as a little-endian u32.
pub const MAGIC: u32 = u32::from_le_bytes(*b"DKRA");
/// Protocol version of this crate. A packet of another version is refused.
pub const VERSION: u16 = 1;
/// Header bytes: magic u32, version u16, kind u16, seq u32.
pub const HEADER_LEN: usize = 12;
/// Encoded size of a [`StatePacket`], bytes (header, clock, q/qd/tau, four u32, CRC).
pub const STATE_LEN: usize = HEADER_LEN + 8 + 3 * NJ * 8 + 4 * 4 + 4;
/// Encoded size of a [`CommandPacket`], bytes (header, state seq, mode, reserved, tau/q/qd, CRC).
pub const COMMAND_LEN: usize = HEADER_LEN + 4 + 2 + 2 + 3 * NJ * 8 + 4;

/// Packet kinds (header `kind`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u16)]
pub enum Kind {
    State = 1,
    Command = 2,
}

/// `StatePacket::status` bits.
pub mod status {
    /// The joint brakes hold the arm (at power-up until commands flow, after an abort).
    pub const BRAKES: u32 = 1;
    /// The arm aborted to its brakes: `missed` consecutive ticks without a valid command
    /// reached its limit. Commands flowing again release the brakes.
    pub const ABORTED: u32 = 2;
    /// A controlled stop is under way on the arm's side (its own stop request).
    pub const STOPPING: u32 = 4;
    /// The last state of a session: the arm stops sending.
    pub const END: u32 = 8;
}

/// Command modes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u16)]
pub enum Mode {
    /// Apply the brakes / hold still; setpoints ignored.
    Hold = 0,
    /// Joint torques `tau` (N·m), applied from the arm's next tick.
    Torque = 1,
    /// Joint positions `q` (rad) and velocities `qd` (rad/s) for the arm's own servo.
    Servo = 2,
}

/// Arm → driver, once per arm tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StatePacket {
    /// Arm's sequence number (+1 per tick; gaps are lost packets).
    pub seq: u32,
    /// The arm's own clock at sampling, ns (monotonic, its own epoch).
    pub arm_time_ns: u64,
    pub q: [f64; NJ],
    pub qd: [f64; NJ],
    /// Torque applied over the last tick, N·m.
    pub tau: [f64; NJ],
    /// [`status`] bits.
    pub status: u32,
    /// Consecutive ticks without a valid command (0 while commands flow).
    pub missed: u32,
    /// `seq` of the last command the arm applied.
    pub last_command_seq: u32,
    /// The arm's abort limit: after this many missed ticks it brakes (Franka's FCI uses 20).
    pub abort_after: u32,
}

/// Driver → arm, one per state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CommandPacket {
    /// Driver's sequence number (+1 per command).
    pub seq: u32,
    /// `seq` of the state this command answers.
    pub state_seq: u32,
    pub mode: Mode,
    pub tau: [f64; NJ],
    pub q: [f64; NJ],
    pub qd: [f64; NJ],
}

/// Why a datagram is not a valid packet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PacketError {
    /// Not the packet's length.
    Length { got: usize, want: usize },
    /// Not a dkrrt arm packet.
    Magic(u32),
    /// Another protocol version.
    Version(u16),
    /// Another kind of packet (or an unknown one).
    Kind(u16),
    /// The CRC-32 does not match: damaged in transit.
    Checksum { got: u32, computed: u32 },
    /// An unknown command mode.
    Mode(u16),
    /// A non-finite number in the named field.
    NonFinite(&'static str),
}

impl fmt::Display for PacketError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PacketError::Length { got, want } => write!(f, "length {got} bytes, expected {want}"),
            PacketError::Magic(m) => write!(f, "bad magic {m:#010x} (not a dkrrt arm packet)"),
            PacketError::Version(v) => write!(f, "protocol version {v}, expected {VERSION}"),
            PacketError::Kind(k) => write!(f, "packet kind {k} where another was expected"),
            PacketError::Checksum { got, computed } => {
                write!(f, "checksum {got:#010x} does not match {computed:#010x}")
            }
            PacketError::Mode(m) => write!(f, "unknown command mode {m}"),
            PacketError::NonFinite(field) => write!(f, "non-finite value in `{field}`"),
        }
    }
}

impl std::error::Error for PacketError {}

/// Little-endian writer over a fixed buffer.
struct W<'a> {
    buf: &'a mut [u8],
    at: usize,
}

impl W<'_> {
    fn put(&mut self, b: &[u8]) {
        self.buf[self.at..self.at + b.len()].copy_from_slice(b);
        self.at += b.len();
    }
    fn u16(&mut self, v: u16) {
        self.put(&v.to_le_bytes());
    }
    fn u32(&mut self, v: u32) {
        self.put(&v.to_le_bytes());
    }
    fn u64(&mut self, v: u64) {
        self.put(&v.to_le_bytes());
    }
    fn f64s(&mut self, v: &[f64; NJ]) {
        for x in v {
            self.put(&x.to_le_bytes());
        }
    }
    fn header(&mut self, kind: Kind, seq: u32) {
        self.u32(MAGIC);
        self.u16(VERSION);
        self.u16(kind as u16);
        self.u32(seq);
    }
    /// Appends the CRC-32 of everything written so far; returns the length.
    fn finish(mut self) -> usize {
        let crc = crc32fast::hash(&self.buf[..self.at]);
        self.u32(crc);
        self.at
    }
}

/// Little-endian reader over a checked slice.
struct R<'a> {
    buf: &'a [u8],
    at: usize,
}

impl R<'_> {
    fn take<const N: usize>(&mut self) -> [u8; N] {
        let mut b = [0u8; N];
        b.copy_from_slice(&self.buf[self.at..self.at + N]);
        self.at += N;
        b
    }
    fn u16(&mut self) -> u16 {
        u16::from_le_bytes(self.take())
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take())
    }
    fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.take())
    }
    fn f64s(&mut self, field: &'static str) -> Result<[f64; NJ], PacketError> {
        let mut v = [0.0; NJ];
        for x in &mut v {
            *x = f64::from_le_bytes(self.take());
            if !x.is_finite() {
                return Err(PacketError::NonFinite(field));
            }
        }
        Ok(v)
    }
}

/// Checks length, checksum, magic, version and kind; returns a reader after the header and
/// the header's `seq`.
fn open(buf: &[u8], want: usize, kind: Kind) -> Result<(R<'_>, u32), PacketError> {
    if buf.len() != want {
        return Err(PacketError::Length { got: buf.len(), want });
    }
    let body = &buf[..want - 4];
    let got = u32::from_le_bytes(buf[want - 4..].try_into().expect("4 bytes"));
    let computed = crc32fast::hash(body);
    if got != computed {
        return Err(PacketError::Checksum { got, computed });
    }
    let mut r = R { buf: body, at: 0 };
    let magic = r.u32();
    if magic != MAGIC {
        return Err(PacketError::Magic(magic));
    }
    let version = r.u16();
    if version != VERSION {
        return Err(PacketError::Version(version));
    }
    let k = r.u16();
    if k != kind as u16 {
        return Err(PacketError::Kind(k));
    }
    let seq = r.u32();
    Ok((r, seq))
}

impl StatePacket {
    /// Writes the packet into `buf`; returns [`STATE_LEN`].
    pub fn encode(&self, buf: &mut [u8; STATE_LEN]) -> usize {
        let mut w = W { buf, at: 0 };
        w.header(Kind::State, self.seq);
        w.u64(self.arm_time_ns);
        w.f64s(&self.q);
        w.f64s(&self.qd);
        w.f64s(&self.tau);
        w.u32(self.status);
        w.u32(self.missed);
        w.u32(self.last_command_seq);
        w.u32(self.abort_after);
        w.finish()
    }

    /// Reads a state packet from a datagram.
    pub fn decode(buf: &[u8]) -> Result<StatePacket, PacketError> {
        let (mut r, seq) = open(buf, STATE_LEN, Kind::State)?;
        let arm_time_ns = r.u64();
        let q = r.f64s("q")?;
        let qd = r.f64s("qd")?;
        let tau = r.f64s("tau")?;
        Ok(StatePacket {
            seq,
            arm_time_ns,
            q,
            qd,
            tau,
            status: r.u32(),
            missed: r.u32(),
            last_command_seq: r.u32(),
            abort_after: r.u32(),
        })
    }
}

impl CommandPacket {
    /// Writes the packet into `buf`; returns [`COMMAND_LEN`].
    pub fn encode(&self, buf: &mut [u8; COMMAND_LEN]) -> usize {
        let mut w = W { buf, at: 0 };
        w.header(Kind::Command, self.seq);
        w.u32(self.state_seq);
        w.u16(self.mode as u16);
        w.u16(0);
        w.f64s(&self.tau);
        w.f64s(&self.q);
        w.f64s(&self.qd);
        w.finish()
    }

    /// Reads a command packet from a datagram.
    pub fn decode(buf: &[u8]) -> Result<CommandPacket, PacketError> {
        let (mut r, seq) = open(buf, COMMAND_LEN, Kind::Command)?;
        let state_seq = r.u32();
        let mode = match r.u16() {
            0 => Mode::Hold,
            1 => Mode::Torque,
            2 => Mode::Servo,
            m => return Err(PacketError::Mode(m)),
        };
        let _reserved = r.u16();
        Ok(CommandPacket { seq, state_seq, mode, tau: r.f64s("tau")?, q: r.f64s("q")?, qd: r.f64s("qd")? })
    }
}

/// The kind of a datagram from its header (without checking it further), to dispatch on.
pub fn kind_of(buf: &[u8]) -> Option<Kind> {
    (buf.len() >= HEADER_LEN && buf[..4] == MAGIC.to_le_bytes()).then_some(())?;
    match u16::from_le_bytes([buf[6], buf[7]]) {
        1 => Some(Kind::State),
        2 => Some(Kind::Command),
        _ => None,
    }
}
