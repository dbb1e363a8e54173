//! A planning problem as a file (`dkrrt plan --problem FILE.json`): its format, its checks and
//! its solution. The format is documented in `docs/planning-problem.md`.

use dkrrt_model::{ArmModel, NJ};
use dkrrt_msg::{DebrisShape, Trajectory, Zeroed};
use dkrrt_otg::{KinState, Limits};
use serde::{Deserialize, Serialize};

use crate::build::Builder;
use crate::check::Checker;
use crate::connect::Connect;
use crate::replan::check_message;
use crate::rrt::{Planner, PlannerConfig, Reach, Request};
use crate::world::{After, TimedPose, WorldInTime};

/// An obstacle's shape (`capsule`: axis along local z).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ProblemShape {
    Sphere {
        radius: f64,
    },
    Box {
        #[serde(deserialize_with = "dkrrt_io::exact::array")]
        half_extents: [f64; 3],
    },
    Capsule {
        half_length: f64,
        radius: f64,
    },
    /// A flat cylinder about the local z axis.
    Disc {
        radius: f64,
        half_thickness: f64,
    },
}

/// One timed pose (base frame of the arm; `q` = w, x, y, z).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProblemPose {
    pub t: f64,
    #[serde(deserialize_with = "dkrrt_io::exact::array")]
    pub p: [f64; 3],
    #[serde(deserialize_with = "dkrrt_io::exact::array")]
    pub q: [f64; 4],
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProblemObstacle {
    pub shape: ProblemShape,
    /// One pose: static; several: linearly interpolated (attitude slerp), held after the last.
    pub poses: Vec<ProblemPose>,
}

/// The problem file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Problem {
    /// URDF file of the arm; "" = the shipped arm.
    pub urdf: String,
    #[serde(deserialize_with = "dkrrt_io::exact::array")]
    pub start: [f64; NJ],
    #[serde(deserialize_with = "dkrrt_io::exact::array")]
    pub goal: [f64; NJ],
    /// Joint speed limits, rad/s (default: the shipped scenario's motion limits).
    #[serde(default, deserialize_with = "dkrrt_io::exact::opt_array")]
    pub v_max: Option<[f64; NJ]>,
    pub margin_m: f64,
    pub time_limit_s: f64,
    pub seed: u64,
    pub obstacles: Vec<ProblemObstacle>,
}

/// A field of the problem that is wrong, and why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{field}: {reason}")]
pub struct ProblemError {
    pub field: String,
    pub reason: String,
}

fn err(field: impl Into<String>, reason: impl Into<String>) -> ProblemError {
    ProblemError { field: field.into(), reason: reason.into() }
}

fn finite(field: &str, xs: &[f64]) -> Result<(), ProblemError> {
    match xs.iter().position(|x| !x.is_finite()) {
        Some(i) => Err(err(format!("{field}[{i}]"), "must be a finite number")),
        None => Ok(()),
    }
}

impl Problem {
    /// Parses and checks a problem; errors name the field (`obstacles[2].poses[0].q`, ...).
    pub fn from_json(text: &str) -> Result<Problem, ProblemError> {
        // The path of the value a type error is in (`seed`, `obstacles[1].poses[0].t`); the
        // whole problem for a syntax error or a missing or unknown field at the top.
        let mut de = serde_json::Deserializer::from_str(text);
        let p: Problem = serde_path_to_error::deserialize(&mut de).map_err(|e| {
            let path = e.path().to_string();
            let field = if path == "." { "problem".to_string() } else { path };
            err(field, e.into_inner().to_string())
        })?;
        // Nothing but white space after the problem (as `serde_json::from_str` checks).
        de.end().map_err(|e| err("problem", e.to_string()))?;
        p.validate()?;
        Ok(p)
    }

    /// Range checks (the joint limits are checked against the arm by [`solve`]).
    pub fn validate(&self) -> Result<(), ProblemError> {
        finite("start", &self.start)?;
        finite("goal", &self.goal)?;
        if let Some(v) = &self.v_max {
            finite("v_max", v)?;
            if let Some(i) = v.iter().position(|x| *x <= 0.0) {
                return Err(err(format!("v_max[{i}]"), "must be > 0"));
            }
        }
        if !(self.margin_m.is_finite() && (0.0..=1.0).contains(&self.margin_m)) {
            return Err(err("margin_m", "must be within [0, 1] m"));
        }
        if !(self.time_limit_s.is_finite() && self.time_limit_s > 0.0 && self.time_limit_s <= 600.0) {
            return Err(err("time_limit_s", "must be within (0, 600] s"));
        }
        if self.obstacles.len() > crate::world::MAX_TRACKS {
            return Err(err("obstacles", format!("at most {} obstacles", crate::world::MAX_TRACKS)));
        }
        for (i, o) in self.obstacles.iter().enumerate() {
            let f = |x: &str| format!("obstacles[{i}].{x}");
            let dims: Vec<(String, f64)> = match &o.shape {
                ProblemShape::Sphere { radius } => vec![(f("shape.radius"), *radius)],
                ProblemShape::Box { half_extents: h } => {
                    (0..3).map(|k| (f(&format!("shape.half_extents[{k}]")), h[k])).collect()
                }
                ProblemShape::Capsule { half_length, radius } => {
                    vec![(f("shape.half_length"), *half_length), (f("shape.radius"), *radius)]
                }
                ProblemShape::Disc { radius, half_thickness } => {
                    vec![(f("shape.radius"), *radius), (f("shape.half_thickness"), *half_thickness)]
                }
            };
            for (name, v) in dims {
                if !(v.is_finite() && v > 0.0 && v <= 50.0) {
                    return Err(err(name, "must be within (0, 50] m"));
                }
            }
            if o.poses.is_empty() {
                return Err(err(f("poses"), "at least one pose"));
            }
            for (k, p) in o.poses.iter().enumerate() {
                let g = |x: &str| format!("obstacles[{i}].poses[{k}].{x}");
                if !p.t.is_finite() {
                    return Err(err(g("t"), "must be a finite number"));
                }
                if k > 0 && p.t <= o.poses[k - 1].t {
                    return Err(err(g("t"), "times must increase"));
                }
                finite(&g("p"), &p.p)?;
                finite(&g("q"), &p.q)?;
                let n = p.q.iter().map(|x| x * x).sum::<f64>().sqrt();
                if (n - 1.0).abs() > 1e-3 {
                    return Err(err(g("q"), format!("must be a unit quaternion (norm {n})")));
                }
            }
        }
        Ok(())
    }

    /// The obstacles as a world in time (held after their last pose).
    pub fn world(&self) -> Result<WorldInTime, ProblemError> {
        let mut w = WorldInTime::new(self.margin_m);
        for (i, o) in self.obstacles.iter().enumerate() {
            let shape = match &o.shape {
                ProblemShape::Sphere { radius } => DebrisShape::sphere(*radius),
                ProblemShape::Box { half_extents } => DebrisShape::cuboid(*half_extents, [0.0; 3]),
                ProblemShape::Capsule { half_length, radius } => DebrisShape::capsule(*half_length, *radius),
                ProblemShape::Disc { radius, half_thickness } => DebrisShape::disc(*radius, *half_thickness),
            };
            let poses: Vec<TimedPose> = o
                .poses
                .iter()
                .map(|p| {
                    let n = p.q.iter().map(|x| x * x).sum::<f64>().sqrt();
                    TimedPose { t: p.t, p: p.p, q: p.q.map(|x| x / n), sigma: 0.0, sigma_pos: 0.0 }
                })
                .collect();
            w.push_track(i as u32, shape, &poses, After::Hold)
                .map_err(|e| err(format!("obstacles[{i}]"), e.to_string()))?;
        }
        Ok(w)
    }
}

/// Largest problem file read, bytes.
pub const MAX_PROBLEM_BYTES: u64 = 64 << 20;

/// Reads and checks a problem file and loads its arm (the shipped one, or its `urdf`, a path
/// relative to the file); `time_limit` overrides the file's. Errors name the file and the field.
pub fn load(path: &std::path::Path, time_limit: Option<f64>) -> Result<(Problem, ArmModel), String> {
    let name = path.display();
    let text = dkrrt_io::read_text_capped(path, MAX_PROBLEM_BYTES).map_err(|e| format!("{name}: {e}"))?;
    let mut p = Problem::from_json(&text).map_err(|e| format!("{name}: {e}"))?;
    if let Some(t) = time_limit {
        p.time_limit_s = t;
        p.validate().map_err(|e| format!("--time-limit: {e}"))?;
    }
    let model = if p.urdf.is_empty() {
        ArmModel::default_arm()
    } else {
        let u = path.parent().unwrap_or(std::path::Path::new(".")).join(&p.urdf);
        ArmModel::from_urdf_file(&u).map_err(|e| format!("{name}: urdf {}: {e}", u.display()))?
    };
    Ok((p, model))
}

/// The answer of [`solve`] (the `dkrrt plan` output).
#[derive(Debug, Clone, Serialize)]
pub struct Solution {
    pub solved: bool,
    pub first_solution_s: Option<f64>,
    /// Configurations the checker measured up to the first solution (when RRT-Connect found
    /// it; every sample of every segment), and in all.
    pub first_solution_configs: Option<u64>,
    pub configs_checked: u64,
    pub plan_time_s: f64,
    pub iterations: u32,
    /// Waypoints (rest configurations: start, …, goal) and the times the arm is at them.
    pub path: Vec<[f64; NJ]>,
    pub times_s: Vec<f64>,
    /// The timed trajectory the tracker would follow, every 10 ms: [t, q1..q6].
    pub trajectory: Vec<[f64; NJ + 1]>,
    pub duration_s: f64,
    pub path_length_rad: f64,
    /// Smallest clearance along the trajectory (every 1 ms, beyond the margin), m; `None`
    /// when unsolved before a plan was made, or when nothing came within
    /// [`MEASURED_UP_TO_M`] of the arm (no obstacles, or all far).
    pub min_clearance_m: Option<f64>,
    /// Why it is not solved, when a reason is known (printed, not in the JSON output).
    #[serde(skip)]
    pub why: Option<String>,
}

/// The finer δ of the final check, m, when the planner's δ rejects a plan (see [`solve`]).
pub const FINE_DELTA_M: f64 = 0.006;

/// The clearances of a problem's start, goal and final check are measured up to this, m.
pub const MEASURED_UP_TO_M: f64 = 100.0;
/// The finest δ a problem's start or goal near an obstacle gets, m (see [`solve`]).
pub const MIN_DELTA_M: f64 = 0.002;

/// A problem made ready to plan: its world, the planner (with the δ the problem needs), the
/// clearances of its start and goal. What [`solve`] plans with, and what a reference planner
/// checks its motions with (the C ABI in `planner/cabi`), so both are judged alike.
pub struct Prepared {
    pub world: WorldInTime,
    pub planner: Planner,
    pub limits: Limits<NJ>,
    /// The start's clearance at t = 0 and the goal's after the last pose, m (< 0: in collision).
    pub start_clear: f64,
    pub goal_clear: f64,
    /// Time of the last obstacle pose, s.
    pub horizon: f64,
    /// No obstacle moves, and the start and the goal leave the δ/2 every segment check needs:
    /// RRT-Connect in joint space applies ([`crate::connect`]).
    pub still: bool,
    model: ArmModel,
}

impl Prepared {
    /// Checks `p` against the arm `model` (joint limits) and prepares it; `v_default`: the
    /// joint speed limits when the file has none; `a_max`/`j_max`: the motion limits.
    pub fn new(
        p: &Problem,
        model: ArmModel,
        v_default: [f64; NJ],
        a_max: [f64; NJ],
        j_max: [f64; NJ],
    ) -> Result<Prepared, ProblemError> {
        let l = *model.limits();
        for (name, q) in [("start", &p.start), ("goal", &p.goal)] {
            for i in 0..NJ {
                if !(l.q_min[i]..=l.q_max[i]).contains(&q[i]) {
                    return Err(err(
                        format!("{name}[{i}]"),
                        format!("outside the joint limits [{}, {}]", l.q_min[i], l.q_max[i]),
                    ));
                }
            }
        }
        let world = p.world()?;
        let horizon = p.obstacles.iter().flat_map(|o| o.poses.last()).map(|x| x.t).fold(0.0, f64::max);
        let limits = Limits { v_max: p.v_max.unwrap_or(v_default), a_max, j_max };
        // Where the start and the goal stand (a reason to give when unsolved).
        let mut probe = Checker::new(model.clone(), &limits.v_max, PlannerConfig::default().delta_m);
        probe.cap = MEASURED_UP_TO_M;
        let start_clear = probe.clearance_at(&world, &p.start, 0.0, 0.0, f64::NEG_INFINITY);
        let goal_clear = probe.clearance_at(&world, &p.goal, horizon, 0.0, f64::NEG_INFINITY);
        // Every sample of a check needs δ/2 of clearance, the arm at rest at the start and at
        // the goal included: a start or a goal nearer than that gets a finer δ (denser samples).
        let near = start_clear.min(goal_clear);
        let delta_m = if near >= 0.0 {
            (1.8 * near).clamp(MIN_DELTA_M, PlannerConfig::default().delta_m)
        } else {
            PlannerConfig::default().delta_m
        };
        let cfg = PlannerConfig {
            seed: p.seed,
            delta_m,
            // The obstacles' motion is known for all time (held after the last pose): check
            // every motion to its end, and rests to 5 s past the last pose.
            lookahead_s: (horizon + 5.0).max(60.0),
            check_whole_motions: true,
            improve_iters: u32::MAX,
            max_configs: u64::MAX,
            max_nodes: 4000,
            ..PlannerConfig::default()
        };
        let planner = Planner::new(model.clone(), limits, cfg);
        let moving =
            p.obstacles.iter().any(|o| o.poses.windows(2).any(|w| w[0].p != w[1].p || w[0].q != w[1].q));
        let half = 0.5 * delta_m;
        let still = !moving && start_clear >= half && goal_clear >= half;
        Ok(Prepared { world, planner, limits, start_clear, goal_clear, horizon, still, model })
    }

    /// The RRT-Connect search of this problem (trees of `max_nodes` each).
    pub fn connect(&self, max_nodes: usize, seed: u64) -> Connect {
        let l = self.model.limits();
        Connect::new(l.q_min.into(), l.q_max.into(), self.limits.v_max, max_nodes, seed)
    }

    /// Times a path of rest configurations (the planner's rest-to-rest motions between its
    /// waypoints) into `out`; the arrival times at its inner waypoints. `None`: a motion could
    /// not be timed, or the message has too few segments for the path.
    pub fn time_path(&self, path: &[[f64; NJ]], out: &mut Trajectory) -> Option<Vec<f64>> {
        write_path(&self.planner, path, out)
    }

    /// The final check of a timed plan: the sampled check of the message (again at
    /// [`FINE_DELTA_M`] if it fails at the planner's δ), and the clearance every 1 ms to 1 s
    /// past its end or past the obstacles' last pose, whichever is later: the arm rests at the
    /// goal after the plan's end, and only once the obstacles hold their last poses too does
    /// nothing change. (passed, smallest clearance beyond the margin [m]).
    pub fn verify(&mut self, out: &Trajectory) -> (bool, f64) {
        let end = out.duration_s.max(self.horizon) + 1.0;
        let (mut ok, _) = check_message(&mut self.planner, &self.world, out, 0.0, end);
        if !ok && self.planner.cfg.delta_m > FINE_DELTA_M {
            // The sampled check needs δ/2 of clearance at each sample, so a plan that passes
            // nearer than that can fail it where a sample falls: checked again with a finer δ.
            let fine = Checker::new(self.model.clone(), &self.limits.v_max, FINE_DELTA_M);
            let coarse = std::mem::replace(&mut self.planner.checker, fine);
            ok = check_message(&mut self.planner, &self.world, out, 0.0, end).0;
            self.planner.checker = coarse;
        }
        let cap = std::mem::replace(&mut self.planner.checker.cap, MEASURED_UP_TO_M);
        let m = self.min_clearance_on_grid(out, end);
        self.planner.checker.cap = cap;
        (ok && m >= 0.0, m)
    }
}

impl Prepared {
    /// The smallest clearance of `out` at the times `k` ms, `0 ≤ k ms ≤ end` — exactly the
    /// minimum over that grid, without measuring every point of it: the clearance changes no
    /// faster than `L` = the arm's speed bound (from its joints' speed peaks over the stretch)
    /// plus the fastest obstacle's (over the stretch),
    /// so between grid points `a < b` it stays above `(c(a) + c(b) − L (b − a)) / 2` (at the
    /// cap when no obstacle comes within the cap of the arm's reach over the stretch); a
    /// stretch whose bound is not below the smallest clearance found so far cannot lower it
    /// and is left unmeasured. Stretches are split at their middle, lowest bound first. Joint
    /// limits (a configuration outside them counts as clearance −1) are checked along the
    /// whole trajectory, between grid points too ([`within_limits`]). A 156 s plan among 32
    /// obstacles: 1.2 s with every point measured (156 000
    /// configurations), test `the_final_check_finds_the_grid_minimum_measuring_few_points`.
    fn min_clearance_on_grid(&mut self, out: &Trajectory, end: f64) -> f64 {
        const DT: f64 = 1e-3;
        let last = (end / DT + 1e-9).floor().max(0.0) as u64;
        let at = |k: u64| (k as f64 * DT).min(end);
        if !within_limits(out, self.model.limits()) {
            return -1.0;
        }
        let n = self.world.len();
        // The point speed bound is linear in the joint speeds: each joint's lever, once.
        let lever: [f64; NJ] = std::array::from_fn(|j| {
            let mut e = [0.0; NJ];
            e[j] = 1.0;
            self.planner.checker.point_speed(&e)
        });
        let rate = |a: f64, b: f64| {
            let peaks = crate::replan::message_speed_peaks(out, a, b);
            (0..NJ).map(|j| peaks[j] * lever[j]).sum::<f64>()
                + (0..n).map(|i| self.world.speed_within(i, a, b)).fold(0.0, f64::max)
        };
        let (reach, cap) = (self.planner.checker.reach(), self.planner.checker.cap);
        let (checker, world) = (&mut self.planner.checker, &self.world);
        let mut measure = |k: u64| {
            let t = at(k);
            checker.clearance_at(world, &out.sample(t).p, t, 0.0, f64::NEG_INFINITY)
        };
        let (c0, c1) = (measure(0), measure(last));
        let mut m = c0.min(c1);
        // (bound, first, last, c(first), c(last)), lowest bound first.
        let mut open = std::collections::BinaryHeap::new();
        // No obstacle within the cap of the arm's reach over the stretch: the cap throughout.
        let (centre, reach) = (reach.0, reach.1 + cap);
        let bound = |a: u64, b: u64, ca: f64, cb: f64| {
            let (ta, tb) = (at(a), at(b));
            if self.world.near(ta, tb, &centre, reach, 0.0).0 == 0 {
                return cap;
            }
            0.5 * (ca + cb - rate(ta, tb) * (tb - ta))
        };
        if last > 1 {
            open.push(Stretch(bound(0, last, c0, c1), 0, last, c0, c1));
        }
        while let Some(Stretch(lb, a, b, ca, cb)) = open.pop() {
            if lb >= m {
                break; // no stretch left can hold a lower clearance
            }
            let k = a + (b - a) / 2;
            let ck = measure(k);
            m = m.min(ck);
            for (x, y, cx, cy) in [(a, k, ca, ck), (k, b, ck, cb)] {
                if y - x > 1 {
                    open.push(Stretch(bound(x, y, cx, cy), x, y, cx, cy));
                }
            }
        }
        m
    }
}

/// Whether every joint of `out` stays within `l` (to 1e-9 rad) at every time, not only at
/// the grid's: each constant-jerk segment's ends and its turning points (where its speed is
/// 0) are its extremes.
fn within_limits(out: &Trajectory, l: &dkrrt_model::JointLimits) -> bool {
    use dkrrt_msg::MAX_SEGMENTS;
    let end = out.duration_s.max(0.0);
    (0..NJ).all(|j| {
        let n = (out.n_seg[j] as usize).clamp(1, MAX_SEGMENTS);
        let ok = |t: f64| {
            let q = out.sample_joint(j, t).0;
            q.is_finite() && q >= l.q_min[j] - 1e-9 && q <= l.q_max[j] + 1e-9
        };
        (0..n).all(|k| {
            let s = &out.seg[j][k];
            let t0 = s.t0.clamp(0.0, end);
            let t1 = if k + 1 < n { out.seg[j][k + 1].t0.clamp(t0, end) } else { end };
            let turns = dkrrt_otg::turning_points(
                s.v + (t0 - s.t0) * (s.a + (t0 - s.t0) * s.j / 2.0),
                s.a + (t0 - s.t0) * s.j,
                s.j,
                t1 - t0,
            );
            ok(t0) && ok(t1) && turns.iter().all(|&r| r.is_nan() || ok(t0 + r))
        })
    })
}

/// A stretch of the final check's grid: (lower bound, first, last, clearances at both ends);
/// ordered so that a max-heap pops the lowest bound first (NaN bounds first: measured).
struct Stretch(f64, u64, u64, f64, f64);

impl PartialEq for Stretch {
    fn eq(&self, o: &Self) -> bool {
        self.cmp(o) == std::cmp::Ordering::Equal
    }
}
impl Eq for Stretch {}
impl PartialOrd for Stretch {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Stretch {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        let key = |x: f64| if x.is_nan() { f64::NEG_INFINITY } else { x };
        key(o.0).total_cmp(&key(self.0)).then(o.1.cmp(&self.1))
    }
}

/// Solves `p` for the arm `model` within `p.time_limit_s` (wall clock), anytime: the first
/// solution, then improvements until the time limit. `a_max`/`j_max`: the motion limits.
pub fn solve(
    p: &Problem,
    model: ArmModel,
    v_default: [f64; NJ],
    a_max: [f64; NJ],
    j_max: [f64; NJ],
) -> Result<Solution, ProblemError> {
    let mut prep = Prepared::new(p, model, v_default, a_max, j_max)?;
    // The clock (the time limit, first_solution_s, plan_time_s) counts the search, from the
    // prepared problem on (as compare.py times OMPL's planners on the prepared C ABI handle).
    let t_start = std::time::Instant::now();
    let (start_clear, goal_clear, horizon) = (prep.start_clear, prep.goal_clear, prep.horizon);
    let mut sol = Solution {
        solved: false,
        first_solution_s: None,
        first_solution_configs: None,
        configs_checked: 0,
        plan_time_s: 0.0,
        iterations: 0,
        path: Vec::new(),
        times_s: Vec::new(),
        trajectory: Vec::new(),
        duration_s: 0.0,
        path_length_rad: 0.0,
        min_clearance_m: None,
        why: None,
    };
    // A start in collision at t = 0, or a goal in collision from the last pose on (where
    // every plan rests), fails every plan's final check: no search.
    let in_collision = if start_clear < 0.0 {
        Some(format!("the start is in collision at t = 0 (clearance {start_clear:.3} m)"))
    } else if goal_clear < 0.0 {
        Some(format!("the goal is in collision from t = {horizon:.2} s on (clearance {goal_clear:.3} m)"))
    } else {
        None
    };
    if in_collision.is_some() {
        sol.why = in_collision;
        sol.plan_time_s = t_start.elapsed().as_secs_f64();
        return Ok(sol);
    }
    let mut out = Box::new(<Trajectory as Zeroed>::zeroed());
    let mut best = Box::new(<Trajectory as Zeroed>::zeroed());
    let mut waypoints: Vec<([f64; NJ], f64)> = Vec::new();
    let limit = p.time_limit_s;
    let req = Request { start: KinState::rest(p.start), t0: 0.0, goal: p.goal };
    let (mut arrival, mut first_solution_s, mut iterations, mut rounds) = (f64::MAX, None, 0u32, 0u32);
    // Nothing moves: RRT-Connect in joint space (`crate::connect`), each path found shortcut
    // and timed by rest-to-rest motions, again and again until the time limit (anytime by
    // restarts, as OMPL's AnytimePathShortening: a first solution in milliseconds, then the
    // best of many). The space-time rounds below get the time only if it finds nothing.
    let connect = prep.still;
    // No plan arrives before the direct rest-to-rest motion would (every joint must cover its
    // own distance within its limits): an arrival that early ends the search.
    let direct = prep.time_path(&[p.start, p.goal], &mut out).map_or(0.0, |_| out.duration_s);
    let optimal = |arrival: f64| arrival <= direct + 1e-6;
    prep.planner.arrival_floor = direct + 1e-6;
    // A check of a very slow motion may take long: none runs past the time limit.
    prep.planner.checker.deadline = Some(t_start + std::time::Duration::from_secs_f64(limit));
    let configs0 = prep.planner.checker.configs_checked;
    let mut first_configs = None;
    if connect {
        let keep_going = || t_start.elapsed().as_secs_f64() < limit;
        let mut c = prep.connect(20_000, p.seed);
        let mut path = Vec::new();
        let mut cand = Box::new(<Trajectory as Zeroed>::zeroed());
        let Prepared { planner, world, .. } = &mut prep;
        loop {
            if !c.solve(&mut planner.checker, world, &p.start, &p.goal, keep_going, &mut path) {
                break;
            }
            let found_s = t_start.elapsed().as_secs_f64();
            let found_configs = planner.checker.configs_checked - configs0;
            // Shortcut; more while the path has more waypoints than a message carries motions.
            for _ in 0..10 {
                c.shortcut(&mut planner.checker, world, &mut path, 200, keep_going);
                if let Some(times) = write_path(planner, &path, &mut cand) {
                    first_solution_s = first_solution_s.or(Some(found_s));
                    first_configs = first_configs.or(Some(found_configs));
                    if cand.duration_s < arrival {
                        arrival = cand.duration_s;
                        *best = *cand;
                        waypoints.clear();
                        waypoints.extend(path[1..path.len() - 1].iter().copied().zip(times));
                    }
                    break;
                }
                if !keep_going() {
                    break;
                }
            }
            // The straight motion is the shortest; else search again (fresh trees, the random
            // stream going on) while time remains, keeping the earliest arrival.
            if path.len() <= 2 || optimal(arrival) || !keep_going() {
                break;
            }
        }
        iterations = iterations.saturating_add(c.iterations.min(u32::MAX as u64) as u32);
    }
    // Rounds until the time limit: a round ends when its tree is full, and the next grows a
    // new tree (the random stream goes on) that keeps only arrivals earlier than the best.
    while !optimal(arrival) {
        let round_s = t_start.elapsed().as_secs_f64();
        let keep_going = || t_start.elapsed().as_secs_f64() < limit;
        let Prepared { planner, world, .. } = &mut prep;
        let plan = planner.plan_to_beat(&req, world, arrival, u32::MAX, keep_going, 1, &mut out);
        iterations = iterations.saturating_add(planner.stats.iterations);
        rounds += 1;
        if let Some(pl) = plan.filter(|x| x.reach == Reach::Goal && x.arrival < arrival) {
            arrival = pl.arrival;
            first_solution_s = first_solution_s.or(planner.first_solution_s.map(|f| round_s + f));
            *best = *out;
            waypoints.clear();
            waypoints.extend(planner.waypoints());
        }
        if t_start.elapsed().as_secs_f64() >= limit {
            break;
        }
    }
    let out = best;
    let plan_time_s = t_start.elapsed().as_secs_f64();
    prep.planner.checker.deadline = None;
    let capped = prep.planner.checker.capped;
    let solved = first_solution_s.is_some();
    sol.first_solution_configs = first_configs;
    sol.configs_checked = prep.planner.checker.configs_checked - configs0;
    sol.plan_time_s = plan_time_s;
    sol.iterations = iterations;
    if !solved {
        sol.first_solution_configs = None;
        // Where resting at the start stops being clear, if it does: every plan must be gone
        // by then (an obstacle sweeping through the start leaves that little time).
        let t_end = prep.planner.cfg.lookahead_s;
        let Prepared { planner, world, .. } = &mut prep;
        let rest = planner.checker.check(world, 0.0, t_end, t_end, false, |_| p.start);
        // A check that ran out of samples found nothing: it says nothing.
        let rest_hit = !rest.ok && planner.checker.capped == capped;
        sol.why = Some(format!(
            "no collision-free motion to the goal found in {plan_time_s:.3} s ({}{rounds} space-time trees){}{}",
            if connect { "RRT-Connect, then " } else { "" },
            if !rest_hit {
                String::new()
            } else {
                format!(
                    "; resting at the start is not clear from t = {:.3} s on (every plan must leave it before)",
                    rest.t_fail
                )
            },
            if capped > 0 {
                format!(
                    "; {capped} motion checks needed more than the {} samples a check takes (motions too slow \
                     to check: see v_max)",
                    prep.planner.checker.max_samples
                )
            } else {
                String::new()
            }
        ));
        return Ok(sol);
    }
    sol.first_solution_s = first_solution_s;
    sol.path.push(p.start);
    sol.times_s.push(0.0);
    for &(q, t) in &waypoints {
        sol.path.push(q);
        sol.times_s.push(t);
    }
    sol.path.push(p.goal);
    sol.times_s.push(out.duration_s);
    sol.duration_s = out.duration_s;
    sol.path_length_rad =
        sol.path.windows(2).map(|w| (0..NJ).map(|j| (w[1][j] - w[0][j]).powi(2)).sum::<f64>().sqrt()).sum();
    let n = (out.duration_s / 0.01).ceil() as usize;
    for k in 0..=n {
        let t = (k as f64 * 0.01).min(out.duration_s);
        let s = out.sample(t);
        let mut row = [0.0; NJ + 1];
        row[0] = t;
        row[1..].copy_from_slice(&s.p);
        sol.trajectory.push(row);
    }
    let (ok, m) = prep.verify(&out);
    // Clearances are measured up to [`MEASURED_UP_TO_M`]: beyond it there is no figure to give
    // (nothing came that near), not a clearance of exactly that much.
    sol.min_clearance_m = (m < MEASURED_UP_TO_M).then_some(m);
    sol.solved = ok && m >= 0.0;
    if !sol.solved {
        // Not a solution: the plan stays in the output (path, trajectory, clearance) for a
        // look, but no first solution is claimed.
        sol.first_solution_s = None;
        sol.first_solution_configs = None;
        sol.why = Some(format!("the plan's final check failed (clearance {m:.3} m)"));
    }
    Ok(sol)
}

/// Writes the path (the planner's rest-to-rest motions between its waypoints) into `out`; the
/// arrival times at its inner waypoints. `None`: a motion could not be timed, or the message
/// has too few segments for the path.
fn write_path(planner: &Planner, path: &[[f64; NJ]], out: &mut Trajectory) -> Option<Vec<f64>> {
    let mut b = Builder::new(out, 1, 0);
    let mut times = Vec::new();
    for w in path.windows(2) {
        b.otg(&planner.motion(&KinState::rest(w[0]), &w[1])?).ok()?;
        times.push(b.duration());
    }
    times.pop();
    b.finish();
    Some(times)
}
