//! Link bookkeeping: loss, reordering and duplication counted against the ground truth.

use dkrrt_udp::link::{Arrival, SeqTracker};
use proptest::prelude::*;

#[test]
fn loss_reordering_and_duplicates_are_told_apart() {
    let mut t = SeqTracker::new();
    let arrivals: Vec<Arrival> =
        [10, 11, 13, 12, 12, 14, 18, 16, 11].iter().map(|&s| t.on_packet(s)).collect();
    use Arrival::*;
    assert_eq!(arrivals, [New, New, New, Late, Duplicate, New, New, Late, Duplicate]);
    // 15 and 17 never came; 12 and 16 came late; 12 and 11 twice.
    assert_eq!((t.stats.received, t.stats.lost, t.stats.late, t.stats.duplicates), (9, 2, 2, 2));
    assert_eq!(t.newest(), Some(18));
}

#[test]
fn sequence_numbers_wrap_at_two_to_the_32() {
    let mut t = SeqTracker::new();
    assert_eq!(t.on_packet(u32::MAX - 1), Arrival::New);
    assert_eq!(t.on_packet(1), Arrival::New); // u32::MAX and 0 skipped
    assert_eq!(t.on_packet(u32::MAX), Arrival::Late);
    assert_eq!(t.on_packet(2), Arrival::New);
    assert_eq!((t.stats.lost, t.stats.late), (1, 1));
}

#[test]
fn a_long_gap_counts_every_missing_packet() {
    let mut t = SeqTracker::new();
    t.on_packet(0);
    assert_eq!(t.on_packet(1000), Arrival::New);
    assert_eq!(t.stats.lost, 999);
    // Far older than the window: late, and still counted lost (it cannot be told apart).
    assert_eq!(t.on_packet(500), Arrival::Late);
    assert_eq!(t.stats.lost, 999);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 500, ..ProptestConfig::default() })]

    /// 200 packets sent in order, each dropped, duplicated or delayed by up to 40 places: the
    /// counters equal what happened.
    #[test]
    fn counters_match_what_the_network_did(
        start in any::<u32>(),
        fate in proptest::collection::vec((0u8..10, 0usize..40), 200),
    ) {
        // Build the arrival order: (arrival position, seq).
        let mut arrivals: Vec<(usize, u32)> = Vec::new();
        for (i, &(f, delay)) in fate.iter().enumerate() {
            let seq = start.wrapping_add(i as u32);
            match f {
                0 => {}                                            // lost
                1 => { arrivals.push((i * 50, seq)); arrivals.push((i * 50 + 1, seq)); } // duplicated
                2 => arrivals.push((i * 50 + delay * 50 + 25, seq)), // delayed (reordered)
                _ => arrivals.push((i * 50, seq)),
            }
        }
        arrivals.sort();
        let mut t = SeqTracker::new();
        let mut newest: Option<u32> = None;
        let mut seen = std::collections::HashSet::new();
        let (mut dup, mut late) = (0u64, 0u64);
        for &(_, seq) in &arrivals {
            let a = t.on_packet(seq);
            let offset = seq.wrapping_sub(start);
            let first = seen.insert(offset);
            let is_new = newest.is_none_or(|n| offset > n);
            let want = if !first { dup += 1; Arrival::Duplicate } else if is_new { Arrival::New } else { late += 1; Arrival::Late };
            prop_assert_eq!(a, want);
            if is_new && first { newest = Some(offset); }
        }
        // Gaps count from the first packet that arrived.
        let first = arrivals.first().map(|a| a.1.wrapping_sub(start));
        let lost = match (first, newest) {
            (Some(f), Some(n)) => (f..=n).filter(|o| !seen.contains(o)).count() as u64,
            _ => 0,
        };
        prop_assert_eq!(t.stats.received, arrivals.len() as u64);
        prop_assert_eq!((t.stats.lost, t.stats.late, t.stats.duplicates), (lost, late, dup));
    }
}
