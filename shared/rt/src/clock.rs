//! CLOCK_MONOTONIC time and absolute-deadline pacing.

/// CLOCK_MONOTONIC in ns. The same clock in every process on the machine.
#[inline]
pub fn mono_ns() -> u64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: valid pointer to a timespec; CLOCK_MONOTONIC always exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// Sleeps until CLOCK_MONOTONIC reaches `deadline_ns` (absolute, so sleeps
/// never accumulate drift). Retries on EINTR unless `stop` says to give up.
pub fn sleep_until(deadline_ns: u64, stop: impl Fn() -> bool) {
    let ts = libc::timespec {
        tv_sec: (deadline_ns / 1_000_000_000) as libc::time_t,
        tv_nsec: (deadline_ns % 1_000_000_000) as libc::c_long,
    };
    loop {
        // SAFETY: valid timespec; a null remainder is allowed with TIMER_ABSTIME.
        let rc = unsafe {
            libc::clock_nanosleep(libc::CLOCK_MONOTONIC, libc::TIMER_ABSTIME, &ts, core::ptr::null_mut())
        };
        if rc != libc::EINTR || stop() {
            return;
        }
    }
}

/// What happened at one wake-up of a [`Pacer`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Wake {
    /// Tick index of this wake-up.
    pub tick: u64,
    /// The absolute deadline of this tick, ns.
    pub deadline_ns: u64,
    /// When we actually woke, ns.
    pub woke_ns: u64,
    /// Ticks skipped because the previous iteration overran them.
    pub skipped: u64,
}

impl Wake {
    /// Wake-up latency: how late after the deadline we ran, ns.
    pub fn latency_ns(&self) -> u64 {
        self.woke_ns.saturating_sub(self.deadline_ns)
    }
}

/// Periodic loop on absolute CLOCK_MONOTONIC deadlines `phase + k·period`.
///
/// Deadlines sit on a grid anchored at the monotonic epoch, so processes
/// started separately with the same period tick in step; `phase_ns` shifts
/// one process against another (the tracker runs just after the plant).
/// A deadline miss is counted when an iteration's work ends after the next
/// deadline; the pacer then skips to the next future grid point.
pub struct Pacer {
    period_ns: u64,
    phase_ns: u64,
    next_deadline: u64,
    tick: u64,
    /// Total missed deadlines.
    pub misses: u64,
}

impl Pacer {
    /// A pacer whose first deadline is the next grid point at least `lead_ns` from now.
    pub fn new(period_ns: u64, phase_ns: u64, lead_ns: u64) -> Pacer {
        assert!(period_ns > 0, "period must be positive");
        let start = mono_ns() + lead_ns;
        let next = align_up(start, period_ns, phase_ns % period_ns);
        Pacer { period_ns, phase_ns: phase_ns % period_ns, next_deadline: next, tick: 0, misses: 0 }
    }

    pub fn period_ns(&self) -> u64 {
        self.period_ns
    }

    /// Sleeps until the next deadline and reports the wake-up.
    pub fn wait(&mut self, stop: impl Fn() -> bool) -> Wake {
        let now = mono_ns();
        let mut skipped = 0;
        if now > self.next_deadline {
            // Overran: this deadline already passed before we went to sleep.
            self.misses += 1;
            let late = now - self.next_deadline;
            skipped = late / self.period_ns;
            if skipped > 0 {
                self.next_deadline += skipped * self.period_ns;
                self.tick += skipped;
            }
        }
        sleep_until(self.next_deadline, stop);
        let w = Wake { tick: self.tick, deadline_ns: self.next_deadline, woke_ns: mono_ns(), skipped };
        self.next_deadline += self.period_ns;
        self.tick += 1;
        w
    }

    pub fn phase_ns(&self) -> u64 {
        self.phase_ns
    }

    /// Moves the grid to `phase_ns`: the next deadline is the first point of the new grid at
    /// least half a period after the last one (no tick is doubled or skipped).
    pub fn set_phase(&mut self, phase_ns: u64) {
        let phase = phase_ns % self.period_ns;
        let last = self.next_deadline - self.period_ns;
        self.next_deadline = align_up(last + self.period_ns / 2, self.period_ns, phase);
        self.phase_ns = phase;
    }
}

/// Follows the phase at which another process's messages arrive (a driver paced by its arm's
/// own clock, a network in between), so a periodic reader can wake just before them instead of
/// on a fixed phase that may sit just after them (it would then read every message a period
/// late). Arrival phases are averaged on the circle (a phase near the period's end and one near
/// its start are close); allocation-free.
#[derive(Debug, Clone)]
pub struct PhaseFollower {
    period_ns: u64,
    lead_ns: u64,
    sum_cos: f64,
    sum_sin: f64,
    n: u32,
    window: u32,
}

impl PhaseFollower {
    /// Suggests waking `lead_ns` before the mean arrival phase of each `window` arrivals.
    pub fn new(period_ns: u64, lead_ns: u64, window: u32) -> PhaseFollower {
        PhaseFollower { period_ns, lead_ns, sum_cos: 0.0, sum_sin: 0.0, n: 0, window: window.max(1) }
    }

    /// Records an arrival at CLOCK_MONOTONIC `t_ns`; every `window` arrivals returns the phase to
    /// wake at (mean arrival phase − lead, modulo the period), `None` in between or when the
    /// arrivals have no dominant phase (spread over the whole period).
    pub fn record(&mut self, t_ns: u64) -> Option<u64> {
        let a = (t_ns % self.period_ns) as f64 / self.period_ns as f64 * std::f64::consts::TAU;
        self.sum_cos += a.cos();
        self.sum_sin += a.sin();
        self.n += 1;
        if self.n < self.window {
            return None;
        }
        let (c, s, n) = (self.sum_cos, self.sum_sin, f64::from(self.n));
        (self.sum_cos, self.sum_sin, self.n) = (0.0, 0.0, 0);
        // Mean resultant length: 1 = all at one phase; near 0 = no phase to follow.
        if (c * c + s * s).sqrt() / n < 0.5 {
            return None;
        }
        let mean =
            s.atan2(c).rem_euclid(std::f64::consts::TAU) / std::f64::consts::TAU * self.period_ns as f64;
        let p = self.period_ns as f64;
        Some((mean - self.lead_ns as f64).rem_euclid(p) as u64 % self.period_ns)
    }
}

/// Smallest `t >= x` with `t ≡ phase (mod period)`.
pub fn align_up(x: u64, period: u64, phase: u64) -> u64 {
    let base = x - x % period + phase;
    if base >= x {
        base
    } else {
        base + period
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn align_up_lands_on_the_grid() {
        assert_eq!(align_up(1_000, 1_000, 0), 1_000);
        assert_eq!(align_up(1_001, 1_000, 0), 2_000);
        assert_eq!(align_up(1_001, 1_000, 300), 1_300);
        assert_eq!(align_up(1_400, 1_000, 300), 2_300);
    }

    #[test]
    fn the_follower_wakes_before_arrivals_also_across_the_period_boundary() {
        let period = 1_000_000;
        for (arrive, want) in [(550_000u64, 450_000u64), (30_000, 930_000), (980_000, 880_000)] {
            let mut f = PhaseFollower::new(period, 100_000, 100);
            let mut got = None;
            for k in 0..100u64 {
                // ±40 µs of jitter around the arrival phase, wrapping past the period's end.
                let jitter = (k * 7919 % 81) * 1000;
                got = f.record(k * period + arrive + period - 40_000 + jitter);
            }
            let got = got.expect("a phase after a window") as i64;
            let err = (got - want as i64).rem_euclid(period as i64);
            assert!(err.min(period as i64 - err) < 10_000, "arrive {arrive}: woke at {got}, want {want}");
        }
        // Arrivals spread over the whole period have no phase to follow.
        let mut f = PhaseFollower::new(period, 100_000, 100);
        let got = (0..100u64).map(|k| f.record(k * period + k * 10_000)).last().unwrap();
        assert_eq!(got, None);
    }

    #[test]
    fn moving_the_phase_neither_doubles_nor_skips_a_tick() {
        let mut p = Pacer::new(1_000_000, 50_000, 0);
        let a = p.wait(|| false);
        p.set_phase(450_000);
        let b = p.wait(|| false);
        assert_eq!(b.deadline_ns % 1_000_000, 450_000);
        assert_eq!(b.deadline_ns - a.deadline_ns, 1_400_000);
        p.set_phase(50_000);
        let c = p.wait(|| false);
        assert_eq!(c.deadline_ns - b.deadline_ns, 600_000);
    }

    #[test]
    fn pacer_deadlines_are_absolute_and_increasing() {
        let mut p = Pacer::new(1_000_000, 0, 0);
        let a = p.wait(|| false);
        let b = p.wait(|| false);
        assert_eq!(a.deadline_ns % 1_000_000, 0);
        assert!(b.deadline_ns > a.deadline_ns);
        assert_eq!((b.deadline_ns - a.deadline_ns) % 1_000_000, 0);
        assert!(a.woke_ns >= a.deadline_ns && b.woke_ns >= b.deadline_ns);
    }

    #[test]
    fn pacer_counts_an_overrun_as_a_miss() {
        let mut p = Pacer::new(1_000_000, 0, 0);
        p.wait(|| false);
        std::thread::sleep(std::time::Duration::from_millis(5));
        let w = p.wait(|| false);
        assert!(p.misses >= 1);
        assert!(w.skipped >= 3, "skipped {}", w.skipped);
    }
}
