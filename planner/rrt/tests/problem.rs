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

/// The centre of link 4 on the straight motion to `goal` at `frac` of its duration.
fn link4_on_straight(lim: &Limits<NJ>, goal: &[f64; NJ], frac: f64) -> [f64; 3] {
    let tr = straight(lim, goal);
    link4_at(&tr.at(frac * tr.duration()).p)
}

/// A static sphere of radius `r` on link 4 of the straight motion to `goal` at `frac` of its
/// duration.
fn sphere_on_straight(lim: &Limits<NJ>, goal: &[f64; NJ], frac: f64, r: f64) -> WorldInTime {
    let mut w = WorldInTime::new(0.0);
    let p = link4_on_straight(lim, goal, frac);
    let pose = TimedPose { t: 0.0, p, q: [1.0, 0.0, 0.0, 0.0], sigma: 0.0, sigma_pos: 0.0 };
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
fn an_unsolved_problem_says_why_at_once_when_no_plan_can_pass() {
    // The start in collision: every plan's final check fails at t = 0, so there is no search
    // (before, a plan moving away from the sphere was found and reported with a first
    // solution time, and an unsolvable problem could use its whole time limit).
    let p = problem(START, GOAL, link4_at(&START), 0.2);
    let sol = solve_default(&p);
    assert!(!sol.solved && sol.first_solution_s.is_none() && sol.min_clearance_m.is_none());
    let why = sol.why.expect("a reason");
    assert!(why.contains("the start is in collision"), "{why}");
    assert_eq!((sol.iterations, sol.configs_checked), (0, 0), "no search");
    // Barely in collision: the arm leaves the sphere at once, but the plan starts inside it.
    let mut caps = [dkrrt_collision::PosedCapsule::default(); NJ];
    dkrrt_collision::ArmPoser::new(ArmModel::default_arm()).pose(&START, &mut caps);
    let k = caps[4];
    let up = [0.0, 0.0, 1.0];
    let axis: [f64; 3] = std::array::from_fn(|i| k.b[i] - k.a[i]);
    let side = [
        axis[1] * up[2] - axis[2] * up[1],
        axis[2] * up[0] - axis[0] * up[2],
        axis[0] * up[1] - axis[1] * up[0],
    ];
    let n = side.iter().map(|v| v * v).sum::<f64>().sqrt();
    let at: [f64; 3] = std::array::from_fn(|i| k.centre[i] + side[i] / n * (k.r + 0.2 - 0.01));
    let sol = solve_default(&problem(START, GOAL, at, 0.2));
    assert!(!sol.solved && sol.first_solution_s.is_none(), "{:?}", sol.first_solution_s);
    assert!(sol.why.expect("a reason").contains("the start is in collision"));
    // The goal in collision from the last pose on, where a plan rests: no search either.
    let p = problem(START, GOAL, link4_at(&GOAL), 0.2);
    let sol = solve_default(&p);
    assert!(!sol.solved && sol.min_clearance_m.is_none());
    let why = sol.why.expect("a reason");
    assert!(why.contains("the goal is in collision"), "{why}");
    assert_eq!(sol.iterations, 0, "no search");
    // Neither: the search itself.
    let far = problem(START, GOAL, [30.0, 0.0, 0.0], 0.2);
    let sol = solve_default(&far);
    assert!(sol.solved && sol.why.is_none(), "{:?}", sol.why);
    assert!(sol.first_solution_s.is_some());
}

/// The final check's clearance is a measured figure or none: with nothing within the range
/// it measures (no obstacle, or one 200 m away) the answer is solved with no clearance, not a
/// clearance of exactly that range (before: `min clearance 100.000 m`).
#[test]
fn a_plan_with_nothing_near_has_no_clearance_figure() {
    let far = problem(START, GOAL, [200.0, 0.0, 0.0], 0.2);
    let mut none = far.clone();
    none.obstacles.clear();
    for p in [far, none] {
        let sol = solve_default(&p);
        assert!(sol.solved && !sol.trajectory.is_empty(), "{:?}", sol.why);
        assert_eq!(sol.min_clearance_m, None);
    }
    // 30 m away: measured (the arm reaches about 1.5 m from its base).
    let sol = solve_default(&problem(START, GOAL, [30.0, 0.0, 0.0], 0.2));
    let m = sol.min_clearance_m.expect("a measured clearance");
    assert!(m > 27.0 && m < problem::MEASURED_UP_TO_M, "{m}");
}

/// A static world of `n` random obstacles around the arm (seeded).
fn clutter(seed: u64, n: u32) -> Problem {
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::SmallRng::seed_from_u64(seed);
    let mut p = problem(START, GOAL, [30.0, 0.0, 0.0], 0.1);
    p.obstacles.clear();
    for _ in 0..n {
        let at = loop {
            let x: [f64; 3] = std::array::from_fn(|_| rng.random_range(-2.8..2.8));
            let d = x.iter().map(|v| v * v).sum::<f64>().sqrt();
            if (0.8..2.9).contains(&d) {
                break x;
            }
        };
        let shape = match rng.random_range(0..3) {
            0 => ProblemShape::Sphere { radius: rng.random_range(0.1..0.3) },
            1 => ProblemShape::Box { half_extents: std::array::from_fn(|_| rng.random_range(0.05..0.3)) },
            _ => ProblemShape::Capsule {
                half_length: rng.random_range(0.1..0.5),
                radius: rng.random_range(0.03..0.15),
            },
        };
        let q: [f64; 4] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
        p.obstacles
            .push(ProblemObstacle { shape, poses: vec![ProblemPose { t: 0.0, p: at, q: q.map(|v| v / n) }] });
    }
    p
}

fn default_limits() -> Limits<NJ> {
    Limits {
        v_max: [0.1, 0.1, 0.1, 0.18, 0.18, 0.18],
        a_max: [0.2, 0.2, 0.2, 0.4, 0.4, 0.4],
        j_max: [1.0, 1.0, 1.0, 2.0, 2.0, 2.0],
    }
}

/// The smallest clearance along the straight segment a → b, at 2000 points.
fn segment_min(ch: &mut Checker, w: &WorldInTime, a: &[f64; NJ], b: &[f64; NJ]) -> f64 {
    (0..=2000)
        .map(|i| {
            let s = i as f64 / 2000.0;
            let q: [f64; NJ] = std::array::from_fn(|j| a[j] + s * (b[j] - a[j]));
            ch.clearance_at(w, &q, 0.0, 0.0, f64::NEG_INFINITY)
        })
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn a_segment_found_clear_is_clear_everywhere_along_it() {
    // Long and short random segments through clutter: the sampled check's verdict "clear" must
    // hold at every point (the check runs at the joint speed limits, whatever the span).
    use rand::{Rng, SeedableRng};
    let lim = default_limits();
    let l = *ArmModel::default_arm().limits();
    let mut rng = rand::rngs::SmallRng::seed_from_u64(3);
    let (mut clear, mut blocked) = (0, 0);
    for k in 0..12 {
        let w = clutter(100 + k, 24).world().unwrap();
        let mut ch = Checker::new(ArmModel::default_arm(), &lim.v_max, 0.03);
        let mut dense = Checker::new(ArmModel::default_arm(), &lim.v_max, 0.03);
        dense.cap = 10.0;
        let mut c = dkrrt_rrt::connect::Connect::new(l.q_min.into(), l.q_max.into(), lim.v_max, 10, 1);
        for _ in 0..25 {
            let a: [f64; NJ] = std::array::from_fn(|j| rng.random_range(0.8 * l.q_min[j]..0.8 * l.q_max[j]));
            let span = [0.05, 0.5, 3.0][rng.random_range(0..3)];
            let b: [f64; NJ] =
                std::array::from_fn(|j| (a[j] + rng.random_range(-span..span)).clamp(l.q_min[j], l.q_max[j]));
            if c.segment_clear(&mut ch, &w, &a, &b) {
                clear += 1;
                let m = segment_min(&mut dense, &w, &a, &b);
                assert!(m >= 0.0, "world {k}: a segment found clear has clearance {m} m");
            } else {
                blocked += 1;
            }
        }
    }
    assert!(clear > 50 && blocked > 50, "both verdicts exercised: {clear} clear, {blocked} blocked");
}

#[test]
fn rrt_connect_finds_clear_paths_through_clutter() {
    use rand::{Rng, SeedableRng};
    let lim = default_limits();
    let l = *ArmModel::default_arm().limits();
    let mut rng = rand::rngs::SmallRng::seed_from_u64(9);
    for k in 0..8 {
        let p = clutter(200 + k, 24);
        let w = p.world().unwrap();
        let mut ch = Checker::new(ArmModel::default_arm(), &lim.v_max, 0.03);
        let mut dense = Checker::new(ArmModel::default_arm(), &lim.v_max, 0.03);
        dense.cap = 10.0;
        // A start and a goal at rest clear of the clutter, far apart.
        let mut rest = |dense: &mut Checker| loop {
            let q: [f64; NJ] = std::array::from_fn(|j| rng.random_range(0.8 * l.q_min[j]..0.8 * l.q_max[j]));
            if dense.clearance_at(&w, &q, 0.0, 0.0, f64::NEG_INFINITY) > 0.05 {
                break q;
            }
        };
        let start = rest(&mut dense);
        let mut c = dkrrt_rrt::connect::Connect::new(l.q_min.into(), l.q_max.into(), lim.v_max, 5000, k);
        // ... with the straight motion between them blocked.
        let goal = loop {
            let g = rest(&mut dense);
            let far = (0..NJ).map(|j| (g[j] - start[j]).abs()).fold(0.0, f64::max) > 1.0;
            if far && !c.segment_clear(&mut ch, &w, &start, &g) {
                break g;
            }
        };
        let mut path = Vec::new();
        // Iteration budgets, not a clock: the same on any machine.
        let mut n = 0;
        let found = c.solve(
            &mut ch,
            &w,
            &start,
            &goal,
            || {
                n += 1;
                n <= 3000
            },
            &mut path,
        );
        assert!(found, "world {k}: no path in 3000 iterations");
        let mut m = 0;
        c.shortcut(&mut ch, &w, &mut path, 200, || {
            m += 1;
            m <= 200
        });
        assert_eq!((path[0], *path.last().unwrap()), (start, goal));
        assert!(path.len() > 2, "world {k}: the straight motion is blocked");
        for s in path.windows(2) {
            let m = segment_min(&mut dense, &w, &s[0], &s[1]);
            assert!(m >= 0.0, "world {k}: a path segment has clearance {m} m");
        }
    }
}

#[test]
fn a_still_problem_blocked_straight_is_solved_clear_and_its_output_agrees() {
    // A sphere on the straight motion: the plan goes around it, clear at every millisecond, and
    // its waypoints are where the sampled trajectory is at their times.
    let lim = default_limits();
    let mut p = problem(START, TURNED, link4_on_straight(&lim, &TURNED, 0.5), 0.15);
    p.time_limit_s = 1.0;
    let sol = solve_default(&p);
    assert!(sol.solved, "{:?}", sol.why);
    assert!(sol.min_clearance_m.unwrap() >= 0.0);
    assert!(sol.path.len() > 2, "a detour");
    assert!(sol.first_solution_s.unwrap() <= sol.plan_time_s);
    assert!(sol.times_s.windows(2).all(|t| t[1] > t[0]));
    for (q, &t) in sol.path.iter().zip(&sol.times_s) {
        let row = sol.trajectory.iter().min_by(|a, b| (a[0] - t).abs().total_cmp(&(b[0] - t).abs())).unwrap();
        assert!((row[0] - t).abs() <= 0.005 + 1e-9);
        let err = (0..NJ).map(|j| (row[j + 1] - q[j]).abs()).fold(0.0, f64::max);
        assert!(err < 1e-3, "waypoint at {t} s off the trajectory by {err} rad");
    }
}

#[test]
fn a_goal_nearer_an_obstacle_than_half_the_sampling_delta_is_reached() {
    // A sphere 8 mm from link 4 of the arm at rest at the goal: a check's samples need δ/2 of
    // clearance (1.5 cm with the planner's 3 cm), so the problem gets a finer δ.
    let mut caps = [dkrrt_collision::PosedCapsule::default(); NJ];
    dkrrt_collision::ArmPoser::new(ArmModel::default_arm()).pose(&GOAL, &mut caps);
    let k = caps[4];
    let axis: [f64; 3] = std::array::from_fn(|i| k.b[i] - k.a[i]);
    let side = [axis[1] * 0.3 - axis[2] * 0.9, axis[2] * 0.1 - axis[0] * 0.3, axis[0] * 0.9 - axis[1] * 0.1];
    let n = side.iter().map(|v| v * v).sum::<f64>().sqrt();
    let at: [f64; 3] = std::array::from_fn(|i| k.centre[i] + side[i] / n * (k.r + 0.1 + 0.008));
    let p = problem(START, GOAL, at, 0.1);
    let mut ch = Checker::new(ArmModel::default_arm(), &default_limits().v_max, 0.03);
    ch.cap = 10.0;
    let c = ch.clearance_at(&p.world().unwrap(), &GOAL, 0.0, 0.0, f64::NEG_INFINITY);
    assert!((c - 0.008).abs() < 1e-6, "the goal's clearance {c}");
    let sol = solve_default(&p);
    assert!(sol.solved, "{:?}", sol.why);
    assert!(sol.min_clearance_m.unwrap() >= 0.0);
}

#[test]
fn a_step_into_an_obstacle_costs_one_sample() {
    // RRT-Connect checks a step's end first: a segment from a clear start that ends inside a
    // sphere is refused after one sample, not after the samples leading up to the sphere.
    let lim = default_limits();
    let l = *ArmModel::default_arm().limits();
    let w = problem(START, TURNED, link4_at(&TURNED), 0.2).world().unwrap();
    let mut ch = Checker::new(ArmModel::default_arm(), &lim.v_max, 0.03);
    let mut c = dkrrt_rrt::connect::Connect::new(l.q_min.into(), l.q_max.into(), lim.v_max, 10, 1);
    assert!(ch.clearance_at(&w, &START, 0.0, 0.0, f64::NEG_INFINITY) > 0.3);
    let before = ch.configs_checked;
    assert!(!c.segment_clear(&mut ch, &w, &START, &TURNED));
    assert_eq!(ch.configs_checked - before, 1, "one sample, at the end");
    // A clear segment is still sampled along its length (its end checked once more as part of
    // it), and a segment that enters the sphere and leaves it is still refused.
    let before = ch.configs_checked;
    let mut short = START;
    short[0] = 0.3;
    assert!(c.segment_clear(&mut ch, &w, &START, &short));
    assert!(ch.configs_checked - before > 2);
    let mut beyond = TURNED;
    beyond[0] = 1.6;
    assert!(ch.clearance_at(&w, &beyond, 0.0, 0.0, f64::NEG_INFINITY) > 0.015, "beyond the sphere, clear");
    assert!(!c.segment_clear(&mut ch, &w, &START, &beyond), "through the sphere");
}

#[test]
fn restarts_keep_the_earliest_arrival() {
    // A still problem restarts RRT-Connect until its time limit and keeps the earliest arrival:
    // never later than the first search's own path (shortcut and timed as `solve` does), which
    // is also the first search of `solve`, the same seed.
    let lim = default_limits();
    let mut p = problem(START, TURNED, link4_on_straight(&lim, &TURNED, 0.5), 0.15);
    p.time_limit_s = 0.5;
    let prep = problem::Prepared::new(&p, ArmModel::default_arm(), lim.v_max, lim.a_max, lim.j_max).unwrap();
    assert!(prep.still);
    let mut prep = prep;
    let mut c = prep.connect(20_000, p.seed);
    let mut path = Vec::new();
    let problem::Prepared { planner, world, .. } = &mut prep;
    assert!(c.solve(&mut planner.checker, world, &p.start, &p.goal, || true, &mut path));
    assert!(path.len() > 2, "the straight motion is blocked");
    c.shortcut(&mut planner.checker, world, &mut path, 200, || true);
    let mut out = Box::new(<Trajectory as Zeroed>::zeroed());
    prep.time_path(&path, &mut out).expect("timed");
    let first = out.duration_s;
    let sol = solve_default(&p);
    assert!(sol.solved, "{:?}", sol.why);
    assert!(
        sol.duration_s <= first + 1e-9,
        "{} s after restarts, {first} s the first search",
        sol.duration_s
    );
    // And the plan kept is checked like any other.
    let (ok, m) = prep.verify(&out);
    assert!(ok && m >= 0.0, "the first search's plan passes the final check ({m} m)");
}

#[test]
fn a_problem_holds_up_to_64_obstacles_and_sees_every_one() {
    // 63 obstacles far away and, last, a sphere on the straight motion: the plan goes around
    // the 64th as around a first one (none is dropped past the forecasts' 32).
    let lim = default_limits();
    let mut p = problem(START, TURNED, link4_on_straight(&lim, &TURNED, 0.5), 0.15);
    p.time_limit_s = 1.0;
    let blocker = p.obstacles.pop().unwrap();
    for k in 0..63 {
        let a = k as f64 * 0.1;
        let far = ProblemPose { t: 0.0, p: [30.0 * a.cos(), 30.0 * a.sin(), 0.0], q: [1.0, 0.0, 0.0, 0.0] };
        p.obstacles.push(ProblemObstacle { shape: ProblemShape::Sphere { radius: 0.2 }, poses: vec![far] });
    }
    p.obstacles.push(blocker);
    assert_eq!(p.obstacles.len(), 64);
    p.validate().unwrap();
    let sol = solve_default(&p);
    assert!(sol.solved, "{:?}", sol.why);
    assert!(sol.path.len() > 2, "a detour round the 64th obstacle");
    assert!(sol.min_clearance_m.unwrap() >= 0.0);
    // Without it, the direct motion.
    let mut free = p.clone();
    free.obstacles.pop();
    let sol = solve_default(&free);
    assert!(sol.solved && sol.path.len() == 2, "{:?}", sol.path.len());
    // A 65th is refused, naming the field.
    p.obstacles.push(p.obstacles[0].clone());
    let e = p.validate().unwrap_err().to_string();
    assert!(e.contains("obstacles") && e.contains("at most 64"), "{e}");
}

#[test]
fn a_checker_measures_all_64_tracks_when_all_are_near() {
    // 63 small spheres 0.5 m above link 4 (within the checker's 1 m cap: every one is
    // measured) and a 64th on link 4: the configuration is in collision. A checker holding
    // fewer obstacles than the world's tracks would drop the last and call it clear.
    let c = link4_at(&START);
    let pose = |p: [f64; 3]| TimedPose { t: 0.0, p, q: [1.0, 0.0, 0.0, 0.0], sigma: 0.0, sigma_pos: 0.0 };
    let mut w = WorldInTime::new(0.0);
    let above = [c[0], c[1], c[2] + 0.5];
    for k in 0..63 {
        w.push_track(k, dkrrt_msg::DebrisShape::sphere(0.01), &[pose(above)], After::Hold).unwrap();
    }
    let mut ch = Checker::new(ArmModel::default_arm(), &default_limits().v_max, 0.03);
    let near = ch.clearance_at(&w, &START, 0.0, 0.0, f64::NEG_INFINITY);
    assert!(near > 0.0 && near < ch.cap, "the 63 are near and clear: {near}");
    w.push_track(63, dkrrt_msg::DebrisShape::sphere(0.1), &[pose(c)], After::Hold).unwrap();
    assert_eq!(w.len(), 64);
    let with_last = ch.clearance_at(&w, &START, 0.0, 0.0, f64::NEG_INFINITY);
    assert!(with_last < 0.0, "the 64th is measured: {with_last}");
    // The world holds no more.
    assert!(w.push_track(64, dkrrt_msg::DebrisShape::sphere(0.1), &[pose(c)], After::Hold).is_err());
}

#[test]
fn an_unsolved_problem_says_when_resting_at_the_start_stops_being_clear() {
    // A 3 m ball sweeps through the arm's base (x from 12 m at t = 0 to 0 at 0.4 s, then to
    // −12 m at 0.8 s): the start is clear at t = 0 and the goal after the last pose, but no
    // arm can get out of the ball's way, and resting at the start is hit from about 0.2 s on.
    let mut p = problem(START, GOAL, [12.0, 0.0, 0.0], 3.0);
    let q = [1.0, 0.0, 0.0, 0.0];
    p.obstacles[0].poses.push(ProblemPose { t: 0.4, p: [0.0, 0.0, 0.0], q });
    p.obstacles[0].poses.push(ProblemPose { t: 0.8, p: [-12.0, 0.0, 0.0], q });
    let sol = solve_default(&p);
    assert!(!sol.solved);
    let why = sol.why.expect("a reason");
    let t: f64 = why
        .split("resting at the start is not clear from t = ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .and_then(|x| x.parse().ok())
        .unwrap_or_else(|| panic!("{why}"));
    // The ball's surface reaches the base at 0.3 s; the arm reaches out ~1 m towards it.
    assert!(t > 0.1 && t < 0.3, "{why}");
}

#[test]
fn a_problem_obstacle_is_at_its_first_pose_before_that_pose_time() {
    // A sphere on link 4 of the arm at the start, its first pose at t = 2 s, gone far away by
    // 4 s: the arm starts inside it (held at its first pose before 2 s), so the problem is
    // unsolvable and says why. Extended backwards instead, the sphere would be 9 m off at
    // t = 0 and the start clear.
    let c = link4_at(&START);
    let mut p = problem(START, GOAL, c, 0.2);
    p.obstacles[0].poses[0].t = 2.0;
    p.obstacles[0].poses.push(ProblemPose { t: 4.0, p: [c[0] + 9.0, c[1], c[2]], q: [1.0, 0.0, 0.0, 0.0] });
    let sol = solve_default(&p);
    assert!(!sol.solved);
    let why = sol.why.expect("a reason");
    assert!(why.contains("the start is in collision at t = 0"), "{why}");
    // Held at the first pose from t = 0 to 2 s, then moving off: the world says the same.
    let prep = dkrrt_rrt::problem::Prepared::new(
        &p,
        ArmModel::default_arm(),
        default_limits().v_max,
        default_limits().a_max,
        default_limits().j_max,
    )
    .unwrap();
    for t in [0.0, 1.0, 1.999] {
        assert_eq!(prep.world.pose_at(0, t).0, c, "at {t} s");
    }
    let (p3, ..) = prep.world.pose_at(0, 3.0);
    assert!((p3[0] - (c[0] + 4.5)).abs() < 1e-9, "{p3:?}");
}

#[test]
fn a_plan_as_early_as_the_direct_motion_ends_the_search() {
    // Nothing in the way (still, and moving): the direct motion is found and nothing can arrive
    // earlier, so the search stops there instead of running to the time limit. The same for
    // a goal equal to the start (a plan of no motion).
    let lim = default_limits();
    let direct = straight(&lim, &GOAL).duration();
    let mut still = problem(START, GOAL, [30.0, 0.0, 0.0], 0.2);
    still.time_limit_s = 5.0;
    let mut moving = still.clone();
    moving.obstacles[0].poses.push(ProblemPose { t: 1.0, p: [31.0, 0.0, 0.0], q: [1.0, 0.0, 0.0, 0.0] });
    for p in [&still, &moving] {
        let sol = solve_default(p);
        assert!(sol.solved, "{:?}", sol.why);
        assert!((sol.duration_s - direct).abs() < 1e-6, "{} vs {direct}", sol.duration_s);
        assert!(sol.plan_time_s < p.time_limit_s, "{} s", sol.plan_time_s);
    }
    let mut same = still.clone();
    same.goal = START;
    let sol = solve_default(&same);
    assert!(sol.solved && sol.duration_s == 0.0, "{:?} {}", sol.why, sol.duration_s);
    assert!(sol.plan_time_s < same.time_limit_s, "{} s", sol.plan_time_s);
    // Blocked: the search uses its time (an earlier arrival might still be found).
    let mut blocked = problem(START, TURNED, link4_on_straight(&lim, &TURNED, 0.5), 0.15);
    blocked.time_limit_s = 0.3;
    let sol = solve_default(&blocked);
    assert!(sol.solved && sol.plan_time_s >= blocked.time_limit_s, "{} s", sol.plan_time_s);
}

#[test]
fn a_fast_leg_over_before_a_motion_does_not_slow_its_check() {
    // An obstacle that comes in from 10⁶ m at 10⁶ m/s and stops 3 m off the arm at 1 s: a
    // bound on its speed over the whole of a motion made every sample after 1 s about
    // 3·10⁻⁸ s apart (a check of seconds: millions of samples). After its last pose it stands
    // still, and the check bounds its speed from where it samples: a few hundred samples.
    let mut p = problem(START, GOAL, [1e6, 0.5, 0.5], 0.1);
    p.obstacles[0].poses.push(ProblemPose { t: 1.0, p: [3.0, 0.5, 0.5], q: [1.0, 0.0, 0.0, 0.0] });
    p.time_limit_s = 5.0;
    let sol = solve_default(&p);
    assert!(sol.solved, "{:?}", sol.why);
    assert!(sol.configs_checked < 20_000, "{} configurations", sol.configs_checked);
}

#[test]
fn a_check_needing_more_samples_than_its_cap_is_not_clear() {
    // A sphere sweeping 2·10⁶ m back and forth past the arm (a few tenths of a metre from it)
    // every 0.1 s (2·10⁷ m/s).
    let c = link4_at(&START);
    let mut ch = Checker::new(ArmModel::default_arm(), &default_limits().v_max, 0.03);
    let pose = |p: [f64; 3]| TimedPose { t: 0.0, p, q: [1.0, 0.0, 0.0, 0.0], sigma: 0.0, sigma_pos: 0.0 };
    // The sweep's line, as a long capsule along x: its clearance from the arm.
    let dz = [0.4, 0.6, 0.8, 1.0, 1.2]
        .into_iter()
        .find(|dz| {
            let mut line = WorldInTime::new(0.0);
            let d = dkrrt_msg::DebrisShape::capsule(50.0, 0.05);
            let along_x = [std::f64::consts::FRAC_1_SQRT_2, 0.0, std::f64::consts::FRAC_1_SQRT_2, 0.0];
            let mut p = pose([c[0], c[1], c[2] + dz]);
            p.q = along_x;
            line.push_track(0, d, &[p], After::Hold).unwrap();
            let m = ch.clearance_at(&line, &START, 0.0, 0.0, f64::NEG_INFINITY);
            m > 0.05 && m < 0.9 * ch.cap
        })
        .expect("a sweep line near the arm and clear of it");
    let mut w = WorldInTime::new(0.0);
    let poses: Vec<TimedPose> = (0..50)
        .map(|k| {
            let x = if k % 2 == 0 { c[0] - 1e6 } else { c[0] + 1e6 };
            TimedPose { t: 0.1 * k as f64, ..pose([x, c[1], c[2] + dz]) }
        })
        .collect();
    w.push_track(0, dkrrt_msg::DebrisShape::sphere(0.05), &poses, After::Hold).unwrap();
    // Conservative advancement samples densely only around each pass: the rest is clear.
    let r = ch.check(&w, 0.0, 4.0, 10.0, false, |_| START);
    assert!(r.ok && r.samples > 200, "{r:?}");
    // With a cap below what it needs, the check gives up: not clear.
    ch.max_samples = 100;
    let r = ch.check(&w, 0.0, 4.0, 10.0, false, |_| START);
    assert!(!r.ok && r.samples == 100, "{r:?}");
    assert_eq!(ch.capped, 1, "counted");
    // A check past its wall-clock deadline (`dkrrt plan`'s time limit) ends at its next look
    // at it, not clear: a long rest (samples at most 0.5 s apart) stops after the first
    // stretch of samples, and without a deadline runs to its end.
    ch.max_samples = dkrrt_rrt::check::MAX_SAMPLES;
    ch.deadline = Some(std::time::Instant::now());
    let r = ch.check(&w, 0.0, 5000.0, 5000.0, false, |_| START);
    assert!(!r.ok && r.samples == dkrrt_rrt::check::DEADLINE_EVERY, "{r:?}");
    ch.deadline = None;
    let r = ch.check(&w, 0.0, 5000.0, 5000.0, false, |_| START);
    assert!(r.ok && r.samples > 2 * dkrrt_rrt::check::DEADLINE_EVERY, "{r:?}");
    assert_eq!(ch.capped, 1, "a deadline is not a cap");
}

/// The final check of `p`'s straight motion from `START` to `TURNED`: the prepared problem,
/// the timed motion, (passed, smallest clearance) and the configurations it measured.
fn verify_straight(p: &Problem) -> (problem::Prepared, Box<Trajectory>, (bool, f64), u64) {
    let lim = default_limits();
    let mut prep =
        problem::Prepared::new(p, ArmModel::default_arm(), lim.v_max, lim.a_max, lim.j_max).unwrap();
    let mut out = Box::new(<Trajectory as Zeroed>::zeroed());
    prep.time_path(&[START, TURNED], &mut out).expect("timed");
    let before = prep.planner.checker.configs_checked;
    let v = prep.verify(&out);
    let measured = prep.planner.checker.configs_checked - before;
    (prep, out, v, measured)
}

#[test]
fn the_final_check_finds_the_grid_minimum_measuring_few_points() {
    // Static clutter and obstacles sweeping through the arm's workspace: the final check's
    // smallest clearance is exactly the smallest of every millisecond measured. With obstacles
    // at ordinary speeds it measures a small part of those milliseconds; with a fast one it
    // measures more (its speed bounds every stretch it moves in), still exactly.
    use rand::{Rng, SeedableRng};
    let lim = default_limits();
    for (seed, fast) in (0..4).flat_map(|s| [(s, false), (s, true)]) {
        let mut rng = rand::rngs::SmallRng::seed_from_u64(100 + seed);
        let mut p = clutter(seed, 20);
        for k in 0..8 {
            let speed = if fast && k == 0 { 40.0 } else { rng.random_range(0.05..0.5) };
            let dir: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
            let n = dir.iter().map(|v| v * v).sum::<f64>().sqrt();
            let mid: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.5..1.5));
            let t_mid = rng.random_range(0.0..12.0);
            let pose = |t: f64| ProblemPose {
                t,
                p: std::array::from_fn(|i| mid[i] + dir[i] / n * speed * (t - t_mid)),
                q: [1.0, 0.0, 0.0, 0.0],
            };
            p.obstacles.push(ProblemObstacle {
                shape: ProblemShape::Capsule { half_length: 0.3, radius: 0.05 },
                poses: vec![pose(t_mid - 4.0), pose(t_mid), pose(t_mid + 6.0)],
            });
        }
        p.validate().unwrap();
        let (prep, out, (_, m), measured) = verify_straight(&p);
        let mut ch = Checker::new(ArmModel::default_arm(), &lim.v_max, 0.03);
        ch.cap = 100.0;
        let end = out.duration_s.max(prep.horizon) + 1.0;
        let last = (end / 1e-3 + 1e-9).floor() as u64;
        let every = (0..=last)
            .map(|k| {
                let t = (k as f64 * 1e-3).min(end);
                ch.clearance_at(&prep.world, &out.sample(t).p, t, 0.0, f64::NEG_INFINITY)
            })
            .fold(f64::INFINITY, f64::min);
        assert_eq!(
            m, every,
            "seed {seed} (fast {fast}): the final check's minimum against every millisecond's"
        );
        assert!(fast || measured * 4 < last, "seed {seed}: {measured} configurations for {last} ms");
    }
    // Nothing within the clearance cap (100 m) of the arm: the cap, from a few measurements
    // (its bound alone never prunes a stretch whose ends are both at the minimum).
    let (_, out, (ok, m), measured) = verify_straight(&problem(START, TURNED, [300.0, 0.0, 0.0], 0.2));
    assert!(ok && m == 100.0, "{m}");
    assert!(measured < 100, "{measured} configurations for {} s", out.duration_s);
}

#[test]
fn the_final_check_finds_a_joint_limit_crossed_between_its_milliseconds() {
    // Joint 0 rises to 0.1 mm past its upper limit at 1.5 ms and is back inside at 1 and 2 ms:
    // the final check sees it (a configuration outside the limits counts as clearance −1).
    let lim = default_limits();
    let p = problem(START, GOAL, [30.0, 0.0, 0.0], 0.2);
    let mut prep =
        problem::Prepared::new(&p, ArmModel::default_arm(), lim.v_max, lim.a_max, lim.j_max).unwrap();
    let q_max = ArmModel::default_arm().limits().q_max[0];
    let mut q = START;
    q[0] = q_max - 0.0004;
    let mut tr = Trajectory::hold(&q);
    tr.duration_s = 0.0025;
    tr.n_seg[0] = 2;
    tr.seg[0][1] = dkrrt_msg::JerkSegment { t0: 0.0005, p: q[0], v: 1.0, a: -1000.0, j: 0.0 };
    for ms in [0.0, 0.001, 0.002, 1.0] {
        let x = tr.sample(ms).p[0];
        assert!(x <= q_max, "inside at {ms} s ({x} against {q_max})");
    }
    assert!(tr.sample(0.0015).p[0] > q_max + 9e-5);
    assert_eq!(prep.verify(&tr).1, -1.0);
    // Kept 0.1 mm inside, the same motion passes with the obstacle's clearance.
    tr.seg[0][1].p -= 0.0002;
    let (_, m) = prep.verify(&tr);
    assert!(m > 20.0, "{m}");
}

#[test]
fn the_final_check_covers_the_rest_at_the_goal_until_the_obstacles_stop() {
    // A sphere passes 5–50 cm from the arm resting at its goal, 4 s after the straight
    // motion ends, and leaves again: the plan's clearance is that pass (the check once ended
    // 1 s past the motion, and reported the motion's own clearance, metres more).
    let lim = default_limits();
    let far = ProblemPose { t: 0.0, p: [30.0, 0.0, 0.0], q: [1.0, 0.0, 0.0, 0.0] };
    let mut p = problem(START, TURNED, [30.0, 0.0, 0.0], 0.2);
    let (_, out, (ok, m0), _) = verify_straight(&p);
    assert!(ok && m0 > 20.0, "{m0}");
    let end = out.duration_s;
    let mut caps = [dkrrt_collision::PosedCapsule::default(); NJ];
    dkrrt_collision::ArmPoser::new(ArmModel::default_arm()).pose(&TURNED, &mut caps);
    let c = caps[4];
    // A point beyond link 4's surface, away from the base's axis, where the sphere clears the
    // resting arm by 5–50 cm.
    let r = (c.centre[0].powi(2) + c.centre[1].powi(2)).sqrt();
    let mut ch = Checker::new(ArmModel::default_arm(), &lim.v_max, 0.03);
    let (prep, pass) = (1..40)
        .find_map(|k| {
            let d = c.r + 0.2 + 0.05 * k as f64;
            p.obstacles[0] = ProblemObstacle {
                shape: ProblemShape::Sphere { radius: 0.2 },
                poses: vec![
                    ProblemPose { t: end + 3.0, ..far },
                    ProblemPose {
                        t: end + 4.0,
                        p: [c.centre[0] * (1.0 + d / r), c.centre[1] * (1.0 + d / r), c.centre[2]],
                        q: [1.0, 0.0, 0.0, 0.0],
                    },
                    ProblemPose { t: end + 5.0, ..far },
                ],
            };
            let prep = verify_straight(&p).0;
            let pass = ch.clearance_at(&prep.world, &TURNED, end + 4.0, 0.0, f64::NEG_INFINITY);
            (0.05..0.5).contains(&pass).then_some((prep, pass))
        })
        .expect("a place for the pass");
    assert_eq!(prep.horizon, end + 5.0);
    let (_, _, (ok, m), _) = verify_straight(&p);
    assert!(ok && m <= pass + 1e-12, "the final check's clearance {m} against the pass's {pass}");
    // Closer than the sphere's radius: the plan fails its final check.
    p.obstacles[0].poses[1].p = c.centre;
    let (_, _, (ok, m), _) = verify_straight(&p);
    assert!(!ok && m < 0.0, "{m}");
}
