//! Deep Koopman training for the predictor (library entry points of `dkrrt train`).
//!
//! The deep model lifts the **attitude** state `(q, ω)` (`n = 7`): that is where the
//! nonlinearity is (Euler's equations, quaternion kinematics). Translation stays the
//! dual-data model (nominal Clohessy–Wiltshire generator + ridge correction), which is linear
//! and already as good as constant velocity on position (see the README study).
//!
//! Data: the debris world ([`DebrisWorld`]) simulates perturbed runs of the named scenes
//! (with their scheduled events removed: free tumbling) and random scenes with many bodies
//! of varied shapes / inertias and body rates; the **true** `(q, ω)` of every object is
//! sampled on the model grid `dt` (quaternions sign-continuous). Seeds are disjoint from
//! the study's (`eval`): training runs use `seed + 100·scene + run`, `seed ≥ 1_000_000` by
//! default, the validation runs `seed + 50_000 + …`.
//!
//! Validation: separate runs of the same generators; per horizon, the median attitude error
//! (rotation angle) and the RMSE of `(q, ω)` of the linear lifted roll-out that the
//! predictor uses (quaternion renormalised on output), next to constant body rate.

use crate::filter::quat_angle;
use dkrrt_debris::{DebrisWorld, RandomSceneParams, Scene, SceneError};
use dkrrt_deep::{DeepKoopman, ModelFileError, Progress, TrainConfig, TrainData, TrainError, TrainReport};
use dkrrt_koopman::debris_state::{align_quaternion, N, ROT};
use dkrrt_koopman::{ConstantVelocity, Lifting};
use serde::Serialize;
use std::path::Path;

/// Name of the attitude model in a model file.
pub const ATTITUDE_MODEL: &str = "attitude";

/// Data generation + training options.
#[derive(Debug, Clone, PartialEq)]
pub struct TrainOptions {
    /// Named scenes ([`Scene::named`]) whose perturbed runs (events removed) give data.
    pub scenes: Vec<String>,
    /// Perturbed runs per named scene.
    pub runs_per_scene: usize,
    /// Random scenes ([`Scene::random`]) in addition.
    pub random_runs: usize,
    /// Objects per random scene.
    pub random_bodies: usize,
    /// Maximum body rate per axis of the random scenes [rad/s].
    pub random_max_rate: f64,
    /// Simulated duration of every run [s].
    pub duration: f64,
    /// Simulation step [s].
    pub sim_dt: f64,
    /// Model grid step [s] (the predictor's `FitConfig::dt`).
    pub dt: f64,
    /// Initial-state perturbation scale of the named-scene runs (see `eval::perturbed_scene`).
    pub perturbation: f64,
    /// Validation runs per generator (named scenes and random scenes).
    pub valid_runs: usize,
    /// Validation horizons [s].
    pub valid_horizons: Vec<f64>,
    /// Master seed (see the module doc).
    pub seed: u64,
    /// Network / optimiser.
    pub deep: TrainConfig,
}

impl Default for TrainOptions {
    /// The configuration of the README (training ≈ 1 min on the 2-core build machine).
    fn default() -> Self {
        TrainOptions {
            scenes: dkrrt_debris::SCENE_NAMES.iter().map(|s| s.to_string()).collect(),
            runs_per_scene: 6,
            random_runs: 4,
            random_bodies: 24,
            random_max_rate: 1.5,
            duration: 30.0,
            sim_dt: 0.01,
            dt: 0.1,
            perturbation: 1.0,
            valid_runs: 1,
            valid_horizons: vec![0.5, 1.0, 2.0, 4.0],
            seed: 1_000_000,
            // The deep crate's defaults, with a smaller step (tuned on the debris attitude data).
            deep: TrainConfig { lr: 3e-3, ..TrainConfig::default() },
        }
    }
}

impl TrainOptions {
    /// A seconds-scale configuration for tests (`eval::StudyConfig::small`).
    pub fn tiny() -> Self {
        TrainOptions {
            scenes: vec!["tumbling-rods".into()],
            runs_per_scene: 2,
            random_runs: 1,
            random_bodies: 8,
            duration: 12.0,
            valid_runs: 1,
            deep: TrainConfig {
                hidden: 16,
                layers: 1,
                extra: 8,
                horizon: 10,
                epochs: 4,
                resolve_every: 2,
                ..Self::default().deep
            },
            ..Self::default()
        }
    }
}

/// Validation error of the trained attitude model at one horizon.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ValidationRow {
    /// Horizon [s].
    pub horizon_s: f64,
    /// Median attitude error of the deep model [rad].
    pub att_err_rad: f64,
    /// RMSE over the 7 coordinates `(q, ω)` of the deep model.
    pub rmse: f64,
    /// Median attitude error of constant body rate from the same true states [rad].
    pub cv_att_err_rad: f64,
    /// Forecasts evaluated.
    pub n: usize,
}

/// Trained models (what `dkrrt train` writes) and their validation.
#[derive(Debug, Clone)]
pub struct TrainedModels {
    /// Attitude model on `(q, ω)`, `n = 7`.
    pub attitude: DeepKoopman,
    /// Training report (`None` when loaded from a file).
    pub report: Option<TrainReport>,
    /// Validation table (empty when loaded from a file).
    pub validation: Vec<ValidationRow>,
}

/// Why [`train_models`] failed.
#[derive(Debug, thiserror::Error)]
pub enum TrainModelsError {
    /// A scene could not be built.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// Training failed.
    #[error(transparent)]
    Train(#[from] TrainError),
}

impl TrainedModels {
    /// Write the model file (`dkrrt-deep` format, model name [`ATTITUDE_MODEL`]).
    pub fn save(&self, path: &Path) -> std::io::Result<()> {
        dkrrt_deep::save_models(path, &[(ATTITUDE_MODEL, &self.attitude)])
    }
    /// Read a model file written by [`TrainedModels::save`]; errors name the problem (not a
    /// model file, version, truncation, checksum, missing `attitude` model, wrong dimension).
    pub fn load(path: &Path) -> Result<Self, ModelFileError> {
        let attitude = dkrrt_deep::load_model(path, ATTITUDE_MODEL, 7)?;
        Ok(TrainedModels { attitude, report: None, validation: Vec::new() })
    }
}

/// The model file shipped with the repository (`models/deep-attitude.dkm`, the one the
/// `dkrrt` binary embeds), for benchmarks and examples.
pub const SHIPPED_MODEL: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../models/deep-attitude.dkm");

/// The model file a benchmark or example uses: the file named by `DEEP_MODEL` if set (a
/// relative path is taken from the directory the command was started in, `PWD`, since
/// `cargo bench` runs in the package directory), else [`SHIPPED_MODEL`].
pub fn bench_model_path() -> std::path::PathBuf {
    match std::env::var_os("DEEP_MODEL") {
        Some(f) => {
            let f = std::path::PathBuf::from(f);
            match std::env::var_os("PWD") {
                Some(cwd) if f.is_relative() => std::path::PathBuf::from(cwd).join(f),
                _ => f,
            }
        }
        None => std::path::PathBuf::from(SHIPPED_MODEL),
    }
}

/// Simulate `scene` and return the true `(q, ω)` trajectory of every object on the `dt` grid.
fn attitude_trajectories(scene: &Scene, opts: &TrainOptions) -> Result<Vec<Vec<f64>>, SceneError> {
    let mut world = DebrisWorld::new(scene)?;
    let every = (opts.dt / opts.sim_dt).round().max(1.0) as usize;
    let steps = (opts.duration / opts.sim_dt).round() as usize;
    let mut trajs: Vec<(u32, Vec<f64>)> =
        world.debris().iter().map(|d| (d.id, Vec::with_capacity(7 * (steps / every + 1)))).collect();
    for k in 0..=steps {
        if k > 0 {
            world.step(opts.sim_dt);
        }
        if k % every != 0 {
            continue;
        }
        for d in world.debris() {
            let Some((_, tr)) = trajs.iter_mut().find(|(id, _)| *id == d.id) else { continue };
            let q = d.state.q.quaternion();
            let mut x = [q.w, q.i, q.j, q.k, d.state.w.x, d.state.w.y, d.state.w.z];
            if tr.len() >= 7 {
                let prev = [tr[tr.len() - 7], tr[tr.len() - 6], tr[tr.len() - 5], tr[tr.len() - 4]];
                align_quaternion(&mut x[..4], &prev);
            }
            tr.extend_from_slice(&x);
        }
    }
    Ok(trajs.into_iter().map(|(_, t)| t).filter(|t| t.len() >= 14).collect())
}

/// Trajectories of all generators; `offset` separates training (0) and validation seeds.
fn generate(
    opts: &TrainOptions,
    offset: u64,
    runs: usize,
    random_runs: usize,
) -> Result<TrainData, SceneError> {
    let mut data = TrainData { n: 7, dt: opts.dt, trajectories: Vec::new() };
    for (si, name) in opts.scenes.iter().enumerate() {
        for r in 0..runs {
            let seed = opts.seed + offset + 100 * si as u64 + r as u64;
            let mut sc = crate::eval::perturbed_scene(name, seed, opts.perturbation)?;
            sc.events.clear();
            data.trajectories.extend(attitude_trajectories(&sc, opts)?);
        }
    }
    let params = RandomSceneParams { max_rate: opts.random_max_rate, ..Default::default() };
    for r in 0..random_runs {
        let seed = opts.seed + offset + 10_000 + r as u64;
        let mut sc = Scene::random(seed, opts.random_bodies, &params);
        sc.events.clear();
        data.trajectories.extend(attitude_trajectories(&sc, opts)?);
    }
    Ok(data)
}

/// Median of a sample (NaN when empty).
fn median(mut v: Vec<f64>) -> f64 {
    crate::eval::median(&mut v)
}

/// Per-horizon validation of an attitude model on true trajectories: linear lifted
/// roll-out (as in the predictor) vs constant body rate.
pub fn validate(dk: &DeepKoopman, data: &TrainData, horizons: &[f64], stride: usize) -> Vec<ValidationRow> {
    let steps: Vec<usize> = horizons.iter().map(|h| (h / data.dt).round().max(1.0) as usize).collect();
    let hmax = steps.iter().copied().max().unwrap_or(1);
    let p = dk.model.p;
    let (mut z, mut zn) = (vec![0.0; p], vec![0.0; p]);
    let mut cvout = vec![0.0; hmax * N];
    let nh = steps.len();
    let (mut att, mut cv, mut sse) = (vec![Vec::new(); nh], vec![Vec::new(); nh], vec![0.0; nh]);
    let cvm = ConstantVelocity { frame_rate: 0.0 };
    for tr in &data.trajectories {
        let t = tr.len() / 7;
        let mut s = 0;
        while s + hmax < t {
            dk.lifting.lift(&tr[s * 7..], &mut z);
            let mut x13 = [0.0; N];
            x13[6] = 1.0;
            x13[ROT].copy_from_slice(&tr[s * 7..(s + 1) * 7]);
            cvm.forecast(&x13, data.dt, &mut cvout);
            for k in 1..=hmax {
                dk.model.step(&z, &[], &mut zn);
                std::mem::swap(&mut z, &mut zn);
                if let Some(j) = steps.iter().position(|&h| h == k) {
                    let truth = &tr[(s + k) * 7..(s + k + 1) * 7];
                    let mut x = [0.0; 7];
                    x.copy_from_slice(&z[..7]);
                    let nq = x[..4].iter().map(|v| v * v).sum::<f64>().sqrt();
                    x[..4].iter_mut().for_each(|v| *v /= nq);
                    att[j].push(quat_angle(&x[..4], &truth[..4]));
                    sse[j] += x.iter().zip(truth).map(|(a, b)| (a - b).powi(2)).sum::<f64>();
                    cv[j].push(quat_angle(&cvout[(k - 1) * N + 6..(k - 1) * N + 10], &truth[..4]));
                }
            }
            s += stride.max(1);
        }
    }
    (0..nh)
        .map(|j| ValidationRow {
            horizon_s: horizons[j],
            n: att[j].len(),
            rmse: (sse[j] / (7 * att[j].len().max(1)) as f64).sqrt(),
            att_err_rad: median(std::mem::take(&mut att[j])),
            cv_att_err_rad: median(std::mem::take(&mut cv[j])),
        })
        .collect()
}

/// Generate data from the debris world (seeded), train the attitude model, validate it on
/// separate runs. `progress` is called after every epoch.
pub fn train_models(
    opts: &TrainOptions,
    progress: &mut dyn FnMut(&Progress),
) -> Result<TrainedModels, TrainModelsError> {
    let data = generate(opts, 0, opts.runs_per_scene, opts.random_runs)?;
    let (attitude, report) = dkrrt_deep::train(&data, &opts.deep, progress)?;
    let valid = generate(opts, 50_000, opts.valid_runs, opts.valid_runs.min(opts.random_runs.max(1)))?;
    let validation = validate(&attitude, &valid, &opts.valid_horizons, 5);
    Ok(TrainedModels { attitude, report: Some(report), validation })
}
