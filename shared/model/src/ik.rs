//! Damped-least-squares (Levenberg–Marquardt) inverse kinematics with joint limits.
//!
//! Error twist `e = [p_target − p; log(R_target Rᵀ)]` (metres; radians, base
//! frame), matching the `[linear; angular]` rows of [`crate::Jacobian`]. Each
//! iteration takes the step `Δq = Jᵀ (J Jᵀ + λ² 1)⁻¹ e`, limits its largest
//! component to [`IkOptions::max_step`], and clamps `q + Δq` into the joint
//! limits. Joints sitting on a limit whose step would push them further out are
//! frozen (their Jacobian column is zeroed) and the step is recomputed, so the
//! other joints compensate. The damping `λ` adapts: a step that lowers `|e|` is
//! accepted and `λ` shrinks, otherwise it is rejected and `λ` grows. When an
//! attempt stalls it restarts from a pseudo-random in-limit configuration
//! (deterministic, seeded by [`IkOptions::seed`]).
//!
//! No allocation happens in [`ArmModel::ik`].

use nalgebra::{Isometry3, Matrix6, Vector6};

use crate::model::ArmModel;
use crate::{JVec, NJ};

/// Options for [`ArmModel::ik`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IkOptions {
    /// Maximum iterations per attempt.
    pub max_iters: usize,
    /// Additional attempts from random in-limit configurations after the first
    /// attempt (which starts at `q0`).
    pub restarts: usize,
    /// Position tolerance on `|p_target − p|` (m).
    pub pos_tol: f64,
    /// Orientation tolerance on the rotation-error angle (rad).
    pub rot_tol: f64,
    /// Initial damping `λ` (units of the Jacobian, i.e. m or 1).
    pub damping: f64,
    /// Largest joint change per iteration (rad).
    pub max_step: f64,
    /// Seed for the restart configurations.
    pub seed: u64,
}

impl Default for IkOptions {
    fn default() -> Self {
        IkOptions {
            max_iters: 100,
            restarts: 64,
            pos_tol: 1e-5,
            rot_tol: 1e-5,
            damping: 1e-2,
            max_step: 0.4,
            seed: 0x5EED_D1CE,
        }
    }
}

/// A converged IK solution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IkSolution {
    /// Joint positions (within the limits).
    pub q: JVec,
    /// Total iterations used, over all attempts.
    pub iterations: usize,
    /// Number of random restarts used (0 = converged from `q0`).
    pub restarts: usize,
    /// Final position error (m).
    pub pos_err: f64,
    /// Final orientation error (rad).
    pub rot_err: f64,
}

/// Why IK failed.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum IkError {
    /// No attempt reached the tolerances: the pose is out of reach (or only
    /// reachable outside the joint limits). Carries the best configuration found.
    #[error("IK target unreachable: residual {residual:.3e} (position {pos_err:.3e} m, orientation {rot_err:.3e} rad) after {iterations} iterations")]
    Unreachable {
        /// `sqrt(pos_err² + rot_err²)` of the best configuration found.
        residual: f64,
        /// Best position error (m).
        pos_err: f64,
        /// Best orientation error (rad).
        rot_err: f64,
        /// Best configuration found (within limits).
        best_q: JVec,
        /// Total iterations used.
        iterations: usize,
    },
    /// The target pose or the initial guess contains NaN/inf.
    #[error("IK input is not finite")]
    NonFinite,
}

/// SplitMix64: tiny deterministic PRNG for restarts (no allocation, no deps).
struct SplitMix(u64);
impl SplitMix {
    fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

fn pose_error(target: &Isometry3<f64>, cur: &Isometry3<f64>) -> Vector6<f64> {
    let dp = target.translation.vector - cur.translation.vector;
    let dr = (target.rotation * cur.rotation.inverse()).scaled_axis();
    Vector6::new(dp.x, dp.y, dp.z, dr.x, dr.y, dr.z)
}

fn split(e: &Vector6<f64>) -> (f64, f64) {
    (e.fixed_rows::<3>(0).norm(), e.fixed_rows::<3>(3).norm())
}

impl ArmModel {
    /// Solve for joint positions placing the end-effector frame at `target`
    /// (base frame), starting from `q0`. Returns the first configuration within
    /// `opts.pos_tol` / `opts.rot_tol`, or [`IkError::Unreachable`] with the best
    /// residual found.
    pub fn ik(&self, target: &Isometry3<f64>, q0: &JVec, opts: &IkOptions) -> Result<IkSolution, IkError> {
        if !(target.translation.vector.iter().all(|v| v.is_finite())
            && target.rotation.coords.iter().all(|v| v.is_finite())
            && q0.iter().all(|v| v.is_finite()))
        {
            return Err(IkError::NonFinite);
        }
        let lim = &self.limits;
        let mut rng = SplitMix(opts.seed);
        let mut iterations = 0;
        let mut best = (f64::INFINITY, JVec::zeros(), 0.0, 0.0);
        for attempt in 0..=opts.restarts {
            let mut q = if attempt == 0 {
                lim.clamp(q0)
            } else {
                JVec::from_fn(|i, _| {
                    let (lo, hi) = (lim.q_min[i], lim.q_max[i]);
                    let u = rng.next_f64();
                    if lo.is_finite() && hi.is_finite() {
                        lo + u * (hi - lo)
                    } else {
                        (2.0 * u - 1.0) * std::f64::consts::PI
                    }
                })
            };
            let mut lambda = opts.damping;
            let (pose, mut jac) = self.fk_jacobian(&q);
            let mut e = pose_error(target, &pose);
            let mut cost = e.norm_squared();
            for _ in 0..opts.max_iters {
                let (pe, re) = split(&e);
                if cost < best.0 {
                    best = (cost, q, pe, re);
                }
                if pe <= opts.pos_tol && re <= opts.rot_tol {
                    return Ok(IkSolution { q, iterations, restarts: attempt, pos_err: pe, rot_err: re });
                }
                iterations += 1;
                let dq = self.dls_step(&q, &jac, &e, lambda);
                let amax = dq.amax();
                let dq = if amax > opts.max_step { dq * (opts.max_step / amax) } else { dq };
                let q_new = lim.clamp(&(q + dq));
                let (pose_new, jac_new) = self.fk_jacobian(&q_new);
                let e_new = pose_error(target, &pose_new);
                let cost_new = e_new.norm_squared();
                if cost_new < cost {
                    (q, jac, e, cost) = (q_new, jac_new, e_new, cost_new);
                    lambda = (lambda * 0.3).max(1e-9);
                } else {
                    lambda *= 5.0;
                    if lambda > 1e4 {
                        break; // stalled: local minimum or limit-locked; restart
                    }
                }
            }
            let (pe, re) = split(&e);
            if cost < best.0 {
                best = (cost, q, pe, re);
            }
            if pe <= opts.pos_tol && re <= opts.rot_tol {
                return Ok(IkSolution { q, iterations, restarts: attempt, pos_err: pe, rot_err: re });
            }
        }
        Err(IkError::Unreachable {
            residual: best.0.sqrt(),
            pos_err: best.2,
            rot_err: best.3,
            best_q: best.1,
            iterations,
        })
    }

    /// One damped-least-squares step with limit-locked joints frozen.
    fn dls_step(&self, q: &JVec, jac: &crate::Jacobian, e: &Vector6<f64>, lambda: f64) -> JVec {
        let lim = &self.limits;
        let mut j = *jac;
        let mut dq = JVec::zeros();
        for _pass in 0..3 {
            let a = j * j.transpose() + Matrix6::identity() * (lambda * lambda);
            let y = match a.cholesky() {
                Some(ch) => ch.solve(e),
                None => return JVec::zeros(),
            };
            dq = j.transpose() * y;
            let mut changed = false;
            for i in 0..NJ {
                let at_hi = q[i] >= lim.q_max[i] && dq[i] > 0.0;
                let at_lo = q[i] <= lim.q_min[i] && dq[i] < 0.0;
                if (at_hi || at_lo) && j.column(i).iter().any(|v| *v != 0.0) {
                    j.column_mut(i).fill(0.0);
                    changed = true;
                }
            }
            if !changed {
                break;
            }
        }
        for i in 0..NJ {
            if j.column(i).iter().all(|v| *v == 0.0) {
                dq[i] = 0.0;
            }
        }
        dq
    }
}
