//! Trajectories through intermediate joint-space waypoints without stopping.
//!
//! Method (not time-optimal, see the crate README for measurements):
//! 1. Estimate each section's duration by a synchronized rest-to-rest motion.
//! 2. Choose a pass-through velocity per joint and waypoint: zero where the
//!    joint reverses direction (or does not move), else the smaller of the two
//!    adjacent sections' average speeds; acceleration 0. Then scale each
//!    waypoint's velocities by a factor from {0, 0.5, 1, 1.5, 2, 3, 4}
//!    (clamped to the velocity limit), chosen by two sweeps of coordinate
//!    descent on the total duration.
//! 3. Compute each section as a time-optimal, time-synchronized state-to-state
//!    motion from the previous section's end state, so all joints pass each
//!    waypoint together. If a section is infeasible with the chosen velocities
//!    they are halved, then zeroed (stop at that waypoint).

use crate::{KinState, Limits, Options, OtgError, Trajectory, MAX_WAYPOINTS};

impl<const N: usize> Trajectory<N> {
    /// Trajectory from `current` through `waypoints` (positions, passed in
    /// order without stopping) to `target`, within `limits`. `options.sync`
    /// applies per section; `min_duration` applies to the whole trajectory's
    /// last section, `period` to every section. At most [`MAX_WAYPOINTS`].
    pub fn calculate_waypoints(
        current: &KinState<N>,
        waypoints: &[[f64; N]],
        target: &KinState<N>,
        limits: &Limits<N>,
        options: &Options<N>,
    ) -> Result<Self, OtgError> {
        let k = waypoints.len();
        if k > MAX_WAYPOINTS {
            return Err(OtgError::TooManyWaypoints { given: k, max: MAX_WAYPOINTS });
        }
        for w in waypoints {
            crate::sync::validate_state(&KinState::rest(*w), &crate::sync::TGT)?;
        }
        if k == 0 {
            return Self::calculate(current, target, limits, options);
        }
        let sec_opts = Options { min_duration: None, ..*options };
        // Section duration estimates (rest to rest).
        let mut est = [0.0f64; MAX_WAYPOINTS + 1];
        let point = |i: usize| -> [f64; N] {
            if i == 0 {
                current.p
            } else if i <= k {
                waypoints[i - 1]
            } else {
                target.p
            }
        };
        for (i, e) in est.iter_mut().enumerate().take(k + 1) {
            let tr =
                Self::calculate(&KinState::rest(point(i)), &KinState::rest(point(i + 1)), limits, &sec_opts)?;
            *e = tr.duration();
        }
        // Base pass-through velocities.
        let mut base = [[0.0f64; N]; MAX_WAYPOINTS];
        for (i, bv) in base.iter_mut().enumerate().take(k) {
            for j in 0..N {
                let din = point(i + 1)[j] - point(i)[j];
                let dout = point(i + 2)[j] - point(i + 1)[j];
                if din * dout > 0.0 && est[i] > 0.0 && est[i + 1] > 0.0 {
                    bv[j] = (din / est[i]).abs().min((dout / est[i + 1]).abs()) * din.signum();
                }
            }
        }
        // Per-waypoint speed factors, refined by coordinate descent on the
        // total duration (each factor only affects its two adjacent sections).
        const FACTORS: [f64; 7] = [0.0, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0];
        let mut fac = [1.0f64; MAX_WAYPOINTS];
        let state_at = |i: usize, fac: &[f64; MAX_WAYPOINTS]| -> KinState<N> {
            if i == 0 {
                return *current;
            }
            if i == k + 1 {
                return *target;
            }
            let mut s = KinState::rest(point(i));
            for j in 0..N {
                s.v[j] = (base[i - 1][j] * fac[i - 1]).clamp(-limits.v_max[j], limits.v_max[j]);
            }
            s
        };
        let sec_dur = |i: usize, fac: &[f64; MAX_WAYPOINTS]| -> f64 {
            Self::calculate(&state_at(i, fac), &state_at(i + 1, fac), limits, &sec_opts)
                .map_or(f64::INFINITY, |t| t.duration())
        };
        for _sweep in 0..2 {
            for w in 0..k {
                let mut best = (f64::INFINITY, fac[w]);
                for f in FACTORS {
                    let mut trial = fac;
                    trial[w] = f;
                    let d = sec_dur(w, &trial) + sec_dur(w + 1, &trial);
                    if d < best.0 {
                        best = (d, f);
                    }
                }
                fac[w] = best.1;
            }
        }
        let mut out = Self::hold(current);
        let mut state = *current;
        for i in 0..=k {
            let last = i == k;
            let mut goal = state_at(i + 1, &fac);
            let o = if last {
                Options {
                    min_duration: options.min_duration.map(|m| (m - out.duration).max(0.0)),
                    ..*options
                }
            } else {
                sec_opts
            };
            let mut sec = Self::calculate(&state, &goal, limits, &o);
            for scale in [0.5, 0.0] {
                if sec.is_ok() || last {
                    break;
                }
                let mut g = goal;
                for v in g.v.iter_mut() {
                    *v *= scale;
                }
                sec = Self::calculate(&state, &g, limits, &o);
                if sec.is_ok() {
                    goal = g;
                }
            }
            let sec = sec?;
            out.append(&sec)?;
            state = goal;
        }
        Ok(out)
    }

    /// Append `other` (which must start where `self` ends) after `self`.
    pub(crate) fn append(&mut self, other: &Trajectory<N>) -> Result<(), OtgError> {
        let t0 = self.duration;
        for j in 0..N {
            let n = self.n_seg[j];
            let m = other.n_seg[j];
            if n + m > crate::MAX_SEGMENTS {
                return Err(OtgError::TooManyWaypoints { given: n + m, max: crate::MAX_SEGMENTS });
            }
            for s in 0..m {
                let mut sg = other.seg[j][s];
                sg.t0 += t0;
                sg.t1 += t0;
                self.seg[j][n + s] = sg;
            }
            self.n_seg[j] = n + m;
            self.end[j] = other.end[j];
        }
        self.duration = t0 + other.duration;
        Ok(())
    }
}
