//! Sampling and building [`Trajectory`] messages (piecewise-constant jerk per joint).

use crate::types::*;

/// Desired joint state sampled from a trajectory.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct JointSample {
    pub p: [f64; NJ],
    pub v: [f64; NJ],
    pub a: [f64; NJ],
    pub j: [f64; NJ],
}

#[inline]
fn eval(s: &JerkSegment, dt: f64) -> (f64, f64, f64) {
    let p = s.p + dt * (s.v + dt * (s.a / 2.0 + dt * s.j / 6.0));
    let v = s.v + dt * (s.a + dt * s.j / 2.0);
    let a = s.a + dt * s.j;
    (p, v, a)
}

impl Trajectory {
    /// Segment index of joint `j` active at time `t` (binary search).
    fn segment_at(&self, j: usize, t: f64) -> usize {
        let n = (self.n_seg[j] as usize).clamp(1, MAX_SEGMENTS);
        let segs = &self.seg[j][..n];
        // First segment whose t0 > t, minus one.
        segs.partition_point(|s| s.t0 <= t).saturating_sub(1)
    }

    /// (p, v, a, jerk) of joint `j` at trajectory time `t` (s). Before 0 the
    /// start state is held; after `duration_s` the end position is held with
    /// the end velocity and acceleration continued by the last segment (a
    /// well-formed trajectory ends at rest, so that is a hold).
    pub fn sample_joint(&self, j: usize, t: f64) -> (f64, f64, f64, f64) {
        let t = t.clamp(0.0, self.duration_s);
        let k = self.segment_at(j, t);
        let s = &self.seg[j][k];
        let (p, v, a) = eval(s, t - s.t0);
        (p, v, a, s.j)
    }

    /// Samples all joints at trajectory time `t` (s).
    pub fn sample(&self, t: f64) -> JointSample {
        let mut out = JointSample::default();
        for j in 0..NJ {
            let (p, v, a, jj) = self.sample_joint(j, t);
            out.p[j] = p;
            out.v[j] = v;
            out.a[j] = a;
            out.j[j] = jj;
        }
        if t >= self.duration_s {
            out.j = [0.0; NJ];
        }
        out
    }

    /// Trajectory time (s) of plant time `stamp_ns`.
    pub fn time_of(&self, stamp_ns: u64) -> f64 {
        (stamp_ns as i128 - self.start_ns as i128) as f64 * 1e-9
    }

    /// A trajectory that holds `q` at rest (one segment per joint).
    pub fn hold(q: &[f64; NJ]) -> Trajectory {
        let mut t = <Trajectory as Zeroed>::zeroed();
        for j in 0..NJ {
            t.n_seg[j] = 1;
            t.seg[j][0] = JerkSegment { t0: 0.0, p: q[j], v: 0.0, a: 0.0, j: 0.0 };
        }
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_constant_jerk_segments_continuously() {
        let mut t = Trajectory::hold(&[0.0; NJ]);
        // Joint 0: jerk +1 for 1 s, then jerk -1 for 1 s: a = t then 1 - (t-1).
        t.duration_s = 2.0;
        t.n_seg[0] = 2;
        t.seg[0][0] = JerkSegment { t0: 0.0, p: 0.0, v: 0.0, a: 0.0, j: 1.0 };
        t.seg[0][1] = JerkSegment { t0: 1.0, p: 1.0 / 6.0, v: 0.5, a: 1.0, j: -1.0 };
        let s = t.sample(0.5);
        assert!((s.p[0] - 0.5f64.powi(3) / 6.0).abs() < 1e-15);
        assert!((s.a[0] - 0.5).abs() < 1e-15);
        let s = t.sample(1.5);
        assert!((s.a[0] - 0.5).abs() < 1e-12);
        assert!((s.v[0] - (0.5 + 0.5 * 1.0 - 0.125)).abs() < 1e-12);
        // After the end: held at the end state.
        let end = t.sample(2.0);
        let after = t.sample(5.0);
        assert_eq!(end.p, after.p);
        assert_eq!(after.j, [0.0; NJ]);
        // Before the start: the start state.
        assert_eq!(t.sample(-1.0).p[0], 0.0);
    }

    #[test]
    fn time_of_handles_stamps_before_start() {
        let mut t = Trajectory::hold(&[0.0; NJ]);
        t.start_ns = 2_000_000_000;
        assert_eq!(t.time_of(1_000_000_000), -1.0);
        assert_eq!(t.time_of(2_500_000_000), 0.5);
    }
}
