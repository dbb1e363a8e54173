//! dkrrt-debris: the debris world of the DK-RRT simulator, as a plain library.
//!
//! * [`orbit`]: module reference orbit (Keplerian, circular by default) and the full nonlinear
//!   relative two-body dynamics in the LVLH frame (x radial, y along-track, z orbit normal),
//!   optional differential J2, Clohessy–Wiltshire closed form for validation.
//! * [`body`]: parry3d shapes, mass/inertia, torque-free Euler dynamics with quaternion kinematics.
//! * [`scene`]: TOML scenes, four embedded named scenes, seeded random scenes.
//! * [`world`]: [`DebrisWorld`] with fixed capacity [`MAX_DEBRIS`], allocation-free RK4 stepping,
//!   unmodelled perturbations and scheduled events (impulses, fragment splits).
//! * [`sensor`]: noisy / dropping / delayed observations into a fixed-capacity buffer.
//!
//! See `README.md` for the model, orbit and frame conventions.

// `Prepared::Split` carries pre-built fragment props; a handful per scene.
#![allow(clippy::large_enum_variant)]

pub mod body;
pub mod orbit;
pub mod scene;
pub mod sensor;
pub mod world;

/// Maximum number of debris objects in a world (including split fragments).
pub const MAX_DEBRIS: usize = 32;

pub use body::{BodyProps, RigidState, ShapeSpec};
pub use orbit::{ChiefState, OrbitConfig, RefOrbit};
pub use scene::{
    DebrisSpec, EventSpec, PerturbationConfig, RandomSceneParams, Scene, SceneError, SCENE_NAMES,
};
pub use sensor::{ObsBuffer, Observation, Sensor, SensorConfig, SensorError};
pub use world::{Debris, DebrisWorld, FiredEvent, FiredKind};
