//! The debris world in time, as the planner sees it: per track a shape and timed poses (from a
//! [`DebrisForecast`], or from a planning-problem file), any time `t` read as an inflated
//! obstacle.
//!
//! * Between poses: position linear, attitude slerp (`dkrrt_collision::interpolate_pose`, the
//!   same function the predictor puts its forecasts on the common grid with), σ linear.
//! * Before the first pose: for a **forecast** track, the motion of the first interval extended
//!   backwards (the forecast's `t0` is one step before its first pose); a **problem** obstacle
//!   is at its first pose (held, as its last is after it).
//! * A forecast's steps are first taken, each, as the attitude of the same shape nearest to
//!   the step before (`dkrrt_collision::pose::same_shape_nearest`: a rod's axis swung without
//!   the spin it does not show, a box's nearest half turn).
//! * Past the last pose of a **forecast** track (its horizon): the last interval's motion goes
//!   on (`dkrrt_collision::pose::continue_pose`: the centre at its velocity, the attitude at
//!   its rate on the same great circle), and each bound keeps growing at the larger of its
//!   mean rate since the forecast's start and its last interval's
//!   (`dkrrt_collision::bounds::growth_rate`; σ at least at σ_pos's rate); the object is in
//!   the shape inflated by σ and in the bounding ball inflated by σ_pos, as before the
//!   horizon (`dkrrt predict-eval` measures this reading: `ForecastBuffer::continued`). A
//!   track of one pose has no motion to go on with: past it, its bounding sphere. Past the
//!   last pose of a **problem** obstacle: the last pose is held, σ = 0.
//! * Inflation: σ(t) + the configured margin (+ what the checker's sampling can miss, added by
//!   the checker).
//!
//! Every track also carries a bound on how fast any point of its inflated surface moves
//! (|v| + ω·ℓ + dσ/dt over its intervals, ℓ the farthest a point of its shape lies from the
//! interval's turn axis, and over the extrapolation), and one on how fast its bounding ball
//! (radius + σ_pos) grows and moves (|v| + dσ_pos/dt), used by the checker to space its
//! samples. Loading a forecast allocates nothing (fixed capacity).

use dkrrt_collision::bounds::growth_rate;
use dkrrt_collision::pose::{quat_mul, same_shape_nearest, slerp_on, SlerpArc};
use dkrrt_collision::{quat_angle, Obstacle, PosedCapsule};
use dkrrt_model::NJ;
use dkrrt_msg::{DebrisForecast, DebrisShape, ShapeKind, FORECAST_STEPS, MAX_DEBRIS};

/// One timed pose of a track.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TimedPose {
    /// Plant time, s.
    pub t: f64,
    pub p: [f64; 3],
    /// (w, x, y, z).
    pub q: [f64; 4],
    /// Surface uncertainty bound of the shape (position + attitude), m.
    pub sigma: f64,
    /// Position uncertainty bound alone (for the bounding sphere), m.
    pub sigma_pos: f64,
}

/// What happens outside a track's poses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum After {
    /// Forecast: extrapolate, after the last pose and before the first (see the module docs).
    Extrapolate,
    /// Problem obstacle: hold the last pose after it, and the first before it.
    Hold,
}

#[derive(Debug, Clone)]
struct Track {
    id: u32,
    shape: DebrisShape,
    radius: f64,
    lever: f64,
    after: After,
    poses: Vec<TimedPose>,
    /// The slerp arc of each interval between consecutive poses (computed once per load).
    arcs: Vec<SlerpArc>,
    /// Max surface speed (incl. σ growth) over the poses and the extrapolation, m/s.
    speed: f64,
    /// The same per interval between consecutive poses (`speeds[k]`: poses `k`, `k + 1`), m/s.
    speeds: Vec<f64>,
    /// Per interval, the largest speed of the surface of the track's bounding ball (centre
    /// `p`, radius `radius + σ_pos` + inflation): `|Δp| + |Δσ_pos|` over the interval's
    /// length. No rotation, no attitude bound: a ball about the centre turns into itself.
    ball_speeds: Vec<f64>,
    /// Growth rate of the position bound after the last pose, m/s.
    sigma_rate: f64,
    /// Growth rate of the surface bound σ after the last pose (at least `sigma_rate`), m/s.
    surface_rate: f64,
    /// The poses' spacing when uniform (forecasts: their step), s; 0: not uniform.
    grid_dt: f64,
}

/// Why a world could not be built from a problem.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WorldError {
    #[error("obstacles: at most {max} (got {got})")]
    TooMany { got: usize, max: usize },
    #[error("obstacles[{index}].poses: {reason}")]
    Poses { index: usize, reason: String },
}

/// Most tracks a world holds: a planning-problem file's obstacles (a forecast carries at most
/// [`MAX_DEBRIS`]). Track sets are bit masks of a `u64`.
pub const MAX_TRACKS: usize = 64;
const _: () = assert!(MAX_DEBRIS <= MAX_TRACKS && MAX_TRACKS <= 64);

/// Tracks of the world in time (fixed capacity: [`MAX_TRACKS`] tracks).
#[derive(Debug, Clone)]
pub struct WorldInTime {
    tracks: Vec<Track>,
    n: usize,
    margin: f64,
    /// Time of the newest forecast (`t0`), s.
    pub t0: f64,
    /// End of the forecast horizon (last step), s.
    pub horizon_end: f64,
    /// The forecasts' bounds are taken times this (1: as published; 0: the predicted shapes
    /// themselves, where the objects most likely are), the margin unchanged
    /// ([`WorldInTime::set_bound_scale`]).
    bound_scale: std::cell::Cell<f64>,
}

impl WorldInTime {
    /// An empty world; obstacles are inflated by σ + `margin_m`.
    pub fn new(margin_m: f64) -> Self {
        let tracks = (0..MAX_TRACKS)
            .map(|_| Track {
                id: 0,
                shape: DebrisShape::default(),
                radius: 0.0,
                lever: 0.0,
                after: After::Hold,
                poses: Vec::with_capacity(FORECAST_STEPS + 1),
                arcs: Vec::with_capacity(FORECAST_STEPS + 1),
                speed: 0.0,
                speeds: Vec::with_capacity(FORECAST_STEPS + 1),
                ball_speeds: Vec::with_capacity(FORECAST_STEPS + 1),
                sigma_rate: 0.0,
                surface_rate: 0.0,
                grid_dt: 0.0,
            })
            .collect();
        WorldInTime {
            tracks,
            n: 0,
            margin: margin_m,
            t0: 0.0,
            horizon_end: 0.0,
            bound_scale: std::cell::Cell::new(1.0),
        }
    }

    pub fn margin(&self) -> f64 {
        self.margin
    }

    pub fn set_margin(&mut self, m: f64) {
        self.margin = m.max(0.0);
    }

    /// Takes the forecasts' bounds times `k ≥ 0` in every check until set back to 1 (0: the
    /// predicted shapes alone, grown by the margin: where the objects most likely are).
    pub fn set_bound_scale(&self, k: f64) {
        self.bound_scale.set(k.max(0.0));
    }

    /// Number of tracks.
    pub fn len(&self) -> usize {
        self.n
    }

    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Removes every track.
    pub fn clear(&mut self) {
        self.n = 0;
        self.t0 = 0.0;
        self.horizon_end = 0.0;
    }

    /// Replaces the tracks by a (validated) forecast's. Allocation-free.
    pub fn load_forecast(&mut self, f: &DebrisForecast) {
        self.n = 0;
        let steps = (f.steps as usize).min(FORECAST_STEPS);
        let t0 = f.t0_ns as f64 * 1e-9;
        self.t0 = t0;
        self.horizon_end = t0 + steps as f64 * f.dt_s;
        for tr in &f.tracks[..(f.count as usize).min(MAX_DEBRIS)] {
            let k = self.n;
            let t = &mut self.tracks[k];
            t.id = tr.id;
            t.shape = tr.shape;
            t.radius = tr.bounding_radius.max(tr.shape.bounding_radius());
            t.lever = tr.shape.rotation_lever(t.radius);
            t.after = After::Extrapolate;
            t.poses.clear();
            for (i, st) in tr.steps[..steps].iter().enumerate() {
                t.poses.push(TimedPose {
                    t: t0 + (i + 1) as f64 * f.dt_s,
                    p: st.p,
                    q: st.q,
                    sigma: st.sigma_m,
                    sigma_pos: st.sigma_pos_m.min(st.sigma_m),
                });
            }
            same_turn(t);
            finish(t);
            self.n += 1;
        }
    }

    /// Adds a track (a problem obstacle, or a test's). Allocates for more than
    /// `FORECAST_STEPS + 1` poses: not for planning cycles.
    pub fn push_track(
        &mut self,
        id: u32,
        shape: DebrisShape,
        poses: &[TimedPose],
        after: After,
    ) -> Result<(), WorldError> {
        if self.n >= MAX_TRACKS {
            return Err(WorldError::TooMany { got: self.n + 1, max: MAX_TRACKS });
        }
        if poses.is_empty() {
            return Err(WorldError::Poses { index: self.n, reason: "at least one pose".into() });
        }
        if poses.windows(2).any(|w| !(w[1].t > w[0].t)) {
            return Err(WorldError::Poses { index: self.n, reason: "times must increase".into() });
        }
        let t = &mut self.tracks[self.n];
        t.id = id;
        t.shape = shape;
        t.radius = shape.bounding_radius();
        t.lever = shape.rotation_lever(t.radius);
        t.after = after;
        t.poses.clear();
        t.poses.extend_from_slice(poses);
        finish(t);
        self.horizon_end = self.horizon_end.max(poses[poses.len() - 1].t);
        self.n += 1;
        Ok(())
    }

    /// The largest surface speed of any track (incl. σ growth), m/s.
    pub fn max_speed(&self) -> f64 {
        self.tracks[..self.n].iter().map(|t| t.speed).fold(0.0, f64::max)
    }

    /// Writes every track's obstacle at time `t`, inflated by σ(t) + margin + `extra`.
    pub fn obstacles_at(&self, t: f64, extra: f64, out: &mut Vec<Obstacle>) {
        self.obstacles_at_masked(t, extra, u64::MAX, out);
    }

    /// The tracks whose inflated shape (inflated by `extra` more) can come within `reach` of
    /// the sphere (`centre`, `radius`) at some time in `[t0, t1]`, as a bit mask (bit `i`:
    /// track `i`), and the largest speed among them over `[t0, t1]`
    /// ([`WorldInTime::speed_within`]). Conservative: at the window's middle every obstacle
    /// built for a track lies within its bounding radius + σ_pos + margin + extra of its
    /// centre (the object lies in its bounding sphere inflated by the position bound, and its
    /// distance is never below that ball's), and centre and σ_pos together move at most at the
    /// ball's speed over the window ([`WorldInTime::ball_speed_within`]), so over the half
    /// window it stays inside that sphere grown by that speed × half window.
    pub fn near(&self, t0: f64, t1: f64, centre: &[f64; 3], radius: f64, extra: f64) -> (u64, f64) {
        let mut speeds = [0.0; MAX_TRACKS];
        let mask = self.near_speeds(t0, t1, centre, radius, extra, &mut speeds);
        (mask, speeds.iter().fold(0.0, |a: f64, &b| a.max(b)))
    }

    /// [`WorldInTime::near`], with each kept track's speed over `[t0, t1]` in `speeds[i]` (0
    /// for the others).
    pub fn near_speeds(
        &self,
        t0: f64,
        t1: f64,
        centre: &[f64; 3],
        radius: f64,
        extra: f64,
        speeds: &mut [f64; MAX_TRACKS],
    ) -> u64 {
        let (tm, half) = (0.5 * (t0 + t1), 0.5 * (t1 - t0).max(0.0));
        let mut mask = 0u64;
        speeds.fill(0.0);
        for (i, tr) in self.tracks[..self.n].iter().enumerate() {
            let s = state_at(tr, tm);
            let r = tr.radius
                + s.sigma_pos
                + self.margin
                + extra
                + within(tr, &tr.ball_speeds, tr.sigma_rate, t0, t1) * half;
            if !(dist3(&s.p, centre) - r - radius > 0.0) {
                mask |= 1 << i;
                speeds[i] = speed_within(tr, t0, t1);
            }
        }
        mask
    }

    /// The largest surface speed (incl. σ growth) of track `i` over `[t0, t1]`, m/s: the
    /// largest of the intervals between its poses that overlap the window (a forecast track
    /// before its first pose: the first interval's; past the last: the last interval's plus
    /// the extrapolated σ growth; a problem obstacle stands still outside its poses: 0 for a
    /// window wholly before the first or after the last). At most [`WorldInTime::max_speed`].
    pub fn speed_within(&self, i: usize, t0: f64, t1: f64) -> f64 {
        speed_within(&self.tracks[i], t0, t1)
    }

    /// The largest speed of any point of the surface of track `i`'s bounding ball over
    /// `[t0, t1]`, m/s: the ball about its centre of radius `radius + σ_pos` plus the
    /// inflation, which holds every obstacle built for it at any attitude (the gaps of
    /// [`Gaps::ball`]). As [`WorldInTime::speed_within`] without the rotation and the
    /// attitude bound's growth: at most it.
    pub fn ball_speed_within(&self, i: usize, t0: f64, t1: f64) -> f64 {
        let tr = &self.tracks[i];
        within(tr, &tr.ball_speeds, tr.sigma_rate, t0, t1)
    }

    /// [`WorldInTime::obstacles_at`] for the tracks in `mask` only (see [`WorldInTime::near`]).
    pub fn obstacles_at_masked(&self, t: f64, extra: f64, mask: u64, out: &mut Vec<Obstacle>) {
        self.obstacles_within(t, extra, mask, None, out);
    }

    /// [`WorldInTime::obstacles_at_masked`], and with `near` without the tracks whose inflated
    /// shape at `t` lies `near.cap` or more from the arm's bounding sphere or from each of its
    /// capsules' bounding spheres (their attitude is never interpolated): what is left out
    /// could not lower a clearance capped at `near.cap`.
    pub fn obstacles_within(
        &self,
        t: f64,
        extra: f64,
        mask: u64,
        near: Option<Near>,
        out: &mut Vec<Obstacle>,
    ) {
        self.obstacles_gapped(t, extra, mask, near, out, None);
    }

    /// [`WorldInTime::obstacles_within`], and with `gaps`: for every track `i` of `mask` and
    /// arm capsule `k`, a lower bound on the clearance between its inflated shape and the
    /// capsule in `gaps.ball[i][k]` (from the bounding spheres: exact enough for the tracks
    /// left out, which lie `near.cap` or more away), and for every obstacle written its track
    /// in `gaps.track`. `gaps` needs `near`.
    pub fn obstacles_gapped(
        &self,
        t: f64,
        extra: f64,
        mask: u64,
        near: Option<Near>,
        out: &mut Vec<Obstacle>,
        mut gaps: Option<&mut Gaps>,
    ) {
        out.clear();
        for (i, tr) in self.tracks[..self.n].iter().enumerate() {
            if mask >> i & 1 == 0 {
                continue;
            }
            let mut s = state_at(tr, t);
            let k = self.bound_scale.get();
            (s.sigma, s.sigma_pos) = (s.sigma * k, s.sigma_pos * k);
            let base = self.margin + extra;
            if let Some(nr) = &near {
                // Every obstacle built below lies in the ball about `s.p` of radius `r`: its
                // bounding sphere inflated by the position bound (a shape's distance is the
                // larger of its own and that ball's).
                let r = tr.radius + s.sigma_pos + base;
                let g_arm = dist3(&s.p, nr.centre) - r - nr.radius;
                if g_arm >= nr.cap {
                    if let Some(g) = gaps.as_deref_mut() {
                        g.ball[i] = [g_arm; NJ];
                    }
                    continue;
                }
                // Per capsule: [`dkrrt_collision::clearance`] measures no pair whose bounding
                // spheres are `cap` apart, so a track no capsule comes that near to is left out
                // (before its attitude is interpolated). `r` bounds the obstacle's own bounding
                // sphere and inflation from `s.p`; the slack covers rounding, so what is left
                // out is exactly what `clearance` would have skipped.
                let mut per = [f64::INFINITY; NJ];
                for (d, c) in per.iter_mut().zip(nr.arm) {
                    *d = dist3(&s.p, &c.centre) - c.bound - r;
                }
                let g_caps = per.iter().fold(f64::INFINITY, |a, &b| a.min(b));
                if let Some(g) = gaps.as_deref_mut() {
                    // Each capsule lies in the arm's sphere too.
                    g.ball[i] = per.map(|d| d.max(g_arm));
                    g.track[out.len().min(MAX_TRACKS - 1)] = i as u8;
                }
                if !(g_caps < nr.cap + 1e-9) {
                    continue;
                }
            }
            // The object lies in the shape inflated by its surface bound and in the bounding
            // sphere inflated by the position bound: the arm's distance to it is at least the
            // larger of its distances to the two (the attitude is interpolated only when the
            // shape needs it). A track without a shape is its sphere alone.
            let o = if s.sphere {
                Obstacle::from_desc(tr.id, &DebrisShape::default(), tr.radius, &s.p, &ID, s.sigma_pos + base)
            } else {
                let q = if tr.lever > 0.0 || tr.shape.offset != [0.0; 3] { s.q() } else { ID };
                Obstacle::from_desc(tr.id, &tr.shape, tr.radius, &s.p, &q, s.sigma + base)
                    .with_ball(&s.p, tr.radius + s.sigma_pos + base)
            };
            // `out` has room for every track (allocation-free); a smaller one would drop some.
            debug_assert!(out.len() < out.capacity(), "obstacles_gapped: `out` holds fewer than the tracks");
            if out.len() < out.capacity() {
                out.push(o);
            }
        }
    }

    /// The pose of track `i` at `t`: (position, attitude, σ, σ of the position,
    /// shape-is-its-bounding-sphere).
    pub fn pose_at(&self, i: usize, t: f64) -> ([f64; 3], [f64; 4], f64, f64, bool) {
        pose_at(&self.tracks[i], t)
    }

    /// Shape of track `i`.
    pub fn shape(&self, i: usize) -> DebrisShape {
        self.tracks[i].shape
    }

    /// Id of track `i`.
    pub fn id(&self, i: usize) -> u32 {
        self.tracks[i].id
    }
}

/// A forecast's attitudes taken, step by step, as the attitude of the same shape nearest to
/// the step before ([`dkrrt_collision::pose::same_shape_nearest`]: a rod's or a disc's axis
/// swung from the step before, without a spin the shape does not show; a box's half turn
/// nearest to it), so the slerp between two steps, and past the last, moves the shape as
/// little as the steps allow (no reported flip swept end over end, no spin read as a tumble).
fn same_turn(t: &mut Track) {
    for k in 1..t.poses.len() {
        t.poses[k].q = same_shape_nearest(&t.shape, &t.poses[k - 1].q, &t.poses[k].q);
    }
}

fn finish(t: &mut Track) {
    let n = t.poses.len();
    t.arcs.clear();
    for w in t.poses.windows(2) {
        t.arcs.push(SlerpArc::between(&w[0].q, &w[1].q));
    }
    let r = t.radius;
    t.grid_dt = 0.0;
    if n >= 2 {
        let dt = t.poses[1].t - t.poses[0].t;
        if t.poses.windows(2).all(|w| ((w[1].t - w[0].t) - dt).abs() <= 1e-9 * dt) {
            t.grid_dt = dt;
        }
    }
    let mut speed: f64 = 0.0;
    t.speeds.clear();
    t.ball_speeds.clear();
    for w in t.poses.windows(2) {
        let dt = w[1].t - w[0].t;
        let dp = ((w[1].p[0] - w[0].p[0]).powi(2)
            + (w[1].p[1] - w[0].p[1]).powi(2)
            + (w[1].p[2] - w[0].p[2]).powi(2))
        .sqrt();
        let da = quat_angle(&w[0].q, &w[1].q);
        let lever = turn_lever(&t.shape, r, &w[0].q, &w[1].q);
        let ds = (w[1].sigma - w[0].sigma).abs();
        t.speeds.push((dp + da * lever + ds) / dt);
        t.ball_speeds.push((dp + (w[1].sigma_pos - w[0].sigma_pos).abs()) / dt);
        speed = speed.max((dp + da * lever + ds) / dt);
    }
    t.sigma_rate = 0.0;
    t.surface_rate = 0.0;
    if t.after == After::Extrapolate && n >= 1 {
        // Past the horizon each bound keeps growing ([`dkrrt_collision::bounds::growth_rate`];
        // the forecast's start is one step before its first pose).
        let last = t.poses[n - 1];
        let step = if n >= 2 { t.poses[1].t - t.poses[0].t } else { 1.0 };
        let span = last.t - t.poses[0].t + step;
        let prev = if n >= 2 { t.poses[n - 2] } else { last };
        let interval = last.t - prev.t;
        t.sigma_rate = growth_rate(last.sigma_pos, prev.sigma_pos, interval, span);
        t.surface_rate = growth_rate(last.sigma, prev.sigma, interval, span).max(t.sigma_rate);
        speed += t.surface_rate;
    }
    t.speed = speed;
}

/// How far from the turn's axis a point of `shape` (bounding radius `r`) can lie when its
/// attitude slerps from `qa` to `qb` (a turn about one body axis `n`): a point moves at most the
/// turn's rate times this. A capsule (along body z, half length `h`, radius `ρ`) is within
/// `|offset| + h·|n × z| + ρ` of the axis: spinning about its own axis moves its surface by
/// `ρ` only. A box is within its farthest corner's `|n × c|` (offset included: the largest
/// over the box is at a corner). A sphere turns into itself (its offset only). Other shapes: `r`.
fn turn_lever(shape: &DebrisShape, r: f64, qa: &[f64; 4], qb: &[f64; 4]) -> f64 {
    let o = &shape.offset;
    let off = (o[0] * o[0] + o[1] * o[1] + o[2] * o[2]).sqrt();
    let d = &shape.dims;
    // The turn's body axis (none: no turn, the bound is not used).
    let rel = quat_mul(&[qa[0], -qa[1], -qa[2], -qa[3]], qb);
    let len = (rel[1] * rel[1] + rel[2] * rel[2] + rel[3] * rel[3]).sqrt();
    if !(len > 1e-12) {
        return r;
    }
    let n = [rel[1] / len, rel[2] / len, rel[3] / len];
    let lever = match ShapeKind::from_u32(shape.kind) {
        Some(ShapeKind::Sphere) => off,
        Some(ShapeKind::Capsule) => off + d[0] * (n[0] * n[0] + n[1] * n[1]).sqrt() + d[1],
        Some(ShapeKind::Box) => (0..8)
            .map(|k| {
                // Corner `k` (offset included): |n × c|² = |c|² − (n·c)².
                let c: [f64; 3] = std::array::from_fn(|j| o[j] + if k >> j & 1 == 1 { d[j] } else { -d[j] });
                let along = n[0] * c[0] + n[1] * c[1] + n[2] * c[2];
                (c[0] * c[0] + c[1] * c[1] + c[2] * c[2] - along * along).max(0.0).sqrt()
            })
            .fold(0.0, f64::max),
        _ => r,
    };
    lever.min(r)
}

const ID: [f64; 4] = [1.0, 0.0, 0.0, 0.0];

fn dist3(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Per track, a lower bound on its clearance from the arm at one time, and the track of each
/// obstacle written ([`WorldInTime::obstacles_gapped`]).
#[derive(Debug, Clone, Copy)]
pub struct Gaps {
    /// `ball[i][k]`: every point of the ball about track `i`'s centre of radius `radius +
    /// σ_pos` + the inflation, which holds every obstacle built for it, is at
    /// least this far from the arm's capsule `k` (from the bounding spheres; its surface moves
    /// at [`WorldInTime::ball_speed_within`]), m.
    pub ball: [[f64; NJ]; MAX_TRACKS],
    /// `track[k]`: the track of the `k`-th obstacle written.
    pub track: [u8; MAX_TRACKS],
}

impl Default for Gaps {
    fn default() -> Self {
        Gaps { ball: [[f64::INFINITY; NJ]; MAX_TRACKS], track: [0; MAX_TRACKS] }
    }
}

/// Where the checker looks: the arm's posed capsules, their bounding sphere (`centre`,
/// `radius`), and the clearance cap (pairs farther apart are not measured).
#[derive(Debug, Clone, Copy)]
pub struct Near<'a> {
    pub arm: &'a [PosedCapsule],
    pub centre: &'a [f64; 3],
    pub radius: f64,
    pub cap: f64,
}

/// A track's state at a time, with the attitude left to compute ([`State::q`]).
struct State {
    p: [f64; 3],
    sigma: f64,
    sigma_pos: f64,
    sphere: bool,
    qa: [f64; 4],
    qb: [f64; 4],
    arc: SlerpArc,
    f: f64,
}

impl State {
    /// The attitude: [`dkrrt_collision::interpolate_pose`]'s between the bracketing steps
    /// (slerp, `f` below 0 taken as 0), and past the last step
    /// [`dkrrt_collision::pose::continue_pose`]'s (`f` > 1), with the interval's arc computed
    /// at load.
    fn q(&self) -> [f64; 4] {
        slerp_on(&self.qa, &self.qb, &self.arc, self.f.max(0.0))
    }
}

fn pose_at(tr: &Track, t: f64) -> ([f64; 3], [f64; 4], f64, f64, bool) {
    let s = state_at(tr, t);
    (s.p, s.q(), s.sigma, s.sigma_pos, s.sphere)
}

/// The interval `[k, k + 1]` of the poses (`n ≥ 2`) holding `t`, clamped to the first and
/// the last: the last pose at or before `t`.
fn interval_of(tr: &Track, t: f64) -> usize {
    let ps = &tr.poses;
    let n = ps.len();
    if t <= ps[0].t {
        0
    } else if tr.grid_dt > 0.0 {
        // Uniform steps: the interval straight from the time, then made exact (the last pose
        // at or before `t`, as the search below finds it).
        let mut k = (((t - ps[0].t) / tr.grid_dt) as usize).min(n - 2);
        while k + 2 < n && ps[k + 1].t <= t {
            k += 1;
        }
        while k > 0 && ps[k].t > t {
            k -= 1;
        }
        k
    } else {
        ps.partition_point(|p| p.t <= t).saturating_sub(1).min(n - 2)
    }
}

fn speed_within(tr: &Track, t0: f64, t1: f64) -> f64 {
    within(tr, &tr.speeds, tr.surface_rate, t0, t1)
}

/// The largest of `speeds` (per interval) over the intervals overlapping `[t0, t1]`, with the
/// extrapolation's σ growth past the last pose (see [`WorldInTime::speed_within`]).
fn within(tr: &Track, speeds: &[f64], rate: f64, t0: f64, t1: f64) -> f64 {
    let n = tr.poses.len();
    if n < 2 {
        // No interval: only σ grows (extrapolated), or nothing moves (held).
        return tr.speed;
    }
    // A problem obstacle stands still before its first pose and after its last.
    if tr.after == After::Hold && (t0 >= tr.poses[n - 1].t || t1 <= tr.poses[0].t) {
        return 0.0;
    }
    let (ka, kb) = (interval_of(tr, t0), interval_of(tr, t1.max(t0)));
    let mut v = speeds[ka..=kb].iter().fold(0.0f64, |m, &x| m.max(x));
    if tr.after == After::Extrapolate && t1 > tr.poses[n - 1].t {
        v = v.max(speeds[n - 2] + rate);
    }
    v
}

/// Pose `a` held.
fn held(a: &TimedPose) -> State {
    State {
        p: a.p,
        sigma: a.sigma,
        sigma_pos: a.sigma_pos,
        sphere: false,
        qa: a.q,
        qb: a.q,
        arc: SlerpArc::between(&a.q, &a.q),
        f: 0.0,
    }
}

fn state_at(tr: &Track, t: f64) -> State {
    let ps = &tr.poses;
    let n = ps.len();
    if n == 1 {
        let a = ps[0];
        let hold = held(&a);
        return match tr.after {
            After::Hold => hold,
            After::Extrapolate => {
                let dt = (t - a.t).max(0.0);
                State {
                    sigma: a.sigma + tr.surface_rate * dt,
                    sigma_pos: a.sigma_pos + tr.sigma_rate * dt,
                    sphere: dt > 0.0,
                    ..hold
                }
            }
        };
    }
    // A problem obstacle is at its first pose until that pose's time (as at its last after).
    if tr.after == After::Hold && t < ps[0].t {
        return held(&ps[0]);
    }
    let k = interval_of(tr, t);
    let (a, b) = (ps[k], ps[k + 1]);
    let f = (t - a.t) / (b.t - a.t);
    let p = [a.p[0] + f * (b.p[0] - a.p[0]), a.p[1] + f * (b.p[1] - a.p[1]), a.p[2] + f * (b.p[2] - a.p[2])];
    if f <= 1.0 {
        let lin = |x: f64, y: f64| (x + f * (y - x)).max(x.min(y));
        return State {
            p,
            sigma: lin(a.sigma, b.sigma),
            sigma_pos: lin(a.sigma_pos, b.sigma_pos),
            sphere: false,
            qa: a.q,
            qb: b.q,
            arc: tr.arcs[k],
            f,
        };
    }
    // Past the last pose.
    match tr.after {
        After::Hold => State {
            p: b.p,
            sigma: b.sigma,
            sigma_pos: b.sigma_pos,
            sphere: false,
            qa: b.q,
            qb: b.q,
            arc: SlerpArc::between(&b.q, &b.q),
            f: 0.0,
        },
        After::Extrapolate => {
            // The last interval's motion continued: the centre at its velocity, the attitude
            // turning on at its rate (the slerp's great circle past `b`), each bound growing
            // at its rate; the obstacle is the shape inflated by σ within the bounding ball
            // inflated by σ_pos (either holds the object while its bound does).
            let dt = t - b.t;
            State {
                p,
                sigma: b.sigma + tr.surface_rate * dt,
                sigma_pos: b.sigma_pos + tr.sigma_rate * dt,
                sphere: false,
                qa: a.q,
                qb: b.q,
                arc: tr.arcs[k],
                f,
            }
        }
    }
}
