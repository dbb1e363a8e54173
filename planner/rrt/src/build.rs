//! Writing a plan (jerk-limited pieces and rests, back to back) into the fixed-size
//! [`Trajectory`] message the tracker follows.

use dkrrt_msg::{JerkSegment, Trajectory, Zeroed, MAX_SEGMENTS, NJ};

/// The message ran out of segments.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("joint {joint} needs more than the {max} segments a trajectory message carries")]
pub struct TooManySegments {
    pub joint: usize,
    pub max: usize,
}

/// Appends pieces to a message trajectory.
pub struct Builder<'a> {
    out: &'a mut Trajectory,
    t: f64,
}

impl<'a> Builder<'a> {
    /// Starts an empty trajectory `traj_id` whose time 0 is plant time `start_ns`.
    pub fn new(out: &'a mut Trajectory, traj_id: u64, start_ns: u64) -> Self {
        *out = <Trajectory as Zeroed>::zeroed();
        out.traj_id = traj_id;
        out.start_ns = start_ns;
        Builder { out, t: 0.0 }
    }

    /// Trajectory time so far, s.
    pub fn duration(&self) -> f64 {
        self.t
    }

    fn push(&mut self, j: usize, s: JerkSegment) -> Result<(), TooManySegments> {
        let n = self.out.n_seg[j] as usize;
        if n > 0 && s.t0 <= self.out.seg[j][n - 1].t0 {
            // Zero-length predecessor: the new segment replaces it.
            self.out.seg[j][n - 1] = s;
            return Ok(());
        }
        if n == MAX_SEGMENTS {
            return Err(TooManySegments { joint: j, max: MAX_SEGMENTS });
        }
        self.out.seg[j][n] = s;
        self.out.n_seg[j] = n as u32 + 1;
        Ok(())
    }

    /// Appends a generated trajectory (it must start where the plan so far ends).
    pub fn otg(&mut self, tr: &dkrrt_otg::Trajectory<NJ>) -> Result<(), TooManySegments> {
        let t0 = self.t;
        for j in 0..NJ {
            let segs = tr.joint_segments(j);
            if segs.is_empty() {
                let s = tr.at(0.0);
                self.push(j, JerkSegment { t0, p: s.p[j], v: s.v[j], a: s.a[j], j: 0.0 })?;
            }
            for s in segs.iter().filter(|s| s.t1 > s.t0) {
                self.push(j, JerkSegment { t0: t0 + s.t0, p: s.p0, v: s.v0, a: s.a0, j: s.jerk })?;
            }
        }
        self.t += tr.duration();
        Ok(())
    }

    /// Appends a rest at `q` for `dur` seconds.
    pub fn rest(&mut self, q: &[f64; NJ], dur: f64) -> Result<(), TooManySegments> {
        if dur <= 0.0 {
            return Ok(());
        }
        let t0 = self.t;
        for (j, &p) in q.iter().enumerate() {
            self.push(j, JerkSegment { t0, p, v: 0.0, a: 0.0, j: 0.0 })?;
        }
        self.t += dur;
        Ok(())
    }

    /// Ends the plan: `duration_s` set, every joint has a first segment at time 0.
    pub fn finish(self) -> f64 {
        self.out.duration_s = self.t;
        for j in 0..NJ {
            if self.out.n_seg[j] == 0 {
                self.out.n_seg[j] = 1;
            }
            self.out.seg[j][0].t0 = 0.0;
        }
        self.t
    }
}
