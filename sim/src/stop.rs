//! The controlled stop of a session, as every driver runs it (docs/driver-contract.md): the
//! simulator (`dkrrt sim`) and the network driver (`dkrrt udp-driver`) call the same policy.
//!
//! A stop begins on a stop request (SIGINT/SIGTERM) or when the session's duration is over with
//! the arm moving. From then on every state carries `FLAG_STOPPING` (the tracker brakes to
//! rest, sources plan nothing); the session ends once the arm has been at rest for
//! [`REST_TICKS`] states. An arm not at rest [`STOP_BRAKE_AFTER_S`] after the request gets its
//! brakes (and commands are no longer applied); the session ends after [`STOP_LIMIT_S`] in any
//! case. Plain data, no clock of its own: the caller passes the tick.

/// A joint slower than this is at rest, rad/s.
pub const REST_SPEED_RAD_S: f64 = 1e-4;
/// A hold answers position noise σ_q (rad) in its measurements with real motion: at the loop's
/// bandwidth √kp it moves by about √kp·σ_q per second at most (and by a small share of a
/// velocity noise σ_qd). The rest test's speed for a plant measured with that noise: at least
/// [`REST_SPEED_RAD_S`], and three times that motion (with `noise_q_std = 1e-4` rad and kp =
/// 400 the hold jitters at about 1.4e-4 rad/s, which a 1e-4 rad/s test never called rest: the
/// run ended in a forced brake).
pub fn rest_speed(noise_q_std: f64, noise_qd_std: f64, kp_max: f64) -> f64 {
    REST_SPEED_RAD_S.max(3.0 * (noise_qd_std + kp_max.max(0.0).sqrt() * noise_q_std))
}

/// [`rest_speed`] for the scenario's measurement noise (`sim.noise_*`: the sim's, and the
/// emulated arm's over UDP) and the tracker's stiffest joint: what `dkrrt sim` and
/// `dkrrt udp-driver` give their [`StopPolicy`].
pub fn scenario_rest_speed(sc: &dkrrt_config::Scenario) -> f64 {
    let kp_max = sc.tracker.kp.iter().fold(0.0f64, |m, &k| m.max(k));
    rest_speed(sc.sim.noise_q_std, sc.sim.noise_qd_std, kp_max)
}

/// The run ends once the arm has been at rest this many ticks in a row (after a stop
/// request, or at the end of its duration).
pub const REST_TICKS: u64 = 50;
/// A controlled stop that has not brought the arm to rest after this much plant time engages
/// the joint brakes (and ignores commands from then on), s.
pub const STOP_BRAKE_AFTER_S: f64 = 5.0;
/// A controlled stop ends the run after this much plant time whatever the arm does, s.
pub const STOP_LIMIT_S: f64 = 15.0;

/// Why and how the run's controlled stop went (`null` in the report: no stop phase).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct StopReport {
    /// `signal` (SIGINT/SIGTERM) or `duration` (the run's duration was over with the arm moving).
    pub cause: &'static str,
    /// Plant time the stop began, s.
    pub t_s: f64,
    /// Plant time from the stop request to rest (or to the stop limit), s.
    pub stop_time_s: f64,
    /// The joint brakes were engaged because the controller had not brought the arm to rest.
    pub brakes_forced: bool,
    /// The arm was at rest when the run ended.
    pub at_rest: bool,
}

/// What the driver does this tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct StopStep {
    /// The stop began at this tick (drop lockstep gates, say so).
    pub began: bool,
    /// A stop is under way: set `FLAG_STOPPING` in the state.
    pub stopping: bool,
    /// Engage the joint brakes now (once; from then on apply no command).
    pub engage_brakes: bool,
    /// The brakes were forced: apply no command.
    pub forced: bool,
    /// This tick's state is the session's last (`FLAG_END_OF_RUN`).
    pub last: bool,
}

/// The stop policy of one session.
#[derive(Debug, Clone)]
pub struct StopPolicy {
    control_hz: f64,
    total_ticks: u64,
    brake_ticks: u64,
    limit_ticks: u64,
    rest_ticks: u64,
    /// A joint slower than this is at rest ([`REST_SPEED_RAD_S`], or [`rest_speed`]).
    rest_speed: f64,
    stop_k: u64,
    report: Option<StopReport>,
    /// A stop request (not the duration) began the stop.
    pub stopped_by_signal: bool,
}

impl StopPolicy {
    /// A session of `total_ticks` ticks at `control_hz`.
    pub fn new(control_hz: f64, total_ticks: u64) -> StopPolicy {
        StopPolicy {
            control_hz,
            total_ticks,
            brake_ticks: (STOP_BRAKE_AFTER_S * control_hz) as u64,
            limit_ticks: (STOP_LIMIT_S * control_hz) as u64,
            rest_ticks: 0,
            rest_speed: REST_SPEED_RAD_S,
            stop_k: 0,
            report: None,
            stopped_by_signal: false,
        }
    }

    /// The rest test's speed, rad/s (at least [`REST_SPEED_RAD_S`]; see [`rest_speed`]).
    pub fn with_rest_speed(mut self, v: f64) -> StopPolicy {
        self.rest_speed = v.max(REST_SPEED_RAD_S);
        self
    }

    /// Tick `k` (ticks since the session began, increasing; gaps allowed) with the arm's largest
    /// measured joint speed and whether a stop was requested.
    pub fn tick(&mut self, k: u64, max_speed: f64, stop_requested: bool) -> StopStep {
        self.rest_ticks = if max_speed < self.rest_speed { self.rest_ticks + 1 } else { 0 };
        let at_rest = self.rest_ticks >= REST_TICKS;
        let mut step = StopStep::default();
        if self.report.is_none() && (stop_requested || (k >= self.total_ticks && !at_rest)) {
            self.stopped_by_signal |= stop_requested;
            self.stop_k = k;
            step.began = true;
            self.report = Some(StopReport {
                cause: if stop_requested { "signal" } else { "duration" },
                t_s: k as f64 / self.control_hz,
                stop_time_s: 0.0,
                brakes_forced: false,
                at_rest: false,
            });
        }
        match self.report.as_mut() {
            None => step.last = k >= self.total_ticks,
            Some(st) => {
                let since = k.saturating_sub(self.stop_k);
                if since >= self.brake_ticks && !st.brakes_forced && !at_rest {
                    st.brakes_forced = true;
                    step.engage_brakes = true;
                }
                st.stop_time_s = since as f64 / self.control_hz;
                st.at_rest = at_rest;
                step.stopping = true;
                step.forced = st.brakes_forced;
                step.last = at_rest || since >= self.limit_ticks;
            }
        }
        step
    }

    /// The stop so far (`None`: none began).
    pub fn report(&self) -> Option<StopReport> {
        self.report
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_session_at_rest_ends_at_its_duration_without_a_stop() {
        let mut p = StopPolicy::new(1000.0, 100);
        for k in 0..100 {
            let s = p.tick(k, 0.0, false);
            assert!(!s.last && !s.stopping, "tick {k}");
        }
        let s = p.tick(100, 0.0, false);
        assert!(s.last && !s.stopping);
        assert!(p.report().is_none());
    }

    #[test]
    fn a_moving_arm_at_the_duration_stops_then_ends_once_at_rest() {
        let mut p = StopPolicy::new(1000.0, 10);
        for k in 0..10 {
            assert!(!p.tick(k, 0.5, false).stopping);
        }
        let s = p.tick(10, 0.5, false);
        assert!(s.began && s.stopping && !s.last);
        for k in 11..20 {
            assert!(!p.tick(k, 0.1, false).last);
        }
        let mut end = None;
        for k in 20..200 {
            if p.tick(k, 0.0, false).last {
                end = Some(k);
                break;
            }
        }
        // At rest from tick 20: the 50th resting state is tick 69.
        assert_eq!(end, Some(20 + REST_TICKS - 1));
        let r = p.report().unwrap();
        assert_eq!(r.cause, "duration");
        assert!(r.at_rest && !r.brakes_forced);
    }

    #[test]
    fn a_stop_request_that_never_brings_rest_forces_the_brakes_then_ends_at_the_limit() {
        let hz = 100.0;
        let mut p = StopPolicy::new(hz, 1_000_000);
        let s = p.tick(7, 1.0, true);
        assert!(s.began && s.stopping);
        let (mut braked_at, mut end) = (None, None);
        for k in 8..10_000 {
            let s = p.tick(k, 1.0, false);
            if s.engage_brakes {
                assert!(braked_at.is_none(), "brakes engaged once");
                braked_at = Some(k);
            }
            if braked_at.is_some() {
                assert!(s.forced);
            }
            if s.last {
                end = Some(k);
                break;
            }
        }
        assert_eq!(braked_at, Some(7 + (STOP_BRAKE_AFTER_S * hz) as u64));
        assert_eq!(end, Some(7 + (STOP_LIMIT_S * hz) as u64));
        let r = p.report().unwrap();
        assert!(r.brakes_forced && !r.at_rest && p.stopped_by_signal);
        assert_eq!(r.cause, "signal");
    }
}
