//! Constant-velocity baseline predictor on the debris state layout ([`crate::debris_state`]).

use crate::debris_state::{quat_exp, quat_mul, N, POS, QUAT, RATE, VEL};

/// Constant velocity and constant body rate: `p(t) = p₀ + v₀ t`, `v = v₀`,
/// `q(t) = exp(−n ẑ t/2) ⊗ q₀ ⊗ exp(ω₀ t/2)` (exact for constant `ω` in a frame rotating at
/// `frame_rate` about z; set `frame_rate = 0` to ignore the LVLH rotation), `ω = ω₀`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ConstantVelocity {
    /// LVLH frame rotation rate about z (orbital mean motion) [rad/s].
    pub frame_rate: f64,
}

impl ConstantVelocity {
    /// Predict `H = out.len() / 13` states at `dt, 2dt, …` into `out` (row-major). Allocation-free.
    pub fn forecast(&self, x0: &[f64], dt: f64, out: &mut [f64]) -> usize {
        let h = out.len() / N;
        let q0 = &x0[QUAT];
        let w = [x0[RATE.start], x0[RATE.start + 1], x0[RATE.start + 2]];
        for k in 0..h {
            let t = (k + 1) as f64 * dt;
            let o = &mut out[k * N..(k + 1) * N];
            for i in 0..3 {
                o[POS.start + i] = x0[POS.start + i] + x0[VEL.start + i] * t;
                o[VEL.start + i] = x0[VEL.start + i];
                o[RATE.start + i] = w[i];
            }
            let body = quat_exp([w[0] * t, w[1] * t, w[2] * t]);
            let frame = quat_exp([0.0, 0.0, -self.frame_rate * t]);
            let q = quat_mul(&quat_mul(&frame, q0), &body);
            o[QUAT].copy_from_slice(&q);
        }
        h
    }
}
