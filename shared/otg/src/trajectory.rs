//! The calculated trajectory: fixed-size per-joint constant-jerk segments,
//! sampled in O(log MAX_SEGMENTS).

use crate::profile::{integrate, Profile};
use crate::{KinState, MAX_SEGMENTS};

/// One constant-jerk piece of one joint's motion, valid on `[t0, t1]`
/// (absolute trajectory time). At time `t` in it:
/// `p = p0 + v0 τ + a0 τ²/2 + jerk τ³/6` with `τ = t − t0`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Segment {
    pub t0: f64,
    pub t1: f64,
    pub p0: f64,
    pub v0: f64,
    pub a0: f64,
    pub jerk: f64,
}

impl Segment {
    const ZERO: Segment = Segment { t0: 0.0, t1: 0.0, p0: 0.0, v0: 0.0, a0: 0.0, jerk: 0.0 };

    /// `(p, v, a)` at absolute time `t` (not clamped to the segment).
    #[inline]
    pub fn state_at(&self, t: f64) -> (f64, f64, f64) {
        integrate(t - self.t0, self.p0, self.v0, self.a0, self.jerk)
    }
}

/// Position, velocity, acceleration and jerk of all joints at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample<const N: usize> {
    pub p: [f64; N],
    pub v: [f64; N],
    pub a: [f64; N],
    pub j: [f64; N],
}

impl<const N: usize> Sample<N> {
    /// The kinematic state (without jerk).
    pub fn state(&self) -> KinState<N> {
        KinState { p: self.p, v: self.v, a: self.a }
    }
}

/// Smallest and largest position one joint reaches, and when.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Extrema {
    pub min: f64,
    pub max: f64,
    pub t_min: f64,
    pub t_max: f64,
}

/// A multi-joint, piecewise-constant-jerk trajectory (fixed size, `Copy`).
///
/// Create it with [`Trajectory::calculate`] (position interface),
/// [`Trajectory::calculate_velocity`] (velocity interface) or the waypoint
/// and online APIs. Sampling clamps time to `[0, duration]`: before the start
/// it returns the initial state, at and after the end the exact final state
/// (for the position interface, the target state).
#[derive(Clone, Copy, Debug)]
pub struct Trajectory<const N: usize> {
    pub(crate) duration: f64,
    pub(crate) n_seg: [usize; N],
    pub(crate) seg: [[Segment; MAX_SEGMENTS]; N],
    pub(crate) end: [[f64; 3]; N],
}

impl<const N: usize> Trajectory<N> {
    /// A trajectory of zero duration holding `state`.
    pub fn hold(state: &KinState<N>) -> Self {
        let mut t = Trajectory {
            duration: 0.0,
            n_seg: [0; N],
            seg: [[Segment::ZERO; MAX_SEGMENTS]; N],
            end: [[0.0; 3]; N],
        };
        for j in 0..N {
            t.end[j] = [state.p[j], state.v[j], state.a[j]];
        }
        t
    }

    /// Build from one profile per joint. `finals[j]` is the exact state the
    /// profile of joint `j` ends in (snapped target); joints whose profile ends
    /// before `duration` continue from it with zero jerk.
    pub(crate) fn from_profiles(profiles: &[Profile; N], finals: &[[f64; 3]; N], duration: f64) -> Self {
        let mut tr = Trajectory {
            duration,
            n_seg: [0; N],
            seg: [[Segment::ZERO; MAX_SEGMENTS]; N],
            end: [[0.0; 3]; N],
        };
        tr.fill(profiles, finals, duration);
        tr
    }

    /// [`Trajectory::from_profiles`] written into `self`: only the segments in use are
    /// written (those past `n_seg` are never read), so refilling a trajectory costs what it
    /// holds, not its capacity (18.7 kB for six joints).
    pub(crate) fn fill(&mut self, profiles: &[Profile; N], finals: &[[f64; 3]; N], duration: f64) {
        let tr = self;
        tr.duration = duration;
        for j in 0..N {
            let pr = &profiles[j];
            let (mut p, mut v, mut a) = (pr.p0, pr.v0, pr.a0);
            let mut t = 0.0;
            let mut k = 0;
            for i in 0..pr.n {
                let dt = pr.t[i];
                tr.seg[j][k] = Segment { t0: t, t1: t + dt, p0: p, v0: v, a0: a, jerk: pr.j[i] };
                k += 1;
                (p, v, a) = integrate(dt, p, v, a, pr.j[i]);
                t += dt;
            }
            let [fp, fv, fa] = finals[j];
            if k > 0 {
                tr.seg[j][k - 1].t1 = t.min(duration);
            }
            if duration > t {
                tr.seg[j][k] = Segment { t0: t, t1: duration, p0: fp, v0: fv, a0: fa, jerk: 0.0 };
                k += 1;
                let (ep, ev, ea) = integrate(duration - t, fp, fv, fa, 0.0);
                tr.end[j] = [ep, ev, ea];
            } else {
                tr.end[j] = [fp, fv, fa];
            }
            tr.n_seg[j] = k;
        }
    }

    /// Total duration in seconds.
    pub fn duration(&self) -> f64 {
        self.duration
    }

    /// State and jerk of every joint at time `t` (clamped to `[0, duration]`).
    pub fn at(&self, t: f64) -> Sample<N> {
        let mut s = Sample { p: [0.0; N], v: [0.0; N], a: [0.0; N], j: [0.0; N] };
        let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, self.duration) };
        for j in 0..N {
            let n = self.n_seg[j];
            if t >= self.duration || n == 0 {
                let [p, v, a] = self.end[j];
                (s.p[j], s.v[j], s.a[j]) = (p, v, a);
                continue;
            }
            let segs = &self.seg[j][..n];
            let k = segs.partition_point(|sg| sg.t0 <= t).saturating_sub(1);
            let sg = &segs[k];
            (s.p[j], s.v[j], s.a[j]) = sg.state_at(t);
            s.j[j] = sg.jerk;
        }
        s
    }

    /// The state at the end of the trajectory.
    pub fn final_state(&self) -> KinState<N> {
        let mut k = KinState::default();
        for j in 0..N {
            (k.p[j], k.v[j], k.a[j]) = (self.end[j][0], self.end[j][1], self.end[j][2]);
        }
        k
    }

    /// Joint `j`'s constant-jerk segments, in time order, covering `[0, duration]`
    /// (empty for a zero-duration trajectory). At most [`MAX_SEGMENTS`].
    /// Panics if `j >= N`.
    pub fn joint_segments(&self, j: usize) -> &[Segment] {
        &self.seg[j][..self.n_seg[j]]
    }

    /// Each joint's largest speed `|v|` over `[0, duration]` (exact: at the segments' ends and
    /// where their acceleration crosses zero, [`speed_peak`]). A point of the arm moved by
    /// this trajectory moves at most `Σ_j peak_j · lever_j`.
    pub fn speed_peaks(&self) -> [f64; N] {
        let mut out = [0.0; N];
        for (j, m) in out.iter_mut().enumerate() {
            *m = self.end[j][1].abs();
            for sg in self.joint_segments(j) {
                *m = m.max(speed_peak(sg.v0, sg.a0, sg.jerk, sg.t1 - sg.t0));
            }
        }
        out
    }

    /// Each joint's position extrema over `[0, duration]`.
    pub fn position_extrema(&self) -> [Extrema; N] {
        let mut out = [Extrema { min: 0.0, max: 0.0, t_min: 0.0, t_max: 0.0 }; N];
        for (j, e) in out.iter_mut().enumerate() {
            let p_end = self.end[j][0];
            *e = Extrema { min: p_end, max: p_end, t_min: self.duration, t_max: self.duration };
            let mut consider = |p: f64, t: f64| {
                if p < e.min {
                    e.min = p;
                    e.t_min = t;
                }
                if p > e.max {
                    e.max = p;
                    e.t_max = t;
                }
            };
            for sg in self.joint_segments(j) {
                consider(sg.p0, sg.t0);
                for tau in turning_points(sg.v0, sg.a0, sg.jerk, sg.t1 - sg.t0) {
                    if !tau.is_nan() {
                        consider(sg.state_at(sg.t0 + tau).0, sg.t0 + tau);
                    }
                }
            }
        }
        out
    }
}

/// The times `τ ∈ (0, len)` where a constant-jerk piece turns, `v(τ) = v0 + a0 τ + jerk τ²/2 = 0`
/// (NaN where there is none): with its ends, where its position has its extremes.
#[inline]
pub fn turning_points(v0: f64, a0: f64, jerk: f64, len: f64) -> [f64; 2] {
    let (a2, b, c) = (jerk / 2.0, a0, v0);
    let mut roots = [f64::NAN; 2];
    if a2 != 0.0 {
        let disc = b * b - 4.0 * a2 * c;
        if disc >= 0.0 {
            let q = -0.5 * (b + b.signum() * disc.sqrt());
            roots = [q / a2, if q != 0.0 { c / q } else { 0.0 }];
        }
    } else if b != 0.0 {
        roots[0] = -c / b;
    }
    roots.map(|tau| if tau > 0.0 && tau < len { tau } else { f64::NAN })
}

/// The largest `|v(τ)|` of a constant-jerk piece over `τ ∈ [0, len]`, with
/// `v(τ) = v0 + a0 τ + jerk τ²/2`: the larger of its ends and, where the acceleration
/// `a0 + jerk τ` crosses zero inside the piece, the turning point.
#[inline]
pub fn speed_peak(v0: f64, a0: f64, jerk: f64, len: f64) -> f64 {
    let len = len.max(0.0);
    let v_at = |t: f64| v0 + t * (a0 + t * jerk / 2.0);
    let mut m = v0.abs().max(v_at(len).abs());
    if jerk != 0.0 {
        let tz = -a0 / jerk;
        if tz > 0.0 && tz < len {
            m = m.max(v_at(tz).abs());
        }
    }
    m
}
