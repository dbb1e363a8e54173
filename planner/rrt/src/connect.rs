//! Bidirectional RRT-Connect in joint space, for a world that does not move (a planning-problem
//! file whose obstacles each have one pose).
//!
//! Where nothing moves, time adds nothing to a plan but its timing: a path of straight
//! joint-space segments becomes the plan the tracker follows by rest-to-rest, phase-synchronized
//! motions between its waypoints (dkrrt-otg), and a phase-synchronized motion moves along the
//! straight segment. So the search needs no clock, and two trees, one from the start and one
//! from the goal, each growing toward random samples and greedily toward the other's newest
//! node (Kuffner and LaValle's RRT-Connect, as in OMPL's `RRTConnect`), find narrow passages
//! that the space-time tree, rooted at the start alone, reaches slowly. The path found is then
//! shortcut (random pairs of its points joined straight where that is clear).
//!
//! A segment is checked by [`Checker::check_motion`] as the segment traversed at the joint
//! speed limits (a pseudo-time; the checker's speed bound then holds): the same sampling
//! argument, with the obstacles' speed 0.

use dkrrt_model::NJ;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

use crate::check::Checker;
use crate::world::WorldInTime;

/// The longest segment one step adds, max-norm over the joints, rad. Chosen on random still
/// problems with 32 obstacles (`planner/rrt/bench/clutter.py` seeds 3-5, checks counted
/// through `planner/cabi/bench/compare.py`): 1 rad reached a first solution with fewer checks
/// than 0.3, 2 or 3 rad, and plans as short (docs/journal.md, 2026-11-28).
pub const STEP_RAD: f64 = 1.0;

/// A node of one tree: a configuration and its parent (`u32::MAX`: the root).
#[derive(Debug, Clone, Copy)]
struct Node {
    q: [f64; NJ],
    parent: u32,
}

const ROOT: u32 = u32::MAX;

/// What one extension step did.
enum Step {
    /// The target itself was added.
    Reached,
    /// A point short of the target was added.
    Advanced,
    Trapped,
}

/// The RRT-Connect search (two preallocated trees).
pub struct Connect {
    trees: [Vec<Node>; 2],
    rng: SmallRng,
    q_min: [f64; NJ],
    q_max: [f64; NJ],
    v_max: [f64; NJ],
    /// Longest segment added in one step (max-norm over joints), rad.
    pub step_rad: f64,
    /// Search iterations so far (a random sample each, then the other tree's connect).
    pub iterations: u64,
}

impl Connect {
    /// Trees of at most `max_nodes` each, in the joint box `[q_min, q_max]`; `v_max`: the joint
    /// speed limits the checker was made with ([`Checker::new`]).
    pub fn new(q_min: [f64; NJ], q_max: [f64; NJ], v_max: [f64; NJ], max_nodes: usize, seed: u64) -> Connect {
        Connect {
            trees: [Vec::with_capacity(max_nodes), Vec::with_capacity(max_nodes)],
            rng: SmallRng::seed_from_u64(seed),
            q_min,
            q_max,
            v_max,
            step_rad: STEP_RAD,
            iterations: 0,
        }
    }

    /// Whether the straight segment `a → b` is clear of the (static) world.
    pub fn segment_clear(
        &mut self,
        checker: &mut Checker,
        world: &WorldInTime,
        a: &[f64; NJ],
        b: &[f64; NJ],
    ) -> bool {
        // Pseudo-time: the segment at the joint speed limits (the checker's speed bound holds
        // for no faster motion).
        let d = (0..NJ).map(|j| (b[j] - a[j]).abs() / self.v_max[j]).fold(0.0, f64::max);
        if d <= 0.0 {
            return checker.check_motion(world, 0.0, 0.0, 0.0, None, |_| *a).ok;
        }
        // The end first (one sample): a step that ends inside an obstacle is refused without
        // the samples that would lead up to it. The segment's own check ends with that sample
        // too, so the answer is the same.
        if !checker.check_motion(world, 0.0, 0.0, 0.0, None, |_| *b).ok {
            return false;
        }
        let speed: [f64; NJ] = std::array::from_fn(|j| (b[j] - a[j]).abs() / d);
        let c = checker.check_joint_motion(world, 0.0, d, d, Some(&speed), |t| {
            let s = (t / d).clamp(0.0, 1.0);
            std::array::from_fn(|j| a[j] + s * (b[j] - a[j]))
        });
        c.ok
    }

    fn nearest(&self, k: usize, q: &[f64; NJ]) -> u32 {
        let mut best = (f64::INFINITY, 0u32);
        for (i, n) in self.trees[k].iter().enumerate() {
            let d: f64 = (0..NJ).map(|j| (q[j] - n.q[j]).powi(2)).sum();
            if d < best.0 {
                best = (d, i as u32);
            }
        }
        best.1
    }

    /// One step of tree `k` toward `target`, from its node `from` (`None`: the nearest).
    fn extend(
        &mut self,
        k: usize,
        checker: &mut Checker,
        world: &WorldInTime,
        target: &[f64; NJ],
        from: Option<u32>,
    ) -> Step {
        if self.trees[k].len() == self.trees[k].capacity() {
            return Step::Trapped;
        }
        let near = from.unwrap_or_else(|| self.nearest(k, target));
        let qn = self.trees[k][near as usize].q;
        let span = (0..NJ).map(|j| (target[j] - qn[j]).abs()).fold(0.0, f64::max);
        let (q, reached) = if span <= self.step_rad {
            (*target, true)
        } else {
            let f = self.step_rad / span;
            (std::array::from_fn(|j| qn[j] + f * (target[j] - qn[j])), false)
        };
        if !self.segment_clear(checker, world, &qn, &q) {
            return Step::Trapped;
        }
        self.trees[k].push(Node { q, parent: near });
        if reached {
            Step::Reached
        } else {
            Step::Advanced
        }
    }

    /// The path from the root of tree `k` to its node `i` (root first) appended to `out`.
    fn branch(&self, k: usize, i: u32, out: &mut Vec<[f64; NJ]>) {
        let from = out.len();
        let mut i = i;
        while i != ROOT {
            let n = self.trees[k][i as usize];
            out.push(n.q);
            i = n.parent;
        }
        out[from..].reverse();
    }

    /// Searches for a clear path `start → goal` while `keep_going()`; the waypoints (start and
    /// goal included) go into `path`. `false`: none found (a tree full, or time out).
    pub fn solve(
        &mut self,
        checker: &mut Checker,
        world: &WorldInTime,
        start: &[f64; NJ],
        goal: &[f64; NJ],
        mut keep_going: impl FnMut() -> bool,
        path: &mut Vec<[f64; NJ]>,
    ) -> bool {
        path.clear();
        if self.segment_clear(checker, world, start, goal) {
            path.extend([*start, *goal]);
            return true;
        }
        for t in self.trees.iter_mut() {
            t.clear();
        }
        self.trees[0].push(Node { q: *start, parent: ROOT });
        self.trees[1].push(Node { q: *goal, parent: ROOT });
        let mut a = 0;
        while keep_going() {
            if self.trees.iter().any(|t| t.len() == t.capacity()) {
                return false;
            }
            self.iterations += 1;
            let qr: [f64; NJ] = std::array::from_fn(|j| {
                self.q_min[j] + (self.q_max[j] - self.q_min[j]) * self.rng.random::<f64>()
            });
            let b = 1 - a;
            if !matches!(self.extend(a, checker, world, &qr, None), Step::Trapped) {
                let q_new = self.trees[a].last().expect("a node").q;
                // Connect: tree b steps toward the new node until it reaches it or is stopped.
                // After its first step, the node just added is the nearest to the target (it
                // lies a step nearer than the nearest was): no search for it.
                let mut from = None;
                let reached = loop {
                    match self.extend(b, checker, world, &q_new, from) {
                        Step::Reached => break true,
                        Step::Advanced => from = Some((self.trees[b].len() - 1) as u32),
                        Step::Trapped => break false,
                    }
                };
                if reached {
                    let (ia, ib) = ((self.trees[a].len() - 1) as u32, (self.trees[b].len() - 1) as u32);
                    let (s, g) = if a == 0 { ((0, ia), (1, ib)) } else { ((0, ib), (1, ia)) };
                    self.branch(s.0, s.1, path);
                    // The goal tree's branch, from the meeting point (already in) to the goal.
                    let mid = path.len();
                    self.branch(g.0, g.1, path);
                    path[mid..].reverse();
                    path.remove(mid);
                    return true;
                }
            }
            a = b;
        }
        false
    }

    /// Shortcuts `path` in place: `tries` random pairs of points on it (anywhere along its
    /// segments) joined straight where that is clear; then waypoints whose neighbours see each
    /// other are dropped.
    pub fn shortcut(
        &mut self,
        checker: &mut Checker,
        world: &WorldInTime,
        path: &mut Vec<[f64; NJ]>,
        tries: u32,
        mut keep_going: impl FnMut() -> bool,
    ) {
        for _ in 0..tries {
            if path.len() < 3 || !keep_going() {
                break;
            }
            let n = path.len() - 1;
            let (mut i, mut j) = (self.rng.random_range(0..n), self.rng.random_range(0..n));
            if i == j {
                continue;
            }
            if i > j {
                std::mem::swap(&mut i, &mut j);
            }
            let (u, v) = (self.rng.random::<f64>(), self.rng.random::<f64>());
            let pa: [f64; NJ] = std::array::from_fn(|k| path[i][k] + u * (path[i + 1][k] - path[i][k]));
            let pb: [f64; NJ] = std::array::from_fn(|k| path[j][k] + v * (path[j + 1][k] - path[j][k]));
            if self.segment_clear(checker, world, &pa, &pb) {
                // i .. pa, pb .. j+1: the points between go.
                path.splice(i + 1..=j, [pa, pb]);
            }
        }
        let mut k = 1;
        while k + 1 < path.len() && keep_going() {
            let (a, b) = (path[k - 1], path[k + 1]);
            if self.segment_clear(checker, world, &a, &b) {
                path.remove(k);
            } else {
                k += 1;
            }
        }
    }
}
