//! dkrrt-collision: the arm's link capsules posed at `q`, and their distances to posed
//! obstacle shapes. One crate for the simulator's true contact check and the planner's
//! predicted checks, so both measure with the same code.
//!
//! * [`ArmPoser`] poses the model's collision capsules (one per moving link) at joint
//!   positions `q`, with per-link bounding spheres for the broad phase, and knows each
//!   joint's lever arm (how fast any link point can move per rad/s of that joint).
//! * [`Obstacle`] is a shape at a pose: a primitive from the message contract
//!   ([`DebrisShape`]: sphere, capsule, box with offset, disc) or an exact parry3d shape (the
//!   simulator's convex hulls), optionally inflated by a radius.
//! * [`proximity`] measures the smallest separation between the arm and the obstacles, with a
//!   bounding-sphere broad phase, closed-form narrow phases for spheres, capsules and boxes
//!   ([`seg_box`]: exact, no iteration; [`seg_disc`]: a 1-D convex search) and parry3d
//!   (GJK) for the simulator's hulls. [`clearance`] is the same with an early exit below a threshold,
//!   for the planner's yes/no checks.
//!
//! Everything here is allocation-free (tested with a counting allocator).

pub mod bounds;
pub mod pose;

use dkrrt_model::{ArmModel, JVec, NJ};
use dkrrt_msg::{DebrisShape, ShapeKind};
use parry3d_f64::glamx::DQuat;
use parry3d_f64::math::{Pose, Vector as PVec};
use parry3d_f64::query;
use parry3d_f64::shape::{Capsule, Shape, SharedShape};

pub use pose::{interpolate_pose, quat_angle, quat_rotate};

/// One arm link's capsule in the base frame: the points within `r` of the segment `a`–`b`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PosedCapsule {
    pub a: [f64; 3],
    pub b: [f64; 3],
    pub r: f64,
    /// Centre of the bounding sphere (the segment's midpoint), and its radius.
    pub centre: [f64; 3],
    pub bound: f64,
}

impl PosedCapsule {
    pub fn new(a: [f64; 3], b: [f64; 3], r: f64) -> Self {
        let centre = [(a[0] + b[0]) * 0.5, (a[1] + b[1]) * 0.5, (a[2] + b[2]) * 0.5];
        PosedCapsule { a, b, r, centre, bound: 0.5 * dist(&a, &b) + r }
    }
}

/// Poses the arm's collision capsules. Built once per model (allocation-free afterwards).
#[derive(Debug, Clone)]
pub struct ArmPoser {
    model: ArmModel,
    /// Base-frame offset added to every posed point (e.g. the base's position in LVLH).
    offset: [f64; 3],
    lever: [f64; NJ],
    /// `capsule_lever[k][i]`: the same bound for the points of capsule `k` only (0 for a joint
    /// that does not move it).
    capsule_lever: [[f64; NJ]; NJ],
}

impl ArmPoser {
    pub fn new(model: ArmModel) -> Self {
        Self::with_offset(model, [0.0; 3])
    }

    /// Capsules are reported in a frame whose origin is `-offset` in the base frame (a point
    /// `x` of the base frame is reported as `x + offset`).
    pub fn with_offset(model: ArmModel, offset: [f64; 3]) -> Self {
        let (lever, capsule_lever) = lever_arms(&model);
        ArmPoser { model, offset, lever, capsule_lever }
    }

    pub fn model(&self) -> &ArmModel {
        &self.model
    }

    /// Per joint `i`: an upper bound on the distance from joint `i`'s axis of any point of the
    /// links it moves, m. A point of the arm moves at most `Σ |q̇_i| · lever[i]` m/s.
    pub fn lever_arms(&self) -> &[f64; NJ] {
        &self.lever
    }

    /// Upper bound on the speed of any arm point when every joint moves at most at `v_max`, m/s.
    pub fn max_point_speed(&self, v_max: &[f64; NJ]) -> f64 {
        (0..NJ).map(|i| v_max[i].abs() * self.lever[i]).sum()
    }

    /// Per capsule of [`ArmPoser::pose`]: an upper bound on the speed of its points when every
    /// joint moves at most at `v_max`, m/s (only the joints before it move it, with their
    /// lever arms to it alone). At most [`ArmPoser::max_point_speed`].
    pub fn capsule_speeds(&self, v_max: &[f64; NJ]) -> [f64; NJ] {
        std::array::from_fn(|k| (0..NJ).map(|i| v_max[i].abs() * self.capsule_lever[k][i]).sum())
    }

    /// The capsules at joint positions `q`.
    /// A sphere (centre, radius) holding every point of every collision capsule at any
    /// configuration: centred on the first joint's origin (on its axis, so fixed), with that
    /// joint's lever arm as radius (the farthest capsule point along the chain, by the
    /// triangle inequality over the joint-to-joint hops).
    pub fn reach_sphere(&self) -> ([f64; 3], f64) {
        let p0 = self.model.link_poses(&JVec::zeros())[0].translation.vector;
        let o = &self.offset;
        ([p0.x + o[0], p0.y + o[1], p0.z + o[2]], self.lever[0])
    }

    pub fn pose(&self, q: &[f64; NJ], out: &mut [PosedCapsule; NJ]) {
        let mut pts = [[[0.0; 3]; 2]; NJ];
        self.model.capsule_points(&JVec::from(*q), &mut pts);
        let o = &self.offset;
        for ((c, lc), [a, b]) in out.iter_mut().zip(self.model.collision_capsules()).zip(pts) {
            *c = PosedCapsule::new(
                [a[0] + o[0], a[1] + o[1], a[2] + o[2]],
                [b[0] + o[0], b[1] + o[1], b[2] + o[2]],
                lc.radius,
            );
        }
    }
}

/// Lever arm bound per joint: the chain of rigid offsets from joint `i`'s origin to the farthest
/// capsule point of every link after it (triangle inequality, so it holds at every `q`); and the
/// same per collision capsule (capsule `k`, joint `i`: 0 when joint `i` comes after its link).
/// Capsules beyond the model's (none, for a model with one per link) get the whole arm's.
fn lever_arms(model: &ArmModel) -> ([f64; NJ], [[f64; NJ]; NJ]) {
    let poses = model.link_poses(&JVec::zeros());
    // Distance between consecutive joint origins (link frame origins): constant in q.
    let mut hop = [0.0; NJ];
    for k in 1..NJ {
        let d = poses[k].translation.vector - poses[k - 1].translation.vector;
        hop[k] = d.norm();
    }
    // From joint `i`'s origin to link `k`'s, along the chain.
    let chain = |i: usize, k: usize| -> f64 { (i + 1..=k).map(|m| hop[m]).sum() };
    let mut reach = [0.0f64; NJ]; // farthest capsule point from link k's origin
    for lc in model.collision_capsules() {
        let r = lc.a.coords.norm().max(lc.b.coords.norm()) + lc.radius;
        reach[lc.link] = reach[lc.link].max(r);
    }
    let mut lever = [0.0; NJ];
    for (i, l) in lever.iter_mut().enumerate() {
        let mut best: f64 = 0.0;
        for (k, r) in reach.iter().enumerate().skip(i) {
            best = best.max(chain(i, k) + r);
        }
        *l = best;
    }
    let mut capsule_lever = [lever; NJ];
    for (cl, lc) in capsule_lever.iter_mut().zip(model.collision_capsules()) {
        let r = lc.a.coords.norm().max(lc.b.coords.norm()) + lc.radius;
        for (i, l) in cl.iter_mut().enumerate() {
            *l = if i <= lc.link { chain(i, lc.link) + r } else { 0.0 };
        }
    }
    (lever, capsule_lever)
}

/// An obstacle's geometry.
#[derive(Clone)]
pub enum Geom {
    Sphere {
        r: f64,
    },
    /// Along the local z axis.
    Capsule {
        half_length: f64,
        r: f64,
    },
    Cuboid {
        half: [f64; 3],
    },
    /// A flat cylinder about the local z axis (its radius and half thickness).
    Disc {
        r: f64,
        half: f64,
    },
    /// Any parry3d shape (exact hulls of the simulator).
    Shape(SharedShape),
}

/// A shape at a pose, inflated by `inflate` (its surface grows by that much).
#[derive(Clone)]
pub struct Obstacle {
    pub id: u32,
    pub geom: Geom,
    /// Position of the geometry's centre and attitude (w, x, y, z).
    pub p: [f64; 3],
    pub q: [f64; 4],
    /// Bounding sphere about `p` (not inflated).
    pub bound: f64,
    pub inflate: f64,
    /// A second container the object also lies in: the ball of radius `ball_r` about `ball_p`
    /// (infinite: none). The object then lies in both, and a capsule's distance to it is at
    /// least the larger of its distances to the two ([`Obstacle::with_ball`]).
    pub ball_p: [f64; 3],
    pub ball_r: f64,
}

impl std::fmt::Debug for Obstacle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Obstacle")
            .field("id", &self.id)
            .field("p", &self.p)
            .field("q", &self.q)
            .field("bound", &self.bound)
            .field("inflate", &self.inflate)
            .field("ball_p", &self.ball_p)
            .field("ball_r", &self.ball_r)
            .finish()
    }
}

impl Obstacle {
    /// From a contract descriptor at body pose (`p`, `q` = w, x, y, z); `bounding_radius` is
    /// used for `Unknown` shapes.
    pub fn from_desc(
        id: u32,
        shape: &DebrisShape,
        bounding_radius: f64,
        p: &[f64; 3],
        q: &[f64; 4],
        inflate: f64,
    ) -> Self {
        let d = shape.dims;
        let off = quat_rotate(q, &shape.offset);
        let c = [p[0] + off[0], p[1] + off[1], p[2] + off[2]];
        let (geom, bound) = match ShapeKind::from_u32(shape.kind) {
            Some(ShapeKind::Sphere) => (Geom::Sphere { r: d[0] }, d[0]),
            Some(ShapeKind::Capsule) => (Geom::Capsule { half_length: d[0], r: d[1] }, d[0] + d[1]),
            Some(ShapeKind::Box) => {
                (Geom::Cuboid { half: d }, (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt())
            }
            Some(ShapeKind::Disc) => (Geom::Disc { r: d[0], half: d[1] }, d[0].hypot(d[1])),
            _ => (Geom::Sphere { r: bounding_radius }, bounding_radius),
        };
        Obstacle { id, geom, p: c, q: *q, bound, inflate, ball_p: c, ball_r: f64::INFINITY }
    }

    /// The same obstacle known also to lie within the ball of radius `r` about `centre` (a
    /// forecast's bounding sphere inflated by its position bound, beside the shape inflated by
    /// its surface bound): distances are then to the intersection's outside, the larger of
    /// the two, never smaller than to either container alone.
    pub fn with_ball(mut self, centre: &[f64; 3], r: f64) -> Self {
        (self.ball_p, self.ball_r) = (*centre, r);
        self
    }

    /// An exact parry3d shape at a pose (`bound`: its bounding radius about `p`). Balls,
    /// cuboids and capsules along the local z axis centred on the origin are measured in
    /// closed form (the same geometry), other shapes through parry3d.
    pub fn from_shape(id: u32, shape: &SharedShape, bound: f64, p: &[f64; 3], q: &[f64; 4]) -> Self {
        let geom = if let Some(b) = shape.as_ball() {
            Geom::Sphere { r: b.radius }
        } else if let Some(c) = shape.as_cuboid() {
            let h = c.half_extents;
            Geom::Cuboid { half: [h.x, h.y, h.z] }
        } else if let Some(c) = shape.as_capsule().filter(|c| {
            let (a, b) = (c.segment.a, c.segment.b);
            [a.x, a.y, b.x, b.y, a.z + b.z].iter().all(|v| *v == 0.0)
        }) {
            Geom::Capsule { half_length: c.segment.b.z.abs(), r: c.radius }
        } else {
            // Only a general shape keeps the shared shape (a reference count; the primitives
            // are copied out of it, so posing them every tick touches no count).
            Geom::Shape(shape.clone())
        };
        Obstacle { id, geom, p: *p, q: *q, bound, inflate: 0.0, ball_p: *p, ball_r: f64::INFINITY }
    }

    fn parry_pose(&self) -> Pose {
        let q = &self.q;
        Pose::from_parts(PVec::new(self.p[0], self.p[1], self.p[2]), DQuat::from_xyzw(q[1], q[2], q[3], q[0]))
    }

    /// Distance from the capsule to the (inflated) obstacle; negative inside, where known.
    pub fn distance(&self, c: &PosedCapsule) -> f64 {
        let raw = match &self.geom {
            Geom::Sphere { r } => seg_point(&c.a, &c.b, &self.p) - c.r - r,
            Geom::Capsule { half_length, r } => {
                let z = quat_rotate(&self.q, &[0.0, 0.0, *half_length]);
                let p0 = [self.p[0] - z[0], self.p[1] - z[1], self.p[2] - z[2]];
                let p1 = [self.p[0] + z[0], self.p[1] + z[1], self.p[2] + z[2]];
                seg_seg(&c.a, &c.b, &p0, &p1) - c.r - r
            }
            Geom::Cuboid { half } => {
                // The capsule's axis in the box frame, then the exact segment–box distance.
                let qc = [self.q[0], -self.q[1], -self.q[2], -self.q[3]];
                let a = quat_rotate(&qc, &sub(&c.a, &self.p));
                let b = quat_rotate(&qc, &sub(&c.b, &self.p));
                seg_box(&a, &b, half) - c.r
            }
            Geom::Disc { r, half } => {
                // The capsule's axis in the disc's frame, then its distance to the solid disc
                // less the capsule's radius (negative when they overlap but the axis is outside).
                let qc = [self.q[0], -self.q[1], -self.q[2], -self.q[3]];
                let a = quat_rotate(&qc, &sub(&c.a, &self.p));
                let b = quat_rotate(&qc, &sub(&c.b, &self.p));
                seg_disc(&a, &b, *r, *half) - c.r
            }
            Geom::Shape(s) => self.parry_distance(c, s.as_ref()),
        };
        (raw - self.inflate).max(self.ball_distance(c))
    }

    /// Distance from the capsule to the second container ([`Obstacle::with_ball`]; −∞ without
    /// one).
    #[inline]
    fn ball_distance(&self, c: &PosedCapsule) -> f64 {
        if self.ball_r.is_finite() {
            seg_point(&c.a, &c.b, &self.ball_p) - c.r - self.ball_r
        } else {
            f64::NEG_INFINITY
        }
    }

    fn parry_distance(&self, c: &PosedCapsule, shape: &dyn Shape) -> f64 {
        let cap = Capsule::new(PVec::new(c.a[0], c.a[1], c.a[2]), PVec::new(c.b[0], c.b[1], c.b[2]), c.r);
        match query::distance(&self.parry_pose(), shape, &Pose::IDENTITY, &cap) {
            Ok(d) => d.distance,
            // Unsupported pair: the bounding spheres' separation (a lower bound).
            Err(_) => dist(&c.centre, &self.p) - c.bound - self.bound,
        }
    }

    /// A lower bound of [`Self::distance`] from the bounding spheres (and the second
    /// container, [`Obstacle::with_ball`]).
    #[inline]
    pub fn lower_bound(&self, c: &PosedCapsule) -> f64 {
        let shape = dist(&c.centre, &self.p) - c.bound - self.bound - self.inflate;
        // The second container's own distance is exact and cheap: where it decides, the
        // shape's distance need not be measured.
        shape.max(self.ball_distance(c))
    }
}

/// The contract descriptor of a parry3d shape as a perception driver would give it: spheres,
/// z-axis capsules and boxes as they are, anything else as its body-frame bounding box.
pub fn descriptor_of(shape: &dyn Shape) -> DebrisShape {
    if let Some(b) = shape.as_ball() {
        return DebrisShape::sphere(b.radius);
    }
    if let Some(c) = shape.as_capsule() {
        let (a, b) = (c.segment.a, c.segment.b);
        let on_z = a.x.abs() < 1e-12 && a.y.abs() < 1e-12 && b.x.abs() < 1e-12 && b.y.abs() < 1e-12;
        if on_z && (a.z + b.z).abs() < 1e-12 {
            return DebrisShape::capsule((b.z - a.z).abs() * 0.5, c.radius);
        }
    }
    if let Some(c) = shape.as_cuboid() {
        let h = c.half_extents;
        return DebrisShape::cuboid([h.x, h.y, h.z], [0.0; 3]);
    }
    let bb = shape.compute_local_aabb();
    let (lo, hi) = (bb.mins, bb.maxs);
    DebrisShape::cuboid(
        [(hi.x - lo.x) * 0.5, (hi.y - lo.y) * 0.5, (hi.z - lo.z) * 0.5],
        [(hi.x + lo.x) * 0.5, (hi.y + lo.y) * 0.5, (hi.z + lo.z) * 0.5],
    )
}

/// The vertices (body frame) of a shape that is a convex hull, whose [`descriptor_of`] is only
/// its bounding box: what the body's true surface is the hull of. `None` for the shapes the
/// descriptor gives exactly (spheres, capsules, boxes).
pub fn hull_vertices(shape: &dyn Shape) -> Option<Vec<[f64; 3]>> {
    shape.as_convex_polyhedron().map(|c| c.points().iter().map(|p| [p.x, p.y, p.z]).collect())
}

/// A link–obstacle pair within the contact margin.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ContactPair {
    /// Link index (0 = first moving link).
    pub link: usize,
    pub id: u32,
    pub distance: f64,
}

/// Result of [`proximity`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Proximity {
    /// Smallest separation (∞ without obstacles), m.
    pub min_distance: f64,
    pub link: usize,
    pub id: u32,
    /// Pairs within the margin (may exceed the contact buffer).
    pub n_contacts: usize,
}

impl Proximity {
    pub fn any_contact(&self) -> bool {
        self.n_contacts > 0
    }
}

/// Smallest separation between the arm's capsules and the obstacles; pairs within `margin` are
/// written to `contacts` (up to its length). Pairs whose bounding spheres cannot beat the
/// current minimum nor reach the margin are skipped.
pub fn proximity(
    arm: &[PosedCapsule],
    obstacles: &[Obstacle],
    margin: f64,
    contacts: &mut [ContactPair],
) -> Proximity {
    let mut out = Proximity { min_distance: f64::INFINITY, link: 0, id: u32::MAX, n_contacts: 0 };
    // Best first: the pair with the smallest lower bound is measured first, so that the
    // bound skips nearly every other pair (the bounds are kept for the second pass).
    const MAX_PAIRS: usize = 6 * 64;
    let mut bounds = [0.0f64; MAX_PAIRS];
    let cached = arm.len() * obstacles.len() <= MAX_PAIRS;
    let mut seed = (f64::INFINITY, usize::MAX, usize::MAX);
    for (li, c) in arm.iter().enumerate() {
        for (oi, o) in obstacles.iter().enumerate() {
            let lower = o.lower_bound(c);
            if cached {
                bounds[li * obstacles.len() + oi] = lower;
            }
            if lower < seed.0 {
                seed = (lower, li, oi);
            }
        }
    }
    if seed.1 != usize::MAX {
        let (li, oi) = (seed.1, seed.2);
        out.min_distance = obstacles[oi].distance(&arm[li]);
        out.link = li;
        out.id = obstacles[oi].id;
    }
    for (li, c) in arm.iter().enumerate() {
        for (oi, o) in obstacles.iter().enumerate() {
            let lower = if cached { bounds[li * obstacles.len() + oi] } else { o.lower_bound(c) };
            let seeded = li == seed.1 && oi == seed.2;
            if (lower > out.min_distance || seeded) && lower > margin {
                continue;
            }
            let d = o.distance(c);
            if d < out.min_distance {
                out.min_distance = d;
                out.link = li;
                out.id = o.id;
            }
            if d <= margin {
                if out.n_contacts < contacts.len() {
                    contacts[out.n_contacts] = ContactPair { link: li, id: o.id, distance: d };
                }
                out.n_contacts += 1;
            }
        }
    }
    out
}

/// The smallest separation, or any value `< stop_below` as soon as one pair is found below it
/// (the planner's check: only "is everything at least `stop_below` away" must be exact).
/// Pairs whose bounding spheres are farther than `cap` are not measured: the result is
/// `min(true clearance, cap)` when everything is farther than `stop_below`.
pub fn clearance(arm: &[PosedCapsule], obstacles: &[Obstacle], stop_below: f64, cap: f64) -> f64 {
    let mut best = cap;
    for o in obstacles {
        best = clearance_one(arm, o, stop_below, best, |_, _| {});
        if best < stop_below {
            return best;
        }
    }
    best
}

/// [`clearance`] against one obstacle (the same result, the same early return), and in
/// `pairs[k]` a lower bound on the obstacle's distance from capsule `arm[k]`: exact where the
/// pair was measured, its bounding spheres' where it was not. After an early return (a result
/// below `stop_below`) the entries not reached are `-∞`.
pub fn clearance_pairs(
    arm: &[PosedCapsule],
    o: &Obstacle,
    stop_below: f64,
    cap: f64,
    pairs: &mut [f64],
) -> f64 {
    let mut reached = 0;
    let best = clearance_one(arm, o, stop_below, cap, |k, d| {
        pairs[k] = d;
        reached = k + 1;
    });
    if best < stop_below {
        pairs[reached..arm.len()].fill(f64::NEG_INFINITY);
    }
    best
}

/// The pairs of `arm` with one obstacle, below `best` (returned lowered to the smallest
/// distance measured; at once when that is below `stop_below`): a pair whose bounding spheres
/// are `best` or more apart is not measured. `pair(k, d)`: capsule `k`'s distance, or its
/// spheres' lower bound where not measured.
#[inline(always)]
fn clearance_one(
    arm: &[PosedCapsule],
    o: &Obstacle,
    stop_below: f64,
    mut best: f64,
    mut pair: impl FnMut(usize, f64),
) -> f64 {
    for (k, c) in arm.iter().enumerate() {
        let lower = o.lower_bound(c);
        if lower >= best {
            pair(k, lower);
            continue;
        }
        let d = o.distance(c);
        pair(k, d);
        if d < best {
            best = d;
            if best < stop_below {
                return best;
            }
        }
    }
    best
}

#[inline]
fn dist(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[inline]
fn sub(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline]
fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Distance from segment `a`–`b` to the axis-aligned box `[−h, h]` (0 when they meet).
///
/// Along the segment `x(t) = a + t (b − a)` the squared distance to the box is
/// `Σ_i max(0, |x_i(t)| − h_i)²`: a convex, piecewise quadratic function of `t` whose pieces
/// change where a coordinate crosses a face plane `±h_i` (at most six break points). On each
/// piece the active terms are fixed, so its minimum is closed form; the smallest over the
/// pieces is exact. Allocation-free, no iteration.
pub fn seg_box(a: &[f64; 3], b: &[f64; 3], h: &[f64; 3]) -> f64 {
    let u = sub(b, a);
    // Break points in (0, 1), with the ends.
    let mut ts = [0.0f64; 8];
    let mut n = 1;
    for i in 0..3 {
        if u[i] != 0.0 {
            for face in [-h[i], h[i]] {
                let t = (face - a[i]) / u[i];
                if t > 0.0 && t < 1.0 {
                    ts[n] = t;
                    n += 1;
                }
            }
        }
    }
    ts[n] = 1.0;
    n += 1;
    // Insertion sort (≤ 8 values).
    for i in 1..n {
        let mut j = i;
        while j > 0 && ts[j - 1] > ts[j] {
            ts.swap(j - 1, j);
            j -= 1;
        }
    }
    let mut best = f64::INFINITY;
    for w in ts[..n].windows(2) {
        let (t0, t1) = (w[0], w[1]);
        // Which side each axis is on inside this piece (its midpoint decides).
        let tm = 0.5 * (t0 + t1);
        // Quadratic A t² + B t (+ const) of the active terms.
        let (mut qa, mut qb) = (0.0, 0.0);
        for i in 0..3 {
            let x = a[i] + tm * u[i];
            let off = if x > h[i] {
                a[i] - h[i]
            } else if x < -h[i] {
                a[i] + h[i]
            } else {
                continue;
            };
            qa += u[i] * u[i];
            qb += 2.0 * u[i] * off;
        }
        let t = if qa > 0.0 { (-qb / (2.0 * qa)).clamp(t0, t1) } else { t0 };
        // Evaluated directly at the piece's minimiser (no cancellation in the expansion).
        let d2: f64 = (0..3).map(|i| ((a[i] + t * u[i]).abs() - h[i]).max(0.0).powi(2)).sum();
        best = best.min(d2);
    }
    best.max(0.0).sqrt()
}

/// Distance from the segment `a`–`b` to the solid disc (flat cylinder) of radius `r` and half
/// thickness `h` about the z axis at the origin (0 where they meet). The distance from a point
/// to the disc has a closed form (radial and axial excess), and along the segment it is a
/// convex function of the segment's parameter (the distance to a convex set): Brent's search
/// finds its least value to 10⁻¹⁰ of the segment's length (where no closed-form bound is
/// reached first), no allocation.
pub fn seg_disc(a: &[f64; 3], b: &[f64; 3], r: f64, h: f64) -> f64 {
    let d = sub(b, a);
    let f = |t: f64| {
        let x = [a[0] + t * d[0], a[1] + t * d[1], a[2] + t * d[2]];
        (x[0].hypot(x[1]) - r).max(0.0).hypot((x[2].abs() - h).max(0.0))
    };
    // Two lower bounds that are often reached (then exact, no search): the distance to the
    // slab |z| ≤ h (the end nearest to it, both ends on one side), where that end lies over
    // the disc; and the distance to the solid infinite cylinder ρ ≤ r (the point of least ρ),
    // where that point lies within the slab.
    if a[2].abs() > h && b[2].abs() > h && a[2].signum() == b[2].signum() {
        let e = if a[2].abs() <= b[2].abs() { a } else { b };
        if e[0].hypot(e[1]) <= r {
            return e[2].abs() - h;
        }
    }
    let dd = d[0] * d[0] + d[1] * d[1];
    let t = if dd > 0.0 { (-(a[0] * d[0] + a[1] * d[1]) / dd).clamp(0.0, 1.0) } else { 0.0 };
    let x = [a[0] + t * d[0], a[1] + t * d[1], a[2] + t * d[2]];
    if x[2].abs() <= h && x[0].hypot(x[1]) >= r {
        return x[0].hypot(x[1]) - r;
    }
    // Convex: not falling off an end, the least value is there.
    let (f0, f1) = (f(0.0), f(1.0));
    if f(1e-9) >= f0 {
        return f0;
    }
    if f(1.0 - 1e-9) >= f1 {
        return f1;
    }
    f0.min(f1).min(brent_min(f, 1e-10))
}

/// The least value of `f` on [0, 1] for a unimodal (here convex) `f`, by Brent's method
/// (golden sections with parabolic steps: a few evaluations for a smooth `f`, never slower
/// than golden sections), to `tol` in the argument.
fn brent_min(f: impl Fn(f64) -> f64, tol: f64) -> f64 {
    const C: f64 = 0.381_966_011_250_105_1;
    let (mut a, mut b) = (0.0f64, 1.0f64);
    let mut x = a + C * (b - a);
    let (mut w, mut v) = (x, x);
    let mut fx = f(x);
    let (mut fw, mut fv) = (fx, fx);
    let (mut d, mut e) = (0.0f64, 0.0f64);
    for _ in 0..100 {
        if fx == 0.0 {
            return 0.0;
        }
        let m = 0.5 * (a + b);
        let tol1 = tol * x.abs() + 1e-12;
        let tol2 = 2.0 * tol1;
        if (x - m).abs() <= tol2 - 0.5 * (b - a) {
            break;
        }
        let mut golden = true;
        if e.abs() > tol1 {
            // A parabola through x, w, v.
            let r = (x - w) * (fx - fv);
            let mut q = (x - v) * (fx - fw);
            let mut p = (x - v) * q - (x - w) * r;
            q = 2.0 * (q - r);
            if q > 0.0 {
                p = -p;
            }
            q = q.abs();
            let e_old = e;
            if p.abs() < (0.5 * q * e_old).abs() && p > q * (a - x) && p < q * (b - x) {
                e = d;
                d = p / q;
                let u = x + d;
                if u - a < tol2 || b - u < tol2 {
                    d = if m >= x { tol1 } else { -tol1 };
                }
                golden = false;
            }
        }
        if golden {
            e = if x >= m { a - x } else { b - x };
            d = C * e;
        }
        let u = if d.abs() >= tol1 { x + d } else { x + if d > 0.0 { tol1 } else { -tol1 } };
        let fu = f(u);
        if fu <= fx {
            if u >= x {
                a = x;
            } else {
                b = x;
            }
            (v, fv, w, fw, x, fx) = (w, fw, x, fx, u, fu);
        } else {
            if u < x {
                a = u;
            } else {
                b = u;
            }
            if fu <= fw || w == x {
                (v, fv, w, fw) = (w, fw, u, fu);
            } else if fu <= fv || v == x || v == w {
                (v, fv) = (u, fu);
            }
        }
    }
    fx
}

/// Distance from point `p` to segment `a`–`b`.
pub fn seg_point(a: &[f64; 3], b: &[f64; 3], p: &[f64; 3]) -> f64 {
    let ab = sub(b, a);
    let l2 = dot(&ab, &ab);
    let s = if l2 > 0.0 { (dot(&sub(p, a), &ab) / l2).clamp(0.0, 1.0) } else { 0.0 };
    dist(&[a[0] + ab[0] * s, a[1] + ab[1] * s, a[2] + ab[2] * s], p)
}

/// Distance between segments `p1`–`q1` and `p2`–`q2` (closest points, clamped; Ericson 5.1.9).
pub fn seg_seg(p1: &[f64; 3], q1: &[f64; 3], p2: &[f64; 3], q2: &[f64; 3]) -> f64 {
    let d1 = sub(q1, p1);
    let d2 = sub(q2, p2);
    let r = sub(p1, p2);
    let a = dot(&d1, &d1);
    let e = dot(&d2, &d2);
    let f = dot(&d2, &r);
    const EPS: f64 = 1e-18;
    let (s, t);
    if a <= EPS && e <= EPS {
        return dist(p1, p2);
    }
    if a <= EPS {
        s = 0.0;
        t = (f / e).clamp(0.0, 1.0);
    } else {
        let c = dot(&d1, &r);
        if e <= EPS {
            t = 0.0;
            s = (-c / a).clamp(0.0, 1.0);
        } else {
            let b = dot(&d1, &d2);
            let denom = a * e - b * b;
            let mut s0 = if denom > EPS * a * e { ((b * f - c * e) / denom).clamp(0.0, 1.0) } else { 0.0 };
            let mut t0 = (b * s0 + f) / e;
            if t0 < 0.0 {
                t0 = 0.0;
                s0 = (-c / a).clamp(0.0, 1.0);
            } else if t0 > 1.0 {
                t0 = 1.0;
                s0 = ((b - c) / a).clamp(0.0, 1.0);
            }
            s = s0;
            t = t0;
        }
    }
    let c1 = [p1[0] + d1[0] * s, p1[1] + d1[1] * s, p1[2] + d1[2] * s];
    let c2 = [p2[0] + d2[0] * t, p2[1] + d2[1] * t, p2[2] + d2[2] * t];
    dist(&c1, &c2)
}
