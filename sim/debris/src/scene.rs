//! Scene configuration (TOML), the four named scenes and a seeded random generator.

use crate::body::{BodyProps, ShapeSpec};
use crate::orbit::OrbitConfig;
use crate::MAX_DEBRIS;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

/// Errors loading or validating a scene. Messages name the offending field.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// TOML syntax or schema error (message includes the key and line).
    #[error("scene TOML: {0}")]
    Parse(#[from] toml::de::Error),
    /// A value is out of range or inconsistent.
    #[error("scene field `{field}`: {reason}")]
    Invalid {
        /// Path of the field, e.g. `debris[3].mass`.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// No embedded scene with that name.
    #[error("unknown scene name `{0}` (known: sparse-slow, dense, fast-crossing, tumbling-rods)")]
    UnknownName(String),
    /// Reading a scene file failed.
    #[error("reading scene file: {0}")]
    Io(#[from] std::io::Error),
}

fn invalid(field: impl Into<String>, reason: impl Into<String>) -> SceneError {
    SceneError::Invalid { field: field.into(), reason: reason.into() }
}

/// Integrator settings (`[integrator]`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct IntegratorConfig {
    /// Maximum RK4 substep [s]; `step(dt)` splits `dt` into `ceil(dt / max_substep)` substeps.
    pub max_substep: f64,
}

impl Default for IntegratorConfig {
    fn default() -> Self {
        IntegratorConfig { max_substep: 0.01 }
    }
}

/// Unmodelled perturbations (`[perturbation]`), all in LVLH, per debris object.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PerturbationConfig {
    /// Std-dev of a constant bias acceleration drawn once per object (differential drag/SRP) [m/s²].
    pub accel_bias_sigma: f64,
    /// Stationary std-dev of a first-order Gauss–Markov acceleration [m/s²].
    pub accel_noise_sigma: f64,
    /// Correlation time of the Gauss–Markov acceleration [s].
    pub accel_noise_tau: f64,
}

impl Default for PerturbationConfig {
    fn default() -> Self {
        PerturbationConfig { accel_bias_sigma: 0.0, accel_noise_sigma: 0.0, accel_noise_tau: 60.0 }
    }
}

fn identity_q() -> [f64; 4] {
    [1.0, 0.0, 0.0, 0.0]
}

/// One debris object (`[[debris]]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DebrisSpec {
    /// Unique id.
    pub id: u32,
    /// Shape (inline table with `kind`).
    pub shape: ShapeSpec,
    /// Mass [kg].
    pub mass: f64,
    /// Optional principal inertia override (body axes) [kg m²]; default: uniform density.
    #[serde(default, deserialize_with = "dkrrt_io::exact::opt_array")]
    pub inertia: Option<[f64; 3]>,
    /// Initial LVLH position [m].
    #[serde(deserialize_with = "dkrrt_io::exact::array")]
    pub p: [f64; 3],
    /// Initial LVLH relative velocity [m/s].
    #[serde(default, deserialize_with = "dkrrt_io::exact::array")]
    pub v: [f64; 3],
    /// Initial attitude body → LVLH as (w, x, y, z); normalised on load.
    #[serde(default = "identity_q", deserialize_with = "dkrrt_io::exact::array")]
    pub q: [f64; 4],
    /// Initial inertial angular velocity in body axes [rad/s].
    #[serde(default, deserialize_with = "dkrrt_io::exact::array")]
    pub w: [f64; 3],
}

/// A scheduled event (`[[events]]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum EventSpec {
    /// Instantaneous velocity / body-rate change of one object.
    Impulse {
        /// Time [s].
        t: f64,
        /// Target id.
        id: u32,
        /// Velocity change, LVLH [m/s].
        #[serde(deserialize_with = "dkrrt_io::exact::array")]
        dv: [f64; 3],
        /// Body-rate change, body axes [rad/s].
        #[serde(default, deserialize_with = "dkrrt_io::exact::array")]
        dw: [f64; 3],
    },
    /// A fragment splits off an object (linear momentum conserved).
    Split {
        /// Time [s].
        t: f64,
        /// Parent id.
        id: u32,
        /// Id of the new fragment.
        new_id: u32,
        /// Fragment shape.
        fragment: ShapeSpec,
        /// Fragment mass [kg] (< parent mass).
        mass: f64,
        /// Optional fragment principal inertia [kg m²].
        #[serde(default, deserialize_with = "dkrrt_io::exact::opt_array")]
        inertia: Option<[f64; 3]>,
        /// Fragment offset from the parent centre of mass, parent body axes [m].
        #[serde(default, deserialize_with = "dkrrt_io::exact::array")]
        offset: [f64; 3],
        /// Fragment velocity relative to the parent, LVLH [m/s].
        #[serde(deserialize_with = "dkrrt_io::exact::array")]
        dv: [f64; 3],
        /// Fragment body rate [rad/s].
        #[serde(default, deserialize_with = "dkrrt_io::exact::array")]
        w: [f64; 3],
    },
}

impl EventSpec {
    /// Event time.
    pub fn time(&self) -> f64 {
        match self {
            EventSpec::Impulse { t, .. } | EventSpec::Split { t, .. } => *t,
        }
    }

    /// The object it acts on: an impulse's target, a split's parent.
    pub fn target(&self) -> u32 {
        match self {
            EventSpec::Impulse { id, .. } | EventSpec::Split { id, .. } => *id,
        }
    }
}

/// A complete debris scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Scene name.
    pub name: String,
    /// Seed of the perturbation random streams.
    #[serde(default)]
    pub seed: u64,
    /// Module reference orbit.
    #[serde(default)]
    pub orbit: OrbitConfig,
    /// Integrator settings.
    #[serde(default)]
    pub integrator: IntegratorConfig,
    /// Unmodelled perturbations.
    #[serde(default)]
    pub perturbation: PerturbationConfig,
    /// Debris objects.
    #[serde(default)]
    pub debris: Vec<DebrisSpec>,
    /// Scheduled events.
    #[serde(default)]
    pub events: Vec<EventSpec>,
}

/// Names of the embedded scenes.
pub const SCENE_NAMES: [&str; 4] = ["sparse-slow", "dense", "fast-crossing", "tumbling-rods"];

const SPARSE_SLOW: &str = include_str!("../scenes/sparse-slow.toml");
const DENSE: &str = include_str!("../scenes/dense.toml");
const FAST_CROSSING: &str = include_str!("../scenes/fast-crossing.toml");
const TUMBLING_RODS: &str = include_str!("../scenes/tumbling-rods.toml");

/// Bounds of a scene's states, those of the message contract every process checks debris
/// observations against (`dkrrt_config::arm::contract_limits`): a scene beyond them would be
/// seen as nothing but rejected messages. Positions from the LVLH origin, m.
pub const MAX_RANGE_M: f64 = 1000.0;
/// Speeds (and velocity changes), m/s.
pub const MAX_SPEED_MPS: f64 = 100.0;
/// Body rates (and their changes), rad/s.
pub const MAX_SPIN_RADPS: f64 = 50.0;

/// A finite vector of norm at most `max` (`unit` for the message).
fn within3(field: &str, v: &[f64; 3], max: f64, unit: &str) -> Result<(), SceneError> {
    finite3(field, v)?;
    let n = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    if n > max {
        return Err(invalid(field, format!("norm {n} exceeds {max} {unit} (the message contract's bound)")));
    }
    Ok(())
}

fn finite3(field: &str, v: &[f64]) -> Result<(), SceneError> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(invalid(field, "must be finite"))
    }
}

impl Scene {
    /// Parse and validate a scene from TOML text.
    pub fn from_toml(text: &str) -> Result<Scene, SceneError> {
        let s: Scene = toml::from_str(text)?;
        s.validate()?;
        Ok(s)
    }

    /// Load and validate a scene file.
    pub fn from_file(path: impl AsRef<std::path::Path>) -> Result<Scene, SceneError> {
        let text = dkrrt_io::read_text_capped(path.as_ref(), dkrrt_io::limits::SCENARIO)
            .map_err(std::io::Error::from)?;
        Scene::from_toml(&text)
    }

    /// One of the embedded named scenes (`SCENE_NAMES`).
    pub fn named(name: &str) -> Result<Scene, SceneError> {
        let text = match name {
            "sparse-slow" => SPARSE_SLOW,
            "dense" => DENSE,
            "fast-crossing" => FAST_CROSSING,
            "tumbling-rods" => TUMBLING_RODS,
            other => return Err(SceneError::UnknownName(other.to_string())),
        };
        Scene::from_toml(text)
    }

    /// Serialise to TOML.
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("scene serialises")
    }

    /// Check ranges and consistency; errors name the field.
    pub fn validate(&self) -> Result<(), SceneError> {
        let o = &self.orbit;
        if !(o.altitude_km.is_finite() && o.altitude_km >= 150.0 && o.altitude_km <= 50_000.0) {
            return Err(invalid("orbit.altitude_km", "must be in [150, 50000] km"));
        }
        if !(o.eccentricity >= 0.0 && o.eccentricity < 0.9) {
            return Err(invalid("orbit.eccentricity", "must be in [0, 0.9)"));
        }
        let perigee = (crate::orbit::R_EARTH + o.altitude_km * 1e3) * (1.0 - o.eccentricity);
        if perigee < crate::orbit::R_EARTH + 100e3 {
            return Err(invalid("orbit.eccentricity", "perigee below 100 km altitude"));
        }
        for (f, v) in [("orbit.inclination_deg", o.inclination_deg), ("orbit.raan_deg", o.raan_deg)]
            .into_iter()
            .chain([
                ("orbit.arg_perigee_deg", o.arg_perigee_deg),
                ("orbit.true_anomaly_deg", o.true_anomaly_deg),
            ])
        {
            if !v.is_finite() {
                return Err(invalid(f, "must be finite"));
            }
        }
        if !(self.integrator.max_substep > 0.0 && self.integrator.max_substep <= 1.0) {
            return Err(invalid("integrator.max_substep", "must be in (0, 1] s"));
        }
        let pc = &self.perturbation;
        if !(pc.accel_bias_sigma >= 0.0 && pc.accel_bias_sigma.is_finite()) {
            return Err(invalid("perturbation.accel_bias_sigma", "must be finite and >= 0"));
        }
        if !(pc.accel_noise_sigma >= 0.0 && pc.accel_noise_sigma.is_finite()) {
            return Err(invalid("perturbation.accel_noise_sigma", "must be finite and >= 0"));
        }
        if !(pc.accel_noise_tau > 0.0 && pc.accel_noise_tau.is_finite()) {
            return Err(invalid("perturbation.accel_noise_tau", "must be finite and > 0"));
        }
        let n_splits = self.events.iter().filter(|e| matches!(e, EventSpec::Split { .. })).count();
        if self.debris.len() + n_splits > MAX_DEBRIS {
            return Err(invalid(
                "debris",
                format!(
                    "{} objects + {} split fragments exceed MAX_DEBRIS = {MAX_DEBRIS}",
                    self.debris.len(),
                    n_splits
                ),
            ));
        }
        let mut ids: Vec<u32> = Vec::new();
        let mut masses: Vec<f64> = Vec::new();
        for (i, d) in self.debris.iter().enumerate() {
            let f = |x: &str| format!("debris[{i}].{x}");
            if ids.contains(&d.id) {
                return Err(invalid(f("id"), format!("duplicate id {}", d.id)));
            }
            BodyProps::new(&d.shape, d.mass, d.inertia).map_err(|e| invalid(f(&e.field), e.reason))?;
            within3(&f("p"), &d.p, MAX_RANGE_M, "m")?;
            within3(&f("v"), &d.v, MAX_SPEED_MPS, "m/s")?;
            within3(&f("w"), &d.w, MAX_SPIN_RADPS, "rad/s")?;
            finite3(&f("q"), &d.q)?;
            let qn = d.q.iter().map(|x| x * x).sum::<f64>().sqrt();
            if qn < 1e-9 {
                return Err(invalid(f("q"), "quaternion has zero norm"));
            }
            ids.push(d.id);
            masses.push(d.mass);
        }
        let mut last_t = 0.0;
        let mut order: Vec<&EventSpec> = self.events.iter().collect();
        order.sort_by(|a, b| a.time().total_cmp(&b.time()));
        for e in order {
            let i = self.events.iter().position(|x| std::ptr::eq(x, e)).unwrap_or(0);
            let f = |x: &str| format!("events[{i}].{x}");
            let t = e.time();
            if !(t.is_finite() && t >= 0.0) {
                return Err(invalid(f("t"), "must be finite and >= 0"));
            }
            debug_assert!(t >= last_t);
            last_t = t;
            match e {
                EventSpec::Impulse { id, dv, dw, .. } => {
                    if !ids.contains(id) {
                        return Err(invalid(f("id"), format!("no debris with id {id} exists at t = {t}")));
                    }
                    within3(&f("dv"), dv, MAX_SPEED_MPS, "m/s")?;
                    within3(&f("dw"), dw, MAX_SPIN_RADPS, "rad/s")?;
                }
                EventSpec::Split { id, new_id, fragment, mass, inertia, offset, dv, w, .. } => {
                    let Some(k) = ids.iter().position(|x| x == id) else {
                        return Err(invalid(f("id"), format!("no debris with id {id} exists at t = {t}")));
                    };
                    if ids.contains(new_id) {
                        return Err(invalid(f("new_id"), format!("id {new_id} already in use")));
                    }
                    BodyProps::new(fragment, *mass, *inertia).map_err(|e| {
                        let field = if e.field == "mass" {
                            "mass".to_string()
                        } else {
                            format!("fragment.{}", e.field)
                        };
                        invalid(f(&field), e.reason)
                    })?;
                    if *mass >= masses[k] {
                        return Err(invalid(f("mass"), "fragment mass must be smaller than the parent's"));
                    }
                    within3(&f("offset"), offset, MAX_RANGE_M, "m")?;
                    within3(&f("dv"), dv, MAX_SPEED_MPS, "m/s")?;
                    within3(&f("w"), w, MAX_SPIN_RADPS, "rad/s")?;
                    masses[k] -= mass;
                    ids.push(*new_id);
                    masses.push(*mass);
                }
            }
        }
        Ok(())
    }

    /// A seeded random scene of `n` objects (`n <= MAX_DEBRIS`).
    pub fn random(seed: u64, n: usize, params: &RandomSceneParams) -> Scene {
        let n = n.min(MAX_DEBRIS);
        let mut rng = SmallRng::seed_from_u64(seed);
        let mut debris = Vec::with_capacity(n);
        let u = |rng: &mut SmallRng, lo: f64, hi: f64| lo + (hi - lo) * rng.random::<f64>();
        for i in 0..n {
            // Position uniformly in a spherical shell.
            let dir = loop {
                let d = [u(&mut rng, -1.0, 1.0), u(&mut rng, -1.0, 1.0), u(&mut rng, -1.0, 1.0)];
                let r2: f64 = d.iter().map(|x| x * x).sum();
                if r2 > 1e-6 && r2 <= 1.0 {
                    let r = r2.sqrt();
                    break [d[0] / r, d[1] / r, d[2] / r];
                }
            };
            let range = u(&mut rng, params.min_range, params.max_range);
            let p = dir.map(|x| x * range);
            let speed = u(&mut rng, 0.0, params.max_speed);
            // Velocity: mostly towards a random point near the module.
            let aim = [u(&mut rng, -1.0, 1.0), u(&mut rng, -1.0, 1.0), u(&mut rng, -1.0, 1.0)];
            let mut vd = [
                aim[0] * params.min_range - p[0],
                aim[1] * params.min_range - p[1],
                aim[2] * params.min_range - p[2],
            ];
            let vn = vd.iter().map(|x| x * x).sum::<f64>().sqrt().max(1e-9);
            vd.iter_mut().for_each(|x| *x *= speed / vn);
            let size = u(&mut rng, params.min_size, params.max_size);
            let shape = match rng.random_range(0..5) {
                0 => ShapeSpec::Sphere { radius: 0.5 * size },
                1 => ShapeSpec::Box { half_extents: [0.5 * size, 0.35 * size, 0.2 * size] },
                2 => ShapeSpec::Rod { half_length: 0.5 * size, radius: 0.06 * size.max(0.2) },
                3 => ShapeSpec::Panel { half_extents: [0.5 * size, 0.3 * size], thickness: 0.02 },
                _ => {
                    let s = 0.5 * size;
                    let points = (0..10)
                        .map(|_| [u(&mut rng, -s, s), u(&mut rng, -s, s), u(&mut rng, -s * 0.6, s * 0.6)])
                        .chain([[s, 0.0, 0.0], [-s, 0.0, 0.0], [0.0, s, 0.0], [0.0, 0.0, s * 0.6]])
                        .collect();
                    ShapeSpec::Convex { points }
                }
            };
            let mut q = [
                u(&mut rng, -1.0, 1.0),
                u(&mut rng, -1.0, 1.0),
                u(&mut rng, -1.0, 1.0),
                u(&mut rng, -1.0, 1.0),
            ];
            let qn = q.iter().map(|x| x * x).sum::<f64>().sqrt().max(1e-9);
            q.iter_mut().for_each(|x| *x /= qn);
            let w = [
                u(&mut rng, -params.max_rate, params.max_rate),
                u(&mut rng, -params.max_rate, params.max_rate),
                u(&mut rng, -params.max_rate, params.max_rate),
            ];
            let mass = params.areal_density * size * size * size.max(0.1) * u(&mut rng, 0.5, 1.5) + 0.1;
            debris.push(DebrisSpec { id: i as u32, shape, mass, inertia: None, p, v: vd, q, w });
        }
        Scene {
            name: format!("random-{seed}"),
            seed,
            orbit: OrbitConfig::default(),
            integrator: IntegratorConfig::default(),
            perturbation: params.perturbation,
            debris,
            events: Vec::new(),
        }
    }
}

/// Parameters of [`Scene::random`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RandomSceneParams {
    /// Minimum initial distance from the module [m].
    pub min_range: f64,
    /// Maximum initial distance from the module [m].
    pub max_range: f64,
    /// Maximum relative speed [m/s].
    pub max_speed: f64,
    /// Maximum body rate per axis [rad/s].
    pub max_rate: f64,
    /// Smallest characteristic size [m].
    pub min_size: f64,
    /// Largest characteristic size [m].
    pub max_size: f64,
    /// Mass scale [kg/m³] applied to size³.
    pub areal_density: f64,
    /// Unmodelled perturbations.
    pub perturbation: PerturbationConfig,
}

impl Default for RandomSceneParams {
    fn default() -> Self {
        RandomSceneParams {
            min_range: 2.0,
            max_range: 12.0,
            max_speed: 0.3,
            max_rate: 0.5,
            min_size: 0.1,
            max_size: 1.0,
            areal_density: 50.0,
            perturbation: PerturbationConfig::default(),
        }
    }
}
