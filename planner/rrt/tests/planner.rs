//! The planner core: free space, a blocking obstacle, waiting, the final check, escapes.

use dkrrt_model::{ArmModel, NJ};
use dkrrt_msg::{DebrisShape, Trajectory, Zeroed};
use dkrrt_otg::{KinState, Limits};
use dkrrt_rrt::*;

fn limits() -> Limits<NJ> {
    Limits {
        v_max: [0.1, 0.1, 0.1, 0.18, 0.18, 0.18],
        a_max: [0.2, 0.2, 0.2, 0.4, 0.4, 0.4],
        j_max: [1.0, 1.0, 1.0, 2.0, 2.0, 2.0],
    }
}

const START: [f64; NJ] = [0.0, -0.5, 1.0, 0.0, 0.5, 0.0];
const GOAL: [f64; NJ] = [0.35, -0.2, 0.7, 0.3, 0.2, 0.4];

fn planner() -> Planner {
    Planner::new(ArmModel::default_arm(), limits(), PlannerConfig::default())
}

#[test]
fn free_space_gives_the_direct_motion_at_once() {
    let mut p = planner();
    let w = WorldInTime::new(0.05);
    let mut out = <Trajectory as Zeroed>::zeroed();
    let req = Request { start: KinState::rest(START), t0: 1.0, goal: GOAL };
    let plan = p.plan(&req, &w, 100, || true, 7, &mut out).expect("a plan");
    assert_eq!(plan.reach, Reach::Goal);
    assert_eq!(p.stats.first_solution_iter, Some(0), "{:?}", p.stats);
    let end = out.sample(out.duration_s);
    for j in 0..NJ {
        assert!((end.p[j] - GOAL[j]).abs() < 1e-9);
        assert!(end.v[j].abs() < 1e-9);
    }
    assert_eq!(out.start_ns, 1_000_000_000);
    assert!((plan.arrival - 1.0 - out.duration_s).abs() < 1e-9);
}
