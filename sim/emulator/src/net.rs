//! The emulated network between the arm and its driver: every datagram offered to a
//! [`DelayLine`] comes out after a one-way delay plus uniform jitter, or never (loss), or twice
//! (duplication), or one period later than its successor (reordering). Fixed capacity, no
//! allocation after construction, seeded: the same seed gives the same impairments.

use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

/// The largest datagram the line carries, bytes (the protocol's packets are 168 and 184).
pub const MAX_DATAGRAM: usize = 256;
/// Datagrams in flight at most (at 1 kHz: 64 ms of delay).
pub const CAPACITY: usize = 64;

/// What the network does to each datagram.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Impairment {
    /// One-way delay, ns.
    pub delay_ns: u64,
    /// Uniform random extra delay in [0, jitter_ns], ns.
    pub jitter_ns: u64,
    /// Probability of loss.
    pub loss: f64,
    /// Probability of a second copy (delayed independently).
    pub duplicate: f64,
    /// Probability of being held back `reorder_ns` more (it then arrives after its successor).
    pub reorder: f64,
    /// The hold-back of a reordered datagram, ns (one period of the sender).
    pub reorder_ns: u64,
}

impl Impairment {
    /// The impairments of a scenario's `[udp]` section for a sender of period `period_ns`.
    pub fn from_scenario(u: &dkrrt_config::UdpCfg, period_ns: u64) -> Impairment {
        Impairment {
            delay_ns: (u.delay_ms * 1e6).round() as u64,
            jitter_ns: (u.jitter_ms * 1e6).round() as u64,
            loss: u.loss,
            duplicate: u.duplicate,
            reorder: u.reorder,
            reorder_ns: period_ns.saturating_mul(3) / 2,
        }
    }

    /// Nothing happens to the datagrams.
    pub fn is_none(&self) -> bool {
        self.delay_ns == 0
            && self.jitter_ns == 0
            && self.loss == 0.0
            && self.duplicate == 0.0
            && self.reorder == 0.0
    }
}

/// What the line did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct NetStats {
    pub offered: u64,
    pub delivered: u64,
    /// Lost on purpose (`loss`).
    pub lost: u64,
    pub duplicated: u64,
    pub reordered: u64,
    /// Dropped because the line was full (more than [`CAPACITY`] in flight) or too long.
    pub overflow: u64,
}

#[derive(Clone, Copy)]
struct Slot {
    due_ns: u64,
    /// Offer order: ties in `due_ns` leave in the order they came.
    order: u64,
    len: usize,
    buf: [u8; MAX_DATAGRAM],
}

/// One direction of the emulated network.
pub struct DelayLine {
    imp: Impairment,
    slots: heapless::Vec<Slot, CAPACITY>,
    rng: SmallRng,
    order: u64,
    pub stats: NetStats,
}

impl DelayLine {
    pub fn new(imp: Impairment, seed: u64) -> DelayLine {
        DelayLine {
            imp,
            slots: heapless::Vec::new(),
            rng: SmallRng::seed_from_u64(seed),
            order: 0,
            stats: NetStats::default(),
        }
    }

    fn delay(&mut self) -> u64 {
        let j = if self.imp.jitter_ns > 0 { self.rng.random_range(0..=self.imp.jitter_ns) } else { 0 };
        self.imp.delay_ns + j
    }

    fn put(&mut self, due_ns: u64, datagram: &[u8]) {
        if datagram.len() > MAX_DATAGRAM {
            self.stats.overflow += 1;
            return;
        }
        let mut buf = [0u8; MAX_DATAGRAM];
        buf[..datagram.len()].copy_from_slice(datagram);
        self.order += 1;
        if self.slots.push(Slot { due_ns, order: self.order, len: datagram.len(), buf }).is_err() {
            self.stats.overflow += 1;
        }
    }

    /// Offers a datagram at `now_ns`.
    pub fn push(&mut self, now_ns: u64, datagram: &[u8]) {
        self.stats.offered += 1;
        if self.imp.loss > 0.0 && self.rng.random_bool(self.imp.loss) {
            self.stats.lost += 1;
            return;
        }
        let mut due = now_ns + self.delay();
        if self.imp.reorder > 0.0 && self.rng.random_bool(self.imp.reorder) {
            self.stats.reordered += 1;
            due += self.imp.reorder_ns;
        }
        self.put(due, datagram);
        if self.imp.duplicate > 0.0 && self.rng.random_bool(self.imp.duplicate) {
            self.stats.duplicated += 1;
            let due = now_ns + self.delay();
            self.put(due, datagram);
        }
    }

    /// When the next datagram is due (`None`: nothing in flight).
    pub fn next_due(&self) -> Option<u64> {
        self.slots.iter().map(|s| s.due_ns).min()
    }

    /// Takes the earliest datagram due at `now_ns` into `out`; returns its length.
    pub fn pop_due(&mut self, now_ns: u64, out: &mut [u8; MAX_DATAGRAM]) -> Option<usize> {
        let i = (0..self.slots.len())
            .filter(|&i| self.slots[i].due_ns <= now_ns)
            .min_by_key(|&i| (self.slots[i].due_ns, self.slots[i].order))?;
        let s = self.slots.swap_remove(i);
        out[..s.len].copy_from_slice(&s.buf[..s.len]);
        self.stats.delivered += 1;
        Some(s.len)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn drain(line: &mut DelayLine, until_ns: u64) -> Vec<(u64, u8)> {
        let mut out = Vec::new();
        let mut buf = [0u8; MAX_DATAGRAM];
        let mut t = 0;
        while t <= until_ns {
            while let Some(n) = line.pop_due(t, &mut buf) {
                assert_eq!(n, 3);
                out.push((t, buf[0]));
            }
            t += 10_000;
        }
        out
    }

    #[test]
    fn an_ideal_line_passes_everything_at_once_in_order() {
        let mut l = DelayLine::new(Impairment::default(), 1);
        let mut buf = [0u8; MAX_DATAGRAM];
        for i in 0..10u8 {
            l.push(u64::from(i) * 1000, &[i, 0, 0]);
            assert_eq!(l.pop_due(u64::from(i) * 1000, &mut buf), Some(3));
            assert_eq!(buf[0], i);
        }
        assert_eq!(l.stats.delivered, 10);
    }

    #[test]
    fn delay_and_jitter_stay_within_their_bounds() {
        let imp = Impairment { delay_ns: 500_000, jitter_ns: 200_000, ..Default::default() };
        let mut l = DelayLine::new(imp, 7);
        for i in 0..50u8 {
            l.push(u64::from(i) * 1_000_000, &[i, 0, 0]);
        }
        let got = drain(&mut l, 60_000_000);
        assert_eq!(got.len(), 50);
        for (t, i) in got {
            let sent = u64::from(i) * 1_000_000;
            assert!(t >= sent + 500_000 && t <= sent + 700_000 + 10_000, "{i}: {t}");
        }
    }

    #[test]
    fn loss_duplication_and_reordering_happen_at_their_rates() {
        let imp = Impairment {
            loss: 0.1,
            duplicate: 0.05,
            reorder: 0.05,
            reorder_ns: 1_500_000,
            ..Default::default()
        };
        let mut l = DelayLine::new(imp, 3);
        let n = 20_000u64;
        let mut buf = [0u8; MAX_DATAGRAM];
        let (mut got, mut out_of_order, mut last) = (0u64, 0u64, 0u64);
        for i in 0..n {
            let t = i * 1_000_000;
            l.push(t, &i.to_le_bytes());
            while let Some(_) = l.pop_due(t, &mut buf) {
                let s = u64::from_le_bytes(buf[..8].try_into().unwrap());
                if s < last {
                    out_of_order += 1;
                }
                last = last.max(s);
                got += 1;
            }
        }
        let f = |x: u64| x as f64 / n as f64;
        assert!((f(l.stats.lost) - 0.1).abs() < 0.01, "{:?}", l.stats);
        assert!((f(l.stats.duplicated) - 0.9 * 0.05).abs() < 0.01, "{:?}", l.stats);
        assert!((f(l.stats.reordered) - 0.9 * 0.05).abs() < 0.01, "{:?}", l.stats);
        // A held-back datagram arrives after its successor.
        assert!(out_of_order > 0 && out_of_order <= l.stats.reordered, "{out_of_order} {:?}", l.stats);
        assert!(got + 2 >= n - l.stats.lost + l.stats.duplicated - 2);
        assert_eq!(l.stats.overflow, 0);
    }

    #[test]
    fn the_same_seed_gives_the_same_network() {
        let imp = Impairment { jitter_ns: 300_000, loss: 0.2, ..Default::default() };
        let run = || {
            let mut l = DelayLine::new(imp, 99);
            for i in 0..200u8 {
                l.push(u64::from(i) * 1_000_000, &[i, 1, 2]);
            }
            drain(&mut l, 300_000_000)
        };
        assert_eq!(run(), run());
    }
}
