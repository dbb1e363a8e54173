//! `dkrrt plan`'s answers checked by someone else's geometry: random problems with moving,
//! turning obstacles; every solved plan's trajectory (the 10 ms rows of the output,
//! interpolated) is measured against the obstacles every 0.5 ms with parry3d's own shapes and
//! distance query, and the obstacles posed by this file's own interpolation of the problem's
//! poses (linear, slerp).

use dkrrt_model::{ArmModel, NJ};
use dkrrt_rrt::problem::{solve, Problem, ProblemObstacle, ProblemPose, ProblemShape};
use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use parry3d_f64::glamx::DQuat;
use parry3d_f64::math::{Pose, Vector as PVec};
use parry3d_f64::query;
use parry3d_f64::shape::{Ball, Capsule, Cuboid, SharedShape};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

const V: [f64; NJ] = [0.1, 0.1, 0.1, 0.18, 0.18, 0.18];

fn unit_quat(rng: &mut SmallRng) -> [f64; 4] {
    let q: [f64; 4] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    q.map(|v| v / n)
}

/// The obstacle's pose at `t`: the first pose before its time, the last after, else linear
/// position and slerped attitude.
fn pose_at(o: &ProblemObstacle, t: f64) -> Pose {
    let ps = &o.poses;
    let of = |p: &ProblemPose| {
        (Vector3::from(p.p), UnitQuaternion::from_quaternion(Quaternion::new(p.q[0], p.q[1], p.q[2], p.q[3])))
    };
    let (p, q) = match ps.iter().position(|x| x.t > t) {
        Some(0) => of(&ps[0]),
        None => of(&ps[ps.len() - 1]),
        Some(k) => {
            let (a, b) = (of(&ps[k - 1]), of(&ps[k]));
            let f = (t - ps[k - 1].t) / (ps[k].t - ps[k - 1].t);
            (a.0 + (b.0 - a.0) * f, a.1.slerp(&b.1, f))
        }
    };
    let q = q.quaternion();
    Pose::from_parts(PVec::new(p.x, p.y, p.z), DQuat::from_xyzw(q.i, q.j, q.k, q.w))
}

fn random_problem(seed: u64) -> Problem {
    let mut rng = SmallRng::seed_from_u64(seed);
    let lim = *ArmModel::default_arm().limits();
    let inner = |k: usize| lim.q_min[k] * 0.8..lim.q_max[k] * 0.8;
    let start: [f64; NJ] = std::array::from_fn(|k| rng.random_range(inner(k)));
    let goal: [f64; NJ] =
        std::array::from_fn(|k| (start[k] + rng.random_range(-1.0..1.0)).clamp(inner(k).start, inner(k).end));
    let n = rng.random_range(1..6);
    let obstacles = (0..n)
        .map(|_| {
            let shape = match rng.random_range(0..3) {
                0 => ProblemShape::Sphere { radius: rng.random_range(0.05..0.3) },
                1 => ProblemShape::Box { half_extents: std::array::from_fn(|_| rng.random_range(0.01..0.4)) },
                _ => ProblemShape::Capsule {
                    half_length: rng.random_range(0.1..0.7),
                    radius: rng.random_range(0.01..0.12),
                },
            };
            let mut t = rng.random_range(0.0..3.0);
            let poses = (0..rng.random_range(1..7))
                .map(|_| {
                    let p = loop {
                        let x: [f64; 3] = std::array::from_fn(|_| rng.random_range(-2.5..2.5));
                        if (0.5..2.6).contains(&x.iter().map(|v| v * v).sum::<f64>().sqrt()) {
                            break x;
                        }
                    };
                    let pose = ProblemPose { t, p, q: unit_quat(&mut rng) };
                    t += rng.random_range(0.3..4.0);
                    pose
                })
                .collect();
            ProblemObstacle { shape, poses }
        })
        .collect();
    Problem {
        urdf: String::new(),
        start,
        goal,
        v_max: Some(V),
        margin_m: 0.0,
        time_limit_s: 0.2,
        seed,
        obstacles,
    }
}

#[test]
fn solved_plans_clear_moving_obstacles_by_an_independent_measure() {
    let model = ArmModel::default_arm();
    let poser = dkrrt_collision::ArmPoser::new(model.clone());
    let (a, j) = ([0.2, 0.2, 0.2, 0.4, 0.4, 0.4], [1.0, 1.0, 1.0, 2.0, 2.0, 2.0]);
    let mut solved = 0;
    for seed in 1..=16 {
        let p = random_problem(seed);
        let sol = solve(&p, model.clone(), V, a, j).unwrap();
        if !sol.solved {
            assert!(sol.why.is_some(), "seed {seed}: unsolved without a reason");
            continue;
        }
        solved += 1;
        let shapes: Vec<SharedShape> = p
            .obstacles
            .iter()
            .map(|o| match o.shape {
                ProblemShape::Sphere { radius } => SharedShape::new(Ball::new(radius)),
                ProblemShape::Box { half_extents: h } => {
                    SharedShape::new(Cuboid::new(PVec::new(h[0], h[1], h[2])))
                }
                ProblemShape::Capsule { half_length, radius } => {
                    SharedShape::new(Capsule::new_z(half_length, radius))
                }
                ProblemShape::Disc { .. } => unreachable!(),
            })
            .collect();
        let rows = &sol.trajectory;
        assert_eq!(rows[0][1..], p.start, "seed {seed}: starts at the start");
        let last = &rows[rows.len() - 1][1..];
        assert!(
            (0..NJ).all(|m| (last[m] - p.goal[m]).abs() < 1e-9),
            "seed {seed}: ends at {last:?}, not the goal"
        );
        for w in rows.windows(2) {
            for i in 0..NJ {
                let v = (w[1][i + 1] - w[0][i + 1]) / (w[1][0] - w[0][0]);
                assert!(v.abs() <= V[i] * (1.0 + 1e-9), "seed {seed}: joint {i} at {v} rad/s");
            }
        }
        // To 1 s past the plan's end or the obstacles' last pose (the arm then rests at the goal).
        let last_pose = p.obstacles.iter().map(|o| o.poses[o.poses.len() - 1].t).fold(0.0, f64::max);
        let end = sol.duration_s.max(last_pose) + 1.0;
        let mut caps = [dkrrt_collision::PosedCapsule::default(); NJ];
        let mut min = f64::INFINITY;
        for k in 0..=(end / 5e-4) as usize {
            let t = k as f64 * 5e-4;
            let i = rows.partition_point(|r| r[0] <= t).clamp(1, rows.len() - 1);
            let (r0, r1) = (&rows[i - 1], &rows[i]);
            let f = ((t - r0[0]) / (r1[0] - r0[0])).clamp(0.0, 1.0);
            let q: [f64; NJ] = std::array::from_fn(|m| r0[m + 1] + f * (r1[m + 1] - r0[m + 1]));
            poser.pose(&q, &mut caps);
            for (o, shape) in p.obstacles.iter().zip(&shapes) {
                let at = pose_at(o, t);
                for c in &caps {
                    let cap = Capsule::new(PVec::from(c.a), PVec::from(c.b), c.r);
                    min = min
                        .min(query::distance(&at, shape.as_ref(), &Pose::IDENTITY, &cap).unwrap().distance);
                }
            }
        }
        // The rows are 10 ms apart: interpolating them moves a point of the arm by < 0.1 mm.
        let reported = sol.min_clearance_m.unwrap_or(f64::INFINITY);
        assert!(min > 0.0, "seed {seed}: a solved plan touches an obstacle ({min} m)");
        assert!(
            (reported - min).abs() < 1e-3 || (min > 99.0 && reported.is_infinite()),
            "seed {seed}: reported clearance {reported} m, measured {min} m"
        );
    }
    assert!(solved >= 3, "only {solved} of 16 solved");
}
