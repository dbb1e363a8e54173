//! Preallocated latency histograms (HdrHistogram, ns resolution, 3 significant
//! digits). Recording never allocates: values beyond the range saturate.

use hdrhistogram::Histogram;

/// Percentiles of a latency histogram, in µs.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Percentiles {
    pub p50: f64,
    pub p99: f64,
    pub p999: f64,
    pub max: f64,
    pub mean: f64,
    pub count: u64,
}

/// A histogram of durations in ns, 1 ns .. 10 s.
pub struct LatencyHist {
    h: Histogram<u64>,
}

impl Default for LatencyHist {
    fn default() -> Self {
        Self::new()
    }
}

impl LatencyHist {
    pub fn new() -> Self {
        let h = Histogram::new_with_bounds(1, 10_000_000_000, 3).expect("valid histogram bounds");
        LatencyHist { h }
    }

    /// Records one duration (ns); allocation-free.
    #[inline]
    pub fn record_ns(&mut self, ns: u64) {
        self.h.saturating_record(ns.max(1));
    }

    pub fn len(&self) -> u64 {
        self.h.len()
    }

    pub fn is_empty(&self) -> bool {
        self.h.is_empty()
    }

    /// The percentile curve (HdrHistogram style): `(nines, µs)` points, `nines = -log10(1 - q)`
    /// (1 = 90 %, 2 = 99 %, 3 = 99.9 %), up to the largest value. Allocates (reporting only).
    pub fn curve_us(&self) -> Vec<(f64, f64)> {
        let mut out = Vec::new();
        if self.h.is_empty() {
            return out;
        }
        let top = 1.0 - 1.0 / self.h.len() as f64;
        for v in self.h.iter_quantiles(4) {
            let q = v.quantile_iterated_to().min(top);
            let p = (
                -(1.0 - q).max(1e-12).log10(),
                self.h.highest_equivalent(v.value_iterated_to()) as f64 / 1000.0,
            );
            if out.last().is_none_or(|l: &(f64, f64)| p.0 > l.0 + 1e-9) {
                out.push(p);
            }
        }
        let last = (-(1.0 - top).max(1e-12).log10(), self.h.max() as f64 / 1000.0);
        match out.last_mut() {
            Some(l) if last.0 <= l.0 + 1e-9 => l.1 = l.1.max(last.1),
            _ => out.push(last),
        }
        for p in &mut out {
            p.0 = p.0.max(0.0);
        }
        out
    }

    /// Summary in µs.
    pub fn percentiles_us(&self) -> Percentiles {
        if self.h.is_empty() {
            return Percentiles::default();
        }
        let us = |ns: u64| ns as f64 / 1000.0;
        Percentiles {
            p50: us(self.h.value_at_quantile(0.5)),
            p99: us(self.h.value_at_quantile(0.99)),
            p999: us(self.h.value_at_quantile(0.999)),
            max: us(self.h.max()),
            mean: self.h.mean() / 1000.0,
            count: self.h.len(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_curve_rises_with_the_nines_and_ends_at_the_max() {
        let mut h = LatencyHist::new();
        for i in 1..=10_000u64 {
            h.record_ns(i * 100); // 0.1 .. 1000 µs, uniform
        }
        let c = h.curve_us();
        assert!(c.len() > 10);
        assert!(c.windows(2).all(|w| w[1].0 > w[0].0 && w[1].1 >= w[0].1), "{c:?}");
        // 99 % (2 nines) of a uniform 0..1000 µs is 990 µs.
        let at2 = c.iter().find(|p| p.0 >= 2.0 - 1e-9).unwrap();
        assert!((at2.1 - 990.0).abs() < 15.0, "{at2:?}");
        assert!((c.last().unwrap().1 - 1000.0).abs() < 1.0);
        assert!(LatencyHist::new().curve_us().is_empty());
    }

    #[test]
    fn percentiles_of_a_known_distribution() {
        let mut h = LatencyHist::new();
        for i in 1..=1000u64 {
            h.record_ns(i * 1000); // 1..1000 µs
        }
        let p = h.percentiles_us();
        assert_eq!(p.count, 1000);
        assert!((p.p50 - 500.0).abs() < 1.0, "{p:?}");
        assert!((p.p99 - 990.0).abs() < 1.5, "{p:?}");
        assert!((p.max - 1000.0).abs() < 1.0, "{p:?}");
    }

    #[test]
    fn out_of_range_values_saturate_instead_of_failing() {
        let mut h = LatencyHist::new();
        h.record_ns(u64::MAX);
        h.record_ns(0);
        assert_eq!(h.len(), 2);
    }
}
