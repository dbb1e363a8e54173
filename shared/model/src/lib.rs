//! `dkrrt-model`: the 6-DoF space-manipulator model used by the dkrrt planner,
//! tracker and simulator.
//!
//! * [`ArmModel`] is loaded from URDF ([`ArmModel::from_urdf_str`],
//!   [`ArmModel::from_urdf_file`]) or is the shipped arm
//!   ([`ArmModel::default_arm`], `urdf/dkrrt_arm.urdf`: an SSRMS-like joint
//!   sequence scaled to ~2.9 m reach and 112 kg; see [`urdf::DEFAULT_ARM_URDF`]
//!   and the crate README for where the numbers come from).
//! * Kinematics: [`ArmModel::fk`], [`ArmModel::link_poses`], [`ArmModel::jacobian`]
//!   (geometric, `[linear; angular]`, base frame).
//! * Dynamics: [`ArmModel::rnea`], [`ArmModel::mass_matrix`],
//!   [`ArmModel::coriolis_matrix`] (`Ṁ − 2C` skew), [`ArmModel::gravity_torque`],
//!   [`ArmModel::nonlinear_effects`], [`ArmModel::forward_dynamics`].
//! * Inverse kinematics: [`ArmModel::ik`] (damped least squares with joint limits).
//! * Collision geometry for the debris checker: [`ArmModel::collision_capsules`].
//!
//! Units are SI (m, kg, s, rad, N m). All kinematic and dynamic queries (and IK)
//! are allocation-free and work on nalgebra fixed-size types.
//!
//! ```
//! use dkrrt_model::{ArmModel, IkOptions, JVec};
//!
//! let arm = ArmModel::default_arm(); // gravity defaults to zero (in orbit)
//! let q = JVec::from_column_slice(&[0.3, -0.5, 1.0, 0.2, -0.4, 0.6]);
//! let qd = JVec::repeat(0.05);
//! let tau = arm.rnea(&q, &qd, &JVec::zeros()); // = C(q, q̇) q̇
//! let qdd = arm.forward_dynamics(&q, &qd, &tau);
//! assert!(qdd.norm() < 1e-9);
//!
//! let target = arm.fk(&q);
//! let sol = arm.ik(&target, &JVec::zeros(), &IkOptions::default()).unwrap();
//! assert!(sol.pos_err < 1e-5);
//! ```

pub mod dynamics;
pub mod ik;
pub mod kinematics;
pub mod mesh;
pub mod model;
pub mod spatial;
pub mod urdf;

use nalgebra::{SMatrix, SVector};

/// Number of actuated joints.
pub const NJ: usize = 6;
/// Joint-space vector (`q`, `q̇`, `q̈`, `τ`).
pub type JVec = SVector<f64, NJ>;
/// Joint-space matrix (`M`, `C`).
pub type JMat = SMatrix<f64, NJ, NJ>;

pub use ik::{IkError, IkOptions, IkSolution};
pub use kinematics::Jacobian;
pub use model::{ArmModel, JointLimits, LinkCapsule, LinkInertial};
pub use urdf::{ModelError, UrdfOptions, DEFAULT_ARM_URDF};
