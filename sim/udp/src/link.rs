//! Sequence bookkeeping of one direction of the link (docs/udp-protocol.md: `seq` +1 per
//! packet, wrapping at 2³²): which arrivals are new, late (out of order) or duplicated, and how
//! many packets were lost. What the driver and the emulator report as the link's figures, and
//! what decides whether a packet is used (only the newest is).

/// What an arriving packet is, relative to those seen before.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Arrival {
    /// Newer than every packet so far: use it.
    New,
    /// Older than the newest, not seen before (reordered or delayed): count it, do not use it.
    Late,
    /// Seen before (a duplicated datagram): drop it.
    Duplicate,
}

/// Counters of one direction, allocation-free. Packets are told apart within a window of the
/// last 64 sequence numbers; older arrivals count as late (and stay counted as lost). Gaps
/// are counted from the first packet seen, for sessions shorter than 2³¹ packets (24 days at
/// 1 kHz).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct SeqStats {
    /// Packets received (every arrival, duplicates included).
    pub received: u64,
    /// Sequence numbers below the newest that have not arrived (so far).
    pub lost: u64,
    /// Arrivals older than the newest, seen for the first time.
    pub late: u64,
    /// Arrivals seen before.
    pub duplicates: u64,
}

/// Tracks the sequence numbers of one direction.
#[derive(Debug, Clone, Copy, Default)]
pub struct SeqTracker {
    /// The first sequence number seen: gaps are counted from it on.
    first: u32,
    newest: Option<u32>,
    /// Bit `i`: sequence number `newest - i` has arrived.
    window: u64,
    pub stats: SeqStats,
}

impl SeqTracker {
    pub fn new() -> Self {
        Self::default()
    }

    /// The newest sequence number so far.
    pub fn newest(&self) -> Option<u32> {
        self.newest
    }

    /// Records an arrival of `seq`.
    pub fn on_packet(&mut self, seq: u32) -> Arrival {
        self.stats.received += 1;
        let Some(newest) = self.newest else {
            self.first = seq;
            self.newest = Some(seq);
            self.window = 1;
            return Arrival::New;
        };
        // Signed distance on the 2^32 circle: ahead if within half of it.
        let d = seq.wrapping_sub(newest) as i32;
        if d > 0 {
            let d = d as u64;
            self.stats.lost += d - 1;
            self.window = if d >= 64 { 0 } else { self.window << d };
            self.window |= 1;
            self.newest = Some(seq);
            return Arrival::New;
        }
        if d == 0 {
            self.stats.duplicates += 1;
            return Arrival::Duplicate;
        }
        let age = d.unsigned_abs() as u64;
        if age < 64 {
            let bit = 1u64 << age;
            if self.window & bit != 0 {
                self.stats.duplicates += 1;
                return Arrival::Duplicate;
            }
            self.window |= bit;
            // It was counted lost when a newer one arrived first (unless it precedes the first
            // packet seen, where no gap was counted).
            if seq.wrapping_sub(self.first) as i32 > 0 {
                self.stats.lost -= 1;
            }
        }
        self.stats.late += 1;
        Arrival::Late
    }
}
