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
