//! The replanning loop: splices at the exact state of the active plan, keeps a valid plan, never
//! publishes an unchecked plan, brakes when nothing is valid, allocates nothing per cycle.

use dkrrt_model::{ArmModel, NJ};
use dkrrt_msg::{ControllerMode, DebrisForecast, DebrisShape, Fallback, ForecastStep, Trajectory, Zeroed};
use dkrrt_otg::{KinState, Limits};
use dkrrt_rrt::*;
use dkrrt_rt::alloc_count::{count, CountingAlloc};

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc;

const START: [f64; NJ] = [0.0, -0.5, 1.0, 0.0, 0.5, 0.0];
const GOAL: [f64; NJ] = [0.35, -0.2, 0.7, 0.3, 0.2, 0.4];

fn limits() -> Limits<NJ> {
    Limits {
        v_max: [0.1, 0.1, 0.1, 0.18, 0.18, 0.18],
        a_max: [0.2, 0.2, 0.2, 0.4, 0.4, 0.4],
        j_max: [1.0, 1.0, 1.0, 2.0, 2.0, 2.0],
    }
}

fn replanner() -> Replanner {
    let rc = ReplanConfig { forecast_wait_s: 0.0, ..ReplanConfig::default() };
    Replanner::new(ArmModel::default_arm(), limits(), PlannerConfig::default(), rc, true)
}

/// A forecast of one sphere at `p` (static) from plant time `t0_ns`.
fn forecast(t0_ns: u64, p: [f64; 3], r: f64) -> Box<DebrisForecast> {
    let mut f = Box::new(<DebrisForecast as Zeroed>::zeroed());
    f.count = 1;
    f.steps = 40;
    f.dt_s = 0.1;
    f.t0_ns = t0_ns;
    f.tracks[0].id = 3;
    f.tracks[0].bounding_radius = r;
    f.tracks[0].shape = DebrisShape::sphere(r);
    for k in 0..40 {
        f.tracks[0].steps[k] = ForecastStep { p, q: [1.0, 0.0, 0.0, 0.0], sigma_m: 0.01, sigma_pos_m: 0.01 };
    }
    f
}

/// The first cycle, at plant time 0 with the debris far away: the free plan from START to GOAL.
fn first_free_plan(rp: &mut Replanner, clk: &mut impl FnMut() -> u64, out: &mut Trajectory) -> Trajectory {
    let idle = TrackerView { mode: ControllerMode::Idle, traj_id: 0 };
    let far = forecast(0, [50.0, 0.0, 0.0], 0.2);
    assert!(rp.step(0, &START, idle, Some(&far), &GOAL, clk, out).publish);
    *out
}

fn clock() -> impl FnMut() -> u64 {
    let mut t = 0u64;
    move || {
        t += 1000;
        t
    }
}

#[test]
fn a_new_plan_continues_the_active_one_exactly_at_the_commit_time() {
    let mut rp = replanner();
    let mut out = Box::new(<Trajectory as Zeroed>::zeroed());
    let mut clk = clock();
    let far = forecast(0, [50.0, 0.0, 0.0], 0.2);
    let idle = TrackerView { mode: ControllerMode::Idle, traj_id: 0 };
    let d = rp.step(0, &START, idle, Some(&far), &GOAL, &mut clk, &mut out);
    assert!(d.publish);
    assert_eq!(d.status.fallback, Fallback::None as u32);
    let first = *out;
    assert_eq!(first.start_ns, 60_000_000, "plans start at now + commit");
    // 2 s later, mid-motion, an obstacle appears on the rest of the path: replan.
    let now = 2_000_000_000u64;
    let q_now = first.sample(first.time_of(now)).p;
    let mut blocked = forecast(now, [0.0; 3], 0.05);
    {
        // Put the sphere on the arm's path a little later.
        let later = first.sample(first.time_of(now + 3_500_000_000)).p;
        let poser = dkrrt_collision::ArmPoser::new(ArmModel::default_arm());
        let mut caps = [dkrrt_collision::PosedCapsule::default(); NJ];
        poser.pose(&later, &mut caps);
        for s in blocked.tracks[0].steps.iter_mut() {
            s.p = caps[5].centre;
        }
    }
    let track = TrackerView { mode: ControllerMode::Track, traj_id: first.traj_id };
    let d = rp.step(now, &q_now, track, Some(&blocked), &GOAL, &mut clk, &mut out);
    assert!(d.publish, "{:?}", d.status);
    assert_eq!(d.status.fallback, Fallback::None as u32, "{:?}", d.status);
    let second = *out;
    assert!(second.traj_id > first.traj_id);
    assert_eq!(second.start_ns, now + 60_000_000);
    // Exact splice: p, v, a of the new plan at its start = the old plan's at that instant.
    let a = first.sample(first.time_of(second.start_ns));
    let b = second.sample(0.0);
    for j in 0..NJ {
        assert!((a.p[j] - b.p[j]).abs() < 1e-12, "p[{j}]");
        assert!((a.v[j] - b.v[j]).abs() < 1e-12, "v[{j}]");
        assert!((a.a[j] - b.a[j]).abs() < 1e-12, "a[{j}]");
    }
    // Whatever was published was checked against the forecast it was planned on.
    let mut p = Planner::new(ArmModel::default_arm(), limits(), PlannerConfig::default());
    let mut w = WorldInTime::new(0.05);
    w.load_forecast(&blocked);
    let t0 = second.start_ns as f64 * 1e-9;
    assert!(check_message(&mut p, &w, &second, t0, t0 + 5.0).0);
}

/// With debris expected and no bound on the wait (the planner on a pose sensor), no motion is
/// published before a forecast comes, however long that takes (a predictor that never comes
/// leaves the arm at rest); an empty forecast (the predictor's word that the sky is empty) is
/// a forecast: the free plan follows at once. Each waiting cycle is counted.
#[test]
fn no_motion_before_a_forecast_and_an_empty_one_lets_the_arm_go() {
    let rc = ReplanConfig { forecast_wait_s: f64::INFINITY, ..ReplanConfig::default() };
    let mut rp = Replanner::new(ArmModel::default_arm(), limits(), PlannerConfig::default(), rc, true);
    let mut out = Box::new(<Trajectory as Zeroed>::zeroed());
    let mut clk = clock();
    let idle = TrackerView { mode: ControllerMode::Idle, traj_id: 0 };
    for k in 0..600u64 {
        let d = rp.step(k * 100_000_000, &START, idle, None, &GOAL, &mut clk, &mut out);
        assert!(!d.publish, "a motion before any forecast, at {} s", k as f64 * 0.1);
    }
    assert_eq!(rp.summary("dk-rrt").cycles_waiting_for_forecast, 600);
    let mut empty = Box::new(<DebrisForecast as Zeroed>::zeroed());
    (empty.steps, empty.dt_s, empty.t0_ns) = (40, 0.1, 60_000_000_000);
    let d = rp.step(60_000_000_000, &START, idle, Some(&empty), &GOAL, &mut clk, &mut out);
    assert!(d.publish, "the empty sky's forecast lets the free plan go");
    assert_eq!(rp.summary("dk-rrt").cycles_waiting_for_forecast, 600);
    // A bounded wait, if one is configured: after it, the arm moves on what it has.
    let rc = ReplanConfig { forecast_wait_s: 2.0, ..ReplanConfig::default() };
    let mut rp = Replanner::new(ArmModel::default_arm(), limits(), PlannerConfig::default(), rc, true);
    let moved =
        (0..30u64).find(|k| rp.step(k * 100_000_000, &START, idle, None, &GOAL, &mut clk, &mut out).publish);
    assert_eq!(moved, Some(20), "from 2 s on");
}

#[test]
fn a_valid_plan_is_kept_and_nothing_valid_means_a_brake_never_an_unchecked_plan() {
    let mut rp = replanner();
    let mut out = Box::new(<Trajectory as Zeroed>::zeroed());
    let mut clk = clock();
    let far = forecast(0, [50.0, 0.0, 0.0], 0.2);
    let d = rp.step(
        0,
        &START,
        TrackerView { mode: ControllerMode::Idle, traj_id: 0 },
        Some(&far),
        &GOAL,
        &mut clk,
        &mut out,
    );
    assert!(d.publish);
    let first = *out;
    let track = TrackerView { mode: ControllerMode::Track, traj_id: first.traj_id };
    // Nothing changed: kept, nothing published.
    let now = 1_000_000_000u64;
    let q_now = first.sample(first.time_of(now)).p;
    let d = rp.step(now, &q_now, track, Some(&far), &GOAL, &mut clk, &mut out);
    assert!(!d.publish);
    assert_eq!(rp.current().traj_id, first.traj_id);
    // A sphere swallowing the whole arm: no plan, the current is invalid → a brake from the
    // commit state, which decelerates to rest.
    let now = 2_000_000_000u64;
    let q_now = first.sample(first.time_of(now)).p;
    let huge = forecast(now, [0.5, 0.5, 0.5], 6.0);
    let d = rp.step(now, &q_now, track, Some(&huge), &GOAL, &mut clk, &mut out);
    assert!(d.publish);
    assert_eq!(d.status.fallback, Fallback::Brake as u32);
    assert_eq!(rp.stats.fallbacks.brake, 1);
    let brake = *out;
    let s0 = brake.sample(0.0);
    let a = first.sample(first.time_of(brake.start_ns));
    for j in 0..NJ {
        assert!((a.v[j] - s0.v[j]).abs() < 1e-12 && (a.p[j] - s0.p[j]).abs() < 1e-12);
    }
    let end = brake.sample(brake.duration_s);
    assert!(end.v.iter().all(|v| v.abs() < 1e-9) && end.a.iter().all(|a| a.abs() < 1e-9));
    assert!(brake.duration_s < 2.0);
    // At rest with nothing valid: hold (nothing published), counted.
    let view = TrackerView { mode: ControllerMode::Hold, traj_id: 0 };
    let d = rp.step(now + 3_000_000_000, &end.p, view, Some(&huge), &GOAL, &mut clk, &mut out);
    assert!(!d.publish);
    assert_eq!(d.status.fallback, Fallback::Brake as u32);
}

#[test]
fn a_planning_cycle_allocates_nothing_after_warm_up() {
    let mut rp = replanner();
    let mut out = Box::new(<Trajectory as Zeroed>::zeroed());
    let mut clk = clock();
    let near = forecast(0, [1.5, 1.0, 0.8], 0.3);
    let idle = TrackerView { mode: ControllerMode::Idle, traj_id: 0 };
    rp.step(0, &START, idle, Some(&near), &GOAL, &mut clk, &mut out);
    let (_, st) = count(|| {
        for k in 1..40u64 {
            // Each cycle plans from rest again (the tracker is idle), with a new forecast.
            let f = &near;
            rp.step(k * 100_000_000, &START, idle, Some(f), &GOAL, &mut clk, &mut out);
        }
        // The last resort (a dodge) evaluates its candidates on the same preallocated state.
        let req = Request { start: KinState::rest(START), t0: 4.0, goal: GOAL };
        let Replanner { planner, world, .. } = &mut rp;
        planner.dodge(&req, world, 99, || true, &mut out);
    });
    assert!(rp.stats.cycles >= 40);
    assert_eq!((st.allocs, st.reallocs), (0, 0), "{st:?}");
}

/// A sphere swallowing the whole arm that arrives from far away at `arrive_s` after `t0_ns`
/// (20 m/s along x).
fn arriving(t0_ns: u64, arrive_s: f64) -> Box<DebrisForecast> {
    let mut f = forecast(t0_ns, [0.5, 0.5, 0.5], 6.0);
    for k in 0..40 {
        let t = 0.1 * (k + 1) as f64;
        f.tracks[0].steps[k].p = [0.5 + 20.0 * (arrive_s - t), 0.5, 0.5];
    }
    f
}

#[test]
fn a_far_conflict_keeps_the_moving_plan_a_near_one_brakes() {
    let rc = ReplanConfig { forecast_wait_s: 0.0, iterations: 20, ..ReplanConfig::default() };
    let mut rp = Replanner::new(ArmModel::default_arm(), limits(), PlannerConfig::default(), rc, true);
    let mut out = Box::new(<Trajectory as Zeroed>::zeroed());
    let mut clk = clock();
    let far = forecast(0, [50.0, 0.0, 0.0], 0.2);
    let idle = TrackerView { mode: ControllerMode::Idle, traj_id: 0 };
    assert!(rp.step(0, &START, idle, Some(&far), &GOAL, &mut clk, &mut out).publish);
    let first = *out;
    let track = TrackerView { mode: ControllerMode::Track, traj_id: first.traj_id };
    // 1 s in, moving: the arm will be swallowed ~3.4 s from now (beyond `move_react_s` = 3 s)
    // whatever it does: the plan is kept (no plan, clean or not, is found) and nothing is
    // published.
    let now = 1_000_000_000u64;
    let q_now = first.sample(first.time_of(now)).p;
    let d = rp.step(now, &q_now, track, Some(&arriving(now, 3.8)), &GOAL, &mut clk, &mut out);
    assert!(!d.publish, "{:?}", d.status);
    assert_eq!(d.status.fallback, Fallback::Keep as u32, "{:?}", d.status);
    assert!(d.status.min_predicted_clearance_m < 0.0, "the conflict is reported: {:?}", d.status);
    assert_eq!(rp.current().traj_id, first.traj_id);
    // 1 s later the same object is ~2.4 s away: inside the reaction time → brake.
    let now = 2_000_000_000u64;
    let q_now = first.sample(first.time_of(now)).p;
    let d = rp.step(now, &q_now, track, Some(&arriving(now, 2.8)), &GOAL, &mut clk, &mut out);
    assert!(d.publish, "{:?}", d.status);
    assert_eq!(d.status.fallback, Fallback::Brake as u32, "{:?}", d.status);
}

#[test]
fn a_pose_goal_becomes_the_clear_ik_solution_nearest_the_arm() {
    use dkrrt_model::JVec;
    let model = ArmModel::default_arm();
    let t = model.fk(&JVec::from_row_slice(&GOAL));
    let p = [t.translation.x, t.translation.y, t.translation.z];
    let r = t.rotation;
    let q = [r.w, r.i, r.j, r.k];
    let sols = dkrrt_rrt::goal::ik_solutions(&model, &p, &q, &[START]);
    assert!(!sols.is_empty());
    for s in &sols {
        let f = model.fk(&JVec::from_row_slice(s));
        assert!((f.translation.vector - t.translation.vector).norm() < 1e-4, "{s:?}");
        assert!(f.rotation.angle_to(&t.rotation) < 1e-4);
        assert!(model.limits().contains(&JVec::from_row_slice(s)));
    }
    // Nearest to the arm when all are clear; another (or the clearest) when that one is not.
    let dist = |a: &[f64; NJ]| (0..NJ).map(|j| (a[j] - START[j]).abs()).fold(0.0, f64::max);
    let near = dkrrt_rrt::goal::choose(&sols, &START, |_| 1.0).unwrap();
    assert!(sols.iter().all(|s| dist(s) >= dist(&near)));
    let other = dkrrt_rrt::goal::choose(&sols, &START, |c| if *c == near { -0.5 } else { 0.2 }).unwrap();
    assert!(sols.len() == 1 || other != near);
    // Out of reach: no solution.
    assert!(dkrrt_rrt::goal::ik_solutions(&model, &[10.0, 0.0, 0.0], &q, &[START]).is_empty());
    // Through the replanning core, against a forecast: the chosen goal reaches the pose and
    // is clear of the debris.
    let mut rp = replanner();
    let mut out = Box::new(<Trajectory as Zeroed>::zeroed());
    let mut clk = clock();
    let far = forecast(0, [50.0, 0.0, 0.0], 0.2);
    let idle = TrackerView { mode: ControllerMode::Idle, traj_id: 0 };
    rp.step(0, &START, idle, Some(&far), &GOAL, &mut clk, &mut out);
    let g = rp.resolve_pose_goal(&p, &q, &START, 0.0).unwrap();
    let f = model.fk(&JVec::from_row_slice(&g));
    assert!((f.translation.vector - t.translation.vector).norm() < 1e-4);
    assert!(rp.resolve_pose_goal(&[10.0, 0.0, 0.0], &q, &START, 0.0).is_none());
}

#[test]
fn a_far_conflict_is_not_traded_for_a_later_arrival() {
    // A small fast object crosses the end effector's path 3.3 s from now (beyond the 3 s
    // reaction time) and is gone 0.3 s later. A clean plan exists (wait, then go) but arrives
    // later: with `keep_earlier_arrival` the moving plan is kept; without, it is replaced.
    let run = |keep: bool| {
        let rc = ReplanConfig {
            forecast_wait_s: 0.0,
            iterations: 300,
            keep_earlier_arrival: keep,
            ..ReplanConfig::default()
        };
        let mut rp = Replanner::new(ArmModel::default_arm(), limits(), PlannerConfig::default(), rc, true);
        let mut out = Box::new(<Trajectory as Zeroed>::zeroed());
        let mut clk = clock();
        let idle = TrackerView { mode: ControllerMode::Idle, traj_id: 0 };
        assert!(
            rp.step(0, &START, idle, Some(&forecast(0, [50.0, 0.0, 0.0], 0.05)), &GOAL, &mut clk, &mut out)
                .publish
        );
        let first = *out;
        let arrival = first.start_ns as f64 * 1e-9 + first.duration_s;
        let now = 300_000_000u64;
        let t_x = 3.6;
        assert!(arrival > t_x + 0.5, "the plan is still moving at the crossing ({arrival} s)");
        // The end effector's point at the crossing time, and a path through it that keeps
        // away from the base (horizontal, perpendicular to the radial direction).
        let poser = dkrrt_collision::ArmPoser::new(ArmModel::default_arm());
        let mut caps = [dkrrt_collision::PosedCapsule::default(); NJ];
        poser.pose(&first.sample(first.time_of((t_x * 1e9) as u64)).p, &mut caps);
        let e = caps[NJ - 1].b;
        let h = (e[0] * e[0] + e[1] * e[1]).sqrt();
        let u = [-e[1] / h, e[0] / h, 0.0];
        let mut f = forecast(now, e, 0.05);
        for k in 0..40 {
            let t = 0.3 + 0.1 * (k + 1) as f64 - t_x;
            f.tracks[0].steps[k].p = [e[0] + 2.0 * u[0] * t, e[1] + 2.0 * u[1] * t, e[2]];
        }
        let track = TrackerView { mode: ControllerMode::Track, traj_id: first.traj_id };
        let q_now = first.sample(first.time_of(now)).p;
        let d = rp.step(now, &q_now, track, Some(&f), &GOAL, &mut clk, &mut out);
        let new_arrival = rp.current().start_ns as f64 * 1e-9 + rp.current().duration_s;
        (d, first.traj_id, rp.current().traj_id, arrival, new_arrival)
    };
    // Without the rule: the conflict is seen, and a clean plan that arrives later replaces it.
    let (d, first, cur, arrival, new_arrival) = run(false);
    assert!(d.publish && cur != first, "{:?}", d.status);
    assert!(new_arrival > arrival, "{new_arrival} vs {arrival}");
    // With it: the moving plan is kept (its conflict is reported), nothing is published.
    let (d, first, cur, _, _) = run(true);
    assert!(!d.publish && cur == first, "{:?}", d.status);
    assert_eq!(d.status.fallback, Fallback::Keep as u32, "{:?}", d.status);
    assert!(d.status.min_predicted_clearance_m < 0.0, "{:?}", d.status);
}

/// A sphere of radius `r` at `c` until plant time `leave_s`, then leaving upwards at 3 m/s
/// (a forecast issued at `t0_ns`).
fn blocking_until(t0_ns: u64, c: [f64; 3], r: f64, leave_s: f64) -> Box<DebrisForecast> {
    let mut f = forecast(t0_ns, c, r);
    for k in 0..40 {
        let t = t0_ns as f64 * 1e-9 + 0.1 * (k + 1) as f64;
        f.tracks[0].steps[k].p[2] = c[2] + 3.0 * (t - leave_s).max(0.0);
    }
    f
}

#[test]
fn a_kept_clean_plan_gives_way_to_an_earlier_arrival_as_the_forecast_clears() {
    // Where the unobstructed motion puts the end effector 70 % of the way.
    let mut probe = replanner();
    let mut out = Box::new(<Trajectory as Zeroed>::zeroed());
    first_free_plan(&mut probe, &mut clock(), &mut out);
    let idle = TrackerView { mode: ControllerMode::Idle, traj_id: 0 };
    let free_arrival = out.start_ns as f64 * 1e-9 + out.duration_s;
    let poser = dkrrt_collision::ArmPoser::new(ArmModel::default_arm());
    let mut caps = [dkrrt_collision::PosedCapsule::default(); NJ];
    poser.pose(&out.sample(0.7 * out.duration_s).p, &mut caps);
    let c = caps[NJ - 1].b;

    let run = |gain: f64| {
        let rc = ReplanConfig {
            forecast_wait_s: 0.0,
            improve_gain_s: gain,
            improve_every: 1,
            ..ReplanConfig::default()
        };
        let mut rp = Replanner::new(ArmModel::default_arm(), limits(), PlannerConfig::default(), rc, true);
        let mut out = Box::new(<Trajectory as Zeroed>::zeroed());
        let mut clk = clock();
        // The first forecast: the object stays on the path until 6 s. The plan goes round it
        // or waits for it: it arrives late.
        let d = rp.step(0, &START, idle, Some(&blocking_until(0, c, 0.08, 6.0)), &GOAL, &mut clk, &mut out);
        assert!(d.publish && d.status.fallback == Fallback::None as u32, "{:?}", d.status);
        let first = *out;
        let late = first.start_ns as f64 * 1e-9 + first.duration_s;
        // A newer forecast: it leaves at 0.5 s. The plan is still clean (nothing to react to).
        let now = 200_000_000u64;
        let q_now = first.sample(first.time_of(now)).p;
        let track = TrackerView { mode: ControllerMode::Track, traj_id: first.traj_id };
        let d =
            rp.step(now, &q_now, track, Some(&blocking_until(now, c, 0.08, 0.5)), &GOAL, &mut clk, &mut out);
        let arrival = rp.current().start_ns as f64 * 1e-9 + rp.current().duration_s;
        (d, first.traj_id, rp.current().traj_id, late, arrival, rp.stats.fallbacks)
    };
    // Improving: the clean plan is traded for one that arrives clearly earlier, and the trade
    // is no fallback.
    let (d, first, cur, late, arrival, fb) = run(0.1);
    assert!(late > free_arrival + 0.5, "the first plan is slowed by the object: {late} vs {free_arrival}");
    assert!(d.publish && cur != first, "{:?}", d.status);
    assert!(arrival < late - 0.1, "{arrival} vs {late}");
    assert_eq!(d.status.fallback, Fallback::None as u32);
    assert_eq!(fb, Fallbacks::default());
    // Off: the clean plan is kept, nothing is published.
    let (d, first, cur, late, arrival, fb) = run(-1.0);
    assert_eq!(arrival, late);
    assert!(!d.publish && cur == first, "{:?}", d.status);
    assert_eq!(fb, Fallbacks::default());
}

/// The end effector's position (link 6 capsule centre) at `q`.
fn ee_at(q: &[f64; NJ]) -> [f64; 3] {
    let poser = dkrrt_collision::ArmPoser::new(ArmModel::default_arm());
    let mut caps = [dkrrt_collision::PosedCapsule::default(); NJ];
    poser.pose(q, &mut caps);
    caps[NJ - 1].centre
}

/// Track `k` of `f`: a sphere of radius `r` that comes in radially from outside the arm at
/// 3 m/s and sits at `c` from plant time `arrive_s` on.
fn sit_from(f: &mut DebrisForecast, k: usize, c: [f64; 3], r: f64, arrive_s: f64) {
    let h = (c[0] * c[0] + c[1] * c[1]).sqrt();
    let u = [c[0] / h, c[1] / h, 0.0];
    let t0 = f.t0_ns as f64 * 1e-9;
    f.count = f.count.max(k as u32 + 1);
    f.tracks[k].id = 10 + k as u32;
    f.tracks[k].bounding_radius = r;
    f.tracks[k].shape = DebrisShape::sphere(r);
    for i in 0..40 {
        let d = 3.0 * (arrive_s - (t0 + 0.1 * (i + 1) as f64)).max(0.0);
        let p = [c[0] + d * u[0], c[1] + d * u[1], c[2]];
        f.tracks[k].steps[i] = ForecastStep { p, q: [1.0, 0.0, 0.0, 0.0], sigma_m: 0.01, sigma_pos_m: 0.01 };
    }
}

#[test]
fn a_plan_kept_with_a_far_conflict_gives_way_to_its_known_escape_when_none_is_found_any_more() {
    // Moving on its plan, the arm learns of two objects arriving 3.3 s from now (beyond the
    // 3 s reaction time): one where the plan will be, one where braking would stop it. The
    // plan is kept while an escape from it is known; when a cycle finds none (here: a budget
    // of 0 iterations leaves only the brake and the direct motion, both blocked), the escape
    // found the cycle before is published, spliced in at its start.
    let run = |first_budget: u32| {
        let mut rp = replanner();
        let mut out = Box::new(<Trajectory as Zeroed>::zeroed());
        let mut clk = clock();
        let plan = first_free_plan(&mut rp, &mut clk, &mut out);
        let track = TrackerView { mode: ControllerMode::Track, traj_id: plan.traj_id };
        let now1 = 300_000_000u64;
        let t_arr = now1 as f64 * 1e-9 + 3.3;
        let world = |now: u64| {
            let mut f = forecast(now, [50.0, 0.0, 0.0], 0.05);
            // Where the plan will be just after the arrival, and where a brake started at
            // this cycle's or the next one's commit time stops.
            let later = plan.sample(plan.time_of(((t_arr + 0.4) * 1e9) as u64)).p;
            sit_from(&mut f, 1, ee_at(&later), 0.12, t_arr);
            let at = plan.sample(plan.time_of(now1 + 160_000_000));
            let lim = limits();
            let stop = dkrrt_otg::Trajectory::calculate_velocity(
                &dkrrt_otg::KinState { p: at.p, v: at.v, a: at.a },
                &[0.0; NJ],
                &[0.0; NJ],
                &lim,
                &dkrrt_otg::Options::default(),
            )
            .unwrap()
            .final_state()
            .p;
            sit_from(&mut f, 2, ee_at(&stop), 0.2, t_arr);
            f
        };
        rp.cfg.iterations = first_budget;
        let q1 = plan.sample(plan.time_of(now1)).p;
        let d1 = rp.step(now1, &q1, track, Some(&world(now1)), &GOAL, &mut clk, &mut out);
        rp.cfg.iterations = 0;
        let now2 = now1 + 100_000_000;
        let q2 = plan.sample(plan.time_of(now2)).p;
        let f2 = world(now2);
        let d2 = rp.step(now2, &q2, track, Some(&f2), &GOAL, &mut clk, &mut out);
        (rp, plan, d1, d2, *out, f2)
    };
    // With a search in the first cycle: an escape is known there, so the plan is kept...
    let (mut rp, plan, d1, d2, out, _) = run(300);
    assert!(!d1.publish, "{:?}", d1.status);
    assert_eq!(d1.status.fallback, Fallback::Keep as u32, "{:?}", d1.status);
    assert!(d1.status.min_predicted_clearance_m < 0.0, "the conflict is seen: {:?}", d1.status);
    // ...and when the next cycle finds none, that escape goes out: at the next commit time
    // of the first cycle, continuing the plan exactly, clean against the forecast.
    assert!(d2.publish, "{:?}", d2.status);
    assert_eq!(d2.status.fallback, Fallback::Escape as u32, "{:?}", d2.status);
    assert_eq!(rp.current().traj_id, out.traj_id);
    assert_ne!(out.traj_id, plan.traj_id);
    assert_eq!(out.start_ns, 300_000_000 + 60_000_000 + 100_000_000);
    let (a, b) = (plan.sample(plan.time_of(out.start_ns)), out.sample(0.0));
    for j in 0..NJ {
        assert!(
            (a.p[j] - b.p[j]).abs() < 1e-9
                && (a.v[j] - b.v[j]).abs() < 1e-9
                && (a.a[j] - b.a[j]).abs() < 1e-9
        );
    }
    let t0 = out.start_ns as f64 * 1e-9;
    assert!(check_message(&mut rp.planner, &rp.world, &out, t0, t0 + 5.0).0);
    assert_eq!(rp.stats.fallbacks.escape, 1);
    // Without an escape found in the first cycle, the second has nothing to give way to: the
    // plan is kept (the trap this guards against).
    let (_, plan, _, d2, _, f2) = run(0);
    assert!(!d2.publish, "{:?}", d2.status);
    assert_eq!(d2.status.fallback, Fallback::Keep as u32, "{:?}", d2.status);
    // The conflict is real: the plan is not clean against that forecast.
    let mut probe = replanner();
    let mut o = Box::new(<Trajectory as Zeroed>::zeroed());
    probe.step(
        400_000_000,
        &START,
        TrackerView { mode: ControllerMode::Idle, traj_id: 0 },
        Some(&f2),
        &GOAL,
        &mut clock(),
        &mut o,
    );
    assert!(!check_message(&mut probe.planner, &probe.world, &plan, 0.5, 5.4).0);
}

#[test]
fn reachable_pose_goals_get_an_ik_solution() {
    // Poses of random in-limit configurations, from a random arm configuration: with 12
    // seeded starts 1.6–2.1 % of them got no solution (taken for out of reach), most near a
    // joint limit; with 64, 2 of 6 000 (three draws of 2 000).
    use dkrrt_model::JVec;
    use rand::{Rng, SeedableRng};
    let model = ArmModel::default_arm();
    let l = *model.limits();
    let mut rng = rand::rngs::SmallRng::seed_from_u64(41);
    let mut none = 0;
    for _ in 0..400 {
        let mut draw = || -> [f64; NJ] { std::array::from_fn(|i| rng.random_range(l.q_min[i]..l.q_max[i])) };
        let (aim, now) = (draw(), draw());
        let t = model.fk(&JVec::from_row_slice(&aim));
        let r = t.rotation;
        let sols = dkrrt_rrt::goal::ik_solutions(
            &model,
            &[t.translation.x, t.translation.y, t.translation.z],
            &[r.w, r.i, r.j, r.k],
            &[now],
        );
        none += usize::from(sols.is_empty());
    }
    assert!(none <= 1, "{none} of 400 reachable poses without a solution");
}

/// A forecast that breaks the message contract (here a NaN attitude, as the predictor once
/// published for a rod whose axis channel had restarted) is refused by the core, counted and
/// named, and the last one stays in force: the lockstep, which has no bus to check its
/// forecasts, refuses what the process set's bus refuses.
#[test]
fn a_forecast_breaking_the_contract_is_refused_by_the_core_and_the_last_one_kept() {
    let mut rp = replanner();
    rp.set_contract(dkrrt_msg::ContractLimits::symmetric(10.0, 10.0, 1e3));
    let mut out = Box::new(<Trajectory as Zeroed>::zeroed());
    let mut clk = clock();
    let idle = TrackerView { mode: ControllerMode::Idle, traj_id: 0 };
    let on_arm = forecast(0, ee_at(&START), 0.2);
    rp.step(0, &START, idle, Some(&on_arm), &GOAL, &mut clk, &mut out);
    assert!(rp.predicted_clearance(&START, 0.1).unwrap() < 0.0);
    // The object said to be 50 m away, one step's attitude NaN: refused.
    let mut bad = forecast(100_000_000, [50.0, 0.0, 0.0], 0.2);
    bad.tracks[0].steps[7].q[0] = f64::NAN;
    rp.step(100_000_000, &START, idle, Some(&bad), &GOAL, &mut clk, &mut out);
    let s = rp.summary("dk-rrt");
    assert_eq!((s.forecasts_invalid, s.forecasts_ahead), (1, 0));
    let why = s.forecast_error.expect("the reason");
    assert!(why.contains("dkrrt/debris_forecast") && why.contains("tracks.steps.q"), "{why}");
    assert!(rp.predicted_clearance(&START, 0.2).unwrap() < 0.0, "the last forecast is in force");
    // The same forecast, whole: taken.
    let good = forecast(200_000_000, [50.0, 0.0, 0.0], 0.2);
    rp.step(200_000_000, &START, idle, Some(&good), &GOAL, &mut clk, &mut out);
    assert_eq!(rp.summary("dk-rrt").forecasts_invalid, 1);
    assert!(rp.predicted_clearance(&START, 0.3).unwrap() > 0.0, "the new forecast is in force");
}

/// A forecast stamped far ahead of the cycle's plant time would be read backwards from its
/// first step: its objects placed where they were long before, away from the arm. It is
/// refused and counted, and the forecast the planner had stays in force: the arm does not
/// move into the object it knows about.
#[test]
fn a_forecast_stamped_ahead_of_the_plant_clock_is_refused_and_the_last_one_kept() {
    use dkrrt_rrt::replan::FORECAST_LEAD_S;
    let mut rp = replanner();
    let mut out = Box::new(<Trajectory as Zeroed>::zeroed());
    let mut clk = clock();
    let idle = TrackerView { mode: ControllerMode::Idle, traj_id: 0 };
    // A sphere sitting on the arm at START: nothing clean; the arm stays.
    let on_arm = forecast(0, ee_at(&START), 0.2);
    rp.step(0, &START, idle, Some(&on_arm), &GOAL, &mut clk, &mut out);
    let before = rp.predicted_clearance(&START, 0.1).unwrap();
    assert!(before < 0.0, "{before}");
    // The same object, said to be 50 m away, from a forecast stamped 100 s ahead: refused.
    let ahead = forecast(100_000_000_000, [50.0, 0.0, 0.0], 0.2);
    rp.step(100_000_000, &START, idle, Some(&ahead), &GOAL, &mut clk, &mut out);
    assert_eq!(rp.summary("dk-rrt").forecasts_ahead, 1);
    assert!(rp.predicted_clearance(&START, 0.2).unwrap() < 0.0, "the last forecast is in force");
    // Within the lead (the lockstep's forecasts may run a little ahead of a cycle): taken.
    let near = forecast(200_000_000 + (0.5 * FORECAST_LEAD_S * 1e9) as u64, [50.0, 0.0, 0.0], 0.2);
    rp.step(200_000_000, &START, idle, Some(&near), &GOAL, &mut clk, &mut out);
    assert_eq!(rp.summary("dk-rrt").forecasts_ahead, 1);
    let c = rp.predicted_clearance(&START, 1.0).unwrap();
    assert!(c > 0.0, "the new forecast is in force: {c}");
}
