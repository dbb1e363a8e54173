//! The bound's allowance for events that no forecast can foresee.
//!
//! The online calibration ([`crate::calib`]) scores a track's forecasts against its own later
//! poses, so it bounds what the object does between events. An impulse or a split changes
//! the object's motion at an instant its past cannot tell: every forecast made within the
//! horizon before it misses by what the event changed, however good the model. Whether a
//! bound meant to hold 99 % of the time must cover those misses depends on how often they
//! happen. If events fall into a fraction `p_e(k)` of all `k`-step forecast windows and a
//! fraction `b` of the forecasts may miss through them (the events' share of the miss
//! budget, [`crate::FitConfig::event_budget`]), then
//!
//! * `p_e(k) ≤ b`: the events may all miss; no allowance;
//! * `p_e(k) > b`: of the forecasts an event falls into, at most `b / p_e(k)` may miss. The
//!   allowance `k` steps ahead is `margin ·` the `1 − b / p_e(k)` quantile of their errors.
//!
//! The fraction and the errors come from the fit's validation forecasts on the training runs
//! ([`crate::Models::fit_bounds`]), where the simulator says when events fired
//! ([`crate::eval::Recording::events`]); never from the runs evaluated. A scene whose
//! training runs have no events gets no allowance. The allowance is non-decreasing in `k`
//! (like every bound here), per channel (position m, attitude rad).

use dkrrt_koopman::bound::{quantile, MAX_HORIZON};

/// Per-step allowance for unforeseeable events, position and attitude.
#[derive(Debug, Clone, PartialEq)]
pub struct EventAllowance {
    h: usize,
    pos: [f64; MAX_HORIZON],
    att: [f64; MAX_HORIZON],
    share: [f64; MAX_HORIZON],
}

/// A validation forecast of the fit: the first of its steps that an event on the object
/// falls into (`None`: none within the horizon), and its errors per step (`h` each).
#[derive(Debug, Clone, Copy)]
pub struct Sample<'a> {
    pub first_event: Option<usize>,
    pub pos: &'a [f64],
    pub att: &'a [f64],
}

impl EventAllowance {
    /// No allowance over `h` steps.
    pub fn none(h: usize) -> Self {
        let h = h.clamp(1, MAX_HORIZON);
        EventAllowance { h, pos: [0.0; MAX_HORIZON], att: [0.0; MAX_HORIZON], share: [0.0; MAX_HORIZON] }
    }

    /// The allowance from validation forecasts (module doc): `budget` is the events' share of
    /// the miss budget, `margin` the factor on the quantile.
    pub fn fit<'a>(
        samples: impl Iterator<Item = Sample<'a>> + Clone,
        h: usize,
        budget: f64,
        margin: f64,
    ) -> Self {
        let mut out = Self::none(h);
        let h = out.h;
        let n = samples.clone().count();
        if n == 0 {
            return out;
        }
        let (mut ep, mut ea) = (Vec::new(), Vec::new());
        let (mut run_p, mut run_a) = (0.0f64, 0.0f64);
        for k in 1..=h {
            ep.clear();
            ea.clear();
            for s in samples.clone().filter(|s| s.first_event.is_some_and(|e| e <= k)) {
                ep.push(s.pos.get(k - 1).copied().unwrap_or(f64::INFINITY));
                ea.push(s.att.get(k - 1).copied().unwrap_or(f64::INFINITY));
            }
            let share = ep.len() as f64 / n as f64;
            out.share[k - 1] = share;
            if share > budget {
                let level = 1.0 - budget / share;
                run_p = run_p.max(margin * quantile(&mut ep, level));
                run_a = run_a.max(margin * quantile(&mut ea, level));
            }
            (out.pos[k - 1], out.att[k - 1]) = (run_p, run_a);
        }
        out
    }

    /// Position allowance `k` steps ahead (clamped to `1..=h`) [m].
    pub fn pos(&self, k: usize) -> f64 {
        self.pos[k.clamp(1, self.h) - 1]
    }

    /// Attitude allowance `k` steps ahead (clamped to `1..=h`) [rad].
    pub fn att(&self, k: usize) -> f64 {
        self.att[k.clamp(1, self.h) - 1]
    }

    /// Raises `out[i]`, an attitude bound `i + 1` steps ahead, to at least the allowance.
    pub fn floor_att(&self, out: &mut [f64]) {
        out.iter_mut().enumerate().for_each(|(i, r)| *r = r.max(self.att(i + 1)));
    }

    /// Fraction of the `k`-step validation forecasts that an event fell into.
    pub fn share(&self, k: usize) -> f64 {
        self.share[k.clamp(1, self.h) - 1]
    }
}

/// The first step `k ≥ 1` of a forecast from `t0` on a grid of `dt` that an event at one of
/// `events` (ascending times) falls into: an event at `t` acts on the truth from step
/// `⌈(t − t0) / dt⌉` on (at least 1). `None` if none within `h` steps.
pub fn first_event_step(events: &[f64], t0: f64, dt: f64, h: usize) -> Option<usize> {
    let t = *events.iter().find(|&&t| t > t0 - 1e-9)?;
    let k = (((t - t0) / dt) - 1e-9).ceil().max(1.0) as usize;
    (k <= h).then_some(k)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Errors `h` steps long: `quiet` everywhere, plus `jump` from step `e` on.
    fn errs(h: usize, quiet: f64, e: Option<usize>, jump: f64) -> Vec<f64> {
        (1..=h).map(|k| quiet + if e.is_some_and(|e| k >= e) { jump } else { 0.0 }).collect()
    }

    #[test]
    fn the_first_event_step_counts_from_the_forecast_start() {
        let ev = [10.0, 15.0];
        assert_eq!(first_event_step(&ev, 9.5, 0.1, 10), Some(5));
        assert_eq!(first_event_step(&ev, 9.95, 0.1, 10), Some(1));
        assert_eq!(first_event_step(&ev, 10.0, 0.1, 10), Some(1), "an event at the start acts from step 1");
        assert_eq!(first_event_step(&ev, 8.0, 0.1, 10), None, "beyond the horizon");
        assert_eq!(first_event_step(&ev, 10.05, 0.1, 60), Some(50), "the next one");
        assert_eq!(first_event_step(&[], 0.0, 0.1, 10), None);
    }

    #[test]
    fn rare_events_get_no_allowance_and_frequent_ones_are_covered() {
        let h = 10;
        // 1000 forecasts; an event falls into `ne` of them at step 3.
        let run = |ne: usize, margin: f64| {
            let rows: Vec<(Option<usize>, Vec<f64>)> = (0..1000)
                .map(|i| {
                    let e = (i < ne).then_some(3);
                    // Event errors 0.1 .. 0.1 + ne·0.001, distinct, so the quantile shows.
                    (e, errs(h, 0.01, e, 0.1 + i as f64 * 0.001))
                })
                .collect();
            let s = rows.iter().map(|(e, v)| Sample { first_event: *e, pos: v, att: v });
            EventAllowance::fit(s, h, 0.005, margin)
        };
        let rare = run(4, 1.5);
        assert!((rare.share(10) - 0.004).abs() < 1e-12 && rare.pos(10) == 0.0, "0.4 % ≤ 0.5 %: none");
        let freq = run(20, 1.5);
        assert_eq!(freq.pos(2), 0.0, "before the event step nothing falls in");
        assert!((freq.share(3) - 0.02).abs() < 1e-12);
        // 20 event forecasts, 5 of 1000 may miss: the quantile 0.75 of 20 → index ⌈0.75·19⌉ = 15.
        let want = 1.5 * (0.01 + 0.1 + 15.0 * 0.001);
        assert!((freq.pos(3) - want).abs() < 1e-12, "{} vs {want}", freq.pos(3));
        assert!(freq.att(10) >= freq.att(3), "non-decreasing");
        // Without the margin, exactly the budget of all forecasts misses (5 of 1000).
        let bare = run(20, 1.0);
        let missed = (0..20).filter(|&i| 0.01 + 0.1 + i as f64 * 0.001 > bare.pos(3)).count();
        assert_eq!(missed, 4, "the 4 largest of 20 miss: within 5 of 1000");
    }
}
