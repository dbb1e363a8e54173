//! dkrrt-predictor: the online debris predictor of DK-RRT.
//!
//! * [`DebrisPredictor`]: track table for up to [`MAX_TRACKS`] objects keyed by debris id,
//!   observation gating, per-track pose filter ([`filter`]), per-track Koopman models
//!   (translation + attitude) refined online by RLS, event detection on the one-step
//!   residual with per-horizon [`dkrrt_koopman::ErrorBound`]s grown after events, and
//!   allocation-free forecasts into a caller-owned [`ForecastBuffer`].
//! * [`models`]: the [`Method`]s of the study, their fits ([`Models::fit`]) and the roll-out
//!   [`models::Engine`].
//! * [`training`]: deep Koopman attitude model training on debris-world data
//!   ([`train_models`]), model files ([`TrainedModels::save`] / [`TrainedModels::load`]).
//! * [`eval`]: the accuracy study (training / held-out runs of the named scenes, median
//!   position / attitude errors at fixed horizons).
//!
//! Memory model: [`DebrisPredictor::new`] allocates every slot (models, RLS covariances,
//! history); [`DebrisPredictor::observe`] and [`DebrisPredictor::forecast`] never allocate.

// Index loops mirror the formulas.
#![allow(clippy::needless_range_loop)]

pub mod axis;
pub mod calib;
pub mod euler;
pub mod eval;
pub mod events;
pub mod filter;
mod kernels;
pub mod models;
pub mod predictor;
pub mod recorded;
pub mod symmetry;
pub mod training;

pub use eval::{run_study, StudyConfig, StudyRow};
pub use filter::{FilterConfig, TrackFilter};
pub use models::{AttitudeLifting, FitConfig, GaussianRbf, Method, Models, Segment, TrainingSet};
pub use predictor::{
    DebrisPredictor, ForecastBuffer, GateStats, ObserveOutcome, PredictorConfig, RejectReason, TrackInfo,
    MAX_TRACKS,
};
pub use training::{train_models, TrainModelsError, TrainOptions, TrainedModels, ValidationRow};
