//! Confidence intervals and paired tests for binary study outcomes (an episode completed or
//! not), as `dkrrt study` reports them.
//!
//! * [`wilson`]: the Wilson score interval of a proportion (well behaved at 0 % and 100 %,
//!   where the Wald interval collapses to a point).
//! * [`mcnemar_exact`]: the exact (binomial) McNemar test of two methods run on the same
//!   episodes: only the discordant episodes (one completed, the other not) carry
//!   information.
//! * [`paired_bootstrap`]: the difference of two completion rates on the same episodes with a
//!   percentile interval from resampling episodes (pairs kept together); seeded, so a study's
//!   numbers are reproducible.

use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

/// The normal quantile of a two-sided 95 % interval.
pub const Z95: f64 = 1.959_963_984_540_054;

/// Wilson score interval `(low, high)` of `k` successes in `n` trials at normal quantile `z`
/// (`(0, 1)` for `n = 0`).
pub fn wilson(k: u64, n: u64, z: f64) -> (f64, f64) {
    if n == 0 {
        return (0.0, 1.0);
    }
    let (k, n) = (k.min(n) as f64, n as f64);
    let p = k / n;
    let z2 = z * z;
    let d = 1.0 + z2 / n;
    let c = (p + z2 / (2.0 * n)) / d;
    let h = z * (p * (1.0 - p) / n + z2 / (4.0 * n * n)).sqrt() / d;
    ((c - h).max(0.0), (c + h).min(1.0))
}

/// Two-sided exact McNemar p-value for `b` pairs where only the first method succeeded and
/// `c` where only the second did: `min(1, 2 · P(X ≤ min(b, c)))` with `X ~ Binomial(b + c, ½)`
/// (1 when there are no discordant pairs).
pub fn mcnemar_exact(b: u64, c: u64) -> f64 {
    let n = b + c;
    if n == 0 {
        return 1.0;
    }
    let k = b.min(c);
    // Σ_{i ≤ k} C(n, i) / 2^n in logs (n can be in the hundreds).
    let ln2n = n as f64 * std::f64::consts::LN_2;
    let mut ln_c = 0.0; // ln C(n, 0)
    let mut tail = 0.0;
    for i in 0..=k {
        if i > 0 {
            ln_c += ((n - i + 1) as f64).ln() - (i as f64).ln();
        }
        tail += (ln_c - ln2n).exp();
    }
    (2.0 * tail).min(1.0)
}

/// A paired comparison of two methods on the same episodes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Paired {
    /// Episodes with both outcomes.
    pub n: u64,
    /// Completion rate of the first method minus that of the second.
    pub diff: f64,
    /// 95 % percentile bootstrap interval of `diff`.
    pub low: f64,
    pub high: f64,
    /// Discordant pairs: only the first / only the second completed.
    pub only_first: u64,
    pub only_second: u64,
    /// Exact McNemar p-value.
    pub p_value: f64,
}

/// Compares outcomes `(first, second)` per episode: the difference of completion rates with
/// a 95 % paired bootstrap interval (`reps` resamples of the episodes, seeded by `seed`) and
/// the exact McNemar test.
pub fn paired_bootstrap(pairs: &[(bool, bool)], reps: usize, seed: u64) -> Paired {
    let n = pairs.len();
    let only_first = pairs.iter().filter(|(a, b)| *a && !*b).count() as u64;
    let only_second = pairs.iter().filter(|(a, b)| !*a && *b).count() as u64;
    let p_value = mcnemar_exact(only_first, only_second);
    if n == 0 {
        return Paired { n: 0, diff: 0.0, low: 0.0, high: 0.0, only_first, only_second, p_value };
    }
    let diff = (only_first as f64 - only_second as f64) / n as f64;
    // Each pair contributes +1 (only first), −1 (only second) or 0.
    let d: Vec<i32> = pairs.iter().map(|(a, b)| *a as i32 - *b as i32).collect();
    let mut rng = SmallRng::seed_from_u64(seed);
    let mut stats: Vec<f64> = (0..reps.max(1))
        .map(|_| (0..n).map(|_| d[rng.random_range(0..n)]).sum::<i32>() as f64 / n as f64)
        .collect();
    stats.sort_by(f64::total_cmp);
    let q = |f: f64| stats[((f * (stats.len() - 1) as f64).round() as usize).min(stats.len() - 1)];
    Paired { n: n as u64, diff, low: q(0.025), high: q(0.975), only_first, only_second, p_value }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wilson_matches_published_values() {
        // Newcombe (1998), Table I: 81/263 → 0.2553–0.3662 (Wilson score, no correction).
        let (lo, hi) = wilson(81, 263, Z95);
        assert!((lo - 0.2553).abs() < 5e-4 && (hi - 0.3662).abs() < 5e-4, "{lo} {hi}");
        // 15/148 → 0.0624–0.1605.
        let (lo, hi) = wilson(15, 148, Z95);
        assert!((lo - 0.0624).abs() < 5e-4 && (hi - 0.1605).abs() < 5e-4, "{lo} {hi}");
        // The edges: 0/20 and 20/20 keep a non-trivial width (the Wald interval would not).
        let (lo, hi) = wilson(0, 20, Z95);
        assert_eq!(lo, 0.0);
        assert!((hi - 0.1611).abs() < 5e-4, "{hi}");
        let (lo, hi) = wilson(20, 20, Z95);
        assert!((lo - 0.8389).abs() < 5e-4 && hi == 1.0, "{lo}");
        assert_eq!(wilson(0, 0, Z95), (0.0, 1.0));
    }

    #[test]
    fn mcnemar_exact_matches_the_binomial_tail() {
        // b = 1, c = 9: 2 · (C(10,0) + C(10,1)) / 2^10 = 22 / 1024.
        assert!((mcnemar_exact(1, 9) - 22.0 / 1024.0).abs() < 1e-12);
        assert!((mcnemar_exact(9, 1) - 22.0 / 1024.0).abs() < 1e-12);
        // Balanced discordance: p = 1.
        assert_eq!(mcnemar_exact(5, 5), 1.0);
        assert_eq!(mcnemar_exact(0, 0), 1.0);
        // 0 vs 12: 2 / 4096.
        assert!((mcnemar_exact(0, 12) - 2.0 / 4096.0).abs() < 1e-15);
        // Large counts stay finite and in (0, 1].
        let p = mcnemar_exact(150, 210);
        assert!(p > 0.0 && p < 0.01, "{p}");
    }

    #[test]
    fn paired_difference_and_its_interval() {
        // 40 episodes: both complete 30, only the first 8, only the second 1, neither 1.
        let mut pairs = vec![(true, true); 30];
        pairs.extend(vec![(true, false); 8]);
        pairs.push((false, true));
        pairs.push((false, false));
        let p = paired_bootstrap(&pairs, 4000, 7);
        assert_eq!((p.n, p.only_first, p.only_second), (40, 8, 1));
        assert!((p.diff - 7.0 / 40.0).abs() < 1e-12);
        assert!(p.low < p.diff && p.diff < p.high, "{p:?}");
        assert!(p.low > 0.0, "8 vs 1 discordant: the interval excludes 0 ({p:?})");
        assert!(p.p_value < 0.05 && (p.p_value - mcnemar_exact(8, 1)).abs() < 1e-15);
        // Same seed, same interval; identical methods: a zero-width interval at 0.
        assert_eq!(paired_bootstrap(&pairs, 4000, 7), p);
        let same = paired_bootstrap(&vec![(true, true); 10], 100, 1);
        assert_eq!((same.diff, same.low, same.high, same.p_value), (0.0, 0.0, 0.0, 1.0));
    }
}
