//! The debris predictor's process-independent core: the scenario's models fitted at
//! start-up, observation frames of the message contract fed to [`DebrisPredictor`] item by
//! item (one bad item never loses the good ones), and forecasts written into the
//! fixed-size [`DebrisForecast`] on one common time grid.
//!
//! Frames: messages carry arm-base-frame poses; the predictor's models work in the module's
//! LVLH frame (relative orbital dynamics), so positions are shifted by `debris.base_lvlh` on
//! the way in and out. Time: plant-clock seconds (`t_meas_ns`).
//!
//! [`PredictorCore::observe_frame`] and [`PredictorCore::forecast_into`] allocate nothing.

use dkrrt_collision::interpolate_pose;
use dkrrt_config::Scenario;
use dkrrt_debris::{Observation, PerturbationConfig, RandomSceneParams, Scene, SCENE_NAMES};
use dkrrt_depthpose::perception::DepthPerception;
use dkrrt_msg::{
    ContractLimits, DebrisForecast, DebrisObservation, DebrisShape, ForecastStep, DEBRIS_AXIS_ONLY,
    DEBRIS_HAS_VELOCITY, DEBRIS_PARTIAL, DEBRIS_RESTART, FORECAST_STEPS, MAX_DEBRIS,
};
use dkrrt_predictor::eval::{perturbed_scene, record, training_set, Recording};
use dkrrt_predictor::training::{TrainedModels, ATTITUDE_MODEL};
use dkrrt_predictor::{
    DebrisPredictor, FitConfig, ForecastBuffer, GateStats, Method, Models, ObserveOutcome, PredictorConfig,
};
use serde::Serialize;

/// Seconds of each simulated training run used for the start-up fit.
pub const FIT_RUN_S: f64 = 20.0;

/// The deep attitude model shipped in the binary (`models/deep-attitude.dkm`, written by
/// `dkrrt train` with its default options); used when `predictor.model` is `""`.
pub const EMBEDDED_MODEL: &[u8] = include_bytes!("../../models/deep-attitude.dkm");

/// The shipped learned visual features f_θ (`dkrrt train --visual`), embedded in the binary.
pub const EMBEDDED_VISUAL: &[u8] = include_bytes!("../../models/visual.dkv");

/// The embedded visual model.
pub fn embedded_visual() -> Result<dkrrt_visual::VisualNet, String> {
    dkrrt_visual::file::from_bytes(EMBEDDED_VISUAL).map_err(|e| format!("embedded visual model: {e}"))
}

/// The depth front end whose attitudes and classes the learned visual features `net` read.
pub fn learned_perception(net: dkrrt_visual::VisualNet) -> DepthPerception {
    DepthPerception::with_model(Box::new(dkrrt_visual::LearnedAxes::new(net)))
}

/// The scenario's trained deep model: the file of `predictor.model`, or the embedded one.
/// Errors name the field and what is wrong with the file (format, version, checksum, ...).
pub fn load_trained(sc: &Scenario) -> Result<TrainedModels, String> {
    match sc.predictor_model_path() {
        Some(p) => TrainedModels::load(&p)
            .map_err(|e| format!("scenario {}: predictor.model = {}: {e}", sc.origin_name(), p.display())),
        None => dkrrt_deep::from_bytes(EMBEDDED_MODEL)
            .and_then(|m| dkrrt_deep::select(m, ATTITUDE_MODEL, 7))
            .map(|attitude| TrainedModels { attitude, report: None, validation: Vec::new() })
            .map_err(|e| format!("embedded deep model: {e}")),
    }
}

/// Reads the model files the scenario's predictor would read at start-up (the deep model of a
/// deep method, the learned front end's f_θ), so that a missing or bad one is an error naming
/// the field and the file before any process starts, not a predictor process that exits at
/// start-up and is restarted.
pub fn check_model_files(sc: &Scenario) -> Result<(), String> {
    if !sc.has_debris() || sc.forecasts() == dkrrt_config::Forecasts::Oracle {
        return Ok(());
    }
    if Method::from_name(sc.predictor_method()).is_some_and(|m| m.deep()) {
        load_trained(sc)?;
    }
    if sc.learned_front_end() {
        if let Some(p) = sc.visual_model_path() {
            dkrrt_visual::file::load(&p)
                .map_err(|e| format!("scenario {}: predictor.visual_model {e}", sc.origin_name()))?;
        }
    }
    Ok(())
}

/// Observation items the core rejected before the predictor saw them (contract violations),
/// plus the predictor's own gate statistics.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct ObsCounters {
    /// Frames received / rejected as a whole (bad `count`, a bad depth image, or a stamp
    /// far ahead of the frames before or far behind them: `frames_ahead`, `frames_behind`).
    pub frames: u64,
    pub frames_rejected: u64,
    /// Of `frames_rejected`: frames stamped too far after the newest frame so far
    /// ([`PredictorCore::stamp_lead_s`]), not (yet) confirmed by the frames after them
    /// ([`FrameClock`]).
    pub frames_ahead: u64,
    /// Of `frames_rejected`: frames stamped too far before the newest frame so far, not (yet)
    /// confirmed by the frames after them.
    pub frames_behind: u64,
    /// Frames refused as stamped too far ahead (or behind) that the frames after them then
    /// confirmed (a sensor back after a gap; the frames after a first frame stamped wrong):
    /// lost, not rejected (not in `frames_rejected`).
    pub frames_before_jump: u64,
    /// Jumps of the frames' clock back (confirmed): the tracks with poses after the new clock
    /// were dropped (their stamps were the wrong ones).
    pub clock_jumps_back: u64,
    /// Frames lost on the bus before the predictor read them (gaps in the publisher's
    /// sequence numbers; 0 in process).
    pub frames_lost: u64,
    /// Items received.
    pub items: u64,
    /// Items rejected by the contract check (NaN/Inf, out-of-range position, non-unit
    /// quaternion, measured after the frame that carries them was sent...).
    pub items_invalid: u64,
    /// Items rejected by the predictor's gate (impossible jumps, out of order, table full, ...).
    pub items_gated: u64,
    /// Depth frames: object views the learned front end's f_θ read (0 with the classical one).
    pub learned_views: u64,
    /// Depth frames: items from views cut by the image border, flagged `DEBRIS_PARTIAL` (no
    /// camera of their capture showed the object whole).
    pub partial_views: u64,
}

impl ObsCounters {
    /// Every rejected observation item (a rejected frame counts once).
    pub fn rejected(&self) -> u64 {
        self.frames_rejected + self.items_invalid + self.items_gated
    }
}

/// The frames' clock, checked. The predictor drops a track when the newest time it has seen
/// is more than the track timeout past the track's last pose, so one frame stamped ahead by
/// nearly that or more (a bad clock, a corrupted message) would age every track out at once,
/// and the objects it carried would then be refused as out of order until the real clock
/// caught up. A frame stamped more than `lead` after the newest admitted one, or more than
/// `lead` before it, is refused; the clock moves on to it only when [`STAMP_CONFIRM`] such
/// frames in a row (each within `lead` of the one before) say so: a sensor back after an
/// outage, or the frames after a first frame that was stamped wrong (the first frame's stamp
/// has nothing to be checked against), not one bad stamp. Stamps within `lead` of the newest
/// are admitted (their items are gated per track as out of order where they are).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FrameClock {
    newest_ns: Option<u64>,
    /// The refused frames in a row that would confirm a jump: the last one's stamp, how many
    /// stamps, and how many frames (a camera rig's faces share their capture's stamp).
    jump: Option<(u64, u32, u32)>,
}

/// [`FrameClock`]: frames in a row (of distinct stamps) that confirm a jump of the clock.
pub const STAMP_CONFIRM: u32 = 3;

/// [`PredictorCore::stamp_lead_s`]: the share of the track timeout a frame may be stamped
/// ahead of the newest one without confirmation (a frame stamped that far ahead can age out
/// early only the tracks not seen for the rest of the timeout).
pub const STAMP_LEAD_SHARE: f64 = 0.25;

impl FrameClock {
    /// Whether a frame stamped `stamp_ns` is admitted, with `lead_ns` the largest step ahead
    /// (or back) taken without confirmation: `None` refused; `Some(k)` admitted, `k` the
    /// frames refused just before it that it confirms (0 but for the frame that confirms a
    /// jump; a jump back leaves [`FrameClock::newest_ns`] lower than before).
    pub fn admit(&mut self, stamp_ns: u64, lead_ns: u64) -> Option<u32> {
        let Some(newest) = self.newest_ns else {
            self.newest_ns = Some(stamp_ns);
            return Some(0);
        };
        if stamp_ns <= newest.saturating_add(lead_ns) && stamp_ns >= newest.saturating_sub(lead_ns) {
            self.newest_ns = Some(newest.max(stamp_ns));
            self.jump = None;
            return Some(0);
        }
        // A chain of steps of at most `lead` cannot cross the admitted window (`2·lead`
        // wide): its frames all lie ahead of the newest, or all behind it.
        // Another frame of the same capture confirms nothing.
        let (n, frames) = match self.jump {
            Some((prev, n, f)) if stamp_ns == prev => (n, f + 1),
            Some((prev, n, f)) if stamp_ns > prev && stamp_ns - prev <= lead_ns => (n + 1, f + 1),
            _ => (1, 1),
        };
        if n >= STAMP_CONFIRM {
            (self.newest_ns, self.jump) = (Some(stamp_ns), None);
            Some(frames - 1)
        } else {
            self.jump = Some((stamp_ns, n, frames));
            None
        }
    }

    /// The newest admitted stamp, ns.
    pub fn newest_ns(&self) -> Option<u64> {
        self.newest_ns
    }
}

/// Builds the predictor's models for the scenario: the scene is simulated `fit_runs` times
/// (seeded, initial states perturbed for named scenes) with the scenario's sensor, and the
/// method is fitted on the filtered estimates. Allocates; start-up only.
pub fn fit_models(sc: &Scenario) -> Result<Models, String> {
    fit_models_with(sc, None)
}

/// [`fit_models`] with the deep attitude network given (`None`: the scenario's,
/// [`load_trained`]).
pub fn fit_models_with(sc: &Scenario, trained: Option<&TrainedModels>) -> Result<Models, String> {
    let method = Method::from_name(sc.predictor_method()).ok_or_else(|| {
        let names: Vec<&str> = Method::ALL.iter().map(|m| m.name()).collect();
        format!("predictor.method {:?}: unknown (one of {})", sc.predictor_method(), names.join(", "))
    })?;
    let scene = sc.load_debris_scene().map_err(|e| e.to_string())?;
    let mut fit = FitConfig {
        dt: sc.predictor.dt_s,
        horizon: sc.predictor.horizon_steps as usize,
        ..FitConfig::default()
    };
    let recs = training_runs(sc, &scene)?;
    fit.frame_rate = recs.first().map_or(fit.frame_rate, |r| r.mean_motion);
    let ts = training_set(&recs, fit.dt, fit.horizon, 1.0, &predictor_config(sc));
    if ts.n_pairs() < 10 && method.koopman() {
        return Err(format!("predictor: the scene gives too little training data ({} pairs)", ts.n_pairs()));
    }
    let loaded = if method.deep() && trained.is_none() { Some(load_trained(sc)?) } else { None };
    let deep = if method.deep() { trained.or(loaded.as_ref()) } else { None };
    Models::fit_with_deep(method, &ts, &fit, deep.map(|d| &d.attitude))
        .map_err(|e| format!("predictor: fitting {}: {e}", method.name()))
}

/// Predictor settings of the scenario: the defaults with the pose filter's measurement noise
/// taken from the scenario's sensor (`debris.pos_sigma_m`, `debris.att_sigma_rad`, and
/// `vel_sigma_mps` / `rate_sigma_radps` for frames with rates; a real perception driver
/// states its own noise there).
pub fn predictor_config(sc: &Scenario) -> PredictorConfig {
    let mut cfg = PredictorConfig::default();
    cfg.filter.pos_sigma = sc.debris.pos_sigma_m.max(1e-4);
    cfg.filter.att_sigma = sc.debris.att_sigma_rad.max(1e-4);
    cfg.filter.vel_sigma = sc.debris.vel_sigma_mps.max(1e-5);
    cfg.filter.rate_sigma = sc.debris.rate_sigma_radps.max(1e-5);
    if sc.depth_input() {
        for_depth(&mut cfg, &sc.camera);
    }
    cfg
}

/// The predictor settings for poses from depth frames (`dkrrt_depthpose::perception`; the
/// same for `dkrrt predict-eval`'s depth views): a pixel spans z/f (6 cm at 5 m for the
/// default camera), and occlusion and the visible side move the centroid (the front end's
/// tests recover centres within 5–10 cm and axes within 0.05 rad), so the filter assumes that
/// noise, or 8 % of the object's size if more (measured per observation: p99 ≈ 0.34 × its
/// estimated radius). Their errors are heavy-tailed and come in runs as an object turns its
/// sides, so: Huber updates beyond 3 deviations, an impulse only on two failing model pairs
/// in a row, and a track dropped while its object was hidden taken up again within 5 s.
/// Far views are noisier: a pixel spans more, and a far object shows few of them, so the
/// noise is also at least [`DEPTH_POS_SIGMA_PIXELS`] of a pixel's span at the object's range
/// from `camera`'s optical centre. Each is off for the pose sensor. A track is forecast from
/// its fifth pose (the pose sensor's from its second). (The published bound holds the
/// filter's own deviations for both, `PredictorConfig::track_sigmas`.)
pub fn for_depth(cfg: &mut PredictorConfig, camera: &dkrrt_camera::CameraConfig) {
    cfg.filter.pos_sigma = cfg.filter.pos_sigma.max(DEPTH_POS_SIGMA_M);
    cfg.filter.att_sigma = cfg.filter.att_sigma.max(DEPTH_ATT_SIGMA_RAD);
    cfg.filter.outlier_sigmas = DEPTH_OUTLIER_SIGMAS;
    cfg.event_persist = 2;
    cfg.event_max_dv = DEPTH_EVENT_MAX_DV;
    cfg.pos_sigma_per_m = DEPTH_POS_SIGMA_PER_M;
    cfg.min_obs_for_forecast = 5;
    cfg.revive_s = 5.0;
    cfg.front_end_margin_m = dkrrt_depthpose::perception::ERROR_MARGIN_M;
    cfg.pos_sigma_per_range = DEPTH_POS_SIGMA_PIXELS * camera.fov_y_rad / camera.height.max(1) as f64;
    cfg.sensor_origin = camera.position_m;
}

/// The position noise of a pose from depth frames is at least this many pixels' span at its
/// range ([`for_depth`]): 0.6 · 16.4 mrad ≈ 1 cm per metre for the default camera, the 5 cm of
/// [`DEPTH_POS_SIGMA_M`] at 5 m.
pub const DEPTH_POS_SIGMA_PIXELS: f64 = 0.6;

/// [`dkrrt_predictor::predictor::PredictorConfig::event_max_dv`] for poses from depth frames:
/// a position event widens the bound's growth by at most this, m/s.
pub const DEPTH_EVENT_MAX_DV: f64 = 0.3;

/// [`dkrrt_predictor::predictor::PredictorConfig::pos_sigma_per_m`] for poses from depth frames.
pub const DEPTH_POS_SIGMA_PER_M: f64 = 0.08;

/// [`dkrrt_predictor::filter::FilterConfig::outlier_sigmas`] for poses from depth frames.
pub const DEPTH_OUTLIER_SIGMAS: f64 = 3.0;

/// The measurement noise the predictor's filter assumes for poses from depth frames, m.
pub const DEPTH_POS_SIGMA_M: f64 = 0.05;
/// ... and for their attitudes, rad.
pub const DEPTH_ATT_SIGMA_RAD: f64 = 0.05;

fn training_runs(sc: &Scenario, scene: &Scene) -> Result<Vec<Recording>, String> {
    let named = SCENE_NAMES.contains(&sc.debris.scene.as_str());
    let generic = sc.predictor.fit == "generic";
    (0..sc.predictor.fit_runs as u64)
        .map(|r| {
            let seed = sc.predictor.fit_seed + r;
            let s = if generic {
                generic_scene(seed)
            } else if named {
                perturbed_scene(&sc.debris.scene, seed, 1.0).map_err(|e| e.to_string())?
            } else {
                scene.clone()
            };
            record(&s, sc.sensor_config(), FIT_RUN_S, 0.01, seed).map_err(|e| e.to_string())
        })
        .collect()
}

/// A random scene for `predictor.fit = "generic"`: objects of every shape at 2–12 m, up to
/// 1.5 m/s and 1.5 rad/s, with small unmodelled accelerations. It shares nothing with any
/// evaluated episode (its seeds are offset far from the episodes').
pub fn generic_scene(seed: u64) -> Scene {
    let params = RandomSceneParams {
        max_speed: 1.5,
        max_rate: 1.5,
        perturbation: PerturbationConfig {
            accel_bias_sigma: 1e-4,
            accel_noise_sigma: 5e-5,
            accel_noise_tau: 30.0,
        },
        ..RandomSceneParams::default()
    };
    Scene::random(0x5eed_0000_0000 + seed, 24, &params)
}

/// The plant-clock forecast grid: the first `k / rate_hz` boundary after `t` (s). One rule for
/// the predictor core's lockstep cadence and the in-process oracle's.
pub fn next_forecast_due(t: f64, rate_hz: f64) -> f64 {
    (t * rate_hz).floor() / rate_hz + 1.0 / rate_hz
}

/// What became of a frame's forecast ([`PredictorCore::observe_then_forecast_if`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cadence {
    /// No forecast was due with this frame.
    NotDue,
    /// Due, with nothing to publish: tracks, but none old enough to forecast.
    Nothing,
    /// Written into the message, to publish: the number of tracks (0: the sky is empty,
    /// [`PredictorCore::publishable`]).
    Written(usize),
    /// Due, but nobody reads it: only what it changes in the predictor was done; the number of
    /// tracks it would have written.
    CalibrationOnly(usize),
}

impl Cadence {
    /// The forecast written to publish and its tracks (`None` unless [`Cadence::Written`]).
    pub fn written(self) -> Option<usize> {
        if let Cadence::Written(n) = self {
            Some(n)
        } else {
            None
        }
    }
}

/// Predictor + forecast buffer + the frame/message conversions.
pub struct PredictorCore {
    pred: DebrisPredictor,
    buf: ForecastBuffer,
    base: [f64; 3],
    steps: usize,
    /// Bounding radius and shape per debris id (from the observations).
    radii: heapless::Vec<(u32, f64, DebrisShape), { 2 * MAX_DEBRIS }>,
    /// Newest observation time seen (plant clock), s.
    pub newest_t: f64,
    pub counters: ObsCounters,
    next_due_s: f64,
    /// `rrt-static`: every step of a forecast is the track's latest estimated pose, with no
    /// uncertainty (the planner adds its margin): no prediction.
    hold_still: bool,
    /// `predictor.input = "depth"`: the front end that turns depth frames into observation
    /// frames, and the frame it fills.
    perception: DepthPerception,
    seen: Option<Box<DebrisObservation>>,
    /// The newest valid frame of the pose sensor (or a perception driver) was empty: it looked
    /// and saw nothing; on the depth input, the newest whole capture (every frame with its
    /// stamp) labelled no object. With no track either, the sky is empty
    /// ([`PredictorCore::publishable`]).
    sky_empty: bool,
    /// The depth capture being read: its stamp and whether a frame of it labelled an object.
    capture: Option<(u64, bool)>,
    /// The frames' stamps, checked before a frame is read.
    clock: FrameClock,
    /// The sensor's frame period (the camera's on the depth input), s.
    frame_period_s: f64,
}

impl PredictorCore {
    /// A core around fitted `models` (allocates once).
    pub fn new(models: Models, sc: &Scenario) -> PredictorCore {
        let pred = DebrisPredictor::new(models, predictor_config(sc));
        let buf = ForecastBuffer::for_predictor(&pred);
        let steps = (sc.predictor.horizon_steps as usize).min(FORECAST_STEPS).min(buf.horizon());
        PredictorCore {
            pred,
            buf,
            base: sc.debris.base_lvlh,
            steps,
            radii: heapless::Vec::new(),
            newest_t: f64::NEG_INFINITY,
            counters: ObsCounters::default(),
            next_due_s: 0.0,
            hold_still: sc.forecasts() == dkrrt_config::Forecasts::Static,
            perception: Default::default(),
            seen: Some(Box::new(<DebrisObservation as dkrrt_msg::Zeroed>::zeroed())),
            sky_empty: false,
            capture: None,
            clock: FrameClock::default(),
            frame_period_s: 1.0
                / if sc.depth_input() { sc.camera.rate_hz } else { sc.debris.sensor_rate_hz }.max(1e-3),
        }
    }

    /// Whether a forecast of `n` tracks (from [`PredictorCore::forecast_into`]) is to be
    /// published: it has tracks, or the sky is empty (no track, and the sensor's newest frame
    /// saw nothing), which the planner must hear to move. With tracks too young to forecast it
    /// is not (the planner goes on waiting, or on its older forecast). An empty sky is said
    /// once per frame that saw it: a sensor that falls silent does not keep it empty.
    pub fn publishable(&mut self, n: usize) -> bool {
        if n > 0 {
            return true;
        }
        let empty = self.sky_empty && self.pred.n_tracks() == 0;
        self.sky_empty = false;
        empty
    }

    /// A core for the scenario: [`new`](Self::new) with the depth front end the scenario names
    /// (`predictor.front_end`: the learned one reads `predictor.visual_model` or the shipped
    /// model; a bad file is an error naming the field and the file).
    pub fn for_scenario(models: Models, sc: &Scenario) -> Result<PredictorCore, String> {
        let mut core = PredictorCore::new(models, sc);
        if sc.learned_front_end() {
            let net = match sc.visual_model_path() {
                Some(p) => dkrrt_visual::file::load(&p)
                    .map_err(|e| format!("scenario {}: predictor.visual_model {e}", sc.origin_name()))?,
                None => embedded_visual()?,
            };
            core.perception = learned_perception(net);
        }
        // The camera's depth noise, which the front end takes out of the views' spreads.
        core.perception.set_depth_noise(sc.camera.noise_base_m, sc.camera.noise_quad_per_m);
        Ok(core)
    }

    /// Whether the depth front end reads attitudes with the learned features f_θ.
    pub fn learned_front_end(&self) -> bool {
        self.perception.learned()
    }

    /// The predictor (statistics, tracks).
    pub fn predictor(&self) -> &DebrisPredictor {
        &self.pred
    }

    /// The predictor's gate statistics.
    pub fn gate(&self) -> &GateStats {
        self.pred.stats()
    }

    /// Feeds one observation frame: a bad `count` rejects the frame; otherwise every item is
    /// checked on its own against the contract and then gated by the predictor.
    pub fn observe_frame(&mut self, frame: &DebrisObservation, lim: &ContractLimits) {
        self.observe_items(frame, lim, true);
    }

    /// [`PredictorCore::observe_frame`]; `sensor`: the frame is the sensor's (an empty one
    /// says the sky is empty), not one the depth front end made of a camera view (where an
    /// empty one may be a view of objects not yet whole).
    fn observe_items(&mut self, frame: &DebrisObservation, lim: &ContractLimits, sensor: bool) {
        self.counters.frames += 1;
        if frame.validate_frame().is_err() {
            self.counters.frames_rejected += 1;
            return;
        }
        // A depth frame's stamp was checked with its image (`depth_valid`).
        if sensor && !self.admit_stamp(frame.header.stamp_ns) {
            return;
        }
        if sensor {
            self.sky_empty = frame.count == 0;
            if self.sky_empty && self.pred.n_tracks() == 0 {
                // Nothing observed and nothing tracked: the clock the forecasts are due on
                // runs on the frames (no measurement carries it).
                self.newest_t = self.newest_t.max(frame.header.stamp_ns as f64 * 1e-9);
            }
        }
        let mut accepted = false;
        for (i, it) in frame.items[..frame.count as usize].iter().enumerate() {
            self.counters.items += 1;
            // Measured after the frame that carries it was sent: a bad stamp, ahead of the
            // clock the frames were checked on.
            if it.validate_item(lim, i).is_err() || it.t_meas_ns > frame.header.stamp_ns {
                self.counters.items_invalid += 1;
                continue;
            }
            let t = it.t_meas_ns as f64 * 1e-9;
            let b = self.base;
            let o = Observation {
                id: it.id,
                t,
                t_avail: frame.header.stamp_ns as f64 * 1e-9,
                p: [it.p[0] + b[0], it.p[1] + b[1], it.p[2] + b[2]],
                q: it.q,
                v: it.v,
                w: it.w,
                has_rates: it.flags & DEBRIS_HAS_VELOCITY != 0,
                partial: it.flags & DEBRIS_PARTIAL != 0,
                restart: it.flags & DEBRIS_RESTART != 0,
                axis_only: it.flags & DEBRIS_AXIS_ONLY != 0,
                seq: frame.header.seq as u32,
            };
            match self.pred.observe(&o) {
                ObserveOutcome::Rejected(_) => self.counters.items_gated += 1,
                _ => {
                    accepted = true;
                    self.newest_t = self.newest_t.max(t);
                    self.set_shape(it.id, it.bounding_radius, it.shape);
                }
            }
        }
        if !accepted {
            // The predictor drops tracks by the newest time its poses bring; a frame that
            // brings none (nothing seen, or nothing it could read) says the sensor looked
            // then: tracks it has not shown for the timeout go (its stamp was checked).
            self.pred.prune(frame.header.stamp_ns as f64 * 1e-9);
        }
    }

    /// Plant-clock forecast schedule (lockstep runs): true once per `1/rate_hz` of observed
    /// plant time, so the forecasts do not depend on how fast the machine is.
    pub fn due_on_plant_clock(&mut self, rate_hz: f64) -> bool {
        if self.newest_t < self.next_due_s {
            return false;
        }
        self.next_due_s = next_forecast_due(self.newest_t, rate_hz);
        true
    }

    /// The lockstep cadence, frame by frame: observes `frame`, then forecasts into `msg` if
    /// that frame took the plant clock past the next `1/rate_hz` boundary. Returns the number
    /// of tracks of a forecast to publish (`None`: not due, or nothing to publish; `Some(0)`:
    /// the sky is empty). Called for every frame in order,
    /// the forecasts are the same however the frames are batched (the in-process lockstep
    /// and the lockstep process share it).
    pub fn observe_then_forecast(
        &mut self,
        frame: &DebrisObservation,
        lim: &ContractLimits,
        rate_hz: f64,
        msg: &mut DebrisForecast,
    ) -> Option<usize> {
        self.observe_then_forecast_if(frame, lim, rate_hz, msg, true).written()
    }

    /// [`PredictorCore::observe_then_forecast`] for a caller that knows whether anyone will
    /// read this frame's forecast: with `read = false` a due forecast only does what it would
    /// change in the predictor ([`DebrisPredictor::forecast_for_calibration`]) and `msg` is
    /// left alone, so the predictor goes on exactly as if it had been written.
    pub fn observe_then_forecast_if(
        &mut self,
        frame: &DebrisObservation,
        lim: &ContractLimits,
        rate_hz: f64,
        msg: &mut DebrisForecast,
        read: bool,
    ) -> Cadence {
        self.observe_items(frame, lim, true);
        self.forecast_if_due(rate_hz, msg, read)
    }

    /// The forecast a frame made due, if any ([`PredictorCore::observe_then_forecast_if`]).
    fn forecast_if_due(&mut self, rate_hz: f64, msg: &mut DebrisForecast, read: bool) -> Cadence {
        if !self.due_on_plant_clock(rate_hz) {
            return Cadence::NotDue;
        }
        let (n, c): (usize, fn(usize) -> Cadence) = if read {
            (self.forecast_into(msg), Cadence::Written)
        } else {
            self.apply_shapes();
            (self.pred.forecast_for_calibration(&mut self.buf), Cadence::CalibrationOnly)
        };
        if self.publishable(n) {
            c(n)
        } else {
            Cadence::Nothing
        }
    }

    /// Feeds one depth camera frame (`predictor.input = "depth"`): the front end
    /// (`dkrrt_depthpose::perception`) makes it an observation frame measured at its capture
    /// (the header its own), which goes the way of a sensor's frame. A bad image is rejected
    /// whole and counted (`frames_rejected`). Allocation-free.
    pub fn observe_depth(&mut self, img: &dkrrt_msg::DepthImage, lim: &ContractLimits) {
        if !self.depth_valid(img, lim) {
            return;
        }
        self.note_capture(img);
        let seen = self.see(img);
        self.observe_items(&seen, lim, false);
        self.seen = Some(seen);
    }

    /// [`PredictorCore::observe_then_forecast`] for a depth frame (the lockstep cadence).
    pub fn observe_depth_then_forecast(
        &mut self,
        img: &dkrrt_msg::DepthImage,
        lim: &ContractLimits,
        rate_hz: f64,
        msg: &mut DebrisForecast,
    ) -> Option<usize> {
        self.observe_depth_then_forecast_if(img, lim, rate_hz, msg, true).written()
    }

    /// [`PredictorCore::observe_then_forecast_if`] for a depth frame.
    pub fn observe_depth_then_forecast_if(
        &mut self,
        img: &dkrrt_msg::DepthImage,
        lim: &ContractLimits,
        rate_hz: f64,
        msg: &mut DebrisForecast,
        read: bool,
    ) -> Cadence {
        if !self.depth_valid(img, lim) {
            return Cadence::NotDue;
        }
        self.note_capture(img);
        let seen = self.see(img);
        self.observe_items(&seen, lim, false);
        let c = self.forecast_if_due(rate_hz, msg, read);
        self.seen = Some(seen);
        c
    }

    /// Checks a depth frame against the contract; a bad one is counted as a rejected frame.
    fn depth_valid(&mut self, img: &dkrrt_msg::DepthImage, lim: &ContractLimits) -> bool {
        use dkrrt_msg::Validate;
        if img.validate(lim).is_ok() {
            if self.admit_stamp(img.header.stamp_ns) {
                return true;
            }
            self.counters.frames += 1;
            return false;
        }
        self.counters.frames += 1;
        self.counters.frames_rejected += 1;
        false
    }

    /// How far ahead of the newest frame a frame may be stamped without confirmation
    /// ([`FrameClock`]): [`STAMP_LEAD_SHARE`] of the track timeout, but at least two frame
    /// periods of the sensor (a dropped frame is no jump), s.
    pub fn stamp_lead_s(&self) -> f64 {
        (STAMP_LEAD_SHARE * self.pred.config().track_timeout).max(2.0 * self.frame_period_s)
    }

    /// [`FrameClock::admit`] with [`PredictorCore::stamp_lead_s`]; a refused frame is counted
    /// (`frames_rejected`, and `frames_ahead` or `frames_behind`), and moved to
    /// `frames_before_jump` when the frames after it confirm the jump. After a jump back, the
    /// tracks with poses after the new clock are dropped (their times came with the wrong
    /// stamps, and their objects' poses would be refused as out of order until the clock
    /// caught up with them), and the forecast schedule starts again from the new clock.
    fn admit_stamp(&mut self, stamp_ns: u64) -> bool {
        let lead_ns = (self.stamp_lead_s() * 1e9) as u64;
        let before = self.clock.newest_ns();
        let behind = before.is_some_and(|b| stamp_ns < b);
        let c = &mut self.counters;
        match self.clock.admit(stamp_ns, lead_ns) {
            Some(0) => true,
            Some(k) => {
                let k = k as u64;
                c.frames_rejected -= k;
                if behind {
                    c.frames_behind -= k;
                    c.clock_jumps_back += 1;
                    let t = stamp_ns as f64 * 1e-9;
                    self.pred.drop_after(t);
                    (self.newest_t, self.next_due_s) = (t, 0.0);
                } else {
                    c.frames_ahead -= k;
                }
                c.frames_before_jump += k;
                true
            }
            None => {
                c.frames_rejected += 1;
                if behind {
                    c.frames_behind += 1;
                } else {
                    c.frames_ahead += 1;
                }
                false
            }
        }
    }

    /// A depth frame's part in the empty-sky rule: a rig's faces come as frames with the
    /// capture's stamp, so a capture is whole when a frame of the next one arrives; one whose
    /// frames labelled no object (a front end's views may be of objects not yet whole, its
    /// labels are not) says the sky was empty then.
    fn note_capture(&mut self, img: &dkrrt_msg::DepthImage) {
        let stamp = img.header.stamp_ns;
        match self.capture {
            Some((s, _)) if s == stamp => {}
            prev => {
                if let Some((s, labelled)) = prev {
                    self.sky_empty = !labelled;
                    if self.sky_empty && self.pred.n_tracks() == 0 {
                        self.newest_t = self.newest_t.max(s as f64 * 1e-9);
                    }
                }
                self.capture = Some((stamp, false));
            }
        }
        if let Some(c) = self.capture.as_mut() {
            c.1 |= img.n_instances > 0;
        }
    }

    /// The observation frame of a depth frame (the core's own buffer, handed back after use).
    fn see(&mut self, img: &dkrrt_msg::DepthImage) -> Box<DebrisObservation> {
        let mut seen = self.seen.take().expect("the depth buffer is back after each use");
        self.perception.convert(img, &mut seen);
        self.counters.learned_views = self.perception.stats.learned;
        self.counters.partial_views = self.perception.stats.partial_reported;
        seen.header = img.header;
        seen
    }

    /// The tracks take their objects' latest shapes (size, inertia hint) before a forecast.
    fn apply_shapes(&mut self) {
        for e in &self.radii {
            self.pred.set_shape(e.0, &e.2);
        }
    }

    fn set_shape(&mut self, id: u32, r: f64, shape: DebrisShape) {
        if let Some(e) = self.radii.iter_mut().find(|e| e.0 == id) {
            (e.1, e.2) = (r, shape);
        } else if self.radii.push((id, r, shape)).is_err() {
            // Full: forget the oldest entry (ids of long-gone tracks).
            self.radii.remove(0);
            let _ = self.radii.push((id, r, shape));
        }
    }

    fn shape(&self, id: u32) -> (f64, DebrisShape) {
        self.radii.iter().find(|e| e.0 == id).map_or((0.0, DebrisShape::default()), |e| (e.1, e.2))
    }

    /// Forecasts every mature track and writes them into `msg` on the common grid
    /// `t0 + k·dt, k = 1..=steps` with `t0` = the newest track time. Positions are in the base
    /// frame; `sigma_m` = position bound + attitude bound × the shape's rotation lever
    /// ([`dkrrt_collision::bounds`]: a rod centred on its body origin uses its axis forecast by
    /// precession and that forecast's calibrated bound, other shapes the full attitude
    /// forecast and bound), `sigma_pos_m` = the position bound alone (for the bounding sphere). Returns the number of tracks written (0: nothing to publish).
    pub fn forecast_into(&mut self, msg: &mut DebrisForecast) -> usize {
        self.apply_shapes();
        let n = self.pred.forecast(&mut self.buf);
        let h = self.buf.horizon();
        let dt = self.buf.dt();
        let t0 = (0..n).map(|i| self.buf.t0(i)).fold(f64::NEG_INFINITY, f64::max);
        msg.count = n as u32;
        msg.steps = self.steps as u32;
        msg.dt_s = dt;
        // An empty forecast (an empty sky) is stamped with the predictor's clock.
        msg.t0_ns = (if n > 0 { t0 } else { self.newest_t }.max(0.0) * 1e9).round() as u64;
        msg.header.stamp_ns = msg.t0_ns;
        msg.header.flags = 0;
        let b = self.base;
        for i in 0..n {
            let id = self.buf.id(i);
            let (radius, shape) = self.shape(id);
            let tr = &mut msg.tracks[i];
            tr.id = id;
            tr.bounding_radius = radius;
            tr.shape = shape;
            if self.hold_still {
                // rrt-static: the latest estimate, held (the same pose at every step).
                let x = self.pred.track(id).map_or([0.0; 13], |t| t.state);
                let step = ForecastStep {
                    p: [x[0] - b[0], x[1] - b[1], x[2] - b[2]],
                    q: [x[6], x[7], x[8], x[9]],
                    sigma_m: 0.0,
                    sigma_pos_m: 0.0,
                };
                tr.steps[..self.steps].iter_mut().for_each(|st| *st = step);
                continue;
            }
            let lag = ((t0 - self.buf.t0(i)) / dt).max(0.0);
            for k in 1..=self.steps {
                // Fractional step of this track's own forecast that falls on the common grid.
                let s = k as f64 + lag;
                if s > h as f64 {
                    // Past this track's own horizon (it lags the newest track): read as the
                    // planner reads any forecast past its last step.
                    let (p, q, sigma_m, pos) = self.buf.continued(i, (s - h as f64) * dt, &shape, radius);
                    let p = [p[0] - b[0], p[1] - b[1], p[2] - b[2]];
                    tr.steps[k - 1] = ForecastStep { p, q, sigma_m, sigma_pos_m: pos };
                    continue;
                }
                let j = (s.floor() as usize).clamp(1, h - 1);
                let f = s - j as f64;
                let (a, c) = (self.buf.state(i, j), self.buf.state(i, j + 1));
                let pa = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
                let pc = [c[0] - b[0], c[1] - b[1], c[2] - b[2]];
                // A rod: its axis from the precession forecast (the spin about it is irrelevant
                // to the shape and poorly predictable).
                let (qa, qc) = (
                    self.buf.published_attitude(i, j, &shape),
                    self.buf.published_attitude(i, j + 1, &shape),
                );
                // The same interpolation the planner reads the forecast with.
                let (p, q) = interpolate_pose(&pa, &qa, &pc, &qc, f);
                let kk = (j + 1).min(h);
                let pos = self.buf.pos_radius(i, kk);
                tr.steps[k - 1] = ForecastStep {
                    p,
                    q,
                    sigma_m: self.buf.published_sigma(i, kk, &shape, radius),
                    sigma_pos_m: pos,
                };
            }
        }
        n
    }
}
