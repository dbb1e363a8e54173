//! Loading the scenario's arm and the message-contract limits derived from it.

use crate::{ArmLimits, ConfigError, Scenario, NJ};
use dkrrt_model::ArmModel;
use dkrrt_msg::ContractLimits;

impl Scenario {
    /// Loads the arm (URDF or the embedded default), applies the scenario's
    /// gravity, and validates the scenario against the arm's limits.
    pub fn load_arm(&self) -> Result<ArmModel, ConfigError> {
        let mut model = match self.urdf_path() {
            None => ArmModel::default_arm(),
            Some(p) => {
                ArmModel::from_urdf_file_with(&p, &self.urdf_options()).map_err(|e| ConfigError::Invalid {
                    origin: self.origin_name(),
                    field: "robot.urdf".into(),
                    value: p.display().to_string(),
                    reason: e.to_string(),
                })?
            }
        };
        let g = self.robot.gravity;
        model.set_gravity(nalgebra::Vector3::new(g[0], g[1], g[2]));
        self.validate(&arm_limits(&model))?;
        Ok(model)
    }
}

impl Scenario {
    /// How the scenario's URDF is read: `robot.base_link`, `robot.tip_link`,
    /// `robot.package_path` (relative entries from the scenario's folder).
    pub fn urdf_options(&self) -> dkrrt_model::UrdfOptions {
        let opt = |s: &str| (!s.is_empty()).then(|| s.to_string());
        dkrrt_model::UrdfOptions {
            base_link: opt(&self.robot.base_link),
            tip_link: opt(&self.robot.tip_link),
            package_path: self
                .robot
                .package_path
                .iter()
                .map(|d| match (&self.base_dir, std::path::Path::new(d).is_relative()) {
                    (Some(b), true) => b.join(d),
                    _ => std::path::PathBuf::from(d),
                })
                .collect(),
            urdf_dir: None,
        }
    }
}

/// The arm's joint limits as plain arrays.
pub fn arm_limits(model: &ArmModel) -> ArmLimits {
    let l = model.limits();
    let a = |v: &dkrrt_model::JVec| {
        let mut o = [0.0; NJ];
        o.copy_from_slice(v.as_slice());
        o
    };
    ArmLimits { q_min: a(&l.q_min), q_max: a(&l.q_max), v_max: a(&l.v_max), tau_max: a(&l.tau_max) }
}

/// Limits every process validates messages against.
pub fn contract_limits(model: &ArmModel) -> ContractLimits {
    let a = arm_limits(model);
    ContractLimits {
        q_min: a.q_min,
        q_max: a.q_max,
        v_max: a.v_max,
        tau_max: a.tau_max,
        q_margin: 0.05,
        v_factor: 1.5,
        // A scene's states are bounded by the same numbers (`dkrrt_debris::scene`).
        debris_range_m: dkrrt_debris::scene::MAX_RANGE_M,
        debris_speed_max: dkrrt_debris::scene::MAX_SPEED_MPS,
        debris_spin_max: dkrrt_debris::scene::MAX_SPIN_RADPS,
    }
}
