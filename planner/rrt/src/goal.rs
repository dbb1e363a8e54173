//! End-effector pose goals (the paper's "grasp a target point") turned into joint goals:
//! inverse kinematics (`dkrrt_model`'s damped least squares) from several seeds — the arm's
//! configuration, the goal in force, then seeded in-limit configurations — gives a set of
//! distinct solutions; the chosen one is the nearest to the arm's configuration (largest
//! joint difference) among those clear of the predicted debris at rest over the look-ahead,
//! else the one with the most clearance. The replanning loop then plans to it like any joint
//! goal.

use dkrrt_model::{ArmModel, IkOptions, JVec, NJ};
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};

/// Most distinct IK solutions considered.
pub const MAX_SOLUTIONS: usize = 8;
/// Seeded in-limit starting configurations tried after the given seeds.
pub const RANDOM_SEEDS: usize = 64;

/// The target pose as an isometry (`q` = (w, x, y, z), normalised).
pub fn target(p: &[f64; 3], q: &[f64; 4]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(p[0], p[1], p[2]),
        UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3])),
    )
}

/// Distinct configurations (within the joint limits) placing the end effector at `p`, `q`:
/// IK from each of `seeds`, then from [`RANDOM_SEEDS`] seeded in-limit configurations; at
/// most [`MAX_SOLUTIONS`]. Deterministic.
pub fn ik_solutions(model: &ArmModel, p: &[f64; 3], q: &[f64; 4], seeds: &[[f64; NJ]]) -> Vec<[f64; NJ]> {
    let t = target(p, q);
    let opts = IkOptions { restarts: 0, ..IkOptions::default() };
    let lim = model.limits();
    let mut out: Vec<[f64; NJ]> = Vec::new();
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let mut rnd = || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut starts: Vec<[f64; NJ]> = seeds.to_vec();
    for _ in 0..RANDOM_SEEDS {
        starts.push(std::array::from_fn(|j| lim.q_min[j] + (lim.q_max[j] - lim.q_min[j]) * rnd()));
    }
    for s in starts {
        if out.len() >= MAX_SOLUTIONS {
            break;
        }
        if let Ok(sol) = model.ik(&t, &JVec::from_row_slice(&s), &opts) {
            let c: [f64; NJ] = std::array::from_fn(|j| sol.q[j]);
            if !out.iter().any(|o| (0..NJ).all(|j| (o[j] - c[j]).abs() < 1e-3)) {
                out.push(c);
            }
        }
    }
    out
}

/// The solution to use: among `solutions` with `clearance(q) > 0`, the nearest to `q_now`
/// (largest joint difference); else the one with the largest clearance. `None` if empty.
pub fn choose(
    solutions: &[[f64; NJ]],
    q_now: &[f64; NJ],
    mut clearance: impl FnMut(&[f64; NJ]) -> f64,
) -> Option<[f64; NJ]> {
    let dist = |a: &[f64; NJ]| (0..NJ).map(|j| (a[j] - q_now[j]).abs()).fold(0.0, f64::max);
    let scored: Vec<(f64, f64, [f64; NJ])> = solutions.iter().map(|s| (clearance(s), dist(s), *s)).collect();
    let clear = scored.iter().filter(|s| s.0 > 0.0).min_by(|a, b| a.1.total_cmp(&b.1));
    clear.or_else(|| scored.iter().max_by(|a, b| a.0.total_cmp(&b.0))).map(|s| s.2)
}
