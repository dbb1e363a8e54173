//! Synthetic training data for tests, benches and examples.

use crate::TrainData;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

/// `x1⁺ = λ x1`, `x2⁺ = μ x2 + c x1²`: exactly linear in the lifting `[x1, x2, x1²]`.
pub fn quadratic_map(traj: usize, steps: usize, seed: u64) -> TrainData {
    let (lam, mu, c) = (0.9, 0.5, 0.8);
    let mut r = SmallRng::seed_from_u64(seed);
    let trajectories = (0..traj)
        .map(|_| {
            let (mut x1, mut x2) = (r.random_range(-1.0..1.0), r.random_range(-1.0..1.0));
            let mut t = Vec::with_capacity(2 * steps);
            for _ in 0..steps {
                t.push(x1);
                t.push(x2);
                let x1n = lam * x1;
                x2 = mu * x2 + c * x1 * x1;
                x1 = x1n;
            }
            t
        })
        .collect();
    TrainData { n: 2, dt: 0.1, trajectories }
}

/// Hamilton product `a ⊗ b` (`[w, x, y, z]`).
pub fn quat_mul(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ]
}

/// Torque-free rigid body, state `[q_w, q_x, q_y, q_z, ω_x, ω_y, ω_z]` (body rates):
/// `q̇ = ½ q ⊗ (0, ω)`, `I ω̇ = (I ω) × ω`.
pub fn rhs(inertia: [f64; 3], s: &[f64; 7]) -> [f64; 7] {
    let q = [s[0], s[1], s[2], s[3]];
    let w = [s[4], s[5], s[6]];
    let qd = quat_mul(q, [0.0, w[0], w[1], w[2]]);
    let iw = [inertia[0] * w[0], inertia[1] * w[1], inertia[2] * w[2]];
    let c = [iw[1] * w[2] - iw[2] * w[1], iw[2] * w[0] - iw[0] * w[2], iw[0] * w[1] - iw[1] * w[0]];
    [
        0.5 * qd[0],
        0.5 * qd[1],
        0.5 * qd[2],
        0.5 * qd[3],
        c[0] / inertia[0],
        c[1] / inertia[1],
        c[2] / inertia[2],
    ]
}

/// One sample step `dt` (RK4, 10 substeps, quaternion renormalised).
pub fn rigid_body_step(inertia: [f64; 3], s: &mut [f64; 7], dt: f64) {
    let sub = 10;
    let h = dt / sub as f64;
    for _ in 0..sub {
        let add = |a: &[f64; 7], k: &[f64; 7], f: f64| {
            let mut o = *a;
            for i in 0..7 {
                o[i] += f * k[i];
            }
            o
        };
        let k1 = rhs(inertia, s);
        let k2 = rhs(inertia, &add(s, &k1, h / 2.0));
        let k3 = rhs(inertia, &add(s, &k2, h / 2.0));
        let k4 = rhs(inertia, &add(s, &k3, h));
        for i in 0..7 {
            s[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
        let nq = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2] + s[3] * s[3]).sqrt();
        for v in &mut s[..4] {
            *v /= nq;
        }
    }
}

/// Tumbling debris (inertia diag(1, 2, 3), dt = 0.1 s): random attitude, each
/// body-rate component uniform in `±w_max` rad/s.
pub fn tumbling(traj: usize, steps: usize, w_max: f64, seed: u64) -> TrainData {
    let inertia = [1.0, 2.0, 3.0];
    let dt = 0.1;
    let mut r = SmallRng::seed_from_u64(seed);
    let trajectories = (0..traj)
        .map(|_| {
            let mut q = [0.0f64; 4];
            for v in &mut q {
                *v = r.random_range(-1.0..1.0);
            }
            let nq = q.iter().map(|v| v * v).sum::<f64>().sqrt();
            let mut s = [q[0] / nq, q[1] / nq, q[2] / nq, q[3] / nq, 0.0, 0.0, 0.0];
            for v in &mut s[4..] {
                *v = r.random_range(-w_max..w_max);
            }
            let mut t = Vec::with_capacity(7 * steps);
            for _ in 0..steps {
                t.extend_from_slice(&s);
                rigid_body_step(inertia, &mut s, dt);
            }
            t
        })
        .collect();
    TrainData { n: 7, dt, trajectories }
}
