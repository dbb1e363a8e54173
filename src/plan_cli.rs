//! `dkrrt plan` (solve a planning-problem file) and `dkrrt plan-problem` (export a scenario's
//! start, goal and true debris motion as one).

use std::path::Path;

use dkrrt_collision::descriptor_of;
use dkrrt_config::Scenario;
use dkrrt_msg::{ShapeKind, NJ};
use dkrrt_rrt::problem::{load, solve, Problem, ProblemObstacle, ProblemPose, ProblemShape, Solution};

/// Reads, checks and solves a problem file; `time_limit` overrides the file's.
pub fn plan(problem: &Path, time_limit: Option<f64>) -> Result<Solution, String> {
    let (p, model) = load(problem, time_limit)?;
    let m = Scenario::default_scenario().motion;
    solve(&p, model, m.v_max, m.a_max, m.j_max).map_err(|e| format!("{}: {e}", problem.display()))
}

/// The scenario (an episode, resolved) as a problem: its start and goal, its debris' true
/// motion every 0.1 s over the run (rods as capsules, panels as boxes, convex pieces as their
/// oriented boxes), in the arm's base frame.
pub fn export(sc: &Scenario) -> Result<Problem, String> {
    let scene = sc.load_debris_scene().map_err(|e| e.to_string())?;
    let mut world = dkrrt_debris::DebrisWorld::new(&scene).map_err(|e| e.to_string())?;
    let base = sc.debris.base_lvlh;
    let mut obstacles: Vec<(u32, ProblemObstacle, [f64; 3])> = Vec::new();
    let dt = 0.1;
    let n = (sc.run.duration_s / dt).ceil() as usize;
    for k in 0..=n {
        let t = k as f64 * dt;
        for d in world.debris() {
            let idx = match obstacles.iter().position(|o| o.0 == d.id) {
                Some(i) => i,
                None => {
                    let desc = descriptor_of(d.props.shape.as_ref());
                    let shape = match ShapeKind::from_u32(desc.kind) {
                        Some(ShapeKind::Sphere) => ProblemShape::Sphere { radius: desc.dims[0] },
                        Some(ShapeKind::Capsule) => {
                            ProblemShape::Capsule { half_length: desc.dims[0], radius: desc.dims[1] }
                        }
                        Some(ShapeKind::Disc) => {
                            ProblemShape::Disc { radius: desc.dims[0], half_thickness: desc.dims[1] }
                        }
                        _ => ProblemShape::Box { half_extents: desc.dims },
                    };
                    obstacles.push((d.id, ProblemObstacle { shape, poses: Vec::new() }, desc.offset));
                    obstacles.len() - 1
                }
            };
            let q = d.state.q.quaternion();
            let qq = [q.w, q.i, q.j, q.k];
            // The box's centre (its offset in the body frame) carries the pose.
            let off = dkrrt_collision::quat_rotate(&qq, &obstacles[idx].2);
            let p = [
                d.state.p.x + off[0] - base[0],
                d.state.p.y + off[1] - base[1],
                d.state.p.z + off[2] - base[2],
            ];
            obstacles[idx].1.poses.push(ProblemPose { t, p, q: qq });
        }
        world.step(dt);
    }
    Ok(Problem {
        urdf: sc.urdf_path().map(|p| p.display().to_string()).unwrap_or_default(),
        start: sc.sim.initial_q,
        goal: joint_goal(sc)?,
        v_max: Some(sc.motion.v_max),
        margin_m: sc.planner.margin_m,
        time_limit_s: 1.0,
        seed: sc.planner.seed,
        obstacles: obstacles.into_iter().map(|o| o.1).collect(),
    })
}

/// The scenario's joint goal; a pose goal becomes the IK solution nearest to the start (a
/// planning problem has a joint goal).
fn joint_goal(sc: &Scenario) -> Result<[f64; NJ], String> {
    match sc.goal.request().ok_or("the scenario gives no goal")? {
        dkrrt_config::GoalRequest::Joint(q) => Ok(q),
        dkrrt_config::GoalRequest::Pose(p, q) => {
            let model = sc.load_arm().map_err(|e| e.to_string())?;
            let sols = dkrrt_rrt::goal::ik_solutions(&model, &p, &q, &[sc.sim.initial_q]);
            dkrrt_rrt::goal::choose(&sols, &sc.sim.initial_q, |_| 1.0)
                .ok_or_else(|| format!("the pose goal at {p:?} is out of reach"))
        }
    }
}
