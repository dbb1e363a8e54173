//! The composite online debris predictor: track table, gating, pose filter, per-track
//! Koopman models with RLS refinement, event detection and error bounds, forecasts into a
//! caller-provided buffer. Allocation-free after construction.

use crate::axis::AxisChannel;
use crate::calib::ForecastScore;
use crate::euler::EulerChannel;
use crate::filter::{propagate, quat_angle, FilterConfig, TrackFilter};
use crate::models::{Engine, Job, Method, Models};
use crate::symmetry::Symmetry;
use dkrrt_debris::Observation;
use dkrrt_koopman::debris_state::{align_quaternion, N, QUAT, RATE, ROT, TRANS};
use dkrrt_koopman::{ConstantVelocity, ErrorBound, KoopmanModel, Lifting, Rls, RlsConfig, Rollout};
use serde::Serialize;

/// Maximum number of tracks (= debris capacity of the world).
pub const MAX_TRACKS: usize = dkrrt_debris::MAX_DEBRIS;
/// Length of the per-track history of filtered states used to form model-step pairs.
pub const HISTORY: usize = 16;

/// Predictor parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PredictorConfig {
    /// Pose filter.
    pub filter: FilterConfig,
    /// Gate: maximum plausible speed [m/s]; a position jump implying more is rejected.
    pub max_speed: f64,
    /// Gate: maximum plausible spin [rad/s]; an attitude jump implying more is rejected.
    pub max_spin: f64,
    /// Gate: position jump allowed on top of `max_speed · Δt` (measurement noise) [m].
    pub jump_pos_margin: f64,
    /// Gate: rotation allowed on top of `max_spin · Δt` (measurement noise) [rad].
    pub jump_att_margin: f64,
    /// After this many consecutive jump rejections the track is re-initialised from the
    /// newest observation (the object really moved, e.g. re-identification).
    pub reinit_after_rejects: u32,
    /// Tracks without an accepted observation for this long (measured against the newest
    /// observation time seen) are dropped and their slots freed [s].
    pub track_timeout: f64,
    /// Tolerance when looking up the filtered state one model step back [s].
    pub pair_tolerance: f64,
    /// RLS of the translational model (state rows).
    pub rls_trans: RlsConfig,
    /// RLS of the attitude model (state rows).
    pub rls_att: RlsConfig,
    /// RLS of the deep attitude model in lifted-linear roll-out (all rows, targets `φ(x⁺)`).
    pub rls_att_deep: RlsConfig,
    /// Event: one-step residual > `event_factor · radius(1)` + noise allowance.
    pub event_factor: f64,
    /// Event: position noise allowance of the one-step residual (raw observation) [m].
    pub event_pos_noise: f64,
    /// Event: the largest change of velocity a position event is taken for [m/s]. An event
    /// widens the position bound by its one-step residual `r` (beyond the noise allowance)
    /// and its rate of growth by `r / dt`, the velocity change that would explain `r` over
    /// one model step, at most this. Infinite for the pose sensor; poses from depth frames
    /// jump by tenths of a metre with what a view shows, which `r / dt` took for changes
    /// of velocity of 1–1.5 m/s.
    pub event_max_dv: f64,
    /// Event: attitude noise allowance [rad].
    pub event_att_noise: f64,
    /// Position noise of a pose per metre of the object's size (its shape's bounding radius,
    /// [`DebrisPredictor::set_shape`]): the filter takes `max(filter.pos_sigma, this · size)`.
    /// 0 for the pose sensor; poses from depth frames: the visible side moves the centroid by
    /// a share of the object's size.
    pub pos_sigma_per_m: f64,
    /// Position noise of a pose per metre of its distance from [`PredictorConfig::sensor_origin`]
    /// (a camera's pixel spans more the farther it looks): the filter takes at least this
    /// times the range. 0 for the pose sensor; poses from depth frames: a share of a pixel's
    /// angle.
    pub pos_sigma_per_range: f64,
    /// Where the sensor looks from (the camera's optical centre), base frame, m.
    pub sensor_origin: [f64; 3],
    /// The published position bound is at least this many of the track filter's own position
    /// deviations at each horizon ([`TrackFilter::pos_std`]: a young track's velocity is
    /// still uncertain, which the model's bound does not know); while the track's online
    /// calibration has not started ([`PredictorConfig::calib_min_obs`]) the two are added in
    /// quadrature (separate errors), and its attitude bound is at least this many of the
    /// filter's attitude deviations ([`TrackFilter::att_std`]). 0: off.
    /// Default [`TRACK_SIGMAS`], for every sensor (without it the pose sensor's forecasts of
    /// tracks in their first second held the truth 41–61 % of the time in three of the four
    /// scenes: `dkrrt predict-eval`'s young-track figures).
    pub track_sigmas: f64,
    /// A dropped track whose object is seen again within this many seconds of its last pose
    /// is taken up again, its filter coasted over the gap (its covariance grown with it),
    /// instead of starting over with an unknown velocity. 0: off (the pose sensor sees every
    /// object every frame); poses from depth frames: objects pass behind the arm and out of
    /// the views.
    pub revive_s: f64,
    /// What the observed poses and shapes may be off by beyond the filter's noise (a
    /// perception front end's error margin: its shapes are its estimates of the bodies),
    /// m: added to every published position bound, so the published shape grown by the bound
    /// holds the body. 0: the pose sensor (its shapes are the true ones); poses from depth
    /// frames: the front end's margin.
    pub front_end_margin_m: f64,
    /// Position noise of a partial view ([`Observation::partial`]) per metre of the object's
    /// size: its centroid can lie anywhere on the object. Its attitude is not used.
    pub partial_sigma_per_m: f64,
    /// Event: minimum time between two events of one track and channel [s].
    pub event_refractory: f64,
    /// Event: the test must fail on this many model pairs in a row (1: any one; poses from
    /// depth frames: 2, so one outlying pose is not taken for an impulse).
    pub event_persist: u32,
    /// Event: no event tests before a track has this many observations (filter transient).
    pub event_min_obs: u32,
    /// Tracks need this many accepted observations before they are forecast: 2 (a velocity;
    /// its uncertainty is in the bound, [`PredictorConfig::track_sigmas`]); poses from depth
    /// frames: 5 (their heavy tails: from the second pose the young tracks of tumbling-rods
    /// were contained 98.0 % of the time, against 100 % from the fifth).
    pub min_obs_for_forecast: u32,
    /// Online calibration ([`crate::calib`], [`crate::axis`]): bound = floor + factor ·
    /// score; floors `[position m, attitude rad]` (the filtered pose the forecasts are scored
    /// against is itself this uncertain).
    pub calib_floor: [f64; 2],
    /// Online calibration: factor on the scores.
    pub calib_factor: f64,
    /// Online calibration: observations a track needs since its filter (re)started (its first
    /// pose, a manoeuvre re-opening, a position restart) before its forecasts are kept for
    /// scoring (earlier ones come from a filter still converging).
    pub calib_min_obs: u32,
    /// Online calibration: steps it covers (from 1). Beyond, the fitted bound, but never
    /// below the calibrated bound of the last covered step. (Calibrating every step of the
    /// 4 s horizon was tried: the decaying maxima of heavy-tailed long-horizon errors made
    /// wider, step-to-step jumpier bounds than the fitted ones, and the threat-episode
    /// completion fell from 85 % to 50–60 % on tumbling-rods.)
    pub calib_steps: usize,
    /// Whether forecasts use the physical attitude channels (a rod's axis by precession, a
    /// box's attitude by Euler's equations); `None`: as the method says
    /// ([`crate::Method::attitude_physics`]: the online Koopman methods do, the baselines not).
    pub attitude_physics: Option<bool>,
}

/// [`PredictorConfig::track_sigmas`]'s default: the radius holding 99 % of a 3-D normal
/// error of unit deviation per axis (√χ²₃(0.99) = √11.345).
pub const TRACK_SIGMAS: f64 = 3.368;

impl Default for PredictorConfig {
    fn default() -> Self {
        PredictorConfig {
            filter: FilterConfig::default(),
            max_speed: 5.0,
            max_spin: 15.0,
            jump_pos_margin: 0.05,
            jump_att_margin: 0.1,
            reinit_after_rejects: 10,
            track_timeout: 1.0,
            pair_tolerance: 0.005,
            rls_trans: RlsConfig { lambda: 0.999, p0: 1e-9, max_trace: 1e6 },
            rls_att: RlsConfig { lambda: 0.995, p0: 1.0, max_trace: 1e6 },
            rls_att_deep: RlsConfig { lambda: 0.997, p0: 100.0, max_trace: 1e8 },
            calib_floor: [0.01, 0.02],
            calib_factor: 1.5,
            calib_min_obs: 50,
            calib_steps: 10,
            attitude_physics: None,
            event_factor: 3.0,
            event_pos_noise: 0.05,
            event_max_dv: f64::INFINITY,
            event_att_noise: 0.08,
            event_refractory: 0.5,
            event_persist: 1,
            pos_sigma_per_m: 0.0,
            pos_sigma_per_range: 0.0,
            sensor_origin: [0.0; 3],
            track_sigmas: TRACK_SIGMAS,
            revive_s: 0.0,
            front_end_margin_m: 0.0,
            partial_sigma_per_m: 0.3,
            event_min_obs: 25,
            min_obs_for_forecast: 2,
        }
    }
}

/// Why an observation was rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum RejectReason {
    /// NaN / Inf in time, position or attitude, or a degenerate quaternion.
    Invalid,
    /// Timestamp not newer than the track's last accepted observation.
    OutOfOrder,
    /// Position jump implying a speed above `max_speed`.
    PositionJump,
    /// Attitude jump implying a spin above `max_spin`.
    AttitudeJump,
    /// New id but all [`MAX_TRACKS`] slots are in use.
    TableFull,
}

/// Result of [`DebrisPredictor::observe`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum ObserveOutcome {
    /// Accepted into an existing track.
    Accepted,
    /// A new track was created (new id, or re-initialised after repeated jumps).
    NewTrack,
    /// Rejected (counted in [`GateStats`]).
    Rejected(RejectReason),
}

/// Counters of the gate and the online machinery.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct GateStats {
    /// Observations accepted (including the ones that created tracks).
    pub accepted: u64,
    /// Rejected: NaN / Inf / degenerate quaternion.
    pub invalid: u64,
    /// Rejected: out of order or duplicate timestamp.
    pub out_of_order: u64,
    /// Rejected: impossible position jump.
    pub pos_jump: u64,
    /// Rejected: impossible attitude jump.
    pub att_jump: u64,
    /// Rejected: track table full.
    pub table_full: u64,
    /// Tracks created.
    pub tracks_created: u64,
    /// Tracks re-initialised after repeated jump rejections.
    pub reinit: u64,
    /// Tracks dropped after the timeout.
    pub tracks_dropped: u64,
    /// Dropped tracks taken up again by their object's next pose
    /// ([`PredictorConfig::revive_s`]).
    pub revived: u64,
    /// Accepted observations from partial views ([`Observation::partial`]).
    pub partial: u64,
    /// Tracks whose position and velocity restarted ([`Observation::restart`]).
    pub restarts: u64,
    /// Detected events (one-step residual beyond the bound), position or attitude.
    pub events: u64,
    /// One-step model pairs processed (residual test and, for online methods, RLS).
    pub model_pairs: u64,
    /// Track roll-outs that left the trust region and were continued by constant velocity
    /// (of those computed: [`DebrisPredictor::forecast_for_calibration`] rolls out fewer).
    pub forecast_fallbacks: u64,
    /// Translation filter re-openings after a manoeuvre (impulse) was detected from the
    /// pose innovations ([`crate::filter`]).
    pub maneuvers: u64,
}

#[derive(Debug, Clone)]
struct Track {
    active: bool,
    id: u32,
    filter: TrackFilter,
    n_obs: u32,
    last_obs_p: [f64; 3],
    last_obs_q: [f64; 4],
    rejects: u32,
    hist_t: [f64; HISTORY],
    hist_x: [[f64; N]; HISTORY],
    hist_head: usize,
    hist_len: usize,
    trans: KoopmanModel,
    att: KoopmanModel,
    rls_t: Rls,
    rls_a: Rls,
    pos_bound: ErrorBound,
    att_bound: ErrorBound,
    last_event_t: [f64; 2],
    /// The object's size (its shape's bounding radius, m; 0: not known).
    size: f64,
    /// The turns its shape cannot show ([`DebrisPredictor::set_shape`]).
    symmetry: Symmetry,
    /// Model pairs in a row whose residual failed the event test, per channel.
    event_run: [u32; 2],
    events: u32,
    last_residual: [f64; 2],
    axis: AxisChannel,
    euler: EulerChannel,
    score: ForecastScore,
    /// Accepted observations since the filter last started (the track's first, a position
    /// restart or a manoeuvre re-opening): the forecasts it makes are kept for scoring from
    /// [`PredictorConfig::calib_min_obs`] on.
    calib_obs: u32,
}

/// Read-only view of one track.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackInfo {
    /// Debris id.
    pub id: u32,
    /// Time of the estimate (last accepted observation) [s].
    pub t: f64,
    /// Filtered 13-state.
    pub state: [f64; N],
    /// Accepted observations.
    pub n_obs: u32,
    /// Events detected on this track (position and/or attitude at one observation).
    pub events: u32,
    /// Last one-step residuals `[position m, attitude rad]` (NaN before the first pair).
    pub last_residual: [f64; 2],
    /// Position bound 1 step and H steps ahead [m].
    pub pos_radius: [f64; 2],
    /// Attitude bound 1 step and H steps ahead [rad].
    pub att_radius: [f64; 2],
}

/// Caller-owned forecast output for up to [`MAX_TRACKS`] tracks × `H` steps.
#[derive(Debug, Clone)]
pub struct ForecastBuffer {
    h: usize,
    dt: f64,
    len: usize,
    ids: [u32; MAX_TRACKS],
    t0: [f64; MAX_TRACKS],
    states: Vec<f64>,
    pos_radius: Vec<f64>,
    att_radius: Vec<f64>,
    axis: Vec<[f64; 3]>,
    axis_radius: Vec<f64>,
    full_q: Vec<[f64; 4]>,
    full_radius: Vec<f64>,
}

impl ForecastBuffer {
    /// Buffer for horizons of `h` steps of `dt` (allocates once).
    pub fn new(h: usize, dt: f64) -> Self {
        ForecastBuffer {
            h,
            dt,
            len: 0,
            ids: [0; MAX_TRACKS],
            t0: [0.0; MAX_TRACKS],
            states: vec![0.0; MAX_TRACKS * h * N],
            pos_radius: vec![0.0; MAX_TRACKS * h],
            att_radius: vec![0.0; MAX_TRACKS * h],
            axis: vec![[0.0; 3]; MAX_TRACKS * h],
            axis_radius: vec![0.0; MAX_TRACKS * h],
            full_q: vec![[1.0, 0.0, 0.0, 0.0]; MAX_TRACKS * h],
            full_radius: vec![0.0; MAX_TRACKS * h],
        }
    }
    /// Buffer matching a predictor.
    pub fn for_predictor(p: &DebrisPredictor) -> Self {
        Self::new(p.models.horizon, p.models.dt)
    }
    /// Horizon `H` (steps).
    pub fn horizon(&self) -> usize {
        self.h
    }
    /// Step [s].
    pub fn dt(&self) -> f64 {
        self.dt
    }
    /// Number of forecast tracks.
    pub fn len(&self) -> usize {
        self.len
    }
    /// No tracks.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    /// Id of forecast `i`.
    pub fn id(&self, i: usize) -> u32 {
        self.ids[i]
    }
    /// Start time of forecast `i` (its track's last observation): step `k` is at `t0 + k·dt`.
    pub fn t0(&self, i: usize) -> f64 {
        self.t0[i]
    }
    /// Index of the forecast of debris `id`.
    pub fn index_of(&self, id: u32) -> Option<usize> {
        self.ids[..self.len].iter().position(|&x| x == id)
    }
    /// Predicted 13-state of forecast `i`, `k` steps ahead (`1 ≤ k ≤ H`).
    pub fn state(&self, i: usize, k: usize) -> &[f64] {
        assert!(i < self.len && (1..=self.h).contains(&k));
        let o = (i * self.h + k - 1) * N;
        &self.states[o..o + N]
    }
    /// All `H` predicted states of forecast `i` (row-major `H × 13`).
    pub fn states(&self, i: usize) -> &[f64] {
        &self.states[i * self.h * N..(i + 1) * self.h * N]
    }
    /// Position error radius of forecast `i`, `k` steps ahead [m].
    pub fn pos_radius(&self, i: usize, k: usize) -> f64 {
        self.pos_radius[i * self.h + k - 1]
    }
    /// Attitude error radius of forecast `i`, `k` steps ahead [rad].
    pub fn att_radius(&self, i: usize, k: usize) -> f64 {
        self.att_radius[i * self.h + k - 1]
    }
    /// Forecast `i`'s body z axis `k` steps ahead by its precession ([`crate::axis`]): what a
    /// rod's (any shape symmetric about its z axis) pose is, whatever its spin about the axis.
    pub fn axis(&self, i: usize, k: usize) -> [f64; 3] {
        self.axis[i * self.h + k - 1]
    }
    /// Error bound of [`ForecastBuffer::axis`] (angle between lines), rad: calibrated online
    /// per track, or the attitude bound while the track is too young to have scored step `k`.
    pub fn axis_radius(&self, i: usize, k: usize) -> f64 {
        self.axis_radius[i * self.h + k - 1]
    }
    /// Forecast `i`'s attitude `k` steps ahead for a shape that needs the full attitude: the
    /// torque-free forecast ([`crate::euler`]) at the steps where its calibrated bound is the
    /// smaller, else the model's ([`ForecastBuffer::state`]).
    pub fn attitude(&self, i: usize, k: usize) -> [f64; 4] {
        self.full_q[i * self.h + k - 1]
    }
    /// Error bound of [`ForecastBuffer::attitude`], rad.
    pub fn attitude_radius(&self, i: usize, k: usize) -> f64 {
        self.full_radius[i * self.h + k - 1]
    }
    /// The surface bound forecast `i` publishes `k` steps ahead for an object of `shape`
    /// (bounding radius `radius`): the position bound plus the attitude bound of the shape's
    /// channel times its lever ([`dkrrt_collision::bounds::surface_sigma`]), m.
    pub fn published_sigma(&self, i: usize, k: usize, shape: &dkrrt_msg::DebrisShape, radius: f64) -> f64 {
        dkrrt_collision::bounds::surface_sigma(
            shape,
            radius,
            self.pos_radius(i, k),
            self.attitude_radius(i, k),
            self.axis_radius(i, k),
        )
    }

    /// Forecast `i` read `after` s past its last step `H` (`H ≥ 2`) as the planner reads a
    /// forecast there: the motion from step `H − 1` to `H` continued
    /// ([`dkrrt_collision::pose::continue_pose`]; the attitude at `H` taken as the one of the
    /// same shape nearest to `H − 1`, [`dkrrt_collision::pose::same_shape_nearest`], as the
    /// planner takes it), and each bound grown from
    /// step `H` at its [`dkrrt_collision::bounds::growth_rate`] over the `H` steps since the
    /// forecast's start and over the last one (the surface bound at least at the position
    /// bound's rate). Returns (position, attitude, surface bound, position bound) for an object
    /// of `shape` (bounding radius `radius`).
    pub fn continued(
        &self,
        i: usize,
        after: f64,
        shape: &dkrrt_msg::DebrisShape,
        radius: f64,
    ) -> ([f64; 3], [f64; 4], f64, f64) {
        use dkrrt_collision::bounds::growth_rate;
        use dkrrt_collision::pose::{continue_pose, same_shape_nearest};
        let (h, dt) = (self.h, self.dt);
        let (xa, xb) = (self.state(i, h - 1), self.state(i, h));
        let qa = self.published_attitude(i, h - 1, shape);
        let qb = same_shape_nearest(shape, &qa, &self.published_attitude(i, h, shape));
        let (p, q) = continue_pose(
            &[xa[0], xa[1], xa[2]],
            &qa,
            &[xb[0], xb[1], xb[2]],
            &qb,
            1.0 + after.max(0.0) / dt,
        );
        let span = h as f64 * dt;
        let (pa, pb) = (self.pos_radius(i, h - 1), self.pos_radius(i, h));
        let (sa, sb) =
            (self.published_sigma(i, h - 1, shape, radius), self.published_sigma(i, h, shape, radius));
        let pos_rate = growth_rate(pb, pa, dt, span);
        let rate = growth_rate(sb, sa, dt, span).max(pos_rate);
        (p, q, sb + rate * after.max(0.0), pb + pos_rate * after.max(0.0))
    }

    /// The attitude forecast `i` publishes `k` steps ahead for an object of `shape` (what the
    /// planner reads): a rod's ([`dkrrt_collision::bounds::AttitudeChannel::Axis`]) is the
    /// model's attitude turned onto the precession forecast's axis; any other shape's is
    /// [`ForecastBuffer::attitude`].
    pub fn published_attitude(&self, i: usize, k: usize, shape: &dkrrt_msg::DebrisShape) -> [f64; 4] {
        use dkrrt_collision::bounds::{attitude_channel, AttitudeChannel};
        if attitude_channel(shape) == AttitudeChannel::Axis {
            let x = self.state(i, k);
            crate::axis::AxisPrecession::align(&[x[6], x[7], x[8], x[9]], &self.axis(i, k))
        } else {
            self.attitude(i, k)
        }
    }
}

/// Online debris predictor for up to [`MAX_TRACKS`] objects (association by id).
#[derive(Debug, Clone)]
pub struct DebrisPredictor {
    cfg: PredictorConfig,
    models: Models,
    tracks: Vec<Track>,
    stats: GateStats,
    engine: Engine,
    phi_t: Vec<f64>,
    phi_a: Vec<f64>,
    phi_a_next: Vec<f64>,
    t_latest: f64,
}

fn finite(o: &Observation) -> bool {
    o.t.is_finite()
        && o.p.iter().all(|v| v.is_finite())
        && o.q.iter().all(|v| v.is_finite())
        && (!o.has_rates || o.v.iter().chain(&o.w).all(|v| v.is_finite()))
        && {
            let n2: f64 = o.q.iter().map(|v| v * v).sum();
            (0.25..=4.0).contains(&n2)
        }
}

impl DebrisPredictor {
    /// Build with fitted models; allocates all [`MAX_TRACKS`] slots (models, RLS, history).
    pub fn new(models: Models, cfg: PredictorConfig) -> Self {
        let mut filter_cfg = cfg.filter;
        filter_cfg.frame_rate = models.frame_rate;
        let cfg = PredictorConfig { filter: filter_cfg, ..cfg };
        let slot = Track {
            active: false,
            id: 0,
            filter: TrackFilter::new(&cfg.filter, 0.0, &[0.0; 3], &[1.0, 0.0, 0.0, 0.0]),
            n_obs: 0,
            last_obs_p: [0.0; 3],
            last_obs_q: [1.0, 0.0, 0.0, 0.0],
            rejects: 0,
            hist_t: [f64::NAN; HISTORY],
            hist_x: [[0.0; N]; HISTORY],
            hist_head: 0,
            hist_len: 0,
            trans: models.trans.clone(),
            att: models.att.clone(),
            rls_t: Rls::for_model_state_rows(&models.trans, cfg.rls_trans),
            // Relift models refine the state rows; the deep model (linear lifted roll-out)
            // refines all rows towards φ(x⁺) so the multi-step lifted roll-out adapts too.
            rls_a: if models.att_rollout == Rollout::Linear {
                Rls::for_model(&models.att, cfg.rls_att_deep)
            } else {
                Rls::for_model_state_rows(&models.att, cfg.rls_att)
            },
            pos_bound: models.pos_bound.clone(),
            att_bound: models.att_bound.clone(),
            last_event_t: [f64::NEG_INFINITY; 2],
            event_run: [0; 2],
            size: 0.0,
            symmetry: Symmetry::NONE,
            events: 0,
            last_residual: [f64::NAN; 2],
            axis: AxisChannel::new(),
            euler: EulerChannel::new(),
            score: ForecastScore::new(models.horizon, models.dt),
            calib_obs: 0,
        };
        DebrisPredictor {
            engine: {
                let mut e = Engine::new(&models);
                e.max_speed = cfg.max_speed;
                e.max_spin = cfg.max_spin;
                e
            },
            phi_t: vec![0.0; models.trans.p + 8],
            phi_a: vec![0.0; models.att.p + 8],
            phi_a_next: vec![0.0; models.att.p + 8],
            tracks: vec![slot; MAX_TRACKS],
            models,
            cfg,
            stats: GateStats::default(),
            t_latest: f64::NEG_INFINITY,
        }
    }

    /// Tells the predictor the shape of debris `id` (its contract descriptor): a box gets the
    /// torque-free attitude forecast with the shape's inertia ([`crate::euler`]), other shapes
    /// none. Takes effect for a track that exists (call it again for later ones; unchanged
    /// shapes cost a lookup).
    pub fn set_shape(&mut self, id: u32, shape: &dkrrt_msg::DebrisShape) {
        if let Some(s) = self.slot_of(id) {
            self.tracks[s].euler.set_inertia(crate::euler::inertia_hint(shape));
            self.tracks[s].size = shape.bounding_radius();
            self.tracks[s].symmetry = Symmetry::of(shape);
        }
    }

    /// Whether forecasts use the physical attitude channels ([`PredictorConfig::attitude_physics`]).
    pub fn attitude_physics(&self) -> bool {
        self.cfg.attitude_physics.unwrap_or(self.models.method.attitude_physics())
    }

    /// Configuration.
    pub fn config(&self) -> &PredictorConfig {
        &self.cfg
    }
    /// Shared (fitted) models.
    pub fn models(&self) -> &Models {
        &self.models
    }
    /// Method.
    pub fn method(&self) -> Method {
        self.models.method
    }
    /// Gate / online counters.
    pub fn stats(&self) -> &GateStats {
        &self.stats
    }
    /// Number of active tracks.
    pub fn n_tracks(&self) -> usize {
        self.tracks.iter().filter(|t| t.active).count()
    }
    /// Slot index of the track of `id` (slots are reused after drops).
    pub fn slot_of(&self, id: u32) -> Option<usize> {
        self.tracks.iter().position(|t| t.active && t.id == id)
    }
    /// Read-only view of the track of `id`.
    pub fn track(&self, id: u32) -> Option<TrackInfo> {
        let t = &self.tracks[self.slot_of(id)?];
        let h = self.models.horizon;
        Some(TrackInfo {
            id,
            t: t.filter.t,
            state: t.filter.x,
            n_obs: t.n_obs,
            events: t.events,
            last_residual: t.last_residual,
            pos_radius: [t.pos_bound.radius(1), t.pos_bound.radius(h)],
            att_radius: [t.att_bound.radius(1), t.att_bound.radius(h)],
        })
    }

    /// Drop tracks whose last accepted observation is older than `t_now − track_timeout`.
    /// Returns the number dropped. Called by [`DebrisPredictor::observe`] with the newest
    /// observation time; call it from the planner clock too if observations stop entirely.
    pub fn prune(&mut self, t_now: f64) -> usize {
        let mut n = 0;
        for tr in self.tracks.iter_mut() {
            if tr.active && t_now - tr.filter.t > self.cfg.track_timeout {
                tr.active = false;
                n += 1;
            }
        }
        self.stats.tracks_dropped += n as u64;
        n
    }

    /// Drops the tracks whose last pose is after `t` (the frames' clock went back: their
    /// times came with wrong stamps); they are counted as dropped, and their slots are free
    /// (not revived: a pose at `t` or later is not after theirs). Returns how many.
    pub fn drop_after(&mut self, t: f64) -> usize {
        let mut n = 0;
        for tr in self.tracks.iter_mut() {
            if tr.active && tr.filter.t > t {
                tr.active = false;
                n += 1;
            }
        }
        self.stats.tracks_dropped += n as u64;
        n
    }

    /// A slot for a new track: the first inactive one; with revival on, one whose track can no
    /// longer be revived, if any.
    fn free_slot(&self, t: f64) -> Option<usize> {
        let free = |i: &usize| !self.tracks[*i].active;
        let stale =
            |i: &usize| t - self.tracks[*i].filter.t > self.cfg.revive_s || self.tracks[*i].n_obs == 0;
        let mut idx = 0..self.tracks.len();
        if self.cfg.revive_s > 0.0 {
            if let Some(i) = idx.clone().filter(free).find(stale) {
                return Some(i);
            }
        }
        idx.find(free)
    }

    fn init_track(&mut self, slot: usize, o: &Observation) {
        let cfg = &self.cfg;
        let m = &self.models;
        let tr = &mut self.tracks[slot];
        // The shape (and the inertia it suggests) belongs to the id: kept when a track is
        // re-initialised, forgotten when the slot goes to another object.
        let same_object = tr.active && tr.id == o.id;
        tr.active = true;
        tr.id = o.id;
        let mut q = o.q;
        let nq = q.iter().map(|v| v * v).sum::<f64>().sqrt();
        q.iter_mut().for_each(|v| *v /= nq);
        tr.filter = TrackFilter::new(&cfg.filter, o.t, &o.p, &q);
        if o.has_rates {
            tr.filter.update_rates(&cfg.filter, &o.v, &o.w);
        }
        tr.n_obs = 1;
        tr.last_obs_p = o.p;
        tr.last_obs_q = q;
        tr.rejects = 0;
        tr.hist_len = 0;
        tr.hist_head = 0;
        tr.trans.ab.copy_from_slice(&m.trans.ab);
        tr.att.ab.copy_from_slice(&m.att.ab);
        tr.rls_t.reset_covariance();
        tr.rls_a.reset_covariance();
        tr.pos_bound.clone_from(&m.pos_bound);
        tr.att_bound.clone_from(&m.att_bound);
        tr.last_event_t = [f64::NEG_INFINITY; 2];
        tr.event_run = [0; 2];
        tr.events = 0;
        tr.last_residual = [f64::NAN; 2];
        tr.axis = AxisChannel::new();
        if same_object {
            tr.euler.restart();
        } else {
            tr.euler = EulerChannel::new();
            tr.size = 0.0;
            tr.symmetry = Symmetry::NONE;
        }
        tr.restart_calibration();
        tr.calib_obs = 1;
        tr.axis.update(o.t, &tr.filter.x[QUAT], &tr.filter.x[QUAT], &tr.filter.x[RATE], m.dt, m.horizon);
        push_hist(tr);
    }

    /// Process one observation (any order of ids; per id, timestamps must increase).
    /// Allocation-free.
    pub fn observe(&mut self, o: &Observation) -> ObserveOutcome {
        if !finite(o) {
            self.stats.invalid += 1;
            return ObserveOutcome::Rejected(RejectReason::Invalid);
        }
        if o.t > self.t_latest {
            self.t_latest = o.t;
            self.prune(o.t);
        }
        let revive = |t: &Track| {
            !t.active
                && t.id == o.id
                && t.n_obs > 0
                && o.t > t.filter.t
                && o.t - t.filter.t <= self.cfg.revive_s
        };
        let slot = match self.slot_of(o.id) {
            Some(s) => s,
            None => match self.tracks.iter().position(revive) {
                Some(s) => {
                    self.tracks[s].active = true;
                    self.stats.revived += 1;
                    s
                }
                None => match self.free_slot(o.t) {
                    Some(s) => {
                        self.init_track(s, o);
                        self.stats.accepted += 1;
                        self.stats.tracks_created += 1;
                        return ObserveOutcome::NewTrack;
                    }
                    None => {
                        self.stats.table_full += 1;
                        return ObserveOutcome::Rejected(RejectReason::TableFull);
                    }
                },
            },
        };
        let cfg = self.cfg;
        let tr = &mut self.tracks[slot];
        if o.t <= tr.filter.t {
            self.stats.out_of_order += 1;
            return ObserveOutcome::Rejected(RejectReason::OutOfOrder);
        }
        // Normalised measurement; of the attitudes its shape cannot tell apart (a box's half
        // turns: a sensor that sees the shape reports any of them) the one nearest to the
        // track's prediction, sign-aligned with it.
        let mut q = o.q;
        let nq = q.iter().map(|v| v * v).sum::<f64>().sqrt();
        q.iter_mut().for_each(|v| *v /= nq);
        let (man0, xprior) = (tr.filter.maneuvers, tr.filter.predicted(&cfg.filter, o.t));
        // A report of an axis alone (a rod's, from a camera): that axis on the prediction's
        // spin; its own spin is the front end's bookkeeping, which drifts as the axis turns.
        q = if o.axis_only {
            crate::symmetry::on_axis(&q, &xprior[QUAT])
        } else {
            tr.symmetry.nearest(&q, &xprior[QUAT])
        };
        align_quaternion(&mut q, &tr.filter.x[QUAT]);
        // Physical plausibility gate against the last accepted observation.
        let dt_obs = o.t - tr.filter.t;
        let dp = (0..3).map(|i| (o.p[i] - tr.last_obs_p[i]).powi(2)).sum::<f64>().sqrt();
        // A partial view measures an axis where the front end says it shows one (a rod's: a
        // cut or half-hidden rod still shows its direction; a disc's normal), nothing else.
        let att_measured = !o.partial || o.axis_only;
        let da = match (att_measured, o.axis_only) {
            (false, _) => 0.0,
            (true, true) => {
                crate::axis::line_angle(&crate::axis::body_z(&q), &crate::axis::body_z(&tr.last_obs_q))
            }
            (true, false) => quat_angle(&q, &tr.last_obs_q),
        };
        // A restart's centre may lie far from the earlier, biased ones: no position gate.
        let reason = if dp > cfg.max_speed * dt_obs + cfg.jump_pos_margin && !o.restart {
            Some(RejectReason::PositionJump)
        } else if da > cfg.max_spin * dt_obs + cfg.jump_att_margin {
            Some(RejectReason::AttitudeJump)
        } else {
            None
        };
        if let Some(r) = reason {
            match r {
                RejectReason::PositionJump => self.stats.pos_jump += 1,
                _ => self.stats.att_jump += 1,
            }
            tr.rejects += 1;
            if tr.rejects >= cfg.reinit_after_rejects {
                self.stats.reinit += 1;
                self.stats.accepted += 1;
                self.init_track(slot, o);
                return ObserveOutcome::NewTrack;
            }
            return ObserveOutcome::Rejected(r);
        }
        tr.rejects = 0;
        if o.restart {
            // The poses so far showed part of the object (`Observation::restart`): its position
            // and velocity start again from this one; the model pairs, the calibration and the
            // event growth built on them go (the attitude, the shape and the models stay).
            tr.filter.restart_position(&cfg.filter, (1.0f64).max(tr.size).powi(2));
            tr.hist_len = 0;
            tr.restart_calibration();
            tr.pos_bound.clone_from(&self.models.pos_bound);
            self.stats.restarts += 1;
        }
        let range = (0..3).map(|i| (o.p[i] - cfg.sensor_origin[i]).powi(2)).sum::<f64>().sqrt();
        let mut sigma =
            cfg.filter.pos_sigma.max(cfg.pos_sigma_per_m * tr.size).max(cfg.pos_sigma_per_range * range);
        if o.partial {
            sigma = sigma.max(cfg.partial_sigma_per_m * tr.size);
            self.stats.partial += 1;
        }
        // Of a position residual, what this pose's own noise and the estimate's own
        // uncertainty explain beyond the event test's fixed allowance (three deviations of
        // both; next to nothing for the pose sensor on a settled track): a residual widens the
        // bound only by what lies beyond it. A track that coasted on loose poses (partial
        // views) is uncertain where it is; a whole view then moves it without a velocity change.
        let prior = tr.filter.pos_std(&cfg.filter, o.t - tr.filter.t);
        let extra = (3.0 * (sigma * sigma + prior * prior).sqrt() - cfg.event_pos_noise).max(0.0);
        tr.filter.update_with(&cfg.filter, sigma, o.t, &o.p, att_measured.then_some(&q), o.partial);
        if o.has_rates {
            tr.filter.update_rates(&cfg.filter, &o.v, &o.w);
        }
        if tr.filter.maneuvers > man0 {
            // The velocity changed: widen the position bound by the innovation, spread as a
            // velocity error over the averaging window of the test.
            let y = (0..3).map(|i| (o.p[i] - xprior[i]).powi(2)).sum::<f64>().sqrt() - extra;
            tr.pos_bound.grow(y, y / (cfg.filter.maneuver_window * dt_obs.max(1e-3)));
            // The forecasts made before came from the old velocity, and those of the next
            // poses come from one still converging: like a young track's, neither tells what
            // the settled forecasts will miss by, so the calibration starts again
            // ([`PredictorConfig::calib_min_obs`] poses on), the grown fitted bound standing
            // in meanwhile. (Kept, the errors of the converging velocity's forecasts, metres
            // at 4 s, held every bound of the track wide for the scores' 20 s memory.)
            tr.restart_calibration();
            self.stats.maneuvers += 1;
        }
        if att_measured && self.cfg.attitude_physics.unwrap_or(self.models.method.attitude_physics()) {
            // The forecasts of the axis start from the measured axes, not the filter's: the
            // filter's constant body rate does not describe a spinning disc's coning, and its
            // attitude trailed a tumbling panel's reported normal by 0.1 rad (as did every
            // forecast started from it).
            tr.axis.update(
                o.t,
                &tr.filter.x[QUAT],
                &q,
                &tr.filter.x[RATE],
                self.models.dt,
                self.models.horizon,
            );
            tr.euler.update(
                o.t,
                &tr.filter.x[QUAT],
                self.models.dt,
                self.models.horizon,
                self.models.frame_rate,
            );
        }
        {
            let (x, t, fr) = (tr.filter.x, tr.filter.t, self.models.frame_rate);
            tr.score.score(o.t, |tau| {
                let y = propagate(&x, fr, tau - t);
                ([y[0], y[1], y[2]], [y[6], y[7], y[8], y[9]])
            });
        }
        tr.n_obs += 1;
        tr.calib_obs += 1;
        tr.last_obs_p = o.p;
        if att_measured {
            tr.last_obs_q = q;
        }
        tr.pos_bound.relax(dt_obs);
        tr.att_bound.relax(dt_obs);
        self.stats.accepted += 1;

        // One model step back in the history → residual test and online refinement.
        let dt = self.models.dt;
        let target = o.t - dt;
        let mut prev = None;
        for j in 0..tr.hist_len {
            let idx = (tr.hist_head + HISTORY - 1 - j) % HISTORY;
            if (tr.hist_t[idx] - target).abs() <= cfg.pair_tolerance {
                prev = Some(idx);
                break;
            }
        }
        if let Some(idx) = prev {
            self.stats.model_pairs += 1;
            let xp = tr.hist_x[idx];
            let m = &self.models;
            // One-step prediction x̂ from the state one model step back.
            let mut xh = [0.0; N];
            if m.method == Method::ConstantVelocity {
                let mut out = [0.0; N];
                ConstantVelocity { frame_rate: m.frame_rate }.forecast(&xp, dt, &mut out);
                xh = out;
            } else {
                m.trans_lift.lift(&xp[TRANS], &mut self.phi_t);
                m.att_lift.lift_fast(&xp[ROT], &mut self.phi_a);
                tr.trans.step_rows(6, &self.phi_t, &[], &mut xh[TRANS]);
                tr.att.step_rows(7, &self.phi_a, &[], &mut xh[ROT]);
            }
            let rp = (0..3).map(|i| (xh[i] - o.p[i]).powi(2)).sum::<f64>().sqrt();
            let ra = quat_angle(&xh[QUAT], &q);
            tr.last_residual = [rp, ra];
            // Position and attitude channels have their own refractory period.
            let armed = tr.n_obs >= cfg.event_min_obs;
            let fails = [
                !o.partial && tr.pos_bound.exceeds(1, rp - cfg.event_pos_noise - extra, cfg.event_factor),
                att_measured && tr.att_bound.exceeds(1, ra - cfg.event_att_noise, cfg.event_factor),
            ];
            for c in 0..2 {
                tr.event_run[c] = if fails[c] { tr.event_run[c] + 1 } else { 0 };
            }
            let fire = |c: usize| {
                armed
                    && o.t - tr.last_event_t[c] >= cfg.event_refractory
                    && tr.event_run[c] >= cfg.event_persist
            };
            let (ev_p, ev_a) = (fire(0), fire(1));
            if ev_p {
                let rp = rp - extra;
                tr.pos_bound.grow(rp, (rp / dt).min(cfg.event_max_dv));
                tr.rls_t.reset_covariance();
                tr.last_event_t[0] = o.t;
            }
            if ev_a {
                tr.att_bound.grow(ra, ra / dt);
                tr.rls_a.reset_covariance();
                tr.axis.restart();
                tr.euler.restart();
                tr.last_event_t[1] = o.t;
            }
            if ev_p || ev_a {
                tr.events += 1;
                self.stats.events += 1;
            }
            if m.method.online() {
                let xn = tr.filter.x;
                tr.rls_t.update_model(&mut tr.trans, &self.phi_t[..m.trans.p], &xn[TRANS]);
                let mut ya = [0.0; 7];
                ya.copy_from_slice(&xn[ROT]);
                align_quaternion(&mut ya[0..4], &xp[QUAT]);
                if !att_measured {
                    // No attitude was measured: nothing to learn from.
                } else if m.att_rollout == Rollout::Linear {
                    m.att_lift.lift_fast(&ya, &mut self.phi_a_next);
                    tr.rls_a.update_model(&mut tr.att, &self.phi_a[..m.att.p], &self.phi_a_next[..m.att.p]);
                } else {
                    tr.rls_a.update_model(&mut tr.att, &self.phi_a[..m.att.p], &ya);
                }
                // A diverged refinement must never poison forecasts: fall back to the fit.
                if !tr.trans.ab.iter().all(|v| v.is_finite()) {
                    tr.trans.ab.copy_from_slice(&m.trans.ab);
                    tr.rls_t.reset_covariance();
                }
                if !tr.att.ab.iter().all(|v| v.is_finite()) {
                    tr.att.ab.copy_from_slice(&m.att.ab);
                    tr.rls_a.reset_covariance();
                }
            }
        }
        push_hist(tr);
        ObserveOutcome::Accepted
    }

    /// Forecast every active track with at least `min_obs_for_forecast` observations
    /// `H = buf.horizon()` steps ahead from its last estimate. Returns the number of tracks
    /// written. Allocation-free.
    pub fn forecast(&mut self, buf: &mut ForecastBuffer) -> usize {
        self.forecast_tracks(buf, false)
    }

    /// What [`DebrisPredictor::forecast`] would change in the predictor, without the forecast:
    /// the tracks whose online calibration keeps this forecast (about one in
    /// `rate · dt` calls) are rolled out and kept; nothing is written for a reader
    /// (`buf.len() == 0`). A caller that knows nobody reads a forecast (the in-process
    /// lockstep, between planner cycles) calls this instead and leaves the predictor exactly
    /// as a full forecast would (a track's roll-out does not depend on the others'). Returns
    /// the number of tracks a forecast would have written. Allocation-free.
    pub fn forecast_for_calibration(&mut self, buf: &mut ForecastBuffer) -> usize {
        self.forecast_tracks(buf, true)
    }

    fn forecast_tracks(&mut self, buf: &mut ForecastBuffer, calibration_only: bool) -> usize {
        let h = buf.h.min(self.models.horizon);
        assert!((buf.dt - self.models.dt).abs() < 1e-12, "forecast buffer dt differs from the model dt");
        let hb = buf.h;
        // Tracks to forecast; rolled out four at a time (overlapping dependency chains).
        let mut sel = [0u16; MAX_TRACKS];
        let (mut n, mut mature) = (0, 0);
        for (i, tr) in self.tracks.iter().enumerate() {
            if !(tr.active && tr.n_obs >= self.cfg.min_obs_for_forecast) {
                continue;
            }
            mature += 1;
            let kept = tr.calib_obs >= self.cfg.calib_min_obs && tr.score.wants(tr.filter.t);
            if kept || !calibration_only {
                sel[n] = i as u16;
                n += 1;
            }
        }
        for (group, rows) in sel[..n].chunks(4).zip(buf.states.chunks_mut(4 * hb * N)) {
            let tracks = &self.tracks;
            let mut rows = rows.chunks_mut(hb * N);
            let mut job = |i: u16| {
                let tr = &tracks[i as usize];
                Job { trans: &tr.trans, att: &tr.att, x0: &tr.filter.x, out: rows.next().unwrap() }
            };
            let m = &self.models;
            match *group {
                [a, b, c, d] => self.engine.run_lanes::<4>(m, [job(a), job(b), job(c), job(d)], h),
                [a, b, c] => self.engine.run_lanes::<3>(m, [job(a), job(b), job(c)], h),
                [a, b] => self.engine.run_lanes::<2>(m, [job(a), job(b)], h),
                [a] => self.engine.run_lanes::<1>(m, [job(a)], h),
                _ => unreachable!(),
            }
        }
        if calibration_only {
            for (k, &i) in sel[..n].iter().enumerate() {
                let tr = &mut self.tracks[i as usize];
                tr.score.record(tr.filter.t, &buf.states[k * hb * N..(k * hb + h) * N]);
            }
            buf.len = 0;
            self.stats.forecast_fallbacks = self.engine.fallbacks;
            return mature;
        }
        let (floor, factor) = (self.cfg.calib_floor, self.cfg.calib_factor);
        let physics = self.attitude_physics();
        for (k, &i) in sel[..n].iter().enumerate() {
            let tr = &mut self.tracks[i as usize];
            tr.pos_bound.radii(&mut buf.pos_radius[k * hb..k * hb + h]);
            tr.att_bound.radii(&mut buf.att_radius[k * hb..k * hb + h]);
            // Calibrated on this track's own published forecasts where scored; the fitted
            // bound (with its event growth) where not yet.
            let mut last = (0.0f64, 0.0f64);
            for s in 1..=h {
                let o = k * hb + s - 1;
                if s <= self.cfg.calib_steps {
                    if let Some((rp, ra)) = tr.score.radius(s, floor, factor) {
                        // Never below the allowance for events the object's past cannot show.
                        let ev = &self.models.events;
                        let (rp, ra) = (rp.max(ev.pos(s)), ra.max(ev.att(s)));
                        (buf.pos_radius[o], buf.att_radius[o]) = (rp, ra);
                        last = (rp, ra);
                    }
                } else {
                    buf.pos_radius[o] = buf.pos_radius[o].max(last.0);
                    buf.att_radius[o] = buf.att_radius[o].max(last.1);
                }
            }
            // Not yet calibrated on its own forecasts (its first poses, or the first after a
            // restart): its bounds and its published attitude are the filter's (below).
            let young = self.cfg.track_sigmas > 0.0 && tr.calib_obs < self.cfg.calib_min_obs;
            if self.cfg.track_sigmas > 0.0 {
                let fc = &self.cfg.filter;
                for s in 1..=h {
                    let o = k * hb + s - 1;
                    let own = self.cfg.track_sigmas * tr.filter.pos_std(fc, s as f64 * buf.dt);
                    // Not yet calibrated: the fitted bound (the model's error on converged
                    // tracks) and this track's own uncertainty are separate errors, added in
                    // quadrature; a calibrated bound has seen the track's own errors.
                    buf.pos_radius[o] =
                        if young { buf.pos_radius[o].hypot(own) } else { buf.pos_radius[o].max(own) };
                    if young {
                        // Not yet calibrated on its own forecasts: nor is its attitude known
                        // better than the filter knows it (its body rate still uncertain).
                        let own = self.cfg.track_sigmas * tr.filter.att_std(fc, s as f64 * buf.dt);
                        buf.att_radius[o] = buf.att_radius[o].max(own);
                    }
                }
            }
            if self.cfg.front_end_margin_m > 0.0 {
                buf.pos_radius[k * hb..k * hb + h].iter_mut().for_each(|r| *r += self.cfg.front_end_margin_m);
            }
            if tr.calib_obs >= self.cfg.calib_min_obs {
                tr.score.record(tr.filter.t, &buf.states[k * hb * N..(k * hb + h) * N]);
            }
            let rows = k * hb..k * hb + h;
            // The precession channel forecasts from its newest measured axis: none since its
            // restart (an attitude event, then only views that show no axis), the model's.
            if physics && tr.axis.prec.has_samples() {
                let om = tr.axis.prec.omega();
                tr.axis.prec.axes_into(
                    &om,
                    tr.filter.t - tr.axis.prec.t,
                    buf.dt,
                    &mut buf.axis[rows.clone()],
                );
                let n_cal = tr.axis.radii(floor[1], factor, &mut buf.axis_radius[rows.clone()]);
                self.models.events.floor_att(&mut buf.axis_radius[k * hb..k * hb + n_cal]);
                let (ar, at) = (&mut buf.axis_radius[rows.clone()], &buf.att_radius[rows]);
                ar[n_cal..].copy_from_slice(&at[n_cal..]);
            } else {
                // The model's own attitude: its body z axis, with the attitude bound.
                for o in rows {
                    let x = &buf.states[o * N..(o + 1) * N];
                    buf.axis[o] =
                        dkrrt_collision::pose::quat_rotate(&[x[6], x[7], x[8], x[9]], &[0.0, 0.0, 1.0]);
                    buf.axis_radius[o] = buf.att_radius[o];
                }
            }
            // Full attitude: the model's, or beyond the model's own calibrated window the
            // torque-free forecast where that is calibrated tighter. A track not yet
            // calibrated publishes its filter's constant-rate attitude instead, the forecast
            // whose deviation its bound holds (the model refined online from its few poses
            // is not yet scored).
            let rows = k * hb..k * hb + h;
            for (s, o) in rows.clone().enumerate() {
                let x = &buf.states[o * N..(o + 1) * N];
                buf.full_q[o] = if young {
                    let xf = propagate(&tr.filter.x, self.models.frame_rate, (s + 1) as f64 * buf.dt);
                    [xf[6], xf[7], xf[8], xf[9]]
                } else {
                    [x[6], x[7], x[8], x[9]]
                };
                buf.full_radius[o] = buf.att_radius[o];
            }
            let mut er = [0.0; crate::calib::MAX_STEPS];
            let n_e = if physics {
                let n = tr.euler.radii(floor[1], factor, &mut er[..h.min(crate::calib::MAX_STEPS)]);
                self.models.events.floor_att(&mut er[..n]);
                n
            } else {
                0
            };
            let first = self.cfg.calib_steps.min(n_e);
            if (first..n_e).any(|s| er[s] < buf.att_radius[k * hb + s]) {
                let mut eq = [[0.0; 4]; crate::calib::MAX_STEPS];
                tr.euler.attitudes_into(self.models.frame_rate, tr.filter.t, buf.dt, &mut eq[..n_e]);
                for s in first..n_e {
                    let o = k * hb + s;
                    if er[s] < buf.full_radius[o] {
                        (buf.full_q[o], buf.full_radius[o]) = (eq[s], er[s]);
                    }
                }
            }
            buf.ids[k] = tr.id;
            buf.t0[k] = tr.filter.t;
        }
        buf.len = n;
        self.stats.forecast_fallbacks = self.engine.fallbacks;
        n
    }
}

impl Track {
    /// Forget the calibration's forecasts and scores; keep the next forecasts for scoring from
    /// [`PredictorConfig::calib_min_obs`] poses on (the filter (re)starts with this pose).
    fn restart_calibration(&mut self) {
        self.score.clear();
        self.calib_obs = 0;
    }
}

fn push_hist(tr: &mut Track) {
    tr.hist_t[tr.hist_head] = tr.filter.t;
    tr.hist_x[tr.hist_head] = tr.filter.x;
    tr.hist_head = (tr.hist_head + 1) % HISTORY;
    tr.hist_len = (tr.hist_len + 1).min(HISTORY);
}
