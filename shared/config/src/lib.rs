//! dkrrt-config: the scenario file.
//!
//! One TOML file configures a run: robot, rates, motion limits, tracker gains,
//! plant options, goal. Unknown keys are refused; every semantic error names
//! the field and the value (e.g. `tracker.kp[2] = -1: must be > 0`). A default
//! scenario is embedded, so `dkrrt launch` needs no argument.

pub mod arm;
pub mod debris;

use dkrrt_io::exact;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

/// Joint count of the configured arm.
pub const NJ: usize = 6;

/// The embedded default scenario (shared/config/scenarios/default.toml).
pub const DEFAULT_SCENARIO: &str = include_str!("../scenarios/default.toml");

#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("cannot read scenario {}: {source}", dkrrt_io::printable(&path.display().to_string()))]
    Io { path: PathBuf, source: std::io::Error },
    #[error("scenario {origin}: {message}")]
    Parse { origin: String, message: String },
    #[error("scenario {origin}: {field} = {value}: {reason}")]
    Invalid { origin: String, field: String, value: String, reason: String },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    Realtime,
    Lockstep,
}

impl std::str::FromStr for Mode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "realtime" => Ok(Mode::Realtime),
            "lockstep" => Ok(Mode::Lockstep),
            _ => Err(format!("unknown mode {s:?} (realtime | lockstep)")),
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    pub name: String,
    pub robot: RobotCfg,
    pub run: RunCfg,
    pub motion: MotionCfg,
    pub tracker: TrackerCfg,
    pub sim: SimCfg,
    pub goal: GoalCfg,
    /// Debris world of the simulator (and its sensor).
    pub debris: DebrisCfg,
    /// The debris predictor process.
    pub predictor: PredictorCfg,
    /// The trajectory source: `straight` (`dkrrt goto`) or the `dk-rrt` planner.
    #[serde(default)]
    pub planner: PlannerCfg,
    /// What a run must achieve to be reported `ok` (`dkrrt launch`).
    #[serde(default)]
    pub checks: ChecksCfg,
    /// Restart policies of the processes that may restart mid-run (`dkrrt launch`).
    #[serde(default)]
    pub supervision: SupervisionCfg,
    /// The UDP link to the arm (`dkrrt launch --driver udp`, `dkrrt udp-driver`,
    /// `dkrrt arm-emulator`): the emulated network's impairments and the arm's abort limit.
    #[serde(default)]
    pub udp: UdpCfg,
    /// The depth camera on the servicer (`dkrrt/depth_image`): pose in the arm's base frame,
    /// image, rate, latency, noise. Off unless `enabled`.
    #[serde(default)]
    pub camera: dkrrt_camera::CameraConfig,
    /// A threat episode (generated start, goal and debris aimed at the straight motion)
    /// replacing `sim.initial_q`, `goal.q` and the debris scene; resolved by the consumer
    /// (`dkrrt_episodes::resolve`) into the fields below.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub episode: Option<EpisodeCfg>,
    /// Directory relative paths are resolved against (not in the file).
    #[serde(skip)]
    pub base_dir: Option<PathBuf>,
    /// The debris scene of a resolved episode (not in the file: every process regenerates it
    /// from `[episode]`, deterministically).
    #[serde(skip)]
    pub scene_override: Option<dkrrt_debris::Scene>,
    /// The resolved episode's time limit, s.
    #[serde(skip)]
    pub episode_time_limit_s: Option<f64>,
    /// The file the scenario was read from (not in the file): errors name it.
    #[serde(skip)]
    pub origin: Option<String>,
}

/// The planning methods (`planner.method`): `straight` (no avoidance) and the replanning loop on
/// five kinds of forecast ([`Forecasts`]).
pub const PLANNER_METHODS: [&str; 6] =
    ["straight", "rrt-static", "cv-rrt", "edmd-rrt", "dk-rrt", "oracle-rrt"];

/// The fixed EDMD model `edmd-rrt` plans on: the better of the two fixed EDMD dictionaries in
/// `dkrrt predict-eval` (polynomial: lower attitude error than the RBF one at every horizon
/// and scene).
pub const EDMD_BASELINE: &str = "edmd-poly";

/// The debris predictor's methods (`predictor.method`; `dkrrt predict-eval` measures them).
pub const PREDICTOR_METHODS: [&str; 7] = [
    "constant-velocity",
    "edmd-poly",
    "edmd-rbf",
    "koopman-online",
    "dual-data",
    "deep-koopman",
    "deep-koopman-online",
];

/// What a planning method plans against.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Forecasts {
    /// Nothing: the straight motion.
    None,
    /// The debris held at their latest estimated poses, no prediction (`rrt-static`, the
    /// paper's "traditional RRT").
    Static,
    /// The debris predictor's forecasts with the method [`Scenario::predictor_method`]
    /// (`cv-rrt`, `edmd-rrt`, `dk-rrt`).
    Predictor,
    /// The true future motion of the debris, zero uncertainty (`oracle-rrt`; in process only).
    Oracle,
}

/// `[planner]`: the trajectory source and the replanning loop.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PlannerCfg {
    /// One of [`PLANNER_METHODS`]: `straight` (a jerk-limited line to the goal, no
    /// avoidance) or the replanning loop on the forecasts [`Scenario::forecasts`] names.
    pub method: String,
    /// Planning cycles per second.
    pub rate_hz: f64,
    /// Compute deadline of a cycle, ms.
    pub deadline_ms: f64,
    /// A new plan starts this long after the cycle's state, ms (>= the deadline + transport).
    pub commit_ms: f64,
    /// Obstacles are inflated by the forecast's sigma plus this margin, m.
    pub margin_m: f64,
    /// Planner iterations per cycle (the work budget; lockstep runs use exactly this).
    pub iterations: u32,
    /// Plans are checked this far ahead, s.
    pub lookahead_s: f64,
    /// Largest relative arm–debris motion between two checks, m.
    pub delta_m: f64,
    pub seed: u64,
    pub cpu: i32,
}

impl Default for PlannerCfg {
    fn default() -> Self {
        PlannerCfg {
            method: "straight".into(),
            rate_hz: 10.0,
            deadline_ms: 50.0,
            commit_ms: 60.0,
            margin_m: 0.05,
            iterations: 300,
            lookahead_s: 5.0,
            delta_m: 0.03,
            seed: 1,
            cpu: -1,
        }
    }
}

/// `[checks]`: the run's verdict. A run is `ok` only if the goal was reached within
/// `goal_tolerance_rad`, nothing collided, no joint exceeded its position or velocity limit,
/// every process exited cleanly, and rejected messages and safe holds stayed within these
/// bounds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ChecksCfg {
    /// Largest final joint error against the goal of the followed trajectory, rad.
    pub goal_tolerance_rad: f64,
    /// Messages any process may reject (invalid by the message contract) in one run.
    pub max_rejected_messages: u64,
    /// Safe holds (the tracker braking on a stale state or a rejected trajectory) in one run.
    /// A machine that stalls its real-time threads causes some: the default (20) is sized for
    /// a 2-core VM, where the default run measured 2–11; on a real-time kernel set 0.
    pub max_safe_holds: u64,
}

impl Default for ChecksCfg {
    fn default() -> Self {
        ChecksCfg { goal_tolerance_rad: 0.01, max_rejected_messages: 0, max_safe_holds: 20 }
    }
}

/// Restart policies (`supervision.predictor`, `supervision.planner`).
pub const RESTART_POLICIES: [&str; 2] = ["never", "on-failure"];

/// `[supervision]`: what the launcher does when the predictor or the planner dies or hangs.
/// `on-failure`: start it again after `backoff_ms` (doubled per restart), at most
/// `max_restarts` times per process; it resumes from the live bus (the planner plans nothing
/// while the tracker follows a plan it does not know, so the tracker keeps that trajectory).
/// The sim and the tracker never restart mid-motion; goto never restarts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SupervisionCfg {
    pub predictor: String,
    pub planner: String,
    pub max_restarts: u32,
    pub backoff_ms: f64,
}

impl Default for SupervisionCfg {
    fn default() -> Self {
        SupervisionCfg {
            predictor: "on-failure".into(),
            planner: "on-failure".into(),
            max_restarts: 3,
            backoff_ms: 200.0,
        }
    }
}

impl SupervisionCfg {
    /// Whether process `name` restarts after a failure.
    pub fn restarts(&self, name: &str) -> bool {
        match name {
            "predictor" => self.predictor == "on-failure",
            "planner" => self.planner == "on-failure",
            _ => false,
        }
    }
}

/// The tracker's command kinds (`tracker.command`).
pub const COMMAND_KINDS: [&str; 2] = ["torque", "servo"];

fn default_command() -> String {
    "torque".into()
}

fn is_torque(s: &String) -> bool {
    s == "torque"
}

/// `[udp]`: the link between `dkrrt udp-driver` and the arm (docs/udp-protocol.md). The
/// impairments are the arm emulator's (`dkrrt arm-emulator`), applied to both directions; a
/// real arm's network has its own.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct UdpCfg {
    /// One-way delay added to every datagram, ms.
    pub delay_ms: f64,
    /// Uniform random extra one-way delay in [0, jitter_ms], ms.
    pub jitter_ms: f64,
    /// Probability that a datagram is lost.
    pub loss: f64,
    /// Probability that a datagram is delivered twice.
    pub duplicate: f64,
    /// Probability that a datagram is held back one more period (arrives after its successor).
    pub reorder: f64,
    /// Seed of the impairments.
    pub seed: u64,
    /// The arm aborts to its brakes after this many ticks without a valid command (Franka's
    /// FCI: 20).
    pub abort_after: u32,
}

impl Default for UdpCfg {
    fn default() -> Self {
        UdpCfg {
            delay_ms: 0.0,
            jitter_ms: 0.0,
            loss: 0.0,
            duplicate: 0.0,
            reorder: 0.0,
            seed: 1,
            abort_after: 20,
        }
    }
}

/// `[episode]`: a generated threat episode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EpisodeCfg {
    /// The scene the episode builds on: a named scene, or a scene file (relative to the
    /// scenario's directory).
    pub scene: String,
    pub index: u64,
    pub seed: u64,
    /// Run duration, s (default: the episode's time limit, 3 × the straight motion + 10 s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub duration_s: Option<f64>,
    /// `true`: the episode's goal is given as the end-effector pose of its goal configuration
    /// (`goal.pose`; the sources solve it by IK, the run reaches it with the end effector
    /// within 1 cm and 0.02 rad), else as the joint goal.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub pose_goal: bool,
    /// Longest straight motion, s (a short episode, e.g. for a quick HIL run): the big joint is
    /// one whose 0.5 rad motion fits, and the motion is shrunk until it does. Default: no cap
    /// (the studies' episodes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_straight_s: Option<f64>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotCfg {
    pub urdf: String,
    #[serde(deserialize_with = "exact::array")]
    pub gravity: [f64; 3],
    /// First link of the arm's chain in the URDF (its frame is the base frame); empty: the root.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub base_link: String,
    /// Last link of the chain (the end-effector frame); empty: the deepest link of the
    /// actuated chain.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub tip_link: String,
    /// Directories searched for `package://NAME/...` meshes (each holding package folders),
    /// before `ROS_PACKAGE_PATH`; relative ones are taken from the scenario's folder.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub package_path: Vec<String>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunCfg {
    pub mode: Mode,
    pub duration_s: f64,
    pub control_hz: f64,
    pub heartbeat_hz: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotionCfg {
    #[serde(deserialize_with = "exact::array")]
    pub v_max: [f64; NJ],
    #[serde(deserialize_with = "exact::array")]
    pub a_max: [f64; NJ],
    #[serde(deserialize_with = "exact::array")]
    pub j_max: [f64; NJ],
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackerCfg {
    #[serde(deserialize_with = "exact::array")]
    pub kp: [f64; NJ],
    #[serde(deserialize_with = "exact::array")]
    pub kd: [f64; NJ],
    pub stale_ticks: u32,
    /// A measured joint further than this from the reference, rad: the tracker brakes to
    /// rest from where the arm is (re-anchors) instead of pulling it back.
    #[serde(default = "default_max_track_error")]
    pub max_track_error_rad: f64,
    pub phase_us: u64,
    pub state_wait_us: u64,
    /// Realtime: wake `phase_us` before the mean arrival phase of the states (re-measured every
    /// 0.5 s) instead of `phase_us` after the monotonic grid: for drivers paced by their own
    /// hardware clock with a network in between (`dkrrt launch --driver udp` sets it).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub follow_states: bool,
    /// What the arm takes: `"torque"` (joint torques, Franka FCI style; the default) or
    /// `"servo"` (joint position and velocity setpoints for the arm's own servo, UR `servoj`
    /// style). Every command carries both; a driver sends the arm what it takes (the simulator
    /// is torque-driven and always applies the torques).
    #[serde(default = "default_command", skip_serializing_if = "is_torque")]
    pub command: String,
    pub predict: bool,
    pub fifo_priority: u32,
    pub mlockall: bool,
    pub cpu: i32,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimCfg {
    #[serde(deserialize_with = "exact::array")]
    pub initial_q: [f64; NJ],
    pub substeps: u32,
    pub noise_q_std: f64,
    pub noise_qd_std: f64,
    pub delay_ticks: u32,
    pub command_timeout_ticks: u32,
    pub brake_damping: f64,
    pub seed: u64,
    pub fifo_priority: u32,
    pub mlockall: bool,
    pub cpu: i32,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GoalCfg {
    /// Joint goal, rad (exactly one of `q` and `pose`).
    #[serde(default, deserialize_with = "exact::opt_array", skip_serializing_if = "Option::is_none")]
    pub q: Option<[f64; NJ]>,
    /// End-effector pose goal in the arm's base frame: `[x, y, z, qw, qx, qy, qz]` (m; a unit
    /// quaternion, normalised on use). The sources turn it into a joint goal by IK from where
    /// the arm is when they start (the planner: the solution clear of the forecast nearest to
    /// the arm); a run reaches it when the end effector is within 1 cm and 0.02 rad.
    #[serde(default, deserialize_with = "exact::opt_array", skip_serializing_if = "Option::is_none")]
    pub pose: Option<[f64; 7]>,
}

/// What a goal asks for (the scenario's `[goal]`, a `dkrrt/goal` message).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GoalRequest {
    Joint([f64; NJ]),
    /// Position (m) and attitude (w, x, y, z) of the end effector in the base frame.
    Pose([f64; 3], [f64; 4]),
}

impl GoalCfg {
    /// A joint goal.
    pub fn joint(q: [f64; NJ]) -> Self {
        GoalCfg { q: Some(q), pose: None }
    }

    /// The goal asked for (`q` if given, else `pose` with its quaternion normalised); `None`
    /// when neither is given ([`Scenario::validate`] refuses that).
    pub fn request(&self) -> Option<GoalRequest> {
        if let Some(q) = self.q {
            return Some(GoalRequest::Joint(q));
        }
        let v = self.pose?;
        let n = (v[3] * v[3] + v[4] * v[4] + v[5] * v[5] + v[6] * v[6]).sqrt();
        Some(GoalRequest::Pose([v[0], v[1], v[2]], [v[3] / n, v[4] / n, v[5] / n, v[6] / n]))
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DebrisCfg {
    /// Named scene (`sparse-slow`, `dense`, `fast-crossing`, `tumbling-rods`), a path to a
    /// scene TOML (relative to the scenario file), or `""` for no debris.
    pub scene: String,
    /// Position of the arm base in the module's LVLH frame, m (base axes = LVLH axes).
    #[serde(deserialize_with = "exact::array")]
    pub base_lvlh: [f64; 3],
    /// A link–debris pair at or below this distance is a contact (a collision: run failed), m.
    pub contact_margin_m: f64,
    /// Sensor sample rate, Hz (30–100).
    pub sensor_rate_hz: f64,
    /// Position noise per axis, m.
    pub pos_sigma_m: f64,
    /// Attitude noise per axis, rad.
    pub att_sigma_rad: f64,
    /// Probability that one measurement is lost.
    pub dropout: f64,
    /// Fixed sensor latency, s.
    pub latency_s: f64,
    /// Additional uniform latency jitter, s.
    pub latency_jitter_s: f64,
    /// Also report (noisy) linear and angular velocity.
    pub report_rates: bool,
    /// Velocity noise per axis when rates are reported, m/s.
    pub vel_sigma_mps: f64,
    /// Body-rate noise per axis when rates are reported, rad/s.
    pub rate_sigma_radps: f64,
    /// Sensor noise seed.
    pub seed: u64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PredictorCfg {
    /// Prediction method (`constant-velocity`, `edmd-poly`, `edmd-rbf`, `koopman-online`,
    /// `dual-data`, and the deep methods when a model file is given).
    pub method: String,
    /// Trained model file (`dkrrt train`), relative to the scenario file; `""` = none.
    pub model: String,
    /// Forecasts published per second (>= 50 for the planner).
    pub rate_hz: f64,
    /// Forecast steps (<= 40) and their spacing, s.
    pub horizon_steps: u32,
    pub dt_s: f64,
    /// Training runs simulated at start-up to fit the models (seeded).
    pub fit_runs: u32,
    /// What they simulate: `scene` (the scenario's own scene, perturbed) or `generic` (random
    /// scenes: nothing of the evaluated episode is seen before it runs).
    #[serde(default = "scene_fit")]
    pub fit: String,
    pub fit_seed: u64,
    pub cpu: i32,
    /// What the predictor observes: `poses` (the pose sensor's `dkrrt/debris_observation`)
    /// or `depth` (the sim's depth camera, `dkrrt/depth_image`, through the classical
    /// front end `dkrrt_depthpose::perception`; turns the camera on).
    #[serde(default = "poses_input")]
    pub input: String,
    /// With `input = "depth"`, the front end: `classical` (the points' principal axes) or
    /// `learned` (the learned visual features f_θ of `dkrrt train --visual` read each object's
    /// axes and class).
    #[serde(default = "classical_front_end")]
    pub front_end: String,
    /// The learned front end's model file (`dkrrt train --visual`), relative to the scenario
    /// file; `""` = the shipped one (embedded in the binary).
    #[serde(default)]
    pub visual_model: String,
}

fn poses_input() -> String {
    "poses".into()
}

fn classical_front_end() -> String {
    "classical".into()
}

fn scene_fit() -> String {
    "scene".into()
}

/// Longest run, s (one week): longer durations are refused (and cannot overflow a deadline).
pub const MAX_DURATION_S: f64 = 7.0 * 86400.0;
/// Largest `kp · period²` of the tracker.
pub const KP_DT2_MAX: f64 = 0.05;
/// Largest `kd · period` of the tracker.
pub const KD_DT_MAX: f64 = 0.5;

/// The largest tracker gains (kp, kd) at `control_hz`: `kp · dt² <= KP_DT2_MAX` (a bandwidth
/// of at most ~0.22 rad per tick) and `kd · dt <= KD_DT_MAX`. At 1 kHz: kp <= 50 000 1/s²,
/// kd <= 500 1/s (the default is 400 / 40).
fn default_max_track_error() -> f64 {
    0.01
}

pub fn gain_limits(control_hz: f64) -> (f64, f64) {
    (KP_DT2_MAX * control_hz * control_hz, KD_DT_MAX * control_hz)
}

/// Joint limits of the arm the scenario is checked against.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmLimits {
    pub q_min: [f64; NJ],
    pub q_max: [f64; NJ],
    pub v_max: [f64; NJ],
    pub tau_max: [f64; NJ],
}

struct Checker<'a> {
    origin: &'a str,
}

impl Checker<'_> {
    fn fail(&self, field: impl Into<String>, value: impl ToString, reason: impl Into<String>) -> ConfigError {
        ConfigError::Invalid {
            origin: self.origin.to_string(),
            field: field.into(),
            value: dkrrt_io::printable(&value.to_string()),
            reason: reason.into(),
        }
    }
    fn positive(&self, field: &str, v: f64) -> Result<(), ConfigError> {
        if v.is_finite() && v > 0.0 {
            Ok(())
        } else {
            Err(self.fail(field, v, "must be a finite number > 0"))
        }
    }
    fn non_negative(&self, field: &str, v: f64) -> Result<(), ConfigError> {
        if v.is_finite() && v >= 0.0 {
            Ok(())
        } else {
            Err(self.fail(field, v, "must be a finite number >= 0"))
        }
    }
    fn at_most(&self, field: &str, v: f64, hi: f64, unit: &str) -> Result<(), ConfigError> {
        if v <= hi {
            Ok(())
        } else {
            Err(self.fail(field, v, format!("must be <= {hi} {unit}").trim_end().to_string()))
        }
    }
    fn at_least(&self, field: &str, v: f64, lo: f64, unit: &str) -> Result<(), ConfigError> {
        if v >= lo {
            Ok(())
        } else {
            Err(self.fail(field, v, format!("must be >= {lo} {unit}").trim_end().to_string()))
        }
    }
    fn all_positive(&self, field: &str, v: &[f64; NJ]) -> Result<(), ConfigError> {
        for (i, x) in v.iter().enumerate() {
            self.positive(&format!("{field}[{i}]"), *x)?;
        }
        Ok(())
    }
    fn within(&self, field: &str, v: &[f64; NJ], lo: &[f64; NJ], hi: &[f64; NJ]) -> Result<(), ConfigError> {
        for i in 0..NJ {
            if !(v[i].is_finite() && lo[i] <= v[i] && v[i] <= hi[i]) {
                return Err(self.fail(
                    format!("{field}[{i}]"),
                    v[i],
                    format!("must lie within the joint limits [{}, {}]", lo[i], hi[i]),
                ));
            }
        }
        Ok(())
    }
}

impl Scenario {
    /// What the scenario's planning method plans against.
    pub fn forecasts(&self) -> Forecasts {
        match self.planner.method.as_str() {
            "straight" => Forecasts::None,
            "rrt-static" => Forecasts::Static,
            "oracle-rrt" => Forecasts::Oracle,
            _ => Forecasts::Predictor,
        }
    }

    /// Whether the trajectory source is the replanning loop (every method but `straight`).
    pub fn replans(&self) -> bool {
        self.forecasts() != Forecasts::None
    }

    /// The debris predictor's method: `constant-velocity` for `cv-rrt`, [`EDMD_BASELINE`] for
    /// `edmd-rrt`, else `predictor.method` (`dk-rrt`'s deep Koopman by default). `rrt-static`
    /// keeps the predictor for its filtered poses (track table, gating) and does not forecast
    /// with it.
    pub fn predictor_method(&self) -> &str {
        match self.planner.method.as_str() {
            "cv-rrt" | "rrt-static" => "constant-velocity",
            "edmd-rrt" => EDMD_BASELINE,
            _ => &self.predictor.method,
        }
    }

    /// Whether the predictor observes through the depth camera (`predictor.input = "depth"`).
    pub fn depth_input(&self) -> bool {
        self.predictor.input == "depth"
    }

    /// Whether the sim renders the depth camera: `[camera] enabled`, or the predictor reads it.
    pub fn camera_on(&self) -> bool {
        self.has_debris() && (self.camera.enabled || self.depth_input())
    }

    /// The embedded default scenario.
    pub fn default_scenario() -> Scenario {
        Scenario::from_toml_str(DEFAULT_SCENARIO, "<embedded default>")
            .expect("the embedded default scenario parses")
    }

    /// Parses a scenario; `origin` names it in errors.
    pub fn from_toml_str(s: &str, origin: &str) -> Result<Scenario, ConfigError> {
        let origin = || dkrrt_io::printable(origin);
        let de = toml::Deserializer::parse(s).map_err(|e| ConfigError::Parse {
            origin: origin(),
            message: e.to_string().trim_end().to_string(),
        })?;
        // A value of the wrong type is named by its path (`motion.v_max[0]: …`) before the
        // parser's line and column.
        serde_path_to_error::deserialize(de).map_err(|e| {
            let path = e.path().to_string();
            let inner = e.into_inner().to_string();
            let message = if path == "." { inner } else { format!("{path}: {inner}") };
            ConfigError::Parse { origin: origin(), message: message.trim_end().to_string() }
        })
    }

    /// Loads a scenario file (`"default"` means the embedded one).
    pub fn load(path: &str) -> Result<Scenario, ConfigError> {
        if path == "default" {
            return Ok(Self::default_scenario());
        }
        let p = Path::new(path);
        let text = dkrrt_io::read_text_capped(p, dkrrt_io::limits::SCENARIO)
            .map_err(|e| ConfigError::Io { path: p.to_path_buf(), source: e.into() })?;
        let mut sc = Self::from_toml_str(&text, path)?;
        sc.base_dir = p.parent().map(|d| d.to_path_buf());
        sc.origin = Some(path.to_string());
        Ok(sc)
    }

    /// Serializes the scenario (to hand the exact same one to every process).
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("a scenario always serializes")
    }

    /// The URDF path to load, resolved against the scenario's directory;
    /// `None` for the embedded default arm.
    pub fn urdf_path(&self) -> Option<PathBuf> {
        self.relative_file(&self.robot.urdf)
    }

    /// The debris scene path, resolved against the scenario's directory, if
    /// `debris.scene` names a file (contains `/` or ends in `.toml`).
    pub fn debris_scene_path(&self) -> Option<PathBuf> {
        self.scene_file(&self.debris.scene)
    }

    /// A scene field's file (`debris.scene`, `episode.scene`) resolved against the
    /// scenario's directory; `None`: a named scene (or none).
    pub fn scene_file(&self, s: &str) -> Option<PathBuf> {
        if !is_scene_path(s) {
            return None;
        }
        self.relative_file(s)
    }

    /// The predictor's model file, resolved against the scenario's directory.
    pub fn predictor_model_path(&self) -> Option<PathBuf> {
        self.relative_file(&self.predictor.model)
    }

    /// The learned front end's model file (`predictor.visual_model`), resolved against the
    /// scenario's directory; `None`: the shipped one.
    pub fn visual_model_path(&self) -> Option<PathBuf> {
        self.relative_file(&self.predictor.visual_model)
    }

    /// A file named in the scenario, resolved against its directory (`""`: none).
    fn relative_file(&self, name: &str) -> Option<PathBuf> {
        if name.is_empty() {
            return None;
        }
        let p = PathBuf::from(name);
        Some(match (&self.base_dir, p.is_relative()) {
            (Some(dir), true) => dir.join(p),
            _ => p,
        })
    }

    /// Whether the depth front end is the learned one.
    pub fn learned_front_end(&self) -> bool {
        self.predictor.front_end == "learned"
    }

    /// Whether the run has debris (and so a predictor).
    pub fn has_debris(&self) -> bool {
        !self.debris.scene.is_empty()
    }

    /// Control period in ns.
    pub fn period_ns(&self) -> u64 {
        (1e9 / self.run.control_hz).round() as u64
    }

    /// How errors name the scenario: the file it was read from, else its `name`.
    pub fn origin_name(&self) -> String {
        dkrrt_io::printable(self.origin.as_deref().unwrap_or(&self.name))
    }

    /// Plant ticks in the run.
    pub fn ticks(&self) -> u64 {
        (self.run.duration_s * self.run.control_hz).round() as u64
    }

    /// Checks values and cross-field rules against the arm's limits. The
    /// error names the field, its value and the rule.
    pub fn validate(&self, arm: &ArmLimits) -> Result<(), ConfigError> {
        let origin = self.origin_name();
        let c = Checker { origin: &origin };
        for (i, g) in self.robot.gravity.iter().enumerate() {
            if !(g.is_finite() && g.abs() <= 100.0) {
                return Err(c.fail(format!("robot.gravity[{i}]"), g, "must be finite, |g| <= 100 m/s^2"));
            }
        }
        c.positive("run.duration_s", self.run.duration_s)?;
        c.at_most("run.duration_s", self.run.duration_s, MAX_DURATION_S, "s (one week)")?;
        c.positive("run.control_hz", self.run.control_hz)?;
        if !(10.0..=20_000.0).contains(&self.run.control_hz) {
            return Err(c.fail("run.control_hz", self.run.control_hz, "must be within [10, 20000] Hz"));
        }
        c.positive("run.heartbeat_hz", self.run.heartbeat_hz)?;
        c.at_most("run.heartbeat_hz", self.run.heartbeat_hz, 1000.0, "Hz")?;
        c.at_least(
            "run.heartbeat_hz",
            self.run.heartbeat_hz,
            1.0,
            "Hz (the launcher's hang detection needs one per 2 s)",
        )?;
        for (name, v, hi) in
            [("motion.a_max", &self.motion.a_max, 1000.0), ("motion.j_max", &self.motion.j_max, 1e5)]
        {
            for (i, x) in v.iter().enumerate() {
                c.at_most(&format!("{name}[{i}]"), *x, hi, "")?;
            }
        }
        c.all_positive("motion.v_max", &self.motion.v_max)?;
        c.all_positive("motion.a_max", &self.motion.a_max)?;
        c.all_positive("motion.j_max", &self.motion.j_max)?;
        for i in 0..NJ {
            if self.motion.v_max[i] > arm.v_max[i] {
                return Err(c.fail(
                    format!("motion.v_max[{i}]"),
                    self.motion.v_max[i],
                    format!("exceeds the arm's velocity limit {}", arm.v_max[i]),
                ));
            }
        }
        c.all_positive("tracker.kp", &self.tracker.kp)?;
        c.all_positive("tracker.kd", &self.tracker.kd)?;
        // Discrete-time stability of the computed-torque loop (one tick of delay): the gains
        // must stay well inside what the control rate can close.
        let (kp_max, kd_max) = gain_limits(self.run.control_hz);
        for i in 0..NJ {
            let why = |g: f64| {
                format!("must be <= {g:.0} at {} Hz (gain x period^2 <= {KP_DT2_MAX}, kd x period <= {KD_DT_MAX}): a higher gain makes the loop unstable", self.run.control_hz)
            };
            if self.tracker.kp[i] > kp_max {
                return Err(c.fail(format!("tracker.kp[{i}]"), self.tracker.kp[i], why(kp_max)));
            }
            if self.tracker.kd[i] > kd_max {
                return Err(c.fail(format!("tracker.kd[{i}]"), self.tracker.kd[i], why(kd_max)));
            }
        }
        if self.tracker.stale_ticks == 0 {
            return Err(c.fail("tracker.stale_ticks", 0, "must be >= 1"));
        }
        let max_stale = (0.1 * self.run.control_hz).ceil() as u32;
        if self.tracker.stale_ticks > max_stale {
            return Err(c.fail(
                "tracker.stale_ticks",
                self.tracker.stale_ticks,
                format!("must be <= {max_stale} (0.1 s): a longer blind interval is no safe hold"),
            ));
        }
        // Above the measurement noise (a false re-anchor at 6 sigma is rare), and small
        // enough that pulling the arm back across it stays a small correction.
        let min_err = (6.0 * self.sim.noise_q_std).max(1e-4);
        if !(self.tracker.max_track_error_rad >= min_err) {
            return Err(c.fail(
                "tracker.max_track_error_rad",
                self.tracker.max_track_error_rad,
                format!("must be >= {min_err} rad (1e-4, and 6 x sim.noise_q_std)"),
            ));
        }
        c.at_most("tracker.max_track_error_rad", self.tracker.max_track_error_rad, 0.3, "rad")?;
        let period_us = 1e6 / self.run.control_hz;
        if (self.tracker.phase_us + self.tracker.state_wait_us) as f64 >= period_us {
            return Err(c.fail(
                "tracker.state_wait_us",
                self.tracker.state_wait_us,
                format!("phase_us + state_wait_us must be below the control period ({period_us} us)"),
            ));
        }
        if self.tracker.fifo_priority > 99 {
            return Err(c.fail("tracker.fifo_priority", self.tracker.fifo_priority, "must be 0..=99"));
        }
        if self.sim.fifo_priority > 99 {
            return Err(c.fail("sim.fifo_priority", self.sim.fifo_priority, "must be 0..=99"));
        }
        c.within("sim.initial_q", &self.sim.initial_q, &arm.q_min, &arm.q_max)?;
        match (&self.goal.q, &self.goal.pose) {
            (Some(q), None) => c.within("goal.q", q, &arm.q_min, &arm.q_max)?,
            (None, Some(v)) => {
                for (i, x) in v.iter().enumerate() {
                    if !x.is_finite() {
                        return Err(c.fail(format!("goal.pose[{i}]"), x, "must be finite"));
                    }
                }
                let n = (v[3] * v[3] + v[4] * v[4] + v[5] * v[5] + v[6] * v[6]).sqrt();
                if (n - 1.0).abs() > 1e-3 {
                    return Err(c.fail(
                        "goal.pose[3..7]",
                        n,
                        "the attitude (qw, qx, qy, qz) must be a unit quaternion (norm 1 ± 1e-3)",
                    ));
                }
                let r = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                if r > 100.0 {
                    return Err(c.fail("goal.pose[0..3]", r, "must lie within 100 m of the base"));
                }
            }
            (Some(_), Some(_)) => {
                return Err(c.fail("goal", "q and pose", "give one of goal.q and goal.pose, not both"))
            }
            (None, None) => {
                return Err(c.fail(
                    "goal",
                    "nothing",
                    "give goal.q (joints, rad) or goal.pose ([x, y, z, qw, qx, qy, qz])",
                ))
            }
        }
        if self.sim.substeps == 0 || self.sim.substeps > 100 {
            return Err(c.fail("sim.substeps", self.sim.substeps, "must be 1..=100"));
        }
        c.non_negative("sim.noise_q_std", self.sim.noise_q_std)?;
        c.at_most("sim.noise_q_std", self.sim.noise_q_std, 0.05, "rad")?;
        c.non_negative("sim.noise_qd_std", self.sim.noise_qd_std)?;
        c.at_most("sim.noise_qd_std", self.sim.noise_qd_std, 0.5, "rad/s")?;
        c.positive("sim.brake_damping", self.sim.brake_damping)?;
        c.at_most("sim.brake_damping", self.sim.brake_damping, 1e5, "N·m·s/rad")?;
        if self.sim.delay_ticks > 1000 {
            return Err(c.fail("sim.delay_ticks", self.sim.delay_ticks, "must be <= 1000"));
        }
        if self.sim.command_timeout_ticks == 0 {
            return Err(c.fail("sim.command_timeout_ticks", 0, "must be >= 1"));
        }
        let max_timeout = (0.5 * self.run.control_hz).ceil() as u32;
        if self.sim.command_timeout_ticks > max_timeout {
            return Err(c.fail(
                "sim.command_timeout_ticks",
                self.sim.command_timeout_ticks,
                format!("must be <= {max_timeout} (0.5 s): the brakes must catch a dead controller"),
            ));
        }
        let d = &self.debris;
        for (i, b) in d.base_lvlh.iter().enumerate() {
            if !b.is_finite() || b.abs() > 1000.0 {
                return Err(c.fail(format!("debris.base_lvlh[{i}]"), b, "must be finite, |x| <= 1000 m"));
            }
        }
        c.non_negative("debris.contact_margin_m", d.contact_margin_m)?;
        if !(30.0..=100.0).contains(&d.sensor_rate_hz) {
            return Err(c.fail("debris.sensor_rate_hz", d.sensor_rate_hz, "must be within [30, 100] Hz"));
        }
        c.at_most("debris.contact_margin_m", d.contact_margin_m, 1.0, "m")?;
        for (name, v, hi) in [
            ("debris.pos_sigma_m", d.pos_sigma_m, 1.0),
            ("debris.att_sigma_rad", d.att_sigma_rad, 1.0),
            ("debris.vel_sigma_mps", d.vel_sigma_mps, 10.0),
            ("debris.rate_sigma_radps", d.rate_sigma_radps, 10.0),
        ] {
            c.non_negative(name, v)?;
            c.at_most(name, v, hi, "")?;
        }
        if !(0.0..1.0).contains(&d.dropout) {
            return Err(c.fail("debris.dropout", d.dropout, "must be within [0, 1)"));
        }
        c.non_negative("debris.latency_s", d.latency_s)?;
        c.non_negative("debris.latency_jitter_s", d.latency_jitter_s)?;
        if d.latency_s + d.latency_jitter_s > 1.0 {
            return Err(c.fail("debris.latency_s", d.latency_s, "latency + jitter must be <= 1 s"));
        }
        let p = &self.predictor;
        if !(1.0..=1000.0).contains(&p.rate_hz) {
            return Err(c.fail("predictor.rate_hz", p.rate_hz, "must be within [1, 1000] Hz"));
        }
        if p.horizon_steps == 0 || p.horizon_steps as usize > dkrrt_msg::FORECAST_STEPS {
            return Err(c.fail(
                "predictor.horizon_steps",
                p.horizon_steps,
                format!("must be 1..={}", dkrrt_msg::FORECAST_STEPS),
            ));
        }
        c.positive("predictor.dt_s", p.dt_s)?;
        c.at_most("predictor.dt_s", p.dt_s, 1.0, "s")?;
        if p.fit_runs == 0 || p.fit_runs > 64 {
            return Err(c.fail("predictor.fit_runs", p.fit_runs, "must be 1..=64"));
        }
        if p.input != "poses" && p.input != "depth" {
            return Err(c.fail(
                "predictor.input",
                format!("{:?}", p.input),
                "must be \"poses\" or \"depth\"",
            ));
        }
        if p.front_end != "classical" && p.front_end != "learned" {
            return Err(c.fail(
                "predictor.front_end",
                format!("{:?}", p.front_end),
                "must be \"classical\" or \"learned\"",
            ));
        }
        if !PREDICTOR_METHODS.contains(&p.method.as_str()) {
            return Err(c.fail(
                "predictor.method",
                format!("{:?}", p.method),
                format!("must be one of {}", PREDICTOR_METHODS.join(", ")),
            ));
        }
        if p.fit != "scene" && p.fit != "generic" {
            return Err(c.fail("predictor.fit", format!("{:?}", p.fit), "must be \"scene\" or \"generic\""));
        }
        let pl = &self.planner;
        if !PLANNER_METHODS.contains(&pl.method.as_str()) {
            return Err(c.fail(
                "planner.method",
                format!("{:?}", pl.method),
                format!("must be one of {}", PLANNER_METHODS.join(", ")),
            ));
        }
        if !(1.0..=100.0).contains(&pl.rate_hz) {
            return Err(c.fail("planner.rate_hz", pl.rate_hz, "must be within [1, 100] Hz"));
        }
        if !(pl.deadline_ms > 0.0 && pl.deadline_ms <= 1000.0 / pl.rate_hz) {
            return Err(c.fail(
                "planner.deadline_ms",
                pl.deadline_ms,
                "must be > 0 and at most the cycle period",
            ));
        }
        if !(pl.commit_ms >= pl.deadline_ms && pl.commit_ms <= 1000.0) {
            return Err(c.fail("planner.commit_ms", pl.commit_ms, "must be within [deadline_ms, 1000]"));
        }
        if !(0.0..=1.0).contains(&pl.margin_m) {
            return Err(c.fail("planner.margin_m", pl.margin_m, "must be within [0, 1] m"));
        }
        if pl.iterations == 0 || pl.iterations > 100_000 {
            return Err(c.fail("planner.iterations", pl.iterations, "must be 1..=100000"));
        }
        if !(pl.lookahead_s > 0.0 && pl.lookahead_s <= 60.0) {
            return Err(c.fail("planner.lookahead_s", pl.lookahead_s, "must be within (0, 60] s"));
        }
        if !(pl.delta_m >= 0.001 && pl.delta_m <= 0.5) {
            return Err(c.fail("planner.delta_m", pl.delta_m, "must be within [0.001, 0.5] m"));
        }
        let su = &self.supervision;
        for (field, v) in [("supervision.predictor", &su.predictor), ("supervision.planner", &su.planner)] {
            if !RESTART_POLICIES.contains(&v.as_str()) {
                return Err(c.fail(field, format!("{v:?}"), "must be \"never\" or \"on-failure\""));
            }
        }
        if su.max_restarts > 100 {
            return Err(c.fail("supervision.max_restarts", su.max_restarts, "must be <= 100"));
        }
        c.positive("supervision.backoff_ms", su.backoff_ms)?;
        c.at_most("supervision.backoff_ms", su.backoff_ms, 60_000.0, "ms")?;
        if !COMMAND_KINDS.contains(&self.tracker.command.as_str()) {
            return Err(c.fail(
                "tracker.command",
                format!("{:?}", self.tracker.command),
                "must be \"torque\" or \"servo\"",
            ));
        }
        let u = &self.udp;
        for (field, v, hi) in [("udp.delay_ms", u.delay_ms, 1000.0), ("udp.jitter_ms", u.jitter_ms, 1000.0)] {
            c.non_negative(field, v)?;
            c.at_most(field, v, hi, "ms")?;
        }
        for (field, v) in [("udp.loss", u.loss), ("udp.duplicate", u.duplicate), ("udp.reorder", u.reorder)] {
            c.non_negative(field, v)?;
            c.at_most(field, v, 1.0, "(a probability)")?;
        }
        if !(1..=1000).contains(&u.abort_after) {
            return Err(c.fail("udp.abort_after", u.abort_after, "must be within [1, 1000] ticks"));
        }
        self.camera.validate().map_err(|e| c.fail(format!("camera.{}", e.field), e.value, e.reason))?;
        let k = &self.checks;
        c.positive("checks.goal_tolerance_rad", k.goal_tolerance_rad)?;
        c.at_most("checks.goal_tolerance_rad", k.goal_tolerance_rad, 0.5, "rad")?;
        if let Some(e) = &self.episode {
            if !dkrrt_debris::SCENE_NAMES.contains(&e.scene.as_str()) && !is_scene_path(&e.scene) {
                return Err(c.fail(
                    "episode.scene",
                    format!("{:?}", e.scene),
                    "must be a named scene or a scene file (a path with a `/` or ending in .toml)",
                ));
            }
            if let Some(d) = e.duration_s {
                if !(d > 0.0 && d <= 3600.0) {
                    return Err(c.fail("episode.duration_s", d, "must be within (0, 3600] s"));
                }
            }
            if let Some(d) = e.max_straight_s {
                if !(d > 0.0 && d <= 3600.0) {
                    return Err(c.fail("episode.max_straight_s", d, "must be within (0, 3600] s"));
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn arm() -> ArmLimits {
        ArmLimits { q_min: [-3.0; NJ], q_max: [3.0; NJ], v_max: [1.0; NJ], tau_max: [100.0; NJ] }
    }

    #[test]
    fn default_scenario_parses_and_validates() {
        let s = Scenario::default_scenario();
        assert_eq!(s.name, "default");
        assert_eq!(s.period_ns(), 1_000_000);
        assert!(s.run.duration_s <= 10.0);
        s.validate(&arm()).unwrap();
    }

    #[test]
    fn round_trips_through_toml() {
        let s = Scenario::default_scenario();
        let back = Scenario::from_toml_str(&s.to_toml(), "rt").unwrap();
        assert_eq!(s, back);
    }

    #[test]
    fn a_bad_value_names_the_field_and_value() {
        let text = DEFAULT_SCENARIO.replace("kp = [400.0, 400.0, 400.0", "kp = [400.0, 400.0, -1.0");
        let s = Scenario::from_toml_str(&text, "x.toml").unwrap();
        let e = s.validate(&arm()).unwrap_err().to_string();
        assert!(e.contains("tracker.kp[2]") && e.contains("-1"), "{e}");

        let text = DEFAULT_SCENARIO.replace("q = [0.35,", "q = [7.0,");
        let e = Scenario::from_toml_str(&text, "x").unwrap().validate(&arm()).unwrap_err().to_string();
        assert!(e.contains("goal.q[0]") && e.contains("joint limits"), "{e}");

        // Pose goals: one of q and pose; a unit quaternion; finite numbers.
        let goal_q = "q = [0.35, -0.2, 0.7, 0.3, 0.2, 0.4]";
        assert!(DEFAULT_SCENARIO.contains(goal_q));
        let pose = DEFAULT_SCENARIO.replace(goal_q, "pose = [0.5, 0.1, 0.6, 0.0, 1.0, 0.0, 0.0]");
        let s = Scenario::from_toml_str(&pose, "x").unwrap();
        s.validate(&arm()).unwrap();
        assert_eq!(s.goal.request(), Some(GoalRequest::Pose([0.5, 0.1, 0.6], [0.0, 1.0, 0.0, 0.0])));
        let both = DEFAULT_SCENARIO
            .replace(goal_q, &format!("{goal_q}\npose = [0.5, 0.1, 0.6, 1.0, 0.0, 0.0, 0.0]"));
        let e = Scenario::from_toml_str(&both, "x").unwrap().validate(&arm()).unwrap_err().to_string();
        assert!(e.contains("goal") && e.contains("not both"), "{e}");
        let none = DEFAULT_SCENARIO.replace(goal_q, "");
        let e = Scenario::from_toml_str(&none, "x").unwrap().validate(&arm()).unwrap_err().to_string();
        assert!(e.contains("goal.pose"), "{e}");
        let skew = DEFAULT_SCENARIO.replace(goal_q, "pose = [0.5, 0.1, 0.6, 0.9, 0.0, 0.0, 0.0]");
        let e = Scenario::from_toml_str(&skew, "x").unwrap().validate(&arm()).unwrap_err().to_string();
        assert!(e.contains("goal.pose[3..7]") && e.contains("unit quaternion"), "{e}");
        let nan = DEFAULT_SCENARIO.replace(goal_q, "pose = [0.5, nan, 0.6, 1.0, 0.0, 0.0, 0.0]");
        let e = Scenario::from_toml_str(&nan, "x").unwrap().validate(&arm()).unwrap_err().to_string();
        assert!(e.contains("goal.pose[1]"), "{e}");

        let text = DEFAULT_SCENARIO.replace("v_max = [0.10,", "v_max = [1.6,");
        let e = Scenario::from_toml_str(&text, "x").unwrap().validate(&arm()).unwrap_err().to_string();
        assert!(e.contains("motion.v_max[0]") && e.contains("velocity limit"), "{e}");

        let text = DEFAULT_SCENARIO.replace("max_straight_s = 3.5", "max_straight_s = -2.0");
        assert_ne!(text, DEFAULT_SCENARIO);
        let e = Scenario::from_toml_str(&text, "x").unwrap().validate(&arm()).unwrap_err().to_string();
        assert!(e.contains("episode.max_straight_s") && e.contains("-2"), "{e}");
    }

    #[test]
    fn a_parse_error_names_the_key() {
        let text = DEFAULT_SCENARIO.replace("substeps = 1 ", "substeps = \"one\" ");
        let e = Scenario::from_toml_str(&text, "bad.toml").unwrap_err().to_string();
        assert!(e.contains("substeps") && e.contains("bad.toml"), "{e}");

        let text = DEFAULT_SCENARIO.replace("[goal]", "[goal]\nspeed = 3");
        let e = Scenario::from_toml_str(&text, "bad.toml").unwrap_err().to_string();
        assert!(e.contains("speed"), "{e}");

        let text = DEFAULT_SCENARIO.replace("mode = \"realtime\"", "mode = \"fast\"");
        let e = Scenario::from_toml_str(&text, "bad.toml").unwrap_err().to_string();
        assert!(e.contains("mode") || e.contains("fast"), "{e}");
    }

    #[test]
    fn the_camera_table_is_read_and_checked_naming_the_field() {
        let ok = Scenario::from_toml_str(DEFAULT_SCENARIO, "d.toml").unwrap();
        assert_eq!(ok.camera, dkrrt_camera::CameraConfig::default(), "default.toml states the defaults");
        let on = DEFAULT_SCENARIO
            .replace("enabled = false", "enabled = true")
            .replace("rate_hz = 20.0 ", "rate_hz = 15.0 ");
        let s = Scenario::from_toml_str(&on, "on.toml").unwrap();
        assert!(s.camera.enabled && s.camera.rate_hz == 15.0);
        s.validate(&arm()).unwrap();
        for (from, to, field) in [
            ("rate_hz = 20.0 ", "rate_hz = 0.0 ", "camera.rate_hz"),
            ("width = 128 ", "width = 200 ", "camera.width"),
            ("dropout = 0.01 ", "dropout = 2.0 ", "camera.dropout"),
            (
                "orientation = [0.5, -0.5, 0.5, -0.5]",
                "orientation = [1.0, 1.0, 0.0, 0.0]",
                "camera.orientation",
            ),
        ] {
            let text = DEFAULT_SCENARIO.replace(from, to);
            assert_ne!(text, DEFAULT_SCENARIO, "{from}");
            let e =
                Scenario::from_toml_str(&text, "bad.toml").unwrap().validate(&arm()).unwrap_err().to_string();
            assert!(e.contains(field), "{field}: {e}");
        }
        let typo = DEFAULT_SCENARIO.replace("noise_base_m = 0.002", "noise_base = 0.002");
        let e = Scenario::from_toml_str(&typo, "typo.toml").unwrap_err().to_string();
        assert!(e.contains("noise_base") && e.contains("typo.toml"), "{e}");
        // The camera's vectors are read exactly, as every array of the scenario.
        let long =
            DEFAULT_SCENARIO.replace("position_m = [0.0, 0.0, -0.8]", "position_m = [0.0, 0.0, -0.8, 3.0]");
        let e = Scenario::from_toml_str(&long, "long.toml").unwrap_err().to_string();
        assert!(e.contains("position_m") && e.contains("exactly 3 numbers"), "{e}");
    }

    #[test]
    fn the_depth_front_end_is_read_and_checked_naming_the_field() {
        let ok = Scenario::from_toml_str(DEFAULT_SCENARIO, "d.toml").unwrap();
        assert!(!ok.learned_front_end() && ok.visual_model_path().is_none());
        let text = DEFAULT_SCENARIO
            .replace("front_end = \"classical\"", "front_end = \"learned\"")
            .replace("visual_model = \"\"", "visual_model = \"f.dkv\"");
        let mut s = Scenario::from_toml_str(&text, "d.toml").unwrap();
        s.base_dir = Some(PathBuf::from("/s"));
        assert!(s.learned_front_end());
        assert_eq!(s.visual_model_path().unwrap(), PathBuf::from("/s/f.dkv"));
        s.validate(&arm()).unwrap();
        let bad = DEFAULT_SCENARIO.replace("front_end = \"classical\"", "front_end = \"cnn\"");
        let e = Scenario::from_toml_str(&bad, "bad.toml").unwrap().validate(&arm()).unwrap_err().to_string();
        assert!(e.contains("predictor.front_end") && e.contains("cnn"), "{e}");
    }

    #[test]
    fn the_udp_link_and_the_command_kind_are_checked_naming_the_field() {
        let ok = Scenario::from_toml_str(DEFAULT_SCENARIO, "d.toml").unwrap();
        assert_eq!((ok.udp.abort_after, ok.tracker.command.as_str()), (20, "torque"));
        for (from, to, field) in [
            ("loss = 0.0 ", "loss = 1.5 ", "udp.loss"),
            ("delay_ms = 0.0 ", "delay_ms = -1.0 ", "udp.delay_ms"),
            ("jitter_ms = 0.0 ", "jitter_ms = nan ", "udp.jitter_ms"),
            ("abort_after = 20 ", "abort_after = 0 ", "udp.abort_after"),
            ("command = \"torque\"", "command = \"velocity\"", "tracker.command"),
        ] {
            let text = DEFAULT_SCENARIO.replace(from, to);
            assert_ne!(text, DEFAULT_SCENARIO, "{from}");
            let s = Scenario::from_toml_str(&text, "bad.toml").unwrap();
            let e = s.validate(&arm()).unwrap_err().to_string();
            assert!(e.contains(field), "{field}: {e}");
        }
        ok.validate(&arm()).unwrap();
        // A scenario without [udp] (every older one) gets the defaults.
        let i = DEFAULT_SCENARIO.find("\n[udp]").unwrap();
        let s = Scenario::from_toml_str(&DEFAULT_SCENARIO[..i], "old.toml").unwrap();
        assert_eq!(s.udp, UdpCfg::default());
        assert_eq!(s.camera, dkrrt_camera::CameraConfig::default());
        let servo = DEFAULT_SCENARIO.replace("command = \"torque\"", "command = \"servo\"");
        assert_eq!(Scenario::from_toml_str(&servo, "s.toml").unwrap().tracker.command, "servo");
    }

    #[test]
    fn relative_urdf_paths_resolve_against_the_file() {
        let mut s = Scenario::default_scenario();
        assert_eq!(s.urdf_path(), None);
        s.robot.urdf = "arms/x.urdf".into();
        s.base_dir = Some(PathBuf::from("/tmp/sc"));
        assert_eq!(s.urdf_path(), Some(PathBuf::from("/tmp/sc/arms/x.urdf")));
    }

    #[test]
    fn a_missing_urdf_or_scene_file_is_named_with_the_scenario_file() {
        // Not by the scenario's `name` (every copy of the default is called "default").
        let dir = std::env::temp_dir().join(format!("dkrrt-origin-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("mine.toml");
        let file = path.to_str().unwrap();
        let write = |from: &str, to: &str| {
            assert!(DEFAULT_SCENARIO.contains(from));
            std::fs::write(&path, DEFAULT_SCENARIO.replace(from, to)).unwrap();
            Scenario::load(file).unwrap()
        };
        let e = write("urdf = \"\"", "urdf = \"nowhere.urdf\"").load_arm().unwrap_err().to_string();
        assert!(e.starts_with(&format!("scenario {file}: robot.urdf = ")), "{e}");
        assert!(e.contains("nowhere.urdf"), "{e}");
        let e = write("scene = \"sparse-slow\"", "scene = \"none.toml\"")
            .load_debris_scene()
            .unwrap_err()
            .to_string();
        assert!(e.starts_with(&format!("scenario {file}: debris.scene = ")), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}

/// Whether a scene field names a file (a `/` in it, or a `.toml` name) rather than a named
/// scene.
pub fn is_scene_path(s: &str) -> bool {
    s.contains('/') || s.ends_with(".toml")
}
