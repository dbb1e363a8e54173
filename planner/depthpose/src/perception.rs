//! A classical perception front end on the depth camera: each segmented `DepthImage` becomes
//! a `DebrisObservation` frame (pose and shape per object, measured at the capture time), so
//! the predictor reads the camera through the message it already reads from a pose sensor.
//!
//! Per instance, the [`Extractor`]'s centroid and principal axes, then per object id:
//! * **Class**, from the largest spread seen per principal axis so far (a tumbling object
//!   shows its sides in turn; one view can hide an extent), in its views of at least
//!   [`SHAPE_POINTS`] pixels once it has one (a far view's few points spread mostly by the
//!   depth noise), in its whole views once it has one (a view cut by the frame or hidden in
//!   part shows a part, and a part can spread
//!   wider than the whole: a panel's two ends with the arm across its middle): a **rod** when the first spread
//!   is over 3 times the second, a **panel** when the third is under a fifth of the second
//!   (a **disc** when its second is at least [`ROUND`] of its first: a square panel, whose
//!   in-plane axes the spreads do not tell), else **bulky** (balls, fragments).
//! * **Shape**, from those spreads (points spread evenly over an extent 2a have σ = a/√3; a
//!   ball's visible cap spreads σ = r/2 sideways): a rod is a capsule of half length √3·σ₀
//!   and radius 2σ₁ (≥ 2 cm), a panel a box of half extents √3·σ (≥ 1 cm thick), a disc
//!   the [`ShapeKind::Disc`] that box sweeps turning about its normal, a bulky
//!   object a sphere of radius max(2σ₀, √3·|σ|) (a ball, or the corners of a chunky box).
//! * **Position**: the centroid of the visible surface lies in front of a bulky object's
//!   centre (a ball's by 2r/3, when its cap's thinnest spread is 0.236 r): it is moved back
//!   along the camera ray by 2.83 × the thinnest spread. A rod's or a panel's visible centroid
//!   is its centre (thin).
//! * **Attitude**: a rod's body z is its axis, turned from the last attitude by the smallest
//!   rotation (the spin about the axis is not observable, so it is not made up; it is
//!   flagged [`DEBRIS_AXIS_ONLY`]: that spin drifts as the axis turns, and so is no
//!   measurement); a disc's body z is its normal, likewise; a panel's
//!   body axes are its principal axes, their signs chosen nearest to the last attitude; a
//!   bulky object's attitude is held (a sphere's attitude does not matter for contact, and
//!   a noisy one would trip the predictor's attitude gate).
//! * **Partial views**: a view whose longest spread is under [`PART`] of the longest seen of
//!   that object (hidden in part by another object or the arm, a rod end-on, a noisy view of
//!   a few pixels) would put its centre off, and the predictor's position bound would grow on
//!   the jumps: it is not reported, the predictor coasts through it. A view **cut by the
//!   image border** (a pixel on it; [`crate::PoseEstimate::cut`]) with one of its two largest
//!   spreads under [`WHOLE`] of the largest seen is held back, and so is every cut or hidden
//!   view while the object has not been seen whole (nothing to measure it against; a 2 m
//!   rod with the arm across it from its first view was reported whole, 0.2–0.4 m off its
//!   centre, and the predictor took the jumps between its visible parts for a velocity of
//!   0.5–1.7 m/s): when no camera of the capture shows the object whole, it is reported
//!   with the next capture, flagged
//!   [`DEBRIS_PARTIAL`] (located from all the capture's views of it: **Rigs** below), with
//!   the shape and attitude last seen whole (never seen whole: the shape of its parts'
//!   spreads, a panel's as the disc it sweeps in its plane, since no part shows its in-plane
//!   attitude), except a rod's axis and a disc's normal where
//!   the visible parts define them (a cut or half-hidden rod still shows its direction, a
//!   panel its plane; taken from all the capture's views of it, else from the view with the
//!   most pixels): then it is also flagged [`DEBRIS_AXIS_ONLY`]. The predictor takes its
//!   position loosely and its attitude only with that flag, so an object that straddles two
//!   cameras of a rig, or the edge of a single camera's view, is still tracked. A view
//!   hidden in part behind something nearer (its outline touches a nearer object or the arm:
//!   [`crate::PoseEstimate::occluded`]) is treated as a cut one, and so is, before the
//!   object's first whole view, a planar object's view **edge-on** (its second spread under
//!   [`EDGE_ON`] of its plane's): a line, which shows neither the plane's extent nor its
//!   normal (taken for a panel's first whole view it made the panel a rod 1 cm thick).
//! * **Restarts**: the largest spread seen grows as the object turns; a view whose longest
//!   spread is over 1/[`PART`] of the longest seen before (a rod seen end-on at first, its
//!   near end taken for its centre, then broadside) shows that the earlier reports were of
//!   part of it. The next whole report is flagged [`DEBRIS_RESTART`]: the predictor restarts
//!   the object's position and velocity from it instead of taking the jump for a change of
//!   motion.
//! * **Rigs**: an object several cameras see in one capture (frames with the same stamp) is
//!   reported once, from the first frame that shows it whole. When none does, its partial
//!   report is located from all the capture's views of it added up, each camera counting only
//!   the directions in its own 90° × 90° pyramid ([`crate::PoseEstimate::own`]; a cube rig's
//!   faces split the directions around their common centre so), not from one camera's part:
//!   a part's centroid stays near the edge that cuts it while the object moves on, which the
//!   predictor took for a velocity (a 0.43 m box crossing two faces at 2 m was reported up to
//!   0.41 m off, drifting at 1 m/s). The report's shape and flags are as before.
//! * **A learned axis model** ([`DepthPerception::with_model`], the visual features f_θ of
//!   `dkrrt-visual`): the attitude and the class come from the axes the model reads from the
//!   view instead: a box (long and short axis seen: body x along the long axis, body z along
//!   the short one, a cuboid from the spreads), a rod (long axis only: body z, a capsule), a
//!   disc (short axis only: body z, a [`ShapeKind::Disc`]) or bulky (neither: attitude held,
//!   a sphere). The class is the model's majority over the views so far.
//!
//! Allocation-free after construction.

use dkrrt_msg::{
    DebrisObs, DebrisObservation, DebrisShape, DepthImage, ShapeKind, DEBRIS_AXIS_ONLY, DEBRIS_PARTIAL,
    DEBRIS_RESTART, DEPTH_MAX_INSTANCES, MAX_DEBRIS,
};

use dkrrt_collision::pose::{quat_mul as mul, rotation_matrix as rotation};

use crate::{Extractor, Intrinsics, Moments, PoseEstimate};

/// Sign-free axes a learned model reads from one view of an object, in the camera's frame
/// (`Intrinsics::rotation` applied).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SeenAxes {
    /// The longest body axis, when the view shows one (a rod's axis, a box's long side).
    pub long: Option<[f64; 3]>,
    /// The shortest body axis, when the view shows one (a panel's or a box's normal).
    pub short: Option<[f64; 3]>,
}

/// Reads an object's axes from a view (the learned visual features f_θ).
pub trait AxisModel: Send {
    /// The axes of instance `e.instance` (object `id`) of `img`.
    fn axes(&mut self, img: &DepthImage, cam: &Intrinsics, e: &PoseEstimate, id: u32) -> SeenAxes;
    /// The fewest valid pixels of a view the model reads (smaller views are outside what it
    /// learned from).
    fn min_points(&self) -> usize;
}

/// A principal axis of a view's points is defined when its spread and its neighbour's differ
/// by this factor.
pub const PCA_DEFINED: f64 = 1.3;

/// An object whose second largest spread is under this share of its largest is a rod for
/// the learned path too.
pub const THIN: f64 = 6.0;

/// An object has a long axis when at least this share of its views so far showed one…
pub const LONG_SHARE: f64 = 0.4;
/// … and a short axis when at least this share did (a view can hide an axis a shape has: a
/// box end-on, a panel edge-on; one it lacks shows in few views).
pub const SHORT_SHARE: f64 = 0.25;

/// What an object looks like to the front end.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Class {
    Rod,
    Panel,
    /// A panel whose two sides look alike (a square one): its in-plane attitude is not told
    /// by the points' spreads, so it is reported as the disc it sweeps turning in its plane,
    /// by its normal alone.
    Disc,
    Bulky,
}

/// A panel is a disc when its second spread is at least this share of its first (its sides
/// differ by under 1/0.87 ≈ 1.15, where the points' in-plane axes are not told apart).
pub const ROUND: f64 = 0.87;

/// What this front end's poses and extents may be off by, m: about twice the median position
/// error of its observations in `dkrrt predict-eval`'s depth view (3–9 cm). The shapes it
/// reports are its estimates of the bodies, without it; whoever bounds them adds it (the
/// predictor's `front_end_margin_m` for depth frames grows every published bound by it: a
/// shape grown by it on every side, its corners rounded).
pub const ERROR_MARGIN_M: f64 = 0.15;

/// A view whose longest spread is under this share of the longest seen shows the object in
/// part (cut by the frame, hidden in part, or end-on): its centre would be off.
pub const PART: f64 = 0.75;

/// A view of a planar object (a panel, a disc) whose second spread is under this share of
/// the plane's shows it edge-on: a line, which tells neither the plane's extent nor its normal
/// (the normal of a line is any direction about it). Before the object's first whole view the
/// plane's spread is its parts' largest, which a part can exceed by up to √2 (a strip along a
/// square's diagonal); it is taken down by that much. Such a view is not taken for the first
/// whole view (it made a panel a rod 1 cm thick). Once the object has been seen whole it is
/// not held back for it: an object taken for a panel by one inflated spread but a rod (seen
/// as a line in every view after) would never be measured again (seen on `predict-eval`, seed
/// 101: a rod read as a 0.3 m wide panel for 7 s, 3 % of fast-crossing's forecasts through the
/// camera uncontained).
pub const EDGE_ON: f64 = 0.35;

/// A view cut by the image border is still whole enough when its two largest spreads are at
/// least this share of the largest seen: cutting `c` off an extent moves the centroid by `c/2`
/// and the spread by `c/√12`, so the centre is off by at most about `√3 · (1 − WHOLE)` of the
/// object's spreads (9 cm for a 1 m half extent).
pub const WHOLE: f64 = 0.9;

/// A view of fewer valid pixels than this tells little of the object's extent: a far one's
/// few points spread by the depth noise (σ 15 cm at 10 m on the default camera; with 2–4
/// points the noise's share of their spread is far from its expected value, which is what
/// the extractor takes out) and by a pixel's span. Its spreads count only while no view of
/// the object had this many; the first that does replaces them (a 0.4 m box seen with 2–4 pixels at 10 m spread 0.34 m, and its views at 5 m,
/// 15–24 pixels, then looked like parts of it and went unreported for 1.3 s).
pub const SHAPE_POINTS: usize = 8;

/// Objects remembered (the oldest seen is forgotten first).
pub const MAX_KNOWN: usize = 128;

#[derive(Debug, Clone, Copy)]
struct Known {
    id: u32,
    /// Largest spread seen along each principal axis (by rank), m.
    spread: [f64; 3],
    /// The most valid pixels of a view those spreads were taken from.
    points: usize,
    q: [f64; 4],
    /// Views the learned model read, and those that showed a long / a short axis.
    votes: [u32; 3],
    last_frame: u64,
    /// Capture time of its last whole report, ns (`u64::MAX`: none): another camera's frame
    /// of the same capture does not report it again.
    last_t_ns: u64,
    /// Its shape and bounding radius as last reported whole.
    shape: Option<(DebrisShape, f64)>,
    /// Its best partial view of the current capture (and that view's pixels), reported with
    /// the next capture unless a camera shows it whole in this one.
    pending: Option<(DebrisObs, usize)>,
    /// A view showed it larger than the reports so far: the next whole report is flagged
    /// [`DEBRIS_RESTART`].
    restart: bool,
    /// A view of it neither cut by the frame nor hidden in part has been seen.
    whole_seen: bool,
    /// Whole views whose points lie in a plane, and those of them whose two in-plane spreads
    /// are alike (within [`ROUND`]).
    round: [u32; 2],
    /// The sums of those planar views' two in-plane spreads, m.
    plane_sum: [f64; 2],
    /// The current capture's views of it added up: the view a partial report is located from.
    fused: Fused,
}

/// One capture's views of an object added up ([`crate::PoseEstimate::own`]: each face of a
/// cube rig its own directions).
#[derive(Debug, Clone, Copy)]
struct Fused {
    moments: Moments,
    /// The capture's stamp, ns.
    stamp_ns: u64,
    /// The optical centre the moments are about.
    origin: [f64; 3],
}

impl Fused {
    const NONE: Fused = Fused { moments: Moments::ZERO, stamp_ns: u64::MAX, origin: [0.0; 3] };
}

impl Known {
    /// Its class ([`classify`] of the largest spreads seen), a panel's told from a disc's by
    /// the majority of its whole planar views once it has one: each view's in-plane spreads
    /// are measured together, while the largest ones seen are each the maximum of noisy
    /// estimates (a square's 12 pixels across spread by ±10 % from view to view).
    fn class(&self) -> Class {
        match classify(&self.spread) {
            Class::Panel | Class::Disc if self.round[0] > 0 => {
                if 2 * self.round[1] > self.round[0] {
                    Class::Disc
                } else {
                    Class::Panel
                }
            }
            c => c,
        }
    }

    /// The spreads its shape is made from: the largest seen; a disc's in-plane ones the mean
    /// over its whole planar views (the largest seen of a square's noisy spreads lies 10–20 %
    /// over its true spread, and a disc's radius takes both).
    fn shape_spread(&self, c: Class) -> [f64; 3] {
        match c {
            Class::Disc if self.round[0] > 0 => {
                let n = self.round[0] as f64;
                [self.plane_sum[0] / n, self.plane_sum[1] / n, self.spread[2]]
            }
            _ => self.spread,
        }
    }
}

/// Counters.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PerceptionStats {
    pub frames: u64,
    /// Objects reported.
    pub objects: u64,
    /// Instances beyond the 32 items of one observation frame (not reported).
    pub dropped: u64,
    /// Objects another camera of the rig already reported for the same capture (not again).
    pub repeats: u64,
    /// Views of an object in part (module docs): not reported whole.
    pub partial: u64,
    /// Objects reported from a view cut by the image border (flagged [`DEBRIS_PARTIAL`]): no
    /// camera showed them whole in that capture.
    pub partial_reported: u64,
    /// Views the learned axis model read.
    pub learned: u64,
    /// Reports flagged [`DEBRIS_RESTART`] (the object seen larger than in the reports before).
    pub restarts: u64,
}

/// The front end (per-object memory and the extractor's buffers).
pub struct DepthPerception {
    extractor: Extractor,
    est: Box<[PoseEstimate; DEPTH_MAX_INSTANCES]>,
    known: heapless::Vec<Known, MAX_KNOWN>,
    pub stats: PerceptionStats,
    model: Option<Box<dyn AxisModel>>,
    /// Capture time of the frames being converted, ns.
    capture_ns: u64,
}

impl Default for DepthPerception {
    fn default() -> Self {
        DepthPerception {
            extractor: Extractor::default(),
            est: Box::new([PoseEstimate::default(); DEPTH_MAX_INSTANCES]),
            known: heapless::Vec::new(),
            stats: PerceptionStats::default(),
            model: None,
            capture_ns: u64::MAX,
        }
    }
}

/// The class of an object whose largest spreads per principal axis are `s`.
pub fn classify(s: &[f64; 3]) -> Class {
    if s[0] > 3.0 * s[1] {
        Class::Rod
    } else if s[2] < 0.2 * s[1] {
        if s[1] >= ROUND * s[0] {
            Class::Disc
        } else {
            Class::Panel
        }
    } else {
        Class::Bulky
    }
}

/// The shape of class `c` with largest spreads `s`, and its bounding radius (the body's
/// estimate: without [`ERROR_MARGIN_M`]).
pub fn shape_of(c: Class, s: &[f64; 3]) -> (DebrisShape, f64) {
    let r3 = 3f64.sqrt();
    match c {
        Class::Rod => {
            let (h, r) = (r3 * s[0], (2.0 * s[1]).max(0.02));
            (DebrisShape::capsule(h, r), h + r)
        }
        Class::Panel => {
            let e = [r3 * s[0], r3 * s[1], (r3 * s[2]).max(0.01)];
            (DebrisShape::cuboid(e, [0.0; 3]), (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt())
        }
        Class::Disc => {
            // The panel's corners, √3·s out along each side, swept about its normal.
            let (r, h) = ((r3 * s[0]).hypot(r3 * s[1]), (r3 * s[2]).max(0.01));
            (DebrisShape::disc(r, h), r.hypot(h))
        }
        Class::Bulky => {
            // A ball's cap spreads r/2; a chunky box's faces spread about its half extents
            // over √3, so its corners lie √3·|σ| out: the sphere covers either.
            let corner = r3 * (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
            let r = (2.0 * s[0]).max(corner).max(0.01);
            (DebrisShape::sphere(r), r)
        }
    }
}

/// The body z axis of a rod (its length) or a disc (its normal) in the view `e` of the object
/// `kn`, where the view's points define it (a disc's: not edge-on, [`EDGE_ON`]; `None` for
/// other shapes).
fn seen_axis(shape: &DebrisShape, e: &PoseEstimate, kn: &Known) -> Option<[f64; 3]> {
    match ShapeKind::from_u32(shape.kind) {
        Some(ShapeKind::Capsule) if e.spread[0] > PCA_DEFINED * e.spread[1] => Some(e.axes[0]),
        Some(ShapeKind::Disc) if e.spread[1] > PCA_DEFINED * e.spread[2] && !edge_on(e, kn) => {
            Some(e.axes[2])
        }
        _ => None,
    }
}

/// Whether the view `e` shows the object `kn`, known to be planar, edge-on ([`EDGE_ON`]).
fn edge_on(e: &PoseEstimate, kn: &Known) -> bool {
    let plane = if kn.whole_seen { kn.spread[1] } else { kn.spread[1] / std::f64::consts::SQRT_2 };
    matches!(classify(&kn.spread), Class::Panel | Class::Disc) && e.spread[1] < EDGE_ON * plane
}

/// Whether a report of `shape` measures only its body z axis ([`DEBRIS_AXIS_ONLY`]): a rod's
/// (a capsule) or a disc's.
fn axis_only(shape: &DebrisShape) -> bool {
    shape.kind == ShapeKind::Capsule as u32 || shape.kind == ShapeKind::Disc as u32
}

impl DepthPerception {
    /// The front end with a learned axis model for attitudes and classes.
    pub fn with_model(model: Box<dyn AxisModel>) -> Self {
        DepthPerception { model: Some(model), ..Self::default() }
    }

    /// Tells the front end its camera's depth noise, σ(z) = `base_m` + `quad_per_m`·z² (m),
    /// which it takes out of the views' spreads ([`Extractor::depth_noise`]).
    pub fn set_depth_noise(&mut self, base_m: f64, quad_per_m: f64) {
        self.extractor.depth_noise = [base_m, quad_per_m];
    }

    /// Whether a learned axis model reads the attitudes.
    pub fn learned(&self) -> bool {
        self.model.is_some()
    }

    /// Converts `img` into `out`: one item per object with enough valid pixels (at most
    /// [`MAX_DEBRIS`], in instance order; more are counted as dropped), measured at the capture time
    /// (`header.stamp_ns`), poses in the base frame. `out.header` is left to the caller (the
    /// frame's delivery). Returns the number of items.
    pub fn convert(&mut self, img: &DepthImage, out: &mut DebrisObservation) -> usize {
        self.stats.frames += 1;
        let frame = self.stats.frames;
        let cam = intrinsics(img);
        let n_px = img.width as usize * img.height as usize;
        let n = self.extractor.extract_with(
            &cam,
            |k| img.depth_mm[k] as f64 * 1e-3,
            &img.instance[..n_px],
            &mut self.est[..],
        );
        let mut count = 0;
        if img.header.stamp_ns != self.capture_ns {
            // The last capture's objects no camera showed whole: their best partial view.
            for kn in self.known.iter_mut() {
                let Some((mut o, _)) = kn.pending.take() else { continue };
                if kn.last_t_ns == o.t_meas_ns {
                    continue;
                }
                if count == MAX_DEBRIS {
                    self.stats.dropped += 1;
                    continue;
                }
                // Located from all that capture's faces showed of it, not from one face's part
                // (whose centroid stays near the edge it is cut at as the object moves on).
                let Fused { moments, stamp_ns, origin } = &kn.fused;
                if let Some(f) = moments.estimate(origin).filter(|_| *stamp_ns == o.t_meas_ns) {
                    o.p = visible_centre(&f, origin, kn.class());
                    // Its axis too, where the parts together define it: a face's part of a
                    // panel cut by its border can be a strip a few pixels wide, whose normal
                    // tilts freely about its length with the depth noise.
                    if let Some(a) = seen_axis(&o.shape, &f, kn) {
                        o.q = align(&o.q, 2, &a);
                        o.flags |= DEBRIS_AXIS_ONLY;
                    }
                }
                out.items[count] = o;
                count += 1;
                self.stats.partial_reported += 1;
            }
            self.capture_ns = img.header.stamp_ns;
        }
        for j in 0..n {
            let e = self.est[j];
            let k = e.instance as usize;
            if k == 0 || k > img.n_instances as usize {
                continue;
            }
            if count == MAX_DEBRIS {
                self.stats.dropped += 1;
                continue;
            }
            let id = img.ids[k - 1];
            let slot = self.slot(id);
            let kn = &mut self.known[slot];
            if kn.last_t_ns == img.header.stamp_ns {
                self.stats.repeats += 1;
                continue;
            }
            if kn.fused.stamp_ns != img.header.stamp_ns || kn.fused.origin != cam.position {
                kn.fused = Fused { stamp_ns: img.header.stamp_ns, origin: cam.position, ..Fused::NONE };
            }
            kn.fused.moments.add(&e.own);
            // A view cut by the frame or hidden in part shows a part, and a part can spread
            // wider than the whole (a panel's two ends with the arm across its middle): the
            // spreads its views are measured against are the whole views' once it has one.
            // Edge-on, only before the first whole view ([`EDGE_ON`]).
            let hidden = e.cut > 0 || e.occluded > 0 || (!kn.whole_seen && edge_on(&e, kn));
            if !hidden {
                // Larger than every view reported so far would have let through: those showed
                // it in part (module docs).
                if kn.last_t_ns != u64::MAX && e.spread[0] * PART > kn.spread[0] {
                    kn.restart = true;
                }
                if !kn.whole_seen {
                    // The first whole view replaces what the parts before it spread.
                    (kn.spread, kn.points, kn.whole_seen) = ([0.0; 3], 0, true);
                }
            }
            if !hidden || !kn.whole_seen {
                // Views of a few pixels count only until one of `SHAPE_POINTS` is seen, which
                // replaces what they spread.
                let told = e.points >= SHAPE_POINTS;
                if told && kn.points < SHAPE_POINTS {
                    kn.spread = [0.0; 3];
                }
                if told || kn.points < SHAPE_POINTS {
                    for i in 0..3 {
                        kn.spread[i] = kn.spread[i].max(e.spread[i]);
                    }
                    kn.points = kn.points.max(e.points);
                }
            }
            kn.last_frame = frame;
            if e.cut == 0 && e.spread[0] < PART * kn.spread[0] {
                // Hidden in part, end-on, or a noisy view of a few pixels: not reported (the
                // predictor coasts meanwhile). Another camera may still show it whole.
                self.stats.partial += 1;
                continue;
            }
            if hidden && (!kn.whole_seen || (0..2).any(|i| e.spread[i] < WHOLE * kn.spread[i])) {
                // Cut by the frame, or hidden in part behind something nearer (the arm, another
                // object: its outline touches it), and smaller than the whole views or with no
                // whole view yet to tell: its centre may be off by up to its size, and its axes
                // wrong.
                // Another camera of the same capture may still show it whole; if none does, the
                // cut view with the most pixels is reported with the next capture (module docs).
                self.stats.partial += 1;
                let better =
                    kn.pending.is_none_or(|(o, px)| o.t_meas_ns != img.header.stamp_ns || px < e.points);
                if better {
                    let (shape, radius) = kn.shape.unwrap_or_else(|| {
                        // Never seen whole, a panel's in-plane attitude is unknown, but its
                        // parts show its plane: it is reported as the disc it sweeps turning
                        // in that plane, by its normal (module docs).
                        let c = match kn.class() {
                            Class::Panel => Class::Disc,
                            c => c,
                        };
                        shape_of(c, &kn.shape_spread(c))
                    });
                    let p = visible_centre(&e, &cam.position, kn.class());
                    // A rod cut or hidden in part still shows its direction, a disc its
                    // normal: from the visible part, where that defines it (module docs);
                    // otherwise the report carries no attitude.
                    let seen = seen_axis(&shape, &e, kn).map(|a| align(&kn.q, 2, &a));
                    let flags = DEBRIS_PARTIAL | if seen.is_some() { DEBRIS_AXIS_ONLY } else { 0 };
                    let q = seen.unwrap_or(kn.q);
                    let o = item(id, flags, img.header.stamp_ns, p, q, (shape, radius));
                    kn.pending = Some((o, e.points));
                }
                continue;
            }
            if e.spread[1] > PCA_DEFINED * e.spread[2] && e.spread[2] < 0.2 * e.spread[1] {
                kn.round[0] += 1;
                kn.round[1] += (e.spread[1] >= ROUND * e.spread[0]) as u32;
                kn.plane_sum[0] += e.spread[0];
                kn.plane_sum[1] += e.spread[1];
            }
            let classical = kn.class();
            let (shape, radius);
            // The model reads views as large as those it learned from; the class of an object it
            // has read is the model's, its attitude from the model's axes or, in a smaller view,
            // from the points' axes.
            let mut seen = SeenAxes::default();
            if let Some(model) = self.model.as_mut().filter(|m| e.points >= m.min_points()) {
                seen = model.axes(img, &cam, &e, id);
                self.stats.learned += 1;
                kn.votes[0] += 1;
                kn.votes[1] += seen.long.is_some() as u32;
                kn.votes[2] += seen.short.is_some() as u32;
            }
            if kn.votes[0] > 0 {
                let sp = &kn.spread;
                let share = |k: usize| kn.votes[k] as f64 / kn.votes[0] as f64;
                // A thin object is a rod whatever the model reads: its cross-section spans a
                // few cells of the model's crop at most, so a strip and a rod look alike.
                let thin = sp[0] > THIN * sp[1];
                let (long, short) = (thin || share(1) >= LONG_SHARE, !thin && share(2) >= SHORT_SHARE);
                (shape, radius) = match (long, short) {
                    (true, true) => shape_of(Class::Panel, sp),
                    (true, false) => shape_of(Class::Rod, sp),
                    (false, true) => {
                        let ds = if kn.round[0] > 0 {
                            kn.shape_spread(Class::Disc)
                        } else {
                            [sp[0], sp[0], sp[2]]
                        };
                        shape_of(Class::Disc, &ds)
                    }
                    (false, false) => shape_of(Class::Bulky, sp),
                };
                // An axis the model did not read in this view: the points' principal axis,
                // where they define it.
                let defined = |i: usize, j: usize| e.spread[i.min(j)] > PCA_DEFINED * e.spread[i.max(j)];
                let seen = SeenAxes {
                    long: seen.long.or_else(|| defined(0, 1).then_some(e.axes[0])),
                    short: seen.short.or_else(|| defined(1, 2).then_some(e.axes[2])),
                };
                kn.q = match (long, short, seen.long, seen.short) {
                    (true, true, Some(a), Some(c)) => {
                        // Body z along the short axis made normal to the long one (body x).
                        let d = a[0] * c[0] + a[1] * c[1] + a[2] * c[2];
                        let z = unit(&std::array::from_fn(|i| c[i] - d * a[i]));
                        nearest_frame(&kn.q, &a, &cross(&z, &a))
                    }
                    // A box seen with one axis: that body axis turned onto it.
                    (true, true, Some(a), None) => align(&kn.q, 0, &a),
                    (true, true, None, Some(c)) => align(&kn.q, 2, &c),
                    (true, false, Some(a), _) => align(&kn.q, 2, &a),
                    (false, true, _, Some(c)) => align(&kn.q, 2, &c),
                    (false, true, _, None) => {
                        // A disc edge-on: the view does not tell its normal; the predictor
                        // coasts.
                        self.stats.partial += 1;
                        continue;
                    }
                    _ => kn.q,
                };
            } else {
                (shape, radius) = shape_of(classical, &kn.shape_spread(classical));
                kn.q = match classical {
                    Class::Rod => rod_attitude(&kn.q, &e.axes[0]),
                    Class::Panel => nearest_frame(&kn.q, &e.axes[0], &e.axes[1]),
                    Class::Disc if e.spread[1] > PCA_DEFINED * e.spread[2] => align(&kn.q, 2, &e.axes[2]),
                    Class::Disc => {
                        // Edge-on: the points do not tell its normal; the predictor coasts.
                        self.stats.partial += 1;
                        continue;
                    }
                    Class::Bulky => kn.q,
                };
            }
            kn.last_t_ns = img.header.stamp_ns;
            let p = visible_centre(&e, &cam.position, classical);
            kn.shape = Some((shape, radius));
            kn.pending = None;
            let flags = if std::mem::take(&mut kn.restart) { DEBRIS_RESTART } else { 0 };
            self.stats.restarts += (flags != 0) as u64;
            out.items[count] = item(id, flags, img.header.stamp_ns, p, kn.q, (shape, radius));
            count += 1;
        }
        out.count = count as u32;
        self.stats.objects += count as u64;
        count
    }

    /// The memory of object `id` (new: no spread seen, identity attitude; the table full:
    /// the object seen longest ago is forgotten).
    fn slot(&mut self, id: u32) -> usize {
        if let Some(i) = self.known.iter().position(|k| k.id == id) {
            return i;
        }
        let fresh = Known {
            id,
            spread: [0.0; 3],
            points: 0,
            q: [1.0, 0.0, 0.0, 0.0],
            votes: [0; 3],
            last_frame: 0,
            last_t_ns: u64::MAX,
            shape: None,
            pending: None,
            restart: false,
            whole_seen: false,
            round: [0; 2],
            plane_sum: [0.0; 2],
            fused: Fused::NONE,
        };
        if self.known.push(fresh).is_ok() {
            return self.known.len() - 1;
        }
        let (i, _) =
            self.known.iter().enumerate().min_by_key(|(_, k)| k.last_frame).expect("full, so not empty");
        self.known[i] = fresh;
        i
    }
}

/// An observation item without rates.
fn item(
    id: u32,
    flags: u32,
    t_ns: u64,
    p: [f64; 3],
    q: [f64; 4],
    (shape, radius): (DebrisShape, f64),
) -> DebrisObs {
    // A rod's attitude is its axis, a disc's its normal (module docs): the spin about it is
    // the front end's bookkeeping. A partial view says itself whether it shows that axis.
    let flags =
        if axis_only(&shape) && flags & DEBRIS_PARTIAL == 0 { flags | DEBRIS_AXIS_ONLY } else { flags };
    DebrisObs { id, flags, t_meas_ns: t_ns, p, q, v: [0.0; 3], w: [0.0; 3], bounding_radius: radius, shape }
}

/// The centre of an object of class `c` from its view `e` seen from `origin` (the optical
/// centre; module docs: a bulky object's visible centroid lies in front of its centre).
fn visible_centre(e: &PoseEstimate, origin: &[f64; 3], c: Class) -> [f64; 3] {
    let p = e.centroid;
    if c != Class::Bulky {
        return p;
    }
    let ray: [f64; 3] = std::array::from_fn(|i| p[i] - origin[i]);
    let l = norm(&ray).max(1e-9);
    let back = 2.83 * e.spread[2];
    std::array::from_fn(|i| p[i] + ray[i] / l * back)
}

/// The camera of a message, as the extractor takes it.
pub fn intrinsics(img: &DepthImage) -> Intrinsics {
    Intrinsics {
        width: img.width as usize,
        height: img.height as usize,
        f: img.focal_px,
        cx: img.cx,
        cy: img.cy,
        position: img.position_m,
        rotation: rotation(&img.orientation),
    }
}

/// The unit quaternion (w ≥ 0 not enforced) of the rotation whose columns are `c`.
fn from_columns(c: &[[f64; 3]; 3]) -> [f64; 4] {
    // m[i][j] = c[j][i].
    let m = |i: usize, j: usize| c[j][i];
    let tr = m(0, 0) + m(1, 1) + m(2, 2);
    let q = if tr > 0.0 {
        let s = (tr + 1.0).sqrt() * 2.0;
        [0.25 * s, (m(2, 1) - m(1, 2)) / s, (m(0, 2) - m(2, 0)) / s, (m(1, 0) - m(0, 1)) / s]
    } else if m(0, 0) > m(1, 1) && m(0, 0) > m(2, 2) {
        let s = (1.0 + m(0, 0) - m(1, 1) - m(2, 2)).sqrt() * 2.0;
        [(m(2, 1) - m(1, 2)) / s, 0.25 * s, (m(0, 1) + m(1, 0)) / s, (m(0, 2) + m(2, 0)) / s]
    } else if m(1, 1) > m(2, 2) {
        let s = (1.0 + m(1, 1) - m(0, 0) - m(2, 2)).sqrt() * 2.0;
        [(m(0, 2) - m(2, 0)) / s, (m(0, 1) + m(1, 0)) / s, 0.25 * s, (m(1, 2) + m(2, 1)) / s]
    } else {
        let s = (1.0 + m(2, 2) - m(0, 0) - m(1, 1)).sqrt() * 2.0;
        [(m(1, 0) - m(0, 1)) / s, (m(0, 2) + m(2, 0)) / s, (m(1, 2) + m(2, 1)) / s, 0.25 * s]
    };
    let n = norm4(&q);
    q.map(|v| v / n)
}

/// A panel's attitude: body axes x, y along `a0`, `a1` (z their cross product), the signs
/// giving the attitude nearest `prev`, signed like it.
fn nearest_frame(prev: &[f64; 4], a0: &[f64; 3], a1: &[f64; 3]) -> [f64; 4] {
    let mut best = *prev;
    let mut best_dot = -1.0;
    for (s0, s1) in [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
        let x = a0.map(|v| v * s0);
        let y = a1.map(|v| v * s1);
        let z = cross(&x, &y);
        let mut q = from_columns(&[x, y, z]);
        let d = dot4(&q, prev);
        if d < 0.0 {
            q = q.map(|v| -v);
        }
        if d.abs() > best_dot {
            (best, best_dot) = (q, d.abs());
        }
    }
    best
}

/// A rod's attitude: `prev` turned by the smallest rotation that takes its body z onto the
/// axis `a` (the sign of `a` nearest that z).
fn rod_attitude(prev: &[f64; 4], a: &[f64; 3]) -> [f64; 4] {
    align(prev, 2, a)
}

/// `prev` turned by the smallest rotation that takes its body axis `i` onto the axis `a` (the
/// sign of `a` nearest that body axis).
fn align(prev: &[f64; 4], i: usize, a: &[f64; 3]) -> [f64; 4] {
    let r = rotation(prev);
    let z = [r[0][i], r[1][i], r[2][i]];
    let a = if a[0] * z[0] + a[1] * z[1] + a[2] * z[2] < 0.0 { a.map(|v| -v) } else { *a };
    let c = cross(&z, &a);
    let swing = [1.0 + z[0] * a[0] + z[1] * a[1] + z[2] * a[2], c[0], c[1], c[2]];
    let n = norm4(&swing);
    let swing = swing.map(|v| v / n);
    let q = mul(&swing, prev);
    let n = norm4(&q);
    q.map(|v| v / n)
}

fn cross(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn unit(a: &[f64; 3]) -> [f64; 3] {
    let n = norm(a).max(1e-12);
    a.map(|v| v / n)
}

fn norm(a: &[f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

fn norm4(a: &[f64; 4]) -> f64 {
    a.iter().map(|v| v * v).sum::<f64>().sqrt()
}

fn dot4(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}
