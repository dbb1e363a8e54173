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

/// A world with one obstacle track: `shape` at `p(t) = p0 + v·t` (identity attitude) with σ.
fn moving(shape: DebrisShape, p0: [f64; 3], v: [f64; 3], t0: f64, t1: f64, sigma: f64) -> WorldInTime {
    let mut w = WorldInTime::new(0.05);
    let n = ((t1 - t0) / 0.1).ceil() as usize;
    let poses: Vec<TimedPose> = (0..=n)
        .map(|k| {
            let t = t0 + k as f64 * 0.1;
            TimedPose {
                t,
                p: [p0[0] + v[0] * t, p0[1] + v[1] * t, p0[2] + v[2] * t],
                q: [1.0, 0.0, 0.0, 0.0],
                sigma,
                sigma_pos: sigma,
            }
        })
        .collect();
    w.push_track(1, shape, &poses, After::Hold).unwrap();
    w
}

/// The point of the straight motion's arm at its middle, base frame.
fn straight_mid_point() -> ([f64; 3], f64) {
    let p = planner();
    let lim = *p.limits();
    let tr = dkrrt_otg::Trajectory::calculate(
        &KinState::rest(START),
        &KinState::rest(GOAL),
        &lim,
        &Default::default(),
    )
    .unwrap();
    let t = 0.5 * tr.duration();
    let poser = dkrrt_collision::ArmPoser::new(ArmModel::default_arm());
    let mut caps = [dkrrt_collision::PosedCapsule::default(); NJ];
    poser.pose(&tr.at(t).p, &mut caps);
    (caps[4].centre, t)
}

/// Every 1 ms of the message: the arm's clearance to the world (no sampling argument needed).
fn dense_min_clearance(w: &WorldInTime, tr: &Trajectory, t_end: f64) -> f64 {
    let mut ch = Checker::new(ArmModel::default_arm(), &limits().v_max, 0.03);
    ch.cap = 10.0;
    let t0 = tr.start_ns as f64 * 1e-9;
    let mut m = f64::INFINITY;
    let mut t = t0;
    while t <= t_end {
        let q = tr.sample(t - t0).p;
        m = m.min(ch.clearance_at(w, &q, t, 0.0, f64::NEG_INFINITY));
        t += 1e-3;
    }
    m
}

#[test]
fn a_crossing_obstacle_is_avoided_and_the_plan_is_clear_at_every_millisecond() {
    // A sphere crosses the straight motion's path at its middle, at that time.
    let (mid, t_mid) = straight_mid_point();
    let v = [0.0, 0.0, 0.6];
    let t0 = 0.0;
    let p0 = [mid[0] - v[0] * t_mid, mid[1] - v[1] * t_mid, mid[2] - v[2] * t_mid];
    let w = moving(DebrisShape::sphere(0.25), p0, v, t0, 30.0, 0.02);
    let mut p = planner();
    let mut out = <Trajectory as Zeroed>::zeroed();
    // The straight motion itself is in collision.
    let mut straight = <Trajectory as Zeroed>::zeroed();
    let mut b = dkrrt_rrt::build::Builder::new(&mut straight, 1, 0);
    b.otg(
        &dkrrt_otg::Trajectory::calculate(
            &KinState::rest(START),
            &KinState::rest(GOAL),
            &limits(),
            &Default::default(),
        )
        .unwrap(),
    )
    .unwrap();
    b.finish();
    assert!(dense_min_clearance(&w, &straight, 20.0) < 0.0, "the test obstacle must hit the straight motion");
    let req = Request { start: KinState::rest(START), t0, goal: GOAL };
    let plan = p.plan(&req, &w, 2000, || true, 2, &mut out).expect("a plan");
    assert_eq!(plan.reach, Reach::Goal);
    let look = p.cfg.lookahead_s;
    let (ok, _) = check_message(&mut p, &w, &out, t0, t0 + look);
    assert!(ok);
    // Within the look-ahead, the sampled checks' guarantee holds at every millisecond.
    let m = dense_min_clearance(&w, &out, t0 + look);
    assert!(m >= 0.0, "clearance {m} at 1 ms resolution");
    let end = out.sample(out.duration_s).p;
    assert!((0..NJ).all(|j| (end[j] - GOAL[j]).abs() < 1e-9));
}

/// The arm at rest at `START`, link 4's capsule, and a thin rod's start and velocity such that
/// it flies at 8 m/s across that link (perpendicular to it and to its own axis, z) through its
/// centre at `t_cross`.
fn rod_across_link4(t_cross: f64) -> (dkrrt_collision::PosedCapsule, [f64; 3], [f64; 3]) {
    let poser = dkrrt_collision::ArmPoser::new(ArmModel::default_arm());
    let mut caps = [dkrrt_collision::PosedCapsule::default(); NJ];
    poser.pose(&START, &mut caps);
    let c = caps[4].centre;
    let (a, b) = (caps[4].a, caps[4].b);
    let ax = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let dir = [ax[1], -ax[0], 0.0];
    let n = (dir[0] * dir[0] + dir[1] * dir[1]).sqrt();
    let v = [8.0 * dir[0] / n, 8.0 * dir[1] / n, 0.0];
    (caps[4], [c[0] - v[0] * t_cross, c[1] - v[1] * t_cross, c[2]], v)
}

#[test]
fn a_thin_fast_rod_does_not_slip_between_samples() {
    // A 2 cm rod (capsule along z) flies along x at 8 m/s through link 4 of the arm at rest.
    let t_cross = 1.05;
    let (link, p0, v) = rod_across_link4(t_cross);
    let (a, b, c) = (link.a, link.b, link.centre);
    let mut w = moving(DebrisShape::capsule(0.3, 0.01), p0, v, 0.0, 3.0, 0.0);
    w.set_margin(0.0);
    let mut ch = Checker::new(ArmModel::default_arm(), &limits().v_max, 0.03);
    // Naive fixed sampling every 0.1 s misses it: the rod is > 0.4 m away at every sample.
    let naive_clear = (0..=30).all(|k| ch.clearance_at(&w, &START, k as f64 * 0.1, 0.0, 0.0) >= 0.0);
    assert!(naive_clear, "the test must be one that coarse sampling misses");
    // The checker's spacing follows the rod's speed and finds the contact.
    let r = ch.check(&w, 0.0, 3.0, 3.0, false, |_| START);
    assert!(!r.ok, "{r:?}");
    assert!((r.t_fail - t_cross).abs() < 0.1, "{r:?}");
    // The same rod passing 5 cm above the link's capsule (beyond δ/2) is not reported.
    let top = a[2].max(b[2]) + link.r;
    let z = top + 0.05 + 0.01 + 0.3 - c[2];
    let mut w2 = moving(DebrisShape::capsule(0.3, 0.01), [p0[0], p0[1], p0[2] + z], v, 0.0, 3.0, 0.0);
    w2.set_margin(0.0);
    let r2 = ch.check(&w2, 0.0, 3.0, 3.0, false, |_| START);
    assert!(r2.ok, "{r2:?}");
}

#[test]
fn an_unavoidable_obstacle_gives_no_plan() {
    // A huge sphere sits on the start configuration: nothing from here is clear.
    let poser = dkrrt_collision::ArmPoser::new(ArmModel::default_arm());
    let mut caps = [dkrrt_collision::PosedCapsule::default(); NJ];
    poser.pose(&START, &mut caps);
    let w = moving(DebrisShape::sphere(0.6), caps[3].centre, [0.0; 3], 0.0, 30.0, 0.0);
    let mut p = planner();
    let mut out = <Trajectory as Zeroed>::zeroed();
    let req = Request { start: KinState::rest(START), t0: 0.0, goal: GOAL };
    assert!(p.plan(&req, &w, 200, || true, 3, &mut out).is_none());
    assert_eq!(out.traj_id, 0, "nothing written");
}

/// Link 4 of the arm resting at `START`, and the horizontal direction square to it.
fn link4() -> (dkrrt_collision::PosedCapsule, [f64; 3]) {
    let poser = dkrrt_collision::ArmPoser::new(ArmModel::default_arm());
    let mut caps = [dkrrt_collision::PosedCapsule::default(); NJ];
    poser.pose(&START, &mut caps);
    let k = caps[4];
    let axis = [k.b[0] - k.a[0], k.b[1] - k.a[1], k.b[2] - k.a[2]];
    let n = (axis[0] * axis[0] + axis[1] * axis[1]).sqrt();
    (k, [axis[1] / n, -axis[0] / n, 0.0]) // axis × z: square to the link
}

/// A sphere of radius `r` (bound `sigma`, margin 0.05) coming at link 4 of the arm resting at
/// START, square to the link at `speed`, its inflated surface `inside` deep in the link at
/// `t0`: its position at t = 0 and its velocity.
fn coming_at_link(r: f64, sigma: f64, inside: f64, speed: f64, t0: f64) -> ([f64; 3], [f64; 3]) {
    let (k, u) = link4();
    let d = k.r + r + sigma + 0.05 - inside;
    let v = [-speed * u[0], -speed * u[1], 0.0];
    ([k.centre[0] + d * u[0] - v[0] * t0, k.centre[1] + d * u[1] - v[1] * t0, k.centre[2]], v)
}

/// A sphere of radius `r` whose bound `sigma` is `inside` metres into link 4 of the arm
/// resting at `START` at `t0`, closing at `speed` (negative: receding); the planner, an empty
/// message and the request from there.
fn sphere_at_resting_arm(
    r: f64,
    sigma: f64,
    inside: f64,
    speed: f64,
    t0: f64,
) -> (WorldInTime, [f64; 3], [f64; 3], Planner, Trajectory, Request) {
    let (p0, v) = coming_at_link(r, sigma, inside, speed, t0);
    let w = moving(DebrisShape::sphere(r), p0, v, 0.0, 30.0, sigma);
    let req = Request { start: KinState::rest(START), t0, goal: GOAL };
    (w, p0, v, planner(), <Trajectory as Zeroed>::zeroed(), req)
}

/// [`sphere_at_resting_arm`], where nothing is clean: the dodge made there (an escape, into
/// `out`) and [`dodge_and_stay_each_ms`] of it.
struct Dodged {
    w: WorldInTime,
    p0: [f64; 3],
    v: [f64; 3],
    p: Planner,
    out: Trajectory,
    req: Request,
    plan: dkrrt_rrt::Plan,
    each: Vec<(f64, f64, f64)>,
}

fn dodged_at_resting_arm(r: f64, sigma: f64, inside: f64, speed: f64, t0: f64) -> Dodged {
    let (w, p0, v, mut p, mut out, req) = sphere_at_resting_arm(r, sigma, inside, speed, t0);
    assert!(p.plan(&req, &w, 300, || true, 9, &mut out).is_none(), "set-up: nothing clean");
    let plan = p.dodge(&req, &w, 9, || true, &mut out).expect("a dodge");
    assert_eq!(plan.reach, Reach::Escape);
    assert_eq!(out.traj_id, 9);
    let each = dodge_and_stay_each_ms(&w, &out, t0);
    Dodged { w, p0, v, p, out, req, plan, each }
}

/// Every millisecond of the look-ahead from `t0`: (t, the clearance of the dodge `out`, the
/// clearance of staying at `START`).
fn dodge_and_stay_each_ms(w: &WorldInTime, out: &Trajectory, t0: f64) -> Vec<(f64, f64, f64)> {
    let t_end = t0 + PlannerConfig::default().lookahead_s;
    let mut ch = Checker::new(ArmModel::default_arm(), &limits().v_max, 0.03);
    let n = ((t_end - t0) / 1e-3) as usize;
    (0..=n)
        .map(|k| {
            let t = t0 + k as f64 * 1e-3;
            let q = out.sample(t - t0).p;
            let c = |q: &[f64; NJ], ch: &mut Checker| ch.clearance_at(w, q, t, 0.0, f64::NEG_INFINITY);
            (t, c(&q, &mut ch), c(&START, &mut ch))
        })
        .collect()
}

/// A newer forecast can put the resting arm just inside an obstacle's inflation (bound plus
/// margin) while the object itself is still away: the planner must move the arm out, never
/// deeper than the relief allows, and out within its time; resting there is not clear.
#[test]
fn a_start_inside_the_inflation_is_left_within_the_relief() {
    let (r, sigma, speed, t0) = (0.1, 0.1, 0.03, 2.0);
    // The sphere's inflated surface (σ + margin 0.05) reaches 1 cm into the link at t0; the
    // object itself is 14 cm away, closing at 3 cm/s.
    let (p0, v) = coming_at_link(r, sigma, 0.01, speed, t0);
    let w = moving(DebrisShape::sphere(r), p0, v, 0.0, 30.0, sigma);
    let cfg = PlannerConfig::default();
    let mut p = planner();
    let c0 = p.checker.clearance_at(&w, &START, t0, 0.5 * p.checker.delta(), f64::NEG_INFINITY);
    assert!((-0.05..0.0).contains(&c0), "set-up: the start is just inside the inflation ({c0})");

    // Resting there fails within the relief time, even under the relief.
    assert!(p.relieve(&w, &KinState::rest(START), t0) < 0.0);
    let rest = p.checker.check(&w, t0, t0 + 4.0, t0 + 4.0, false, |_| START);
    p.checker.end_relief();
    // (found at the first sample past the relief; samples are at most 0.5 s apart)
    assert!(!rest.ok && rest.t_fail <= t0 + cfg.relief_s + 0.5, "{rest:?}");

    let mut out = <Trajectory as Zeroed>::zeroed();
    let req = Request { start: KinState::rest(START), t0, goal: GOAL };
    let plan = p.plan(&req, &w, 300, || true, 5, &mut out).expect("a way out of the inflation");
    // Every millisecond: no deeper than the relief, clear after it, and the object itself
    // (σ and margin off) never touched.
    let t_end = t0 + cfg.lookahead_s;
    let mut bare = moving(DebrisShape::sphere(r), p0, v, 0.0, 30.0, 0.0);
    bare.set_margin(0.0);
    let mut ch = Checker::new(ArmModel::default_arm(), &limits().v_max, 0.03);
    ch.cap = 10.0;
    let mut t = t0;
    while t <= t_end {
        let q = out.sample(t - t0).p;
        let c = ch.clearance_at(&w, &q, t, 0.0, f64::NEG_INFINITY);
        let floor = if t < t0 + cfg.relief_s { c0 - cfg.relief_m } else { 0.0 };
        assert!(c >= floor - 1e-9, "{:?} at t = {t:.3}: clearance {c:.4} below {floor:.4}", plan.reach);
        assert!(ch.clearance_at(&bare, &q, t, 0.0, f64::NEG_INFINITY) > 0.0);
        t += 1e-3;
    }
    // The same message passes the final check (which applies the same relief).
    assert!(check_message(&mut p, &w, &out, t0, t_end).0);
}

/// An object coming fast at the resting arm: no motion is clean, and the dodge (the motion
/// with the most predicted clearance) leaves the arm clearly better off than staying.
#[test]
fn with_nothing_clean_the_dodge_moves_away_from_a_coming_object() {
    let (r, sigma, speed, t0) = (0.1, 0.1, 0.15, 2.0);
    // At t0 the inflated sphere is 2 cm inside the link; it passes right through it.
    let Dodged { mut p, mut out, req, plan, each, .. } = dodged_at_resting_arm(r, sigma, 0.02, speed, t0);
    // Measured every millisecond over the look-ahead: the dodge against staying.
    let moved = each.iter().map(|x| x.1).fold(f64::INFINITY, f64::min);
    let stay = each.iter().map(|x| x.2).fold(f64::INFINITY, f64::min);
    assert!(moved > stay + 0.5 * DODGE_GAIN_M, "dodge {moved:.3} vs staying {stay:.3}");
    assert!((plan.min_clearance - moved).abs() < 0.02, "{} vs {moved}", plan.min_clearance);
    let s0 = out.sample(0.0);
    assert!((0..NJ).all(|j| s0.p[j] == START[j] && s0.v[j] == 0.0));
    // Where nothing is coming, there is nothing to dodge.
    let calm = WorldInTime::new(0.05);
    assert!(p.dodge(&req, &calm, 10, || true, &mut out).is_none());
}

/// A wide bound (an object whose attitude is unknown is bounded by its whole sweep) already
/// 0.3 m into the resting arm, creeping over it at 5 cm/s: staying and every motion are deeper
/// than the dodge depth from the start, so no motion puts that off. The dodge then backs the
/// arm out: over the look-ahead its depth, integrated, is at most `DODGE_AREA_FRACTION` of
/// staying's, it is never deeper than staying gets, it ends out of the bound's deep part, and
/// farther from the object.
#[test]
fn inside_a_creeping_bound_the_dodge_backs_out() {
    let (r, sigma, speed, t0) = (0.1, 0.6, 0.05, 2.0);
    let Dodged { p0, v, p, out, each, .. } = dodged_at_resting_arm(r, sigma, 0.3, speed, t0);
    let depth = p.cfg.dodge_depth_m;
    assert!(each[0].2 < -depth, "set-up: the arm starts deeper than the dodge depth ({:.3})", each[0].2);
    let area = |f: fn(&(f64, f64, f64)) -> f64| each.iter().map(|x| (-f(x)).max(0.0) * 1e-3).sum::<f64>();
    let (moved, stay) = (area(|x| x.1), area(|x| x.2));
    assert!(moved <= DODGE_AREA_FRACTION * stay + 1e-3, "integrated depth {moved:.3} vs staying {stay:.3}");
    // It ends out of the bound's deep part, where staying is still in it.
    let last = each.last().unwrap();
    assert!(
        last.1 >= -depth - 0.01 && last.2 < -depth,
        "at the end: dodge {:.3}, staying {:.3}",
        last.1,
        last.2
    );
    let deepest = |f: fn(&(f64, f64, f64)) -> f64| each.iter().map(f).fold(f64::INFINITY, f64::min);
    assert!(deepest(|x| x.1) >= deepest(|x| x.2) - 0.01, "{} vs {}", deepest(|x| x.1), deepest(|x| x.2));
    // The object itself (no bound): the dodge leaves the arm farther from it at the end.
    let met = met_by_the_object(r, p0, v, &out, t0);
    assert!(
        met.end_moved > met.end_stay + 0.05,
        "object clearance at the end: dodge {:.3}, staying {:.3}",
        met.end_moved,
        met.end_stay
    );
}

/// The same wide bound 0.6 m into the resting arm, but receding at 5 cm/s: staying gets
/// shallower by itself, so there is nothing to back out of, and no dodge is made (the rule of
/// [`inside_a_creeping_bound_the_dodge_backs_out`] is for a bound still advancing over the arm
/// at the look-ahead's end).
#[test]
fn inside_a_receding_bound_there_is_no_dodge() {
    let (w, _, _, mut p, mut out, req) = sphere_at_resting_arm(0.1, 0.6, 0.6, -0.05, 2.0);
    let t0 = req.t0;
    let mut ch = Checker::new(ArmModel::default_arm(), &limits().v_max, 0.03);
    let t_end = t0 + p.cfg.lookahead_s;
    let first = ch.clearance_at(&w, &START, t0, 0.0, f64::NEG_INFINITY);
    let last = ch.clearance_at(&w, &START, t_end, 0.0, f64::NEG_INFINITY);
    let depth = p.cfg.dodge_depth_m;
    assert!(
        first < last - 0.1 && last < -depth,
        "set-up: deep all along, shallower at the end ({first:.3} → {last:.3})"
    );
    assert!(p.dodge(&req, &w, 9, || true, &mut out).is_none());
}

/// The sphere of radius `r` itself (no bound, no margin) from `p0` at `v`, against the dodge
/// `out` from `t0` and against staying at `START`, every millisecond of the look-ahead: when
/// each first touches it (infinite: never), and their clearances at the look-ahead's end.
struct Met {
    moved: f64,
    stay: f64,
    end_moved: f64,
    end_stay: f64,
}

impl Met {
    /// Staying meets the object by `t_end`; the dodge [`DODGE_TIME_GAIN_S`] later or never.
    fn assert_dodged(&self, t_end: f64) {
        assert!(self.stay < t_end, "set-up: staying meets the object within the look-ahead");
        assert!(
            self.moved >= self.stay + DODGE_TIME_GAIN_S,
            "met at {:.2} s, staying at {:.2} s",
            self.moved,
            self.stay
        );
    }
}

fn met_by_the_object(r: f64, p0: [f64; 3], v: [f64; 3], out: &Trajectory, t0: f64) -> Met {
    let mut bare = moving(DebrisShape::sphere(r), p0, v, 0.0, 30.0, 0.0);
    bare.set_margin(0.0);
    let mut ch = Checker::new(ArmModel::default_arm(), &limits().v_max, 0.03);
    let t_end = t0 + PlannerConfig::default().lookahead_s;
    let (mut met, mut t) =
        (Met { moved: f64::INFINITY, stay: f64::INFINITY, end_moved: 0.0, end_stay: 0.0 }, t0);
    while t <= t_end {
        let cm = ch.clearance_at(&bare, &out.sample(t - t0).p, t, 0.0, f64::NEG_INFINITY);
        let cs = ch.clearance_at(&bare, &START, t, 0.0, f64::NEG_INFINITY);
        if cm < 0.0 && met.moved.is_infinite() {
            met.moved = t;
        }
        if cs < 0.0 && met.stay.is_infinite() {
            met.stay = t;
        }
        (met.end_moved, met.end_stay) = (cm, cs);
        t += 1e-3;
    }
    met
}

/// A bound that holds the arm whatever it does (an object whose position is known to a
/// metre, already 0.7 m into the resting arm), with the object itself 0.35 m from a link and
/// closing at 0.1 m/s: every candidate is as deep as staying from the first instant, so no
/// rule on the bounds tells them apart, and braking there waits for the object. The dodge then
/// moves the arm away from where the object most likely is (its predicted shape, bound × 0):
/// staying meets the object itself within the look-ahead, the dodge keeps clear of it longer
/// and ends farther from it.
#[test]
fn in_a_bound_that_holds_the_arm_the_dodge_moves_away_from_the_likely_object() {
    let (r, sigma, speed, t0) = (0.1, 1.0, 0.1, 2.0);
    let Dodged { w, p0, v, p, out, each, .. } = dodged_at_resting_arm(r, sigma, 0.7, speed, t0);
    let depth = p.cfg.dodge_depth_m;
    assert!(each.iter().all(|x| x.1 < -depth && x.2 < -depth), "set-up: deep all along, moved or not");
    let met = met_by_the_object(r, p0, v, &out, t0);
    met.assert_dodged(t0 + p.cfg.lookahead_s);
    assert!(
        met.end_moved > met.end_stay + 0.05,
        "at the end: dodge {:.3}, staying {:.3}",
        met.end_moved,
        met.end_stay
    );
    // The bounds as published in every check after it.
    let mut ch = Checker::new(ArmModel::default_arm(), &limits().v_max, 0.03);
    assert!(ch.clearance_at(&w, &START, t0, 0.0, f64::NEG_INFINITY) < -0.6);
}

/// A wide bound that will sweep over the resting arm faster than any nearby move gets out of
/// its way (fast-crossing, seed 4470, episode 1 through the camera: the arm braked where a
/// box's 1 m bound was coming, and the box hit it) is dodged by where the object most likely
/// is, as a bound that holds the arm already is.
#[test]
fn a_bound_about_to_sweep_the_arm_is_dodged_by_the_likely_object() {
    let (r, sigma, speed, t0) = (0.1, 1.0, 0.8, 2.0);
    // The bound 0.3 m short of link 4 at t0, the object itself 1.45 m short of it.
    let Dodged { w, p0, v, mut p, mut out, req, each, .. } = dodged_at_resting_arm(r, sigma, -0.3, speed, t0);
    let depth = p.cfg.dodge_depth_m;
    let deep = |k: usize| each.iter().find(|x| [x.1, x.2][k] < -depth).map_or(f64::INFINITY, |x| x.0);
    let (deep_moved, deep_stay) = (deep(0), deep(1));
    assert!(each[0].2 > 0.0, "set-up: the arm is out of the bound at first");
    assert!(deep_stay < t0 + p.cfg.dodge_react_s, "set-up: staying goes deep within the reaction time");
    assert!(deep_moved < deep_stay + DODGE_TIME_GAIN_S, "set-up: the bound's rules take no move");
    let met = met_by_the_object(r, p0, v, &out, t0);
    met.assert_dodged(t0 + p.cfg.lookahead_s);

    // Acting only on a bound the arm is already deep in (before), nothing is dodged: the arm
    // stays where the object comes.
    p.cfg.dodge_react_s = 0.1;
    assert!(p.dodge(&req, &w, 9, || true, &mut out).is_none());
}

/// A wide bound (1 m) about to sweep over the resting arm whose object itself passes it by
/// (0.45 m off link 4, crossing at 1.5 m/s): a young track's bound, wide for a second, is the
/// common case. The object most likely misses the arm where it rests, so nothing is dodged
/// for it: the arm waits for the next forecasts (a likely dodge there moved the arm away and
/// back at the start of many camera episodes, 0.3–0.5 s of time to goal on average).
#[test]
fn a_bound_ahead_whose_object_passes_by_is_not_dodged() {
    let (r, sigma, speed, t0) = (0.1, 1.0, 1.5, 2.0);
    let (k, u) = link4();
    let e = {
        let a = [k.b[0] - k.a[0], k.b[1] - k.a[1], k.b[2] - k.a[2]];
        let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        a.map(|c| c / n)
    };
    // Square to the link and to `u`: the object's path keeps its distance to link 4.
    let w_dir = [u[1] * e[2] - u[2] * e[1], u[2] * e[0] - u[0] * e[2], u[0] * e[1] - u[1] * e[0]];
    let (off, t_c) = (k.r + r + 0.45, t0 + 1.5);
    let v = w_dir.map(|c| speed * c);
    let p0: [f64; 3] = std::array::from_fn(|i| k.centre[i] + off * u[i] - v[i] * t_c);
    let w = moving(DebrisShape::sphere(r), p0, v, 0.0, 30.0, sigma);
    let mut p = planner();
    let depth = p.cfg.dodge_depth_m;
    let mut bare = moving(DebrisShape::sphere(r), p0, v, 0.0, 30.0, 0.0);
    bare.set_margin(0.0);
    let mut ch = Checker::new(ArmModel::default_arm(), &limits().v_max, 0.03);
    let (mut deep_stay, mut touch) = (f64::INFINITY, f64::INFINITY);
    let mut t = t0;
    while t <= t0 + p.cfg.lookahead_s {
        if ch.clearance_at(&w, &START, t, 0.0, f64::NEG_INFINITY) < -depth {
            deep_stay = deep_stay.min(t);
        }
        if ch.clearance_at(&bare, &START, t, 0.0, f64::NEG_INFINITY) < 0.2 {
            touch = touch.min(t);
        }
        t += 1e-3;
    }
    assert!(
        ch.clearance_at(&w, &START, t0, 0.0, f64::NEG_INFINITY) > 0.0,
        "set-up: out of the bound at first"
    );
    assert!(deep_stay < t0 + p.cfg.dodge_react_s, "set-up: staying goes deep within the reaction time");
    assert!(touch.is_infinite(), "set-up: the object itself stays 0.2 m off the resting arm");
    let mut out = <Trajectory as Zeroed>::zeroed();
    let req = Request { start: KinState::rest(START), t0, goal: GOAL };
    assert!(p.dodge(&req, &w, 9, || true, &mut out).is_none(), "the arm stays");
}

#[test]
fn plans_are_deterministic_for_a_seed() {
    let (mid, t_mid) = straight_mid_point();
    let v = [0.0, 0.5, 0.0];
    let p0 = [mid[0], mid[1] - v[1] * t_mid, mid[2]];
    let w = moving(DebrisShape::cuboid([0.3, 0.2, 0.05], [0.0; 3]), p0, v, 0.0, 30.0, 0.02);
    let run = || {
        let mut p = planner();
        let mut out = <Trajectory as Zeroed>::zeroed();
        let req = Request { start: KinState::rest(START), t0: 0.0, goal: GOAL };
        let plan = p.plan(&req, &w, 500, || true, 4, &mut out);
        (plan, out)
    };
    let (a, ta) = run();
    let (b, tb) = run();
    assert_eq!(a, b);
    assert_eq!(ta, tb);
    assert!(a.is_some());
}

#[test]
fn world_interpolates_and_extrapolates_past_the_horizon() {
    use dkrrt_msg::{DebrisForecast, ForecastStep};
    let mut f = <DebrisForecast as Zeroed>::zeroed();
    f.count = 1;
    f.steps = 4;
    f.dt_s = 0.1;
    f.t0_ns = 2_000_000_000;
    f.tracks[0].id = 9;
    f.tracks[0].bounding_radius = 0.5;
    f.tracks[0].shape = DebrisShape::capsule(0.45, 0.05);
    let h = std::f64::consts::FRAC_1_SQRT_2;
    for k in 0..4 {
        let s = 0.1 * (k + 1) as f64;
        // 1 m/s along x; a quarter turn about x (end over end) over the first 0.1 s only.
        let q = if k == 0 { [1.0, 0.0, 0.0, 0.0] } else { [h, h, 0.0, 0.0] };
        f.tracks[0].steps[k] = ForecastStep {
            p: [s, 0.0, 0.0],
            q,
            sigma_m: 0.01 * (k + 1) as f64,
            sigma_pos_m: 0.005 * (k + 1) as f64,
        };
    }
    let mut w = WorldInTime::new(0.0);
    w.load_forecast(&f);
    assert_eq!(w.len(), 1);
    // Between steps: linear position, slerp attitude (half of the quarter turn), σ linear.
    let (p, q, s, sp, sphere) = w.pose_at(0, 2.15);
    assert!((p[0] - 0.15).abs() < 1e-12 && !sphere);
    assert!((q[0] - (std::f64::consts::PI / 8.0).cos()).abs() < 1e-12, "{q:?}");
    assert!((s - 0.015).abs() < 1e-12 && (sp - 0.0075).abs() < 1e-12);
    // Past the horizon (2.4 s): the centre goes on at the last velocity, the attitude at the
    // last interval's rate (none: it stays the quarter turn), the shape stays the shape, each
    // bound grows at its own rate: the larger of the last step's and its mean since t0 (the
    // position bound 0.005 per 0.1 s and 0.02 over 0.4 s; the surface bound 0.01 per 0.1 s and
    // 0.04 over 0.4 s).
    let (p, q, s, sp, sphere) = w.pose_at(0, 3.4);
    assert!((p[0] - 1.4).abs() < 1e-9, "{p:?}");
    assert!(!sphere);
    // (the rod's axis along y: the quarter turn one way or the other, the same rod)
    let z = dkrrt_collision::quat_rotate(&q, &[0.0, 0.0, 1.0]);
    assert!((z[1].abs() - 1.0).abs() < 1e-12, "{q:?}");
    assert!((sp - (0.02 + 0.05)).abs() < 1e-12 && (s - (0.04 + 0.1)).abs() < 1e-12, "{s} {sp}");
    // The speed bound covers the motion: 1 m/s + the turn's ω times the farthest a point of
    // the capsule lies from the turn's axis (its half length + radius) + σ growth.
    let omega = std::f64::consts::FRAC_PI_2 / 0.1;
    assert!(w.max_speed() >= 1.0 + omega * 0.5, "{}", w.max_speed());
    assert!(w.max_speed() < 1.0 + omega * 0.55, "{}", w.max_speed());
    // The same rod spinning about its own axis (z) instead: a spin its shape does not show
    // is not read as a turn (`dkrrt_collision::pose::axis_swing`): its axis stays, and only
    // its radius could move with it, so its speed bound is its own 1 m/s + σ growth.
    for k in 1..4 {
        f.tracks[0].steps[k].q = [h, 0.0, 0.0, h];
    }
    w.load_forecast(&f);
    let (_, q, ..) = w.pose_at(0, 2.15);
    assert_eq!(q, [1.0, 0.0, 0.0, 0.0]);
    assert!(w.max_speed() < 1.0 + omega * 0.05, "{}", w.max_speed());
}

#[test]
fn past_the_horizon_a_tumbling_rod_keeps_its_shape_and_turn() {
    // A 1.2 m rod beside link 4 of the arm at rest, end over end about the line to the link
    // at 0.5 rad/s: it turns in a plane 0.5 m from the link's centre. Its bounding ball (radius
    // 0.65 m) reaches into the link; the rod, inflated by its bounds, leaves the arm clear.
    use dkrrt_collision::quat_rotate;
    use dkrrt_msg::{DebrisForecast, ForecastStep};
    let (link, d) = link4();
    let c = [link.centre[0] + 0.5 * d[0], link.centre[1] + 0.5 * d[1], link.centre[2]];
    let (omega, dt, steps) = (0.5, 0.1, 40usize);
    let mut f = <DebrisForecast as Zeroed>::zeroed();
    f.count = 1;
    f.steps = steps as u32;
    f.dt_s = dt;
    f.t0_ns = 1_000_000_000;
    f.tracks[0].id = 3;
    f.tracks[0].bounding_radius = 0.65;
    f.tracks[0].shape = DebrisShape::capsule(0.6, 0.05);
    let turn = |t: f64| {
        let (s, co) = ((0.5 * omega * t).sin(), (0.5 * omega * t).cos());
        [co, s * d[0], s * d[1], s * d[2]]
    };
    for k in 0..steps {
        let t = (k + 1) as f64 * dt;
        f.tracks[0].steps[k] =
            ForecastStep { p: c, q: turn(t), sigma_m: 0.004 * t / dt, sigma_pos_m: 0.002 * t / dt };
    }
    let mut w = WorldInTime::new(0.05);
    w.load_forecast(&f);
    let t_h = 1.0 + steps as f64 * dt;
    let mut ch = Checker::new(ArmModel::default_arm(), &limits().v_max, 0.03);
    for after in [0.5, 1.0] {
        let (p, q, s, sp, sphere) = w.pose_at(0, t_h + after);
        // The rod goes on turning at its rate, where it is, its bounds growing.
        assert!(!sphere);
        assert!((p[0] - c[0]).abs() < 1e-12 && (p[1] - c[1]).abs() < 1e-12, "{p:?}");
        // (the rod's axis: the world takes each step as the half turn nearest the one before)
        let (za, zb) = (
            quat_rotate(&q, &[0.0, 0.0, 1.0]),
            quat_rotate(&turn(steps as f64 * dt + after), &[0.0, 0.0, 1.0]),
        );
        assert!((za[0] * zb[0] + za[1] * zb[1] + za[2] * zb[2]).abs() > 1.0 - 1e-12, "{q:?}");
        assert!((s - 0.004 * (steps as f64 + after / dt)).abs() < 1e-9, "{s}");
        assert!((sp - 0.002 * (steps as f64 + after / dt)).abs() < 1e-9, "{sp}");
        // Its ball, inflated, reaches into the link; the rod, inflated, leaves the arm clear.
        let ball = 0.65 + sp + w.margin();
        assert!(0.5 - link.r - ball < -0.1, "the test needs a ball that blocks");
        let clear = ch.clearance_at(&w, &START, t_h + after, 0.0, f64::NEG_INFINITY);
        assert!(clear > 0.03, "{clear}");
    }
}

#[test]
fn the_broad_phase_never_sets_aside_a_track_that_comes_near() {
    // Random moving, turning, growing tracks; random windows and spheres: every track whose
    // inflated shape comes within the reach of the sphere at a sampled time of the window is
    // in the mask, and the mask's speed bounds the kept tracks.
    use dkrrt_collision::PosedCapsule;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};
    let mut rng = SmallRng::seed_from_u64(9);
    let shapes = [
        DebrisShape::sphere(0.2),
        DebrisShape::capsule(0.8, 0.05),
        DebrisShape::cuboid([0.6, 0.3, 0.02], [0.0; 3]),
    ];
    let mut kept_near = 0;
    for round in 0..200 {
        let mut w = WorldInTime::new(0.05);
        for id in 0..8u32 {
            let p0: [f64; 3] = std::array::from_fn(|_| rng.random_range(-4.0..4.0));
            let v: [f64; 3] = std::array::from_fn(|_| rng.random_range(-0.5..0.5));
            let wz = rng.random_range(-2.0..2.0);
            let s0 = rng.random_range(0.0..0.1);
            let poses: Vec<TimedPose> = (0..=40)
                .map(|k| {
                    let t = 0.1 * k as f64;
                    let a = 0.5 * wz * t;
                    TimedPose {
                        t,
                        p: [p0[0] + v[0] * t, p0[1] + v[1] * t, p0[2] + v[2] * t],
                        q: [a.cos(), 0.0, 0.0, a.sin()],
                        sigma: s0 + 0.05 * t,
                        sigma_pos: s0 + 0.02 * t,
                    }
                })
                .collect();
            let after = if round % 2 == 0 { After::Hold } else { After::Extrapolate };
            w.push_track(id, shapes[id as usize % 3], &poses, after).unwrap();
        }
        let t0 = rng.random_range(0.0..5.0);
        let t1 = t0 + rng.random_range(0.0..3.0);
        let centre: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        let (radius, extra) = (rng.random_range(0.2..1.5), 0.015);
        let (mask, v) = w.near(t0, t1, &centre, radius, extra);
        // A probe sphere as a zero-length capsule of that radius.
        let probe = PosedCapsule::new(centre, centre, radius);
        let mut obs = Vec::with_capacity(32);
        for k in 0..=60 {
            let t = t0 + (t1 - t0) * k as f64 / 60.0;
            w.obstacles_at(t, extra, &mut obs);
            for (i, o) in obs.iter().enumerate() {
                if o.distance(&probe) <= 0.0 {
                    assert!(
                        mask >> i & 1 == 1,
                        "round {round}: track {i} comes near at {t} but is set aside"
                    );
                    kept_near += 1;
                }
            }
        }
        // Held tracks stand still past their last pose (4 s): a window wholly after it may have
        // speed 0.
        let moving = t0 < 4.0 || round % 2 == 1;
        for i in 0..w.len() {
            if mask >> i & 1 == 1 {
                assert!((v > 0.0 || !moving) && v <= w.max_speed() + 1e-12, "round {round}: {v}");
            }
        }
    }
    assert!(kept_near > 100, "near cases exercised: {kept_near}");
}

#[test]
fn the_checker_leaves_out_only_what_cannot_lower_its_capped_clearance() {
    // Random moving, turning shapes (forecast-like: 0.1 s steps), random arm configurations
    // and times: the checker's clearance (tracks beyond the arm's sphere + cap left out, the
    // step found straight from the time) equals the capped clearance against every obstacle,
    // and a track on a uniform grid is posed as one whose grid is broken after the window.
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::SmallRng::seed_from_u64(23);
    let shapes = [
        DebrisShape::sphere(0.3),
        DebrisShape::capsule(0.6, 0.05),
        DebrisShape::cuboid([0.4, 0.3, 0.02], [0.1, 0.0, 0.0]),
    ];
    let model = ArmModel::default_arm();
    let mut checker = Checker::new(model.clone(), &limits().v_max, 0.03);
    let poser = dkrrt_collision::ArmPoser::new(model);
    let mut caps = [dkrrt_collision::PosedCapsule::default(); NJ];
    let mut obs = Vec::with_capacity(32);
    let mut near = 0;
    for _ in 0..100 {
        let mut w = WorldInTime::new(0.05);
        let mut broken = WorldInTime::new(0.05);
        for id in 0..12u32 {
            let p0: [f64; 3] = std::array::from_fn(|_| rng.random_range(-2.5..2.5));
            let v: [f64; 3] = std::array::from_fn(|_| rng.random_range(-0.6..0.6));
            let wz = rng.random_range(-2.0..2.0);
            let mut poses: Vec<TimedPose> = (0..=40)
                .map(|k| {
                    let t = 0.1 * (k + 1) as f64;
                    let a = 0.5 * wz * t;
                    TimedPose {
                        t,
                        p: [p0[0] + v[0] * t, p0[1] + v[1] * t, p0[2] + v[2] * t],
                        q: [a.cos(), 0.0, a.sin() * 0.6, a.sin() * 0.8],
                        sigma: 0.01 + 0.05 * t,
                        sigma_pos: 0.01 + 0.02 * t,
                    }
                })
                .collect();
            w.push_track(id, shapes[id as usize % 3], &poses, After::Extrapolate).unwrap();
            poses[40].t += 1e-4;
            broken.push_track(id, shapes[id as usize % 3], &poses, After::Extrapolate).unwrap();
        }
        for _ in 0..20 {
            let q: [f64; NJ] = std::array::from_fn(|_| rng.random_range(-2.0..2.0));
            // On grid points too (where the step boundary is decided).
            let t = if rng.random::<bool>() {
                0.1 * rng.random_range(1..40) as f64
            } else {
                rng.random_range(0.0..4.5)
            };
            let extra = 0.015;
            let got = checker.clearance_at(&w, &q, t, extra, f64::NEG_INFINITY);
            poser.pose(&q, &mut caps);
            w.obstacles_at(t, extra, &mut obs);
            let want = dkrrt_collision::clearance(&caps, &obs, f64::NEG_INFINITY, checker.cap);
            assert!(got == want || (got - want).abs() < 1e-12, "{got} vs {want} at t = {t}");
            near += (want < checker.cap) as usize;
            if t < 3.95 {
                for i in 0..w.len() {
                    assert_eq!(w.pose_at(i, t), broken.pose_at(i, t), "track {i} at {t}");
                }
            }
        }
    }
    assert!(near > 50, "cases exercised: {near} near");
}

/// Random forecast-like tracks (0.1 s steps, turning, σ growing unevenly).
fn random_world(rng: &mut rand::rngs::SmallRng, n: u32) -> WorldInTime {
    use rand::Rng;
    let shapes = [
        DebrisShape::sphere(0.3),
        DebrisShape::capsule(0.6, 0.05),
        DebrisShape::cuboid([0.4, 0.3, 0.02], [0.1, 0.0, 0.0]),
    ];
    let mut w = WorldInTime::new(0.05);
    for id in 0..n {
        let p0: [f64; 3] = std::array::from_fn(|_| rng.random_range(-2.5..2.5));
        let v: [f64; 3] = std::array::from_fn(|_| rng.random_range(-2.0..2.0));
        let wz = rng.random_range(-3.0..3.0);
        let mut sigma = 0.01;
        let poses: Vec<TimedPose> = (0..=40)
            .map(|k| {
                let t = 0.1 * (k + 1) as f64;
                let a = 0.5 * wz * t;
                sigma += rng.random_range(0.0..0.3) * rng.random_range(0.0..1.0f64).powi(4);
                TimedPose {
                    t,
                    p: [p0[0] + v[0] * t, p0[1] + v[1] * t, p0[2] + v[2] * t],
                    q: [a.cos(), 0.0, a.sin() * 0.6, a.sin() * 0.8],
                    sigma,
                    sigma_pos: 0.5 * sigma,
                }
            })
            .collect();
        w.push_track(id, shapes[id as usize % 3], &poses, After::Extrapolate).unwrap();
    }
    w
}

#[test]
fn a_tracks_speed_over_a_window_bounds_its_motion_there() {
    // Centre and σ together move no faster than `speed_within` over any window, which is never
    // above the track's speed over its whole forecast (and is much below it in most windows);
    // centre and σ_pos no faster than `ball_speed_within`.
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::SmallRng::seed_from_u64(7);
    let (mut lower, mut slower) = (0, 0);
    let mut windows = 0;
    for _ in 0..30 {
        let w = random_world(&mut rng, 6);
        for i in 0..w.len() {
            for _ in 0..20 {
                let a = rng.random_range(-0.5..5.5);
                let b = a + rng.random_range(0.0..1.5);
                let v = w.speed_within(i, a, b);
                assert!(v <= w.max_speed() + 1e-12);
                windows += 1;
                lower += (v < 0.8 * w.max_speed()) as usize;
                // The centre and σ.
                assert_moves_within(&w, i, a, b, v, |(p, _, s, _, _)| (p, s));
                // The bounding ball (centre, radius + σ_pos), at `ball_speed_within`: below
                // `speed_within` for a turning shape.
                let vb = w.ball_speed_within(i, a, b);
                assert_moves_within(&w, i, a, b, vb, |(p, _, _, sp, _)| (p, sp));
                slower += (vb < 0.9 * v) as usize;
            }
        }
    }
    assert!(lower * 2 > windows, "a window's speed is rarely below the whole forecast's: {lower}/{windows}");
    assert!(slower * 3 > windows, "the ball is rarely slower than the shape: {slower}/{windows}");
}

/// Over `[a, b]` in 50 steps, a centre and a radius read from track `i`'s pose (`of`) move
/// together no faster than `v`.
fn assert_moves_within(
    w: &WorldInTime,
    i: usize,
    a: f64,
    b: f64,
    v: f64,
    of: impl Fn(([f64; 3], [f64; 4], f64, f64, bool)) -> ([f64; 3], f64),
) {
    let (mut pp, mut rp) = of(w.pose_at(i, a));
    for k in 1..=50 {
        let t = a + (b - a) * k as f64 / 50.0;
        let (p, r) = of(w.pose_at(i, t));
        let moved = ((p[0] - pp[0]).powi(2) + (p[1] - pp[1]).powi(2) + (p[2] - pp[2]).powi(2)).sqrt()
            + (r - rp).abs();
        assert!(moved <= v * (b - a) / 50.0 + 1e-9, "track {i} in [{a}, {b}]: {moved} > {v}");
        (pp, rp) = (p, r);
    }
}

#[test]
fn each_tracks_gap_is_a_lower_bound_on_its_clearance() {
    // The per-track gaps the checker spaces its samples by never exceed the track's true
    // clearance from the arm (measured without a cap), for tracks left out or kept.
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::SmallRng::seed_from_u64(11);
    let poser = dkrrt_collision::ArmPoser::new(ArmModel::default_arm());
    let mut caps = [dkrrt_collision::PosedCapsule::default(); NJ];
    let (mut obs, mut one) = (Vec::with_capacity(32), Vec::with_capacity(32));
    let mut gaps = Gaps::default();
    let mut kept = 0;
    for _ in 0..60 {
        let w = random_world(&mut rng, 10);
        for _ in 0..20 {
            let q: [f64; NJ] = std::array::from_fn(|_| rng.random_range(-2.0..2.0));
            let t = rng.random_range(0.0..4.5);
            poser.pose(&q, &mut caps);
            let n = caps.len() as f64;
            let c: [f64; 3] = std::array::from_fn(|k| caps.iter().map(|x| x.centre[k]).sum::<f64>() / n);
            let r = caps
                .iter()
                .map(|x| ((0..3).map(|k| (x.centre[k] - c[k]).powi(2)).sum::<f64>()).sqrt() + x.bound)
                .fold(0.0, f64::max);
            let near = dkrrt_rrt::world::Near { arm: &caps, centre: &c, radius: r, cap: 1.0 };
            w.obstacles_gapped(t, 0.015, u64::MAX, Some(near), &mut obs, Some(&mut gaps));
            kept += obs.len();
            for i in 0..w.len() {
                w.obstacles_within(t, 0.015, 1 << i, None, &mut one);
                let truth = dkrrt_collision::clearance(&caps, &one, f64::NEG_INFINITY, f64::INFINITY);
                let gap = gaps.ball[i].iter().fold(f64::INFINITY, |a, &b| a.min(b));
                assert!(gap <= truth + 1e-9, "track {i} at {t}: gap {gap} > {truth}");
                // Per capsule, the ball's gap bounds the track's clearance from that capsule.
                for (k, cap) in caps.iter().enumerate() {
                    let truth_k = dkrrt_collision::clearance(
                        std::slice::from_ref(cap),
                        &one,
                        f64::NEG_INFINITY,
                        f64::INFINITY,
                    );
                    assert!(gaps.ball[i][k] <= truth_k + 1e-9, "track {i}, capsule {k} at {t}");
                }
            }
            for (k, o) in obs.iter().enumerate() {
                assert_eq!(w.id(gaps.track[k] as usize), o.id);
            }
        }
    }
    assert!(kept > 0, "some tracks must be near enough to be kept");
}

#[test]
fn a_fast_track_far_away_does_not_shorten_the_samples_near_a_slow_one() {
    // A slow ball rests 0.2 m from the resting arm; a thin rod crosses the arm 3 s later at
    // 8 m/s. The contact with the rod is found (nothing slips between samples), and until the
    // rod comes near the samples are spaced by the slow ball, not by the rod's speed.
    let t_cross = 3.05;
    let (link, p0, v) = rod_across_link4(t_cross);
    let mut w = moving(DebrisShape::capsule(0.3, 0.01), p0, v, 0.0, 4.0, 0.0);
    let ball_at = [link.centre[0], link.centre[1], link.a[2].max(link.b[2]) + link.r + 0.2 + 0.1];
    let ball: Vec<TimedPose> = (0..=40)
        .map(|k| TimedPose {
            t: 0.1 * k as f64,
            p: ball_at,
            q: [1.0, 0.0, 0.0, 0.0],
            sigma: 0.0,
            sigma_pos: 0.0,
        })
        .collect();
    w.push_track(2, DebrisShape::sphere(0.1), &ball, After::Hold).unwrap();
    w.set_margin(0.0);
    let mut ch = Checker::new(ArmModel::default_arm(), &limits().v_max, 0.03);
    let r = ch.check(&w, 0.0, 4.0, 4.0, false, |_| START);
    assert!(!r.ok && (r.t_fail - t_cross).abs() < 0.1, "{r:?}");
    // One speed for all tracks would space the first 2.5 s by at most (cap + δ) / 8 m/s.
    let uniform = (2.5 * 8.0 / (ch.cap + ch.delta())).floor() as u32;
    let r = ch.check(&w, 0.0, 2.5, 2.5, false, |_| START);
    assert!(r.ok && r.samples * 2 < uniform, "{} samples (uniform spacing: {uniform})", r.samples);
}

/// A sphere rising through the straight motion's middle at its time, and the request from rest
/// at `START` at time 0.
fn crossing_sphere() -> (WorldInTime, Request) {
    let (mid, t_mid) = straight_mid_point();
    let v = [0.0, 0.0, 0.6];
    let p0 = [mid[0] - v[0] * t_mid, mid[1] - v[1] * t_mid, mid[2] - v[2] * t_mid];
    let w = moving(DebrisShape::sphere(0.25), p0, v, 0.0, 30.0, 0.02);
    (w, Request { start: KinState::rest(START), t0: 0.0, goal: GOAL })
}

#[test]
fn a_search_to_beat_an_arrival_returns_only_earlier_plans_and_checks_no_later_edge() {
    let (w, req) = crossing_sphere();
    let mut out = <Trajectory as Zeroed>::zeroed();
    let mut p = planner();
    let best = p.plan(&req, &w, 2000, || true, 2, &mut out).expect("a plan");
    // Nothing arrives before the start: no edge is even checked, and no escape is offered.
    assert_eq!(p.plan_to_beat(&req, &w, 0.0, 2000, || true, 3, &mut out), None);
    assert_eq!(p.stats.edges_checked, 0, "{:?}", p.stats);
    // Beating a late arrival: a plan to the goal that arrives before it, checked clean.
    let late = best.arrival + 5.0;
    let mut q = planner();
    let again = q.plan_to_beat(&req, &w, late, 2000, || true, 4, &mut out).expect("a plan");
    assert_eq!(again.reach, Reach::Goal);
    assert!(again.arrival < late);
    let look = q.cfg.lookahead_s;
    let (ok, _) = check_message(&mut q, &w, &out, 0.0, look);
    assert!(ok);
    // Whatever it finds against a tight bound arrives before it.
    for k in 1..=5 {
        let before = best.arrival - 0.05 * k as f64;
        if let Some(b) = q.plan_to_beat(&req, &w, before, 2000, || true, 5, &mut out) {
            assert!(b.reach == Reach::Goal && b.arrival < before, "{b:?} vs {before}");
        }
    }
}

#[test]
fn message_speed_peaks_bound_the_sampled_joint_speeds() {
    let (w, req) = crossing_sphere();
    let mut out = <Trajectory as Zeroed>::zeroed();
    planner().plan(&req, &w, 2000, || true, 2, &mut out).expect("a plan");
    let d = out.duration_s;
    for (a, b) in [(0.0, d), (0.1 * d, 0.3 * d), (0.5 * d, 0.52 * d), (0.9 * d, d + 3.0), (d + 1.0, d + 2.0)]
    {
        let peaks = message_speed_peaks(&out, a, b);
        let mut seen = [0.0f64; NJ];
        for k in 0..=2000 {
            let s = out.sample(a + (b - a) * k as f64 / 2000.0);
            for j in 0..NJ {
                seen[j] = seen[j].max(s.v[j].abs());
            }
        }
        for j in 0..NJ {
            assert!(peaks[j] >= seen[j] - 1e-12, "[{a}, {b}] joint {j}: {} < {}", peaks[j], seen[j]);
            assert!(
                peaks[j] <= seen[j] + limits().a_max[j] * (b - a) / 2000.0 + 1e-9,
                "[{a}, {b}] joint {j}"
            );
        }
    }
}

/// A bound that engulfs the arm's whole reach (a ball 0.4 m beside link 4 whose position
/// bound grows at 0.3 m/s, to 1.5 m over the look-ahead, as after a fragment splits off):
/// every motion and every rest goes deeper than the dodge depth within the look-ahead. The
/// dodge then takes the motion that goes that deep latest, away from where the bound grows
/// from, when it buys at least `DODGE_TIME_GAIN_S` over staying.
#[test]
fn when_a_bound_engulfs_everything_the_dodge_puts_the_conflict_off() {
    let (r, t0) = (0.1, 2.0);
    let (gap, rate) = (0.4, 0.3);
    let (p0, _) = coming_at_link(r, 0.05, -gap, 0.0, t0);
    let poses: Vec<TimedPose> = (0..=40)
        .map(|k| {
            let t = t0 + 0.1 * k as f64;
            let s = 0.05 + rate * (t - t0);
            TimedPose { t, p: p0, q: [1.0, 0.0, 0.0, 0.0], sigma: s, sigma_pos: s }
        })
        .collect();
    let mut w = WorldInTime::new(0.05);
    w.push_track(1, DebrisShape::sphere(r), &poses, After::Extrapolate).unwrap();
    let mut p = planner();
    let mut out = <Trajectory as Zeroed>::zeroed();
    let req = Request { start: KinState::rest(START), t0, goal: GOAL };
    assert!(p.plan(&req, &w, 300, || true, 9, &mut out).is_none(), "set-up: nothing clean");
    let depth = p.cfg.dodge_depth_m;
    let plan = p.dodge(&req, &w, 9, || true, &mut out).expect("a dodge");
    assert_eq!(plan.reach, Reach::Escape);
    // Measured every millisecond: when the dodge and staying first go deeper than the depth.
    let each = dodge_and_stay_each_ms(&w, &out, t0);
    let first =
        |f: fn(&(f64, f64, f64)) -> f64| each.iter().find(|x| f(x) < -depth).map_or(f64::INFINITY, |x| x.0);
    let (moved, stay) = (first(|x| x.1), first(|x| x.2));
    assert!(moved.is_finite() && stay.is_finite(), "set-up: both go too deep ({moved}, {stay})");
    assert!(moved >= stay + DODGE_TIME_GAIN_S - DODGE_DT, "dodge deep at {moved:.3}, staying at {stay:.3}");
}

/// A rod whose attitude is barely known (its surface bound 0.85 m, its position bound 0.25 m)
/// lies end-on 1.2 m from link 4. The rod inflated by its surface bound reaches 0.35 m into the
/// link; its bounding sphere inflated by the position bound stays 0.25 m off. The object lies
/// in both, so the checker counts the larger distance: the arm is clear, by the sphere's gap.
#[test]
fn a_track_is_as_far_as_the_farther_of_its_shape_and_its_sphere() {
    let (h, r, sigma_pos, sigma, t0) = (0.6, 0.05, 0.25, 0.85, 2.0);
    let (k, u) = link4();
    let d = k.r + 1.2;
    let p = [k.centre[0] + d * u[0], k.centre[1] + d * u[1], k.centre[2]];
    // Body z onto -u (end-on towards the link): a quarter turn about z × (-u).
    let ax = [u[1], -u[0], 0.0];
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let q = [s, s * ax[0], s * ax[1], s * ax[2]];
    let poses: Vec<TimedPose> =
        (0..=60).map(|i| TimedPose { t: 0.1 * i as f64, p, q, sigma, sigma_pos }).collect();
    let mut w = WorldInTime::new(0.05);
    let rod = DebrisShape::capsule(h, r);
    w.push_track(1, rod, &poses, After::Hold).unwrap();
    let margin = 0.05;
    let shape_alone = dkrrt_collision::Obstacle::from_desc(1, &rod, h + r, &p, &q, sigma + margin);
    assert!(shape_alone.distance(&k) < -0.3, "set-up: the inflated rod reaches into link 4");
    let mut ch = Checker::new(ArmModel::default_arm(), &limits().v_max, 0.03);
    ch.cap = 10.0;
    let c = ch.clearance_at(&w, &START, t0, 0.0, f64::NEG_INFINITY);
    let ball_gap = 1.2 - (h + r + sigma_pos + margin);
    assert!(c > 0.0 && c <= ball_gap + 1e-9, "clearance {c:.3}, the sphere's gap {ball_gap:.3}");
}

/// A rod (half length 0.6 m, radius 0.05 m, no bound) spinning at 10 rad/s about the direction
/// `u` square to link 4 of the arm resting at `START`, its centre `d` from the link's centre
/// along `u`, over 4 s.
fn rod_spinning_beside_link4(d: f64) -> WorldInTime {
    let (k, u) = link4();
    let p = [k.centre[0] + d * u[0], k.centre[1] + d * u[1], k.centre[2]];
    // Spin about z: the rod (body z) starts along x and sweeps the horizontal plane, which
    // holds `u`; a quarter turn about y first lays it down.
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let lay = [s, 0.0, s, 0.0];
    let poses: Vec<TimedPose> = (0..=40)
        .map(|i| {
            let t = 0.1 * i as f64;
            let h = 0.5 * 10.0 * t;
            let spin = [h.cos(), 0.0, 0.0, h.sin()];
            TimedPose { t, p, q: dkrrt_collision::pose::quat_mul(&spin, &lay), sigma: 0.0, sigma_pos: 0.0 }
        })
        .collect();
    let mut w = WorldInTime::new(0.0);
    w.push_track(1, DebrisShape::capsule(0.6, 0.05), &poses, After::Hold).unwrap();
    w
}

#[test]
fn a_spinning_rod_whose_ball_stays_clear_is_sampled_by_its_ball_and_one_that_sweeps_in_is_hit() {
    let (k, _) = link4();
    let mut ch = Checker::new(ArmModel::default_arm(), &limits().v_max, 0.03);
    // The rod's ball (0.65 m) stays 0.2 m off the link: its spin (6.5 m/s at the tips) no
    // longer spaces the samples. By the spin they would be at most (gap + δ) / 6.5 m/s apart,
    // the rod's gap to the link being at most 0.8 m (its centre's, less its radius).
    let w = rod_spinning_beside_link4(k.r + 0.65 + 0.2);
    let r = ch.check(&w, 0.0, 4.0, 4.0, false, |_| START);
    let by_spin = (4.0 * 6.5 / (0.8 + ch.delta())).floor() as u32;
    assert!(r.ok && r.samples * 2 <= by_spin, "{r:?} ({by_spin} samples by the spin)");
    // 0.3 m nearer, the tips sweep into the link twice a turn: found where a check every
    // millisecond first finds it.
    let w = rod_spinning_beside_link4(k.r + 0.65 - 0.1);
    let first = (0..=4000).map(|i| i as f64 * 1e-3).find(|&t| ch.clearance_at(&w, &START, t, 0.0, 0.0) < 0.0);
    let first = first.expect("set-up: the rod sweeps into the link");
    let r = ch.check(&w, 0.0, 4.0, 4.0, false, |_| START);
    assert!(!r.ok && r.t_fail <= first + 1e-3 && r.t_fail > first - 0.2, "{r:?}, first contact at {first}");
}

#[test]
fn a_clear_check_is_clear_at_every_millisecond() {
    // Random tumbling, turning, growing tracks; the arm at rest or moving within its speed
    // limits. Whenever the checker says clear, the clearance every millisecond is ≥ 0 (the
    // samples' δ/2 covers everything between them).
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::SmallRng::seed_from_u64(31);
    let lim = limits();
    let mut ch = Checker::new(ArmModel::default_arm(), &lim.v_max, 0.03);
    let mut dense = Checker::new(ArmModel::default_arm(), &lim.v_max, 0.03);
    dense.cap = 10.0;
    let (mut clear, mut close) = (0, 0);
    for _ in 0..40 {
        let w = random_world(&mut rng, 8);
        let q0: [f64; NJ] = std::array::from_fn(|j| START[j] + rng.random_range(-0.5..0.5));
        let moving = rng.random_bool(0.5);
        let dq: [f64; NJ] =
            std::array::from_fn(|j| if moving { lim.v_max[j] * rng.random_range(-1.0..1.0) } else { 0.0 });
        let at = |t: f64| -> [f64; NJ] { std::array::from_fn(|j| q0[j] + dq[j] * t) };
        let (t0, t1) = (rng.random_range(0.0..2.0), rng.random_range(2.0..4.5));
        let r = ch.check(&w, t0, t1, t1, moving, at);
        if !r.ok {
            continue;
        }
        clear += 1;
        let n = ((t1 - t0) / 1e-3) as usize;
        let m = (0..=n)
            .map(|i| {
                let t = t0 + (t1 - t0) * i as f64 / n as f64;
                dense.clearance_at(&w, &at(t), t, 0.0, f64::NEG_INFINITY)
            })
            .fold(f64::INFINITY, f64::min);
        assert!(m >= -1e-9, "clear by the checker, but {m} at some millisecond");
        close += (m < 0.2) as usize;
    }
    assert!(clear >= 5 && close >= 2, "cases exercised: {clear} clear, {close} of them close");
}

#[test]
fn a_fast_spinning_object_crossing_the_arm_is_never_missed() {
    // Small rods, bars and spheres at 3–10 m/s, spinning, each aimed at a random point of a random
    // link of the arm (at rest or moving within its limits) at a random time, passing within
    // -0.1..0.3 m of it. Whenever a check every half millisecond finds a contact, the checker
    // reports one (its samples, spaced by the shape's and the ball's gaps, skip none); when it
    // finds none, neither does the checker by more than its δ/2.
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::SmallRng::seed_from_u64(41);
    let lim = limits();
    let poser = dkrrt_collision::ArmPoser::new(ArmModel::default_arm());
    let mut caps = [dkrrt_collision::PosedCapsule::default(); NJ];
    let mut ch = Checker::new(ArmModel::default_arm(), &lim.v_max, 0.03);
    let mut dense = Checker::new(ArmModel::default_arm(), &lim.v_max, 0.03);
    dense.cap = 10.0;
    let (mut hits, mut misses) = (0, 0);
    for case in 0..60 {
        let q0: [f64; NJ] = std::array::from_fn(|j| START[j] + rng.random_range(-0.3..0.3));
        let moving = case % 2 == 1;
        let dq: [f64; NJ] =
            std::array::from_fn(|j| if moving { lim.v_max[j] * rng.random_range(-1.0..1.0) } else { 0.0 });
        let at = |t: f64| -> [f64; NJ] { std::array::from_fn(|j| q0[j] + dq[j] * t) };
        let t_c = rng.random_range(0.3..3.7);
        poser.pose(&at(t_c), &mut caps);
        let c = caps[rng.random_range(1..NJ)];
        let f = rng.random_range(0.0..1.0);
        let aim: [f64; 3] = std::array::from_fn(|k| c.a[k] + f * (c.b[k] - c.a[k]));
        let dir: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        let n = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]).sqrt();
        let speed = rng.random_range(3.0..10.0);
        let v: [f64; 3] = std::array::from_fn(|k| speed * dir[k] / n);
        // Off the line by a random miss, square to the flight.
        let side = [dir[1], -dir[0], 0.0];
        let sn = (side[0] * side[0] + side[1] * side[1]).sqrt().max(1e-9);
        let (shape, size) = match case % 3 {
            0 => (DebrisShape::sphere(0.05), 0.05),
            1 => (DebrisShape::capsule(0.15, 0.02), 0.17),
            _ => (DebrisShape::cuboid([0.15, 0.03, 0.02], [0.0; 3]), 0.155),
        };
        let miss = c.r + size + rng.random_range(-0.1..0.3);
        let p_c: [f64; 3] = std::array::from_fn(|k| aim[k] + miss * side[k] / sn);
        let w_spin = rng.random_range(-8.0..8.0);
        let poses: Vec<TimedPose> = (0..=45)
            .map(|i| {
                let t = 0.1 * i as f64;
                let h = 0.5 * w_spin * t;
                TimedPose {
                    t,
                    p: std::array::from_fn(|k| p_c[k] + v[k] * (t - t_c)),
                    q: [h.cos(), h.sin() * 0.6, 0.0, h.sin() * 0.8],
                    sigma: 0.0,
                    sigma_pos: 0.0,
                }
            })
            .collect();
        let mut w = WorldInTime::new(0.0);
        w.push_track(1, shape, &poses, After::Hold).unwrap();
        let r = ch.check(&w, 0.0, 4.0, 4.0, moving, at);
        let steps = 8000;
        let truth = (0..=steps)
            .map(|i| {
                let t = 4.0 * i as f64 / steps as f64;
                dense.clearance_at(&w, &at(t), t, 0.0, f64::NEG_INFINITY)
            })
            .fold(f64::INFINITY, f64::min);
        if truth < 0.0 {
            hits += 1;
            assert!(!r.ok, "case {case}: a contact ({truth:.3} m) the checker missed: {r:?}");
        } else {
            misses += 1;
            assert!(r.ok || truth < ch.delta(), "case {case}: clear by {truth:.3} m, yet {r:?}");
        }
    }
    assert!(hits >= 10 && misses >= 10, "cases exercised: {hits} contacts, {misses} clear");
}

#[test]
fn a_turning_shapes_points_move_no_faster_than_its_speed_bound() {
    // Shapes turning at 2 rad/s about fixed axes, the centre still, no bound: over any short
    // window every point of the shape moves at most `speed_within` × the window. For a box
    // the bound is exact (its farthest corner from the turn's axis); for a rod it is its end's
    // distance plus its radius, however small the turn's share across the rod's axis.
    let shapes = [
        (DebrisShape::cuboid([0.4, 0.3, 0.02], [0.1, 0.0, 0.0]), true),
        (DebrisShape::cuboid([0.05, 0.05, 0.6], [0.0; 3]), true),
        (DebrisShape::capsule(0.6, 0.05), false),
    ];
    let axes: [[f64; 3]; 4] = [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 0.6, 0.8], [0.3, 0.5, 0.8]];
    let omega = 2.0;
    for (shape, exact) in shapes {
        for ax in axes {
            let l = (ax[0] * ax[0] + ax[1] * ax[1] + ax[2] * ax[2]).sqrt();
            let n = ax.map(|x| x / l);
            let q_at = |t: f64| {
                let h = 0.5 * omega * t;
                [h.cos(), n[0] * h.sin(), n[1] * h.sin(), n[2] * h.sin()]
            };
            let poses: Vec<TimedPose> = (0..=30)
                .map(|k| {
                    let t = 0.1 * k as f64;
                    TimedPose { t, p: [0.0; 3], q: q_at(t), sigma: 0.0, sigma_pos: 0.0 }
                })
                .collect();
            let mut w = WorldInTime::new(0.0);
            w.push_track(1, shape, &poses, After::Hold).unwrap();
            // Body points: a box's corners; a rod's ends with its radius in 64 directions.
            let (d, o) = (shape.dims, shape.offset);
            let mut pts = Vec::new();
            if shape.kind == dkrrt_msg::ShapeKind::Box as u32 {
                for s in 0..8 {
                    let sg = |b: usize| if s >> b & 1 == 1 { 1.0 } else { -1.0 };
                    pts.push([o[0] + sg(0) * d[0], o[1] + sg(1) * d[1], o[2] + sg(2) * d[2]]);
                }
            } else {
                for e in [-1.0, 1.0] {
                    for k in 0..64 {
                        let (a, b) = (k as f64 * 0.7, k as f64 * 1.3);
                        let u = [a.sin() * b.cos(), a.sin() * b.sin(), a.cos()];
                        pts.push([d[1] * u[0], d[1] * u[1], e * d[0] + d[1] * u[2]]);
                    }
                }
            }
            let mut tightest: f64 = 0.0;
            for k in 0..50 {
                let (a, dt) = (0.05 + 0.05 * k as f64, 0.01);
                let v = w.speed_within(0, a, a + dt);
                let (qa, qb) = (w.pose_at(0, a).1, w.pose_at(0, a + dt).1);
                for x in &pts {
                    let (pa, pb) = (
                        dkrrt_collision::pose::quat_rotate(&qa, x),
                        dkrrt_collision::pose::quat_rotate(&qb, x),
                    );
                    let moved =
                        ((pa[0] - pb[0]).powi(2) + (pa[1] - pb[1]).powi(2) + (pa[2] - pb[2]).powi(2)).sqrt();
                    assert!(moved <= v * dt + 1e-12, "{shape:?} about {n:?} at {a}: {moved} > {}", v * dt);
                    tightest = tightest.max(moved / (v * dt));
                }
            }
            if exact {
                assert!(tightest > 0.99, "{shape:?} about {n:?}: the bound is loose ({tightest})");
            }
        }
    }
}

#[test]
fn a_forecast_rod_or_box_reported_end_over_end_is_not_swept_between_steps() {
    // A still rod (and a still bar) whose forecast attitude alternates between two half turns
    // of each other, the same shape at every step: between steps it stays where it is (no
    // sweep through half a turn, no turn speed), and a box with an offset (not its own half
    // turn) keeps the turns it was given.
    use dkrrt_msg::{DebrisForecast, ForecastStep};
    let lay = [std::f64::consts::FRAC_1_SQRT_2, 0.0, std::f64::consts::FRAC_1_SQRT_2, 0.0];
    let flipped = dkrrt_collision::pose::quat_mul(&lay, &[0.0, 1.0, 0.0, 0.0]);
    let shapes = [
        (DebrisShape::capsule(0.6, 0.05), true),
        (DebrisShape::cuboid([0.05, 0.05, 0.6], [0.0; 3]), true),
        (DebrisShape::cuboid([0.05, 0.05, 0.6], [0.0, 0.0, 0.2]), false),
    ];
    for (shape, symmetric) in shapes {
        let mut f = <DebrisForecast as Zeroed>::zeroed();
        (f.count, f.steps, f.dt_s, f.t0_ns) = (1, 10, 0.1, 0);
        f.tracks[0].id = 3;
        f.tracks[0].shape = shape;
        f.tracks[0].bounding_radius = shape.bounding_radius();
        for k in 0..10 {
            let q = if k % 2 == 0 { lay } else { flipped };
            f.tracks[0].steps[k] = ForecastStep { p: [2.0, 0.0, 0.0], q, sigma_m: 0.01, sigma_pos_m: 0.01 };
        }
        let mut w = WorldInTime::new(0.0);
        w.load_forecast(&f);
        if symmetric {
            assert!(w.max_speed() < 0.1, "{shape:?}: {}", w.max_speed()); // the bound's growth past the horizon
                                                                          // Mid-step, the shape's axis is the reported one (up to its sign).
            let q = w.pose_at(0, 0.25).1;
            let z = dkrrt_collision::pose::quat_rotate(&q, &[0.0, 0.0, 1.0]);
            assert!(z[0].abs() > 1.0 - 1e-9, "{shape:?}: axis {z:?}");
        } else {
            assert!(w.max_speed() > 10.0, "{shape:?}: {}", w.max_speed());
        }
    }
}

#[test]
fn a_fast_leg_after_a_still_one_is_not_stepped_over() {
    // A 2 cm ball holds still 2.4 m from link 4 until 0.59 s, then flies through the link at
    // 8 m/s (at 0.89 s, and gone 30 ms later): the samples before the fast leg are spaced by
    // the speeds ahead of them over the longest step, not by the still leg's, and the contact
    // is found.
    let t_cross = 0.89;
    let (_, p0, v) = rod_across_link4(t_cross);
    let line = |t: f64| -> [f64; 3] { std::array::from_fn(|k| p0[k] + v[k] * t) };
    let poses: Vec<TimedPose> = (0..=30)
        .map(|k| {
            let t = 0.1 * k as f64;
            TimedPose { t, p: line(t.max(0.59)), q: [1.0, 0.0, 0.0, 0.0], sigma: 0.0, sigma_pos: 0.0 }
        })
        .collect();
    let mut w = WorldInTime::new(0.0);
    w.push_track(1, DebrisShape::sphere(0.02), &poses, After::Hold).unwrap();
    let mut ch = Checker::new(ArmModel::default_arm(), &limits().v_max, 0.03);
    let r = ch.check(&w, 0.0, 3.0, 3.0, false, |_| START);
    assert!(!r.ok && (r.t_fail - t_cross).abs() < 0.1, "{r:?}");
}
