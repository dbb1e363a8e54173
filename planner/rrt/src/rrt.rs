//! The anytime space-time planner.
//!
//! States are (q, t). The tree grows forward in time from the start state at the commit time
//! (which may be moving); every other node is a configuration the arm reaches **at rest** at a
//! time `t`. An edge is "wait `w` at the parent, then a time-synchronized, jerk-limited
//! rest-to-rest motion (dkrrt-otg) to the child", so the planned timing *is* the executed
//! timing: the message the tracker follows is these very pieces. Waits are what make the
//! search space-time (ST-RRT*'s conditional time sampling): a wait of 0 s half the time, else
//! uniform up to `max_wait_s`. The goal time is not fixed: any arrival whose rest at the goal
//! stays clear until the look-ahead's end is a solution; the earliest arrival wins.
//!
//! * First solution fast (RRT-Connect's greedy connect): every new node, and the start with a
//!   ladder of waits, tries to connect straight to the goal.
//! * Anytime: after the first solution the search goes on for `improve_iters` iterations (or
//!   the budget), keeping the earliest arrival; the best path is then shortcut (each of its
//!   nodes tries to reach the goal directly, with the same ladder of waits).
//! * Sampling: goal-biased; otherwise uniform in the box spanning start and goal widened by
//!   `sample_box_rad` (informed), or in the whole joint range with probability 0.1.
//! * No solution: the best *escape* is the reached configuration whose rest stays clear until
//!   the look-ahead's end with the largest clearance (a safe haven to wait in).
//!
//! Preallocated: the tree has a fixed capacity; a planning call allocates nothing.

use dkrrt_model::{ArmModel, NJ};
use dkrrt_msg::Trajectory;
use dkrrt_otg::{KinState, Limits, Options, Sync};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

use crate::build::{Builder, TooManySegments};
use crate::check::{Check, Checker};
use crate::world::WorldInTime;

/// Planner settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlannerConfig {
    /// Tree capacity (nodes).
    pub max_nodes: usize,
    /// Probability of sampling the goal.
    pub goal_bias: f64,
    /// Longest edge (max-norm over joints), rad.
    pub step_rad: f64,
    /// Probability that an edge starts with a wait, and the longest wait, s.
    pub wait_prob: f64,
    pub max_wait_s: f64,
    /// The informed sampling box: start–goal box widened by this, rad.
    pub sample_box_rad: f64,
    /// Largest relative arm–obstacle motion between two checks, m (see [`crate::check`]).
    pub delta_m: f64,
    /// Checks cover [t0, t0 + lookahead_s]; beyond, the replanning loop re-checks later.
    pub lookahead_s: f64,
    /// Check every motion to its end, even past the look-ahead (a planning-problem file,
    /// whose obstacles' motion is known for all time and held after its last pose: a rest that
    /// begins past the look-ahead is then clear if its first instant is, as the motion's end).
    /// The replanning loop leaves it off: its forecasts end, and it re-checks every cycle.
    pub check_whole_motions: bool,
    /// Iterations after the first solution.
    pub improve_iters: u32,
    /// A start inside the inflated obstacles ([`crate::check`]): motions from it may go this
    /// much deeper, m, and must be out within this time, s.
    pub relief_m: f64,
    pub relief_s: f64,
    /// The deepest predicted clearance a dodge ([`Planner::dodge`]) may have, m.
    pub dodge_depth_m: f64,
    /// A dodge acts on where the objects most likely are when staying goes `dodge_depth_m`
    /// deep within this time and the bounds show no way out ([`Planner::dodge`]); a conflict
    /// further ahead is left to newer forecasts, as the replanning loop's reaction times
    /// (`ReplanConfig::move_react_s`, `rest_react_s`) leave it, s.
    pub dodge_react_s: f64,
    /// Configuration checks per `plan` call: a deterministic proxy for compute time (one check
    /// against 32 forecast tracks takes about 1.5 µs on the development VM: the README's
    /// benchmark table, `cargo bench -p dkrrt-rrt --bench rrt`).
    pub max_configs: u64,
    pub seed: u64,
}

impl Default for PlannerConfig {
    fn default() -> Self {
        PlannerConfig {
            max_nodes: 1500,
            goal_bias: 0.2,
            step_rad: 0.4,
            wait_prob: 0.5,
            max_wait_s: 3.0,
            sample_box_rad: 0.8,
            delta_m: 0.03,
            lookahead_s: 5.0,
            check_whole_motions: false,
            improve_iters: 40,
            max_configs: 4000,
            relief_m: 0.02,
            relief_s: 1.0,
            dodge_depth_m: 0.1,
            dodge_react_s: 3.0,
            seed: 1,
        }
    }
}

/// One planning problem.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Request {
    /// The arm's state at `t0` (may be moving).
    pub start: KinState<NJ>,
    /// Plant time the plan starts at, s.
    pub t0: f64,
    pub goal: [f64; NJ],
}

/// What a plan reaches.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Reach {
    /// The goal, at rest, clear until the look-ahead's end.
    Goal,
    /// A safe haven short of the goal.
    Escape,
}

/// The result of [`Planner::plan`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plan {
    pub reach: Reach,
    /// Arrival (at rest) at the plan's last configuration, plant time, s.
    pub arrival: f64,
    /// Smallest predicted clearance along the plan (capped at the checker's cap), m.
    pub min_clearance: f64,
    /// Waypoints (rest configurations) after the start, and the wait before each leg.
    pub n_waypoints: usize,
}

/// Counters of the last [`Planner::plan`] call.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct PlanStats {
    pub iterations: u32,
    pub nodes: u32,
    /// Iteration of the first solution (`None`: none).
    pub first_solution_iter: Option<u32>,
    pub edges_checked: u32,
    pub configs_checked: u64,
}

#[derive(Debug, Clone, Copy)]
struct Node {
    q: [f64; NJ],
    /// Arrival at rest, s.
    t: f64,
    parent: u32,
    /// Wait at the parent before the motion here, s.
    wait: f64,
    min_clear: f64,
}

const WAIT_LADDER: [f64; 9] = [0.0, 0.3, 0.6, 1.0, 1.5, 2.0, 3.0, 4.5, 6.0];
const ROOT: u32 = 0;

/// [`Planner::dodge`]: its sampling step, s, its random candidates, and how much more
/// predicted clearance than staying it must offer, m.
pub const DODGE_DT: f64 = 0.05;
const DODGE_RANDOM: usize = 20;
pub const DODGE_GAIN_M: f64 = 0.01;
/// When every candidate goes deeper than `dodge_depth_m` within the look-ahead (a bound that
/// engulfs the arm's reach), a dodge must put that off by this much over staying, s.
pub const DODGE_TIME_GAIN_S: f64 = 0.5;
/// When none puts it off so, a dodge must cut the depth integrated over the look-ahead to at
/// most this fraction of staying's.
pub const DODGE_AREA_FRACTION: f64 = 0.75;
/// When the arm is already deep in the bounds and none of those rules takes a candidate, a
/// dodge scored against the predicted shapes alone that stays out of them as staying does must
/// keep this much more clearance from them, m ([`Planner::dodge`]).
pub const DODGE_LIKELY_GAIN_M: f64 = 0.05;

/// A dodge candidate over the look-ahead: its smallest predicted clearance (m; negative: a
/// depth into the inflated obstacles), the first sample time deeper than `dodge_depth_m`
/// (infinite: never), the depth integrated over time (m·s), the clearance at the look-ahead's
/// end (m) and its arrival time (s).
#[derive(Debug, Clone, Copy, PartialEq)]
struct DodgeScore {
    min: f64,
    deep: f64,
    area: f64,
    last: f64,
    arrival: f64,
}

/// What checking an edge found.
enum Edge {
    /// Clear: (arrival, min clearance).
    Clear(f64, f64),
    /// It meets an obstacle, or cannot be timed.
    Blocked,
    /// It arrives no earlier than the best plan so far: not checked.
    Late,
}

/// The planner (tree, checker, random stream: all preallocated).
pub struct Planner {
    pub cfg: PlannerConfig,
    pub checker: Checker,
    limits: Limits<NJ>,
    q_min: [f64; NJ],
    q_max: [f64; NJ],
    nodes: Vec<Node>,
    root: KinState<NJ>,
    root_moving: bool,
    t0: f64,
    rng: SmallRng,
    best_goal: Option<(u32, f64, f64, f64)>, // (parent node, wait, arrival, min clearance)
    /// Only arrivals before this are wanted ([`Planner::plan_to_beat`]; else infinite).
    before: f64,
    /// No plan can arrive earlier than this (plant time, s): a search that finds such an
    /// arrival stops there (a problem file's direct motion; else −∞, never).
    pub arrival_floor: f64,
    path: Vec<u32>,
    pub stats: PlanStats,
    /// Wall time from the start of the last `plan` call to its first solution, s.
    pub first_solution_s: Option<f64>,
    pub debug: bool,
    /// The motion of the edge being checked, refilled in place ([`Planner::edge`]).
    edge_motion: Box<dkrrt_otg::Trajectory<NJ>>,
}

impl Planner {
    pub fn new(model: ArmModel, limits: Limits<NJ>, cfg: PlannerConfig) -> Planner {
        let l = model.limits();
        let (q_min, q_max) = (l.q_min.into(), l.q_max.into());
        Planner {
            checker: Checker::new(model, &limits.v_max, cfg.delta_m),
            limits,
            q_min,
            q_max,
            nodes: Vec::with_capacity(cfg.max_nodes.max(2)),
            root: KinState::rest([0.0; NJ]),
            root_moving: false,
            t0: 0.0,
            rng: SmallRng::seed_from_u64(cfg.seed),
            best_goal: None,
            before: f64::INFINITY,
            arrival_floor: f64::NEG_INFINITY,
            path: Vec::with_capacity(cfg.max_nodes.max(2)),
            stats: PlanStats::default(),
            first_solution_s: None,
            debug: false,
            edge_motion: Box::new(dkrrt_otg::Trajectory::hold(&KinState::rest([0.0; NJ]))),
            cfg,
        }
    }

    pub fn limits(&self) -> &Limits<NJ> {
        &self.limits
    }

    /// The rest-to-rest (or from the moving root) motion to `q`: phase-synchronized, so from
    /// rest it follows the straight joint-space segment.
    pub(crate) fn motion(&self, from: &KinState<NJ>, q: &[f64; NJ]) -> Option<dkrrt_otg::Trajectory<NJ>> {
        let opts = Options { sync: Sync::Phase, ..Options::default() };
        dkrrt_otg::Trajectory::calculate(from, &KinState::rest(*q), &self.limits, &opts).ok()
    }

    /// [`Planner::motion`] into `self.edge_motion` (refilled in place: no 18.7 kB value built
    /// per edge); whether there is one.
    fn edge_motion_to(&mut self, from: &KinState<NJ>, q: &[f64; NJ]) -> bool {
        let opts = Options { sync: Sync::Phase, ..Options::default() };
        self.edge_motion.calculate_into(from, &KinState::rest(*q), &self.limits, &opts).is_ok()
    }

    /// A lower bound on the duration of any rest-to-rest motion from `a` to `b` within the
    /// limits: for each joint moving `d`, `d / v_max`, `2 √(d / a_max)` (bang-bang
    /// acceleration) and `∛(32 d / j_max)` (bang-bang jerk) each bound its time-optimal
    /// profile from below.
    fn least_time(&self, a: &[f64; NJ], b: &[f64; NJ]) -> f64 {
        let l = &self.limits;
        (0..NJ)
            .map(|j| {
                let d = (b[j] - a[j]).abs();
                (d / l.v_max[j]).max(2.0 * (d / l.a_max[j]).sqrt()).max((32.0 * d / l.j_max[j]).cbrt())
            })
            .fold(0.0, f64::max)
    }

    fn node_state(&self, i: u32) -> KinState<NJ> {
        if i == ROOT {
            self.root
        } else {
            KinState::rest(self.nodes[i as usize].q)
        }
    }

    fn t_end(&self) -> f64 {
        self.t0 + self.cfg.lookahead_s
    }

    /// The arrival a new solution must beat: the best one's, or the bound of
    /// [`Planner::plan_to_beat`].
    fn arrival_bound(&self) -> f64 {
        self.best_goal.map_or(self.before, |b| b.2.min(self.before))
    }

    /// Checks "wait `w` at node `from`, then move to rest at `q`"; returns (arrival, min
    /// clearance). An edge arriving no earlier than [`Planner::arrival_bound`] could serve no
    /// better plan: it is [`Edge::Late`], and left unchecked.
    fn edge(&mut self, world: &WorldInTime, from: u32, w: f64, q: &[f64; NJ]) -> Edge {
        let w = if from == ROOT && self.root_moving { 0.0 } else { w };
        let n = self.nodes[from as usize];
        // From rest the motion takes at least its slowest joint's time-optimal bound: a late
        // edge is known before its motion is even computed.
        let bound = self.arrival_bound();
        if bound.is_finite()
            && !(from == ROOT && self.root_moving)
            && n.t + w + self.least_time(&n.q, q) >= bound
        {
            return Edge::Late;
        }
        let st = self.node_state(from);
        if !self.edge_motion_to(&st, q) {
            return Edge::Blocked;
        }
        let tr = &*self.edge_motion;
        if n.t + w + tr.duration() >= bound {
            return Edge::Late;
        }
        self.stats.edges_checked += 1;
        let t_end = self.t_end();
        let mut clear = n.min_clear;
        if w > 0.0 {
            let c = self.checker.check(world, n.t, n.t + w, t_end, false, |_| n.q);
            if !c.ok {
                return Edge::Blocked;
            }
            clear = clear.min(c.min_clearance);
        }
        let ts = n.t + w;
        let d = tr.duration();
        let peaks = tr.speed_peaks();
        let t_end = if self.cfg.check_whole_motions { t_end.max(ts + d) } else { t_end };
        let c = self.checker.check_joint_motion(world, ts, ts + d, t_end, Some(&peaks), |t| tr.at(t - ts).p);
        if !c.ok {
            if self.debug && from == ROOT {
                eprintln!(
                    "    edge from root (wait {w:.2}) fails at t = {:.2} (start {ts:.2}, duration {d:.2})",
                    c.t_fail
                );
            }
            return Edge::Blocked;
        }
        Edge::Clear(ts + d, clear.min(c.min_clearance))
    }

    /// The rest at `q` from `t` until the look-ahead's end (nothing to check after it).
    fn rest_ok(&mut self, world: &WorldInTime, q: &[f64; NJ], t: f64) -> Check {
        let t_end = self.t_end();
        self.checker.check(world, t, t_end, t_end, false, |_| *q)
    }

    fn try_goal(&mut self, world: &WorldInTime, from: u32, goal: &[f64; NJ], waits: &[f64]) -> bool {
        let mut found = false;
        for &w in waits {
            if from == ROOT && self.root_moving && w > 0.0 {
                break;
            }
            let t_leave = self.nodes[from as usize].t + w;
            if t_leave >= self.arrival_bound() {
                break; // cannot beat the best arrival
            }
            let (arr, clear) = match self.edge(world, from, w, goal) {
                Edge::Clear(arr, clear) => (arr, clear),
                Edge::Late => break,
                Edge::Blocked => continue,
            };
            let r = self.rest_ok(world, goal, arr);
            if self.debug && from == ROOT {
                eprintln!("    goal rest from {arr:.2}: ok {} at {:.2}", r.ok, r.t_fail);
            }
            if r.ok {
                self.best_goal = Some((from, w, arr, clear.min(r.min_clearance)));
                found = true;
                break;
            }
        }
        found
    }

    fn sample(&mut self, goal: &[f64; NJ]) -> [f64; NJ] {
        if self.rng.random::<f64>() < self.cfg.goal_bias {
            return *goal;
        }
        let wide = self.rng.random::<f64>() < 0.1;
        let s = self.root.p;
        std::array::from_fn(|i| {
            let (lo, hi) = if wide {
                (self.q_min[i], self.q_max[i])
            } else {
                let b = self.cfg.sample_box_rad;
                ((s[i].min(goal[i]) - b).max(self.q_min[i]), (s[i].max(goal[i]) + b).min(self.q_max[i]))
            };
            lo + (hi - lo) * self.rng.random::<f64>()
        })
    }

    fn nearest(&self, q: &[f64; NJ]) -> u32 {
        let mut best = (f64::INFINITY, 0u32);
        for (i, n) in self.nodes.iter().enumerate() {
            let d = (0..NJ).map(|j| (q[j] - n.q[j]).abs() / self.limits.v_max[j]).fold(0.0, f64::max);
            let score = d + 0.25 * (n.t - self.t0);
            if score < best.0 {
                best = (score, i as u32);
            }
        }
        best.1
    }

    /// Plans from `req` for at most `budget` iterations (and while `keep_going()`), writes the
    /// best plan into `out` (id `traj_id`, starting at `req.t0`) and returns it; `None` when
    /// neither the goal nor a safe haven was reached (`out` is then untouched).
    pub fn plan(
        &mut self,
        req: &Request,
        world: &WorldInTime,
        budget: u32,
        keep_going: impl FnMut() -> bool,
        traj_id: u64,
        out: &mut Trajectory,
    ) -> Option<Plan> {
        self.plan_to_beat(req, world, f64::INFINITY, budget, keep_going, traj_id, out)
    }

    /// [`Planner::plan`] for a plan to the goal arriving before `before` only (plant time, s;
    /// infinite: [`Planner::plan`]): the anytime improvement of a plan already held. Edges that
    /// arrive later are never checked, no safe haven is sought, and the search stops
    /// `improve_iters` iterations after its first solution, or after `improve_iters` without
    /// one (at most `budget`).
    #[allow(clippy::too_many_arguments)]
    pub fn plan_to_beat(
        &mut self,
        req: &Request,
        world: &WorldInTime,
        before: f64,
        budget: u32,
        keep_going: impl FnMut() -> bool,
        traj_id: u64,
        out: &mut Trajectory,
    ) -> Option<Plan> {
        self.before = before;
        self.stats = PlanStats::default();
        let wall = std::time::Instant::now();
        self.first_solution_s = None;
        let c0 = self.checker.configs_checked;
        self.reset(req);
        // A start inside the inflated obstacles may only be left (the checker's relief).
        self.relieve(world, &req.start, req.t0);
        let plan = self.grow(req, world, budget, keep_going, traj_id, out, (wall, c0));
        self.checker.end_relief();
        self.stats.configs_checked = self.checker.configs_checked - c0;
        self.before = f64::INFINITY;
        plan
    }

    /// An empty tree rooted at the request's start.
    fn reset(&mut self, req: &Request) {
        self.nodes.clear();
        self.best_goal = None;
        self.root = req.start;
        self.root_moving = req.start.v.iter().chain(req.start.a.iter()).any(|x| x.abs() > 1e-12);
        self.t0 = req.t0;
        self.nodes.push(Node {
            q: req.start.p,
            t: req.t0,
            parent: ROOT,
            wait: 0.0,
            min_clear: self.checker.cap,
        });
    }

    /// Where the jerk-limited brake from the moving state `s` comes to rest.
    fn brake_point(&self, s: &KinState<NJ>) -> Option<[f64; NJ]> {
        dkrrt_otg::Trajectory::calculate_velocity(
            s,
            &[0.0; NJ],
            &[0.0; NJ],
            &self.limits,
            &Options::default(),
        )
        .ok()
        .map(|b| b.final_state().p)
    }

    /// Sets the checker's relief for motions from `start` at `t0` ([`crate::check`]).
    pub fn relieve(&mut self, world: &WorldInTime, start: &KinState<NJ>, t0: f64) -> f64 {
        self.checker.relieve_start(world, &start.p, t0, self.cfg.relief_m, self.cfg.relief_s)
    }

    #[allow(clippy::too_many_arguments)]
    fn grow(
        &mut self,
        req: &Request,
        world: &WorldInTime,
        budget: u32,
        mut keep_going: impl FnMut() -> bool,
        traj_id: u64,
        out: &mut Trajectory,
        (wall, c0): (std::time::Instant, u64),
    ) -> Option<Plan> {
        let goal = req.goal;
        // A moving start can first brake to rest: the rest-at-start node (waits grow from it).
        if self.root_moving {
            if let Some(tr) = self.brake_point(&req.start) {
                if let Edge::Clear(t, clear) = self.edge(world, ROOT, 0.0, &tr) {
                    self.nodes.push(Node { q: tr, t, parent: ROOT, wait: 0.0, min_clear: clear });
                }
            }
        }
        // First solution fast: the direct motion, then waiting first.
        for i in 0..self.nodes.len() as u32 {
            self.try_goal(world, i, &goal, &WAIT_LADDER);
        }
        let mut first = self.best_goal.map(|_| 0u32);
        if first.is_some() {
            self.first_solution_s = Some(wall.elapsed().as_secs_f64());
        }
        let mut it = 0u32;
        while it < budget && keep_going() && self.checker.configs_checked - c0 < self.cfg.max_configs {
            if let Some(f) = first {
                let floor = self.best_goal.is_some_and(|b| b.2 <= self.arrival_floor);
                if floor || it >= f.saturating_add(self.cfg.improve_iters) {
                    break;
                }
            } else if self.before.is_finite() && it >= self.cfg.improve_iters {
                break;
            }
            it += 1;
            if self.nodes.len() >= self.nodes.capacity() {
                break;
            }
            let qs = self.sample(&goal);
            let near = self.nearest(&qs);
            let qn = self.nodes[near as usize].q;
            let span = (0..NJ).map(|j| (qs[j] - qn[j]).abs()).fold(0.0, f64::max);
            let f = if span > self.cfg.step_rad { self.cfg.step_rad / span } else { 1.0 };
            let q_new: [f64; NJ] = std::array::from_fn(|j| qn[j] + f * (qs[j] - qn[j]));
            let w = if self.rng.random::<f64>() < self.cfg.wait_prob {
                self.cfg.max_wait_s * self.rng.random::<f64>()
            } else {
                0.0
            };
            // An edge arriving after the best solution is useless: not even checked.
            let Edge::Clear(t, clear) = self.edge(world, near, w, &q_new) else { continue };
            let idx = self.nodes.len() as u32;
            self.nodes.push(Node { q: q_new, t, parent: near, wait: w, min_clear: clear });
            if self.try_goal(world, idx, &goal, &WAIT_LADDER[..4]) && first.is_none() {
                first = Some(it);
                self.first_solution_s = Some(wall.elapsed().as_secs_f64());
            }
        }
        self.stats.iterations = it;
        self.stats.first_solution_iter = first;
        let plan = if let Some(best) = self.best_goal {
            self.shortcut(world, &goal, best.0);
            let (parent, wait, arrival, clear) = self.best_goal.unwrap_or(best);
            self.write(parent, Some((wait, &goal)), traj_id, out).ok()?;
            Some(Plan { reach: Reach::Goal, arrival, min_clearance: clear, n_waypoints: self.path.len() })
        } else if self.before.is_finite() {
            None
        } else {
            self.escape(world, traj_id, out)
        };
        self.stats.nodes = self.nodes.len() as u32;
        plan
    }

    /// Each node of the best path tries to reach the goal directly (earlier arrival wins).
    fn shortcut(&mut self, world: &WorldInTime, goal: &[f64; NJ], last: u32) {
        self.path.clear();
        let mut i = last;
        loop {
            self.path.push(i);
            if i == ROOT {
                break;
            }
            i = self.nodes[i as usize].parent;
        }
        // From the start side: the earliest node that connects gives the biggest cut.
        for k in (0..self.path.len()).rev() {
            let n = self.path[k];
            self.try_goal(world, n, goal, &WAIT_LADDER);
        }
    }

    /// The best safe haven: a reached node whose rest stays clear to the look-ahead's end.
    fn escape(&mut self, world: &WorldInTime, traj_id: u64, out: &mut Trajectory) -> Option<Plan> {
        // Candidates: the most clear-pathed nodes first (bounded work).
        let mut best: Option<(u32, f64)> = None;
        let mut tried = 0;
        let mut order: [(f64, u32); 48] = [(f64::NEG_INFINITY, 0); 48];
        for (i, n) in self.nodes.iter().enumerate() {
            let worst = order
                .iter()
                .enumerate()
                .min_by(|a, b| a.1 .0.total_cmp(&b.1 .0))
                .map(|(k, _)| k)
                .unwrap_or(0);
            if n.min_clear > order[worst].0 && !(i == 0 && self.root_moving) {
                order[worst] = (n.min_clear, i as u32);
            }
        }
        order.sort_by(|a, b| b.0.total_cmp(&a.0));
        for &(score, i) in order.iter() {
            if score == f64::NEG_INFINITY || tried >= 24 {
                break;
            }
            tried += 1;
            let n = self.nodes[i as usize];
            let r = self.rest_ok(world, &n.q, n.t);
            if r.ok {
                let s = n.min_clear.min(r.min_clearance);
                if best.is_none_or(|b| s > b.1) {
                    best = Some((i, s));
                }
            }
        }
        let (i, clear) = best?;
        self.write(i, None, traj_id, out).ok()?;
        Some(Plan {
            reach: Reach::Escape,
            arrival: self.nodes[i as usize].t,
            min_clearance: clear,
            n_waypoints: self.path.len(),
        })
    }

    /// The last resort when [`Planner::plan`] found neither the goal nor a safe haven and the
    /// arm would otherwise stay (or brake) where a conflict is predicted: the motion from
    /// `req.start` to rest at one of a few nearby configurations (one step of `step_rad` along
    /// each joint either way, random ones within that step, the goal) whose predicted
    /// clearance, sampled every [`DODGE_DT`] over the look-ahead (motion and rest after it;
    /// negative values are depths into the inflated obstacles), is the largest. Written into
    /// `out` only when that beats staying (at rest at the start, or the brake from a moving
    /// start) by [`DODGE_GAIN_M`] and goes no deeper than `dodge_depth_m` into the inflated
    /// obstacles (deeper, it would most likely meet the object itself: brake instead). When
    /// every candidate, staying included, goes that deep before the look-ahead's end (a bound
    /// grown over the whole reach, as after a fragment splits off), the one that goes that deep
    /// latest is taken if it puts that off by [`DODGE_TIME_GAIN_S`] over staying: the object is
    /// most likely where its bound grows from.
    ///
    /// When none does, the arm is already that deep, and staying is deepest at the look-ahead's
    /// end (a bound still advancing over the arm; one that passes or recedes leaves by itself),
    /// the arm backs out rather than wait in the bound for the object: of the candidates that end
    /// no deeper than `dodge_depth_m` and are never deeper than staying gets, the one with the
    /// least depth integrated over the look-ahead, if that is at most [`DODGE_AREA_FRACTION`] of
    /// staying's.
    ///
    /// When none of that takes a candidate and the arm goes deeper than `dodge_depth_m` where
    /// it would stay within `dodge_react_s` (a bound that holds the arm whatever it does, as
    /// after an object seen again close by, its axis unknown: its whole sweep; or one that will
    /// sweep over it faster than a nearby move gets out of its way), the bounds say nothing
    /// more of where in them the object is, and braking there waits for it: the nearby
    /// candidates are scored against the predicted shapes alone (bounds × 0), where the
    /// objects most likely are, and the one that meets them latest is taken if that is
    /// [`DODGE_TIME_GAIN_S`] later than staying (`dodge_likely`).
    ///
    /// A best effort, not a clean plan: its clearance
    /// may be negative, and the next cycle checks it like any other plan. Candidates are tried
    /// while `keep_going()` (the cycle's deadline).
    pub fn dodge(
        &mut self,
        req: &Request,
        world: &WorldInTime,
        traj_id: u64,
        mut keep_going: impl FnMut() -> bool,
        out: &mut Trajectory,
    ) -> Option<Plan> {
        self.reset(req);
        // Staying: the rest at the start, or the brake to rest.
        let stay_q = if self.root_moving { self.brake_point(&req.start)? } else { req.start.p };
        let stay = self.dodge_score(world, &stay_q)?;
        // The most clearance; among candidates that all go too deep, the latest to; and the
        // least integrated depth.
        let mut best: Option<([f64; NJ], DodgeScore)> = None;
        let mut least: Option<([f64; NJ], DodgeScore)> = None;
        let step = self.cfg.step_rad;
        // The nearby candidates (not the goal), for `dodge_likely`.
        let mut near = [[0.0; NJ]; 2 * NJ + DODGE_RANDOM];
        let mut n_near = 0;
        for k in 0..(2 * NJ + DODGE_RANDOM + 1) {
            if !keep_going() {
                break; // the candidates so far (the deadline)
            }
            let q: [f64; NJ] = if k < 2 * NJ {
                let mut q = stay_q;
                q[k / 2] += if k % 2 == 0 { step } else { -step };
                q
            } else if k < 2 * NJ + DODGE_RANDOM {
                std::array::from_fn(|j| stay_q[j] + step * (2.0 * self.rng.random::<f64>() - 1.0))
            } else {
                req.goal
            };
            let q: [f64; NJ] = std::array::from_fn(|j| q[j].clamp(self.q_min[j], self.q_max[j]));
            if k < 2 * NJ + DODGE_RANDOM {
                near[n_near] = q;
                n_near += 1;
            }
            if let Some(s) = self.dodge_score(world, &q) {
                if best.is_none_or(|(_, b)| s.deep > b.deep || (s.deep == b.deep && s.min > b.min)) {
                    best = Some((q, s));
                }
                let out_by_end = s.last >= -self.cfg.dodge_depth_m;
                if s.min >= stay.min && out_by_end && least.is_none_or(|(_, b)| s.area < b.area) {
                    least = Some((q, s));
                }
            }
        }
        let takes = |s: &DodgeScore| {
            if s.deep.is_finite() {
                s.deep >= stay.deep + DODGE_TIME_GAIN_S
            } else {
                s.min >= stay.min + DODGE_GAIN_M
            }
        };
        let (q, DodgeScore { min: score, arrival, .. }) = match (best, least) {
            (Some(b), _) if takes(&b.1) => b,
            (_, Some(l))
                if stay.last < -self.cfg.dodge_depth_m
                    && stay.last <= stay.min + DODGE_GAIN_M
                    && l.1.area <= DODGE_AREA_FRACTION * stay.area =>
            {
                l
            }
            // That deep where it would stay within the reaction time, and no candidate puts
            // it off: the bounds say nothing more of where in them the objects are.
            _ if stay.deep <= self.t0 + self.cfg.dodge_react_s => {
                let already = stay.deep <= self.t0 + 2.0 * DODGE_DT;
                self.dodge_likely(world, &stay_q, &near[..n_near], already, &mut keep_going)?
            }
            _ => return None,
        };
        if self.nodes.len() >= self.nodes.capacity() {
            return None;
        }
        self.nodes.push(Node { q, t: arrival, parent: ROOT, wait: 0.0, min_clear: score });
        self.write(1, None, traj_id, out).ok()?;
        Some(Plan { reach: Reach::Escape, arrival, min_clearance: score, n_waypoints: 1 })
    }

    /// [`Planner::dodge`] when the arm is already deeper than `dodge_depth_m` in the bounds
    /// where it would stay and no candidate is taken by the bounds' rules: the candidates
    /// `near` (the goal left out: a dodge stays a nearby move) scored against the predicted
    /// shapes alone (bounds × 0, the margin kept), where the objects most likely are. The one
    /// that goes `dodge_depth_m` into them latest (never, best; ties to the larger clearance)
    /// is taken if that is [`DODGE_TIME_GAIN_S`] later than staying does, or, when staying
    /// never does and the arm is `already` that deep in the bounds, if it never does either
    /// and keeps [`DODGE_LIKELY_GAIN_M`] more clearance (moving on away rather than braking
    /// halfway out). A bound still ahead of the arm whose object most likely passes it by
    /// (a young track's, wide for a second) is left to the next forecasts: the arm stays.
    /// Returns it with its score against the bounds, as any dodge.
    fn dodge_likely(
        &mut self,
        world: &WorldInTime,
        stay_q: &[f64; NJ],
        near: &[[f64; NJ]],
        already: bool,
        keep_going: &mut impl FnMut() -> bool,
    ) -> Option<([f64; NJ], DodgeScore)> {
        world.set_bound_scale(0.0);
        let found = (|| {
            let stay = self.dodge_score(world, stay_q)?;
            let mut best: Option<([f64; NJ], DodgeScore)> = None;
            for q in near {
                if !keep_going() {
                    break;
                }
                if let Some(s) = self.dodge_score(world, q) {
                    if best.is_none_or(|(_, b)| s.deep > b.deep || (s.deep == b.deep && s.min > b.min)) {
                        best = Some((*q, s));
                    }
                }
            }
            best.filter(|(_, b)| {
                if stay.deep.is_finite() {
                    b.deep >= stay.deep + DODGE_TIME_GAIN_S
                } else {
                    already && b.deep.is_infinite() && b.min >= stay.min + DODGE_LIKELY_GAIN_M
                }
            })
        })();
        world.set_bound_scale(1.0);
        let (q, _) = found?;
        // Scored as a dodge is (with the bounds), for the plan's figures.
        Some((q, self.dodge_score(world, &q)?))
    }

    /// How "move from the root to rest at `q`, then stay" fares over the look-ahead, sampled
    /// every [`DODGE_DT`]; `None` when no such motion is found.
    fn dodge_score(&mut self, world: &WorldInTime, q: &[f64; NJ]) -> Option<DodgeScore> {
        let tr = self.motion(&self.root, q);
        if tr.is_none() && (self.root_moving || *q != self.root.p) {
            return None;
        }
        let (t0, t_end, d) = (self.t0, self.t_end(), tr.as_ref().map_or(0.0, |t| t.duration()));
        let mut s =
            DodgeScore { min: f64::INFINITY, deep: f64::INFINITY, area: 0.0, last: 0.0, arrival: t0 + d };
        let mut t = t0;
        while t <= t_end + 1e-9 {
            let at = match &tr {
                Some(tr) if t - t0 < d => tr.at(t - t0).p,
                _ => *q,
            };
            let c = self.checker.clearance_at(world, &at, t, 0.0, f64::NEG_INFINITY);
            s.min = s.min.min(c);
            s.area += (-c).max(0.0) * DODGE_DT;
            s.last = c;
            if s.min < -self.cfg.dodge_depth_m && s.deep.is_infinite() {
                s.deep = t;
            }
            t += DODGE_DT;
        }
        Some(s)
    }

    /// The intermediate waypoints of the last written plan (rest configurations after the start,
    /// before the goal) with their arrival times (plant time, s).
    pub fn waypoints(&self) -> impl Iterator<Item = ([f64; NJ], f64)> + '_ {
        self.path.iter().map(|&i| (self.nodes[i as usize].q, self.nodes[i as usize].t))
    }

    /// Writes the path root → … → `last` (→ goal after `wait`) into `out`.
    fn write(
        &mut self,
        last: u32,
        goal: Option<(f64, &[f64; NJ])>,
        traj_id: u64,
        out: &mut Trajectory,
    ) -> Result<(), TooManySegments> {
        self.path.clear();
        let mut i = last;
        while i != ROOT {
            self.path.push(i);
            i = self.nodes[i as usize].parent;
        }
        self.path.reverse();
        let start_ns = (self.t0 * 1e9).round().max(0.0) as u64;
        let mut b = Builder::new(out, traj_id, start_ns);
        let mut from = self.root;
        let mut from_idx = ROOT;
        let legs = self.path.len();
        for k in 0..=legs {
            let (w, q) = if k < legs {
                let n = self.nodes[self.path[k] as usize];
                (n.wait, n.q)
            } else if let Some((w, g)) = goal {
                (w, *g)
            } else {
                break;
            };
            let w = if from_idx == ROOT && self.root_moving { 0.0 } else { w };
            b.rest(&from.p, w)?;
            if let Some(tr) = self.motion(&from, &q) {
                b.otg(&tr)?;
            }
            from = KinState::rest(q);
            from_idx = if k < legs { self.path[k] } else { u32::MAX };
        }
        b.finish();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_least_time_never_exceeds_a_motions_duration() {
        let limits = Limits {
            v_max: [0.1, 0.1, 0.1, 0.18, 0.18, 0.18],
            a_max: [0.2, 0.2, 0.2, 0.4, 0.4, 0.4],
            j_max: [1.0, 1.0, 1.0, 2.0, 2.0, 2.0],
        };
        let p = Planner::new(ArmModel::default_arm(), limits, PlannerConfig::default());
        let mut rng = SmallRng::seed_from_u64(5);
        let mut tight = 0;
        for k in 0..2000 {
            // Short and long moves, one joint or all.
            let scale = [1e-4, 0.01, 0.3, 2.0][k % 4];
            let a: [f64; NJ] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
            let b: [f64; NJ] = std::array::from_fn(|j| {
                if k % 3 == 0 && j != 2 {
                    a[j]
                } else {
                    a[j] + scale * rng.random_range(-1.0..1.0)
                }
            });
            let d = p.motion(&KinState::rest(a), &b).expect("a motion").duration();
            let lb = p.least_time(&a, &b);
            assert!(lb <= d + 1e-9, "{lb} > {d} for {a:?} -> {b:?}");
            tight += (lb > 0.7 * d) as usize;
        }
        assert!(tight > 1000, "the bound is rarely close: {tight} of 2000");
    }
}
