//! Planning-problem files (`dkrrt plan`): whole motions checked past the look-ahead, the
//! anytime search that goes on after a first solution found late, and the reasons given for
//! an unsolved problem.

use dkrrt_model::{ArmModel, NJ};
use dkrrt_msg::{Trajectory, Zeroed};
use dkrrt_otg::{KinState, Limits};
use dkrrt_rrt::problem::{solve, Problem, ProblemObstacle, ProblemPose, ProblemShape};
use dkrrt_rrt::*;

const START: [f64; NJ] = [0.0, -0.5, 1.0, 0.0, 0.5, 0.0];
const GOAL: [f64; NJ] = [0.35, -0.2, 0.7, 0.3, 0.2, 0.4];
/// A turn of the base by 1 rad from START: link 4 sweeps an arc of about 1.5 m.
const TURNED: [f64; NJ] = [1.0, -0.5, 1.0, 0.0, 0.5, 0.0];

/// Slow joints: the straight motion from START to TURNED takes about 100 s.
fn slow() -> Limits<NJ> {
    Limits { v_max: [0.01; NJ], a_max: [0.01; NJ], j_max: [0.05; NJ] }
}

fn straight(lim: &Limits<NJ>, goal: &[f64; NJ]) -> dkrrt_otg::Trajectory<NJ> {
    dkrrt_otg::Trajectory::calculate(&KinState::rest(START), &KinState::rest(*goal), lim, &Default::default())
        .unwrap()
}

/// A static sphere of radius `r` on link 4 of the straight motion to `goal` at `frac` of its
/// duration.
fn sphere_on_straight(lim: &Limits<NJ>, goal: &[f64; NJ], frac: f64, r: f64) -> WorldInTime {
    let tr = straight(lim, goal);
    let poser = dkrrt_collision::ArmPoser::new(ArmModel::default_arm());
    let mut caps = [dkrrt_collision::PosedCapsule::default(); NJ];
    poser.pose(&tr.at(frac * tr.duration()).p, &mut caps);
    let mut w = WorldInTime::new(0.0);
    let pose = TimedPose { t: 0.0, p: caps[4].centre, q: [1.0, 0.0, 0.0, 0.0], sigma: 0.0, sigma_pos: 0.0 };
    w.push_track(1, dkrrt_msg::DebrisShape::sphere(r), &[pose], After::Hold).unwrap();
    w
}

/// Every 1 ms of the plan to its end and 1 s beyond: its smallest clearance.
fn dense_min_clearance(w: &WorldInTime, tr: &Trajectory) -> f64 {
    let mut ch = Checker::new(ArmModel::default_arm(), &slow().v_max, 0.03);
    ch.cap = 10.0;
    let mut m = f64::INFINITY;
    let mut t = 0.0;
    while t <= tr.duration_s + 1.0 {
        m = m.min(ch.clearance_at(w, &tr.sample(t).p, t, 0.0, f64::NEG_INFINITY));
        t += 1e-3;
    }
    m
}

#[test]
fn a_motion_longer_than_the_look_ahead_is_checked_to_its_end() {
    let lim = slow();
    let d = straight(&lim, &TURNED).duration();
    assert!(d > 90.0, "the straight motion must outlast the 60 s look-ahead by far ({d} s)");
    // A static sphere on the straight motion 70 % of the way: past the look-ahead, and clear
    // of the arm at rest at the start and at the goal.
    let w = sphere_on_straight(&lim, &TURNED, 0.7, 0.1);
    let mut ch = Checker::new(ArmModel::default_arm(), &lim.v_max, 0.03);
    ch.cap = 10.0;
    for q in [START, TURNED] {
        assert!(ch.clearance_at(&w, &q, 0.0, 0.0, f64::NEG_INFINITY) > 0.1);
    }
    let req = Request { start: KinState::rest(START), t0: 0.0, goal: TURNED };
    let plan_with = |whole: bool| {
        let cfg = PlannerConfig {
            lookahead_s: 60.0,
            check_whole_motions: whole,
            max_configs: u64::MAX,
            ..PlannerConfig::default()
        };
        let mut p = Planner::new(ArmModel::default_arm(), lim, cfg);
        let mut out = Box::new(<Trajectory as Zeroed>::zeroed());
        let plan = p.plan(&req, &w, 400, || true, 1, &mut out);
        (plan, out)
    };
    // Checked to the look-ahead only, the straight motion passes and is hit after it.
    let (plan, out) = plan_with(false);
    assert_eq!(plan.map(|x| x.reach), Some(Reach::Goal));
    assert!(dense_min_clearance(&w, &out) < 0.0, "unchecked past the look-ahead, the plan is hit");
    // Checked whole, every plan found is clear at every millisecond.
    let (plan, out) = plan_with(true);
    let plan = plan.expect("a plan");
    assert_eq!(plan.reach, Reach::Goal);
    let m = dense_min_clearance(&w, &out);
    assert!(m >= 0.0, "clearance {m} m at 1 ms resolution");
}

#[test]
fn the_search_goes_on_after_a_first_solution_found_late() {
    // With no cap on the improvement (`improve_iters` = u32::MAX, as `dkrrt plan` sets it), a
    // first solution at iteration f > 0 must not end the search (f + u32::MAX wrapped around).
    let lim = slow();
    let w = sphere_on_straight(&lim, &GOAL, 0.5, 0.15);
    let cfg = PlannerConfig {
        improve_iters: u32::MAX,
        lookahead_s: 200.0,
        max_configs: u64::MAX,
        ..PlannerConfig::default()
    };
    let mut p = Planner::new(ArmModel::default_arm(), lim, cfg);
    let mut out = Box::new(<Trajectory as Zeroed>::zeroed());
    let req = Request { start: KinState::rest(START), t0: 0.0, goal: GOAL };
    let budget = 300;
    p.plan(&req, &w, budget, || true, 1, &mut out).expect("a plan");
    let first = p.stats.first_solution_iter.expect("a first solution");
    assert!(first > 0, "the sphere must block the direct motion ({:?})", p.stats);
    assert_eq!(p.stats.iterations, budget, "{:?}", p.stats);
}

fn problem(start: [f64; NJ], goal: [f64; NJ], at: [f64; 3], r: f64) -> Problem {
    Problem {
        urdf: String::new(),
        start,
        goal,
        v_max: None,
        margin_m: 0.0,
        time_limit_s: 0.2,
        seed: 1,
        obstacles: vec![ProblemObstacle {
            shape: ProblemShape::Sphere { radius: r },
            poses: vec![ProblemPose { t: 0.0, p: at, q: [1.0, 0.0, 0.0, 0.0] }],
        }],
    }
}

/// The centre of link 4 at rest at `q`.
fn link4_at(q: &[f64; NJ]) -> [f64; 3] {
    let poser = dkrrt_collision::ArmPoser::new(ArmModel::default_arm());
    let mut caps = [dkrrt_collision::PosedCapsule::default(); NJ];
    poser.pose(q, &mut caps);
    caps[4].centre
}

fn solve_default(p: &Problem) -> problem::Solution {
    let (v, a, j) =
        ([0.1, 0.1, 0.1, 0.18, 0.18, 0.18], [0.2, 0.2, 0.2, 0.4, 0.4, 0.4], [1.0, 1.0, 1.0, 2.0, 2.0, 2.0]);
    solve(p, ArmModel::default_arm(), v, a, j).unwrap()
}

#[test]
fn an_unsolved_problem_says_why_and_uses_its_whole_time() {
    // The start in collision.
    let sol = solve_default(&problem(START, GOAL, link4_at(&START), 0.2));
    assert!(!sol.solved);
    let why = sol.why.expect("a reason");
    assert!(why.contains("the start is in collision"), "{why}");
    // The goal in collision: no search tree can reach it, and the search goes on, tree after
    // tree, until the time limit.
    let p = problem(START, GOAL, link4_at(&GOAL), 0.2);
    let sol = solve_default(&p);
    assert!(!sol.solved && sol.min_clearance_m.is_none());
    let why = sol.why.expect("a reason");
    assert!(why.contains("the goal is in collision"), "{why}");
    assert!(sol.plan_time_s >= p.time_limit_s, "{} s", sol.plan_time_s);
    // Neither: the search itself.
    let far = problem(START, GOAL, [30.0, 0.0, 0.0], 0.2);
    let sol = solve_default(&far);
    assert!(sol.solved && sol.why.is_none(), "{:?}", sol.why);
}
