//! Learned visual features f_θ (issue #15, the paper's Algorithm 1) for the depth camera.
//!
//! * **Input** ([`FrameScan::crop`]): per object, a square crop of the segmented depth image around the
//!   object's pixels, resampled to [`CROP`] × [`CROP`] cells, two channels (mask, depth about
//!   the object's mean depth in units of the crop's width in metres), for the current view and
//!   the object's previous view from the same camera (so the features can carry motion), plus
//!   three numbers: the log of the crop's width in metres and the direction of its centre.
//! * **f_θ** ([`VisualNet`]): three 3 × 3 stride-2 convolutions (ReLU), a dense ReLU layer and
//!   a linear layer give the features ξ̂ = [observables (12), extra (6)]; with a constant 1 they
//!   are the Koopman state, advanced by `K` (19 × 19).
//! * **Observables** ([`targets`]): sign-free, symmetry-aware attitude in the camera frame:
//!   `a₀a₀ᵀ` of the object's longest body axis and `a₂a₂ᵀ` of its shortest (6 entries each).
//!   Where the shape leaves an axis undefined (a rod's short axes, a square panel's in-plane
//!   axes, a ball's), the target is the average over the symmetry (`(I − aaᵀ)/2` or `I/3`), so
//!   the largest eigenvalue of the prediction says how sure the view is ([`decode`]).
//! * **Training** ([`train`]): Algorithm 1: the loss is the multi-step prediction error of the
//!   observables, `Σₖ ‖C Kᵏ ξ̂(τ₀) − y(τ₀ + k)‖²`, through f_θ; `K` is re-solved by least squares
//!   on all consecutive feature pairs every `M` epochs, and held between.
//! * **Inference** on fixed arrays ([`VisualNet::forward`]), allocation-free; [`LearnedAxes`]
//!   is the depth front end's [`AxisModel`].

pub mod file;
pub mod train;

use dkrrt_depthpose::perception::{AxisModel, SeenAxes, PCA_DEFINED};
use dkrrt_depthpose::{Intrinsics, PoseEstimate};
use dkrrt_msg::{DepthImage, DEPTH_MAX_INSTANCES};
use nalgebra::{Matrix3, SymmetricEigen};

/// Crop side, cells.
pub const CROP: usize = 24;
/// Channels of one view (mask, depth).
pub const VIEW_CH: usize = 2;
/// Input channels (current and previous view).
pub const IN_CH: usize = 2 * VIEW_CH;
/// Cells of one view.
pub const VIEW_LEN: usize = VIEW_CH * CROP * CROP;
/// Values of the image input.
pub const IN_LEN: usize = IN_CH * CROP * CROP;
/// Scalar inputs (log crop width, crop centre direction x, y).
pub const N_SCALARS: usize = 3;
/// Attitude observables (`a₀a₀ᵀ`, `a₂a₂ᵀ`, 6 entries each).
pub const N_OBS: usize = 12;
/// Extra learned features.
pub const N_EXTRA: usize = 6;
/// Network outputs.
pub const N_OUT: usize = N_OBS + N_EXTRA;
/// Koopman state: outputs and the constant 1.
pub const P: usize = N_OUT + 1;
/// Convolution channels.
pub const C1: usize = 8;
pub const C2: usize = 16;
pub const C3: usize = 16;
/// Spatial sizes after each convolution.
pub const S1: usize = CROP / 2;
pub const S2: usize = S1 / 2;
pub const S3: usize = S2 / 2;
/// Flattened convolution output plus scalars.
pub const FLAT: usize = C3 * S3 * S3 + N_SCALARS;
/// Dense hidden width.
pub const HIDDEN: usize = 64;
/// An axis is told apart when its extent differs from the middle one by this factor.
pub const DISTINCT: f64 = 1.15;
/// A predicted observable matrix shows an axis when its largest eigenvalue exceeds this
/// (1 for a sure axis, 1/2 when it is anywhere in a plane, 1/3 when anywhere).
pub const SURE: f64 = 0.75;
/// Depth values are clamped to ± this many crop widths.
pub const DEPTH_CLAMP: f32 = 2.0;

/// One view of one object.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    /// Mask then depth, row-major `CROP × CROP` each.
    pub px: [f32; VIEW_LEN],
    pub scalars: [f32; N_SCALARS],
}

impl Default for View {
    fn default() -> Self {
        View { px: [0.0; VIEW_LEN], scalars: [0.0; N_SCALARS] }
    }
}

/// Per-instance pixel box and depth sums of one frame.
#[derive(Debug, Clone, Copy, Default)]
struct InstBox {
    u0: u32,
    u1: u32,
    v0: u32,
    v1: u32,
    n: u32,
    zsum: f64,
}

/// One pass over a frame: each instance's pixel box and mean depth (allocation-free).
#[derive(Debug, Clone)]
pub struct FrameScan {
    boxes: [InstBox; DEPTH_MAX_INSTANCES + 1],
}

impl Default for FrameScan {
    fn default() -> Self {
        FrameScan { boxes: [InstBox::default(); DEPTH_MAX_INSTANCES + 1] }
    }
}

impl FrameScan {
    /// Scans `img` (valid pixels only).
    pub fn scan(&mut self, img: &DepthImage) {
        let (w, h) = (img.width as usize, img.height as usize);
        for b in self.boxes.iter_mut() {
            *b = InstBox { u0: u32::MAX, v0: u32::MAX, ..InstBox::default() };
        }
        for v in 0..h {
            for u in 0..w {
                let k = v * w + u;
                let (i, d) = (img.instance[k] as usize, img.depth_mm[k]);
                if i == 0 || i > DEPTH_MAX_INSTANCES || d == 0 {
                    continue;
                }
                let b = &mut self.boxes[i];
                b.u0 = b.u0.min(u as u32);
                b.u1 = b.u1.max(u as u32);
                b.v0 = b.v0.min(v as u32);
                b.v1 = b.v1.max(v as u32);
                b.n += 1;
                b.zsum += d as f64 * 1e-3;
            }
        }
    }

    /// Valid pixels of instance `inst` in the frame scanned last.
    pub fn pixels(&self, inst: u8) -> usize {
        self.boxes.get(inst as usize).map_or(0, |b| b.n as usize)
    }

    /// The crop of instance `inst` of `img` (scanned last) into `out`; false when it has no
    /// valid pixel.
    pub fn crop(&self, img: &DepthImage, inst: u8, out: &mut View) -> bool {
        let b = match self.boxes.get(inst as usize) {
            Some(b) if b.n > 0 && inst > 0 => *b,
            _ => return false,
        };
        let (w, h) = (img.width as i64, img.height as i64);
        let zc = b.zsum / b.n as f64;
        let side_px = ((b.u1 - b.u0 + 1).max(b.v1 - b.v0 + 1) as f64 * 1.15 + 2.0).max(4.0);
        let uc = 0.5 * (b.u0 + b.u1 + 1) as f64;
        let vc = 0.5 * (b.v0 + b.v1 + 1) as f64;
        let f = img.focal_px;
        let s_m = side_px * zc / f;
        let cell = side_px / CROP as f64;
        let (mask, depth) = out.px.split_at_mut(CROP * CROP);
        for i in 0..CROP {
            let v = (vc + (i as f64 + 0.5 - 0.5 * CROP as f64) * cell).floor() as i64;
            for j in 0..CROP {
                let u = (uc + (j as f64 + 0.5 - 0.5 * CROP as f64) * cell).floor() as i64;
                let c = i * CROP + j;
                mask[c] = 0.0;
                depth[c] = 0.0;
                if u < 0 || v < 0 || u >= w || v >= h {
                    continue;
                }
                let k = (v * w + u) as usize;
                if img.instance[k] != inst || img.depth_mm[k] == 0 {
                    continue;
                }
                mask[c] = 1.0;
                let z = img.depth_mm[k] as f64 * 1e-3;
                depth[c] = (((z - zc) / s_m) as f32).clamp(-DEPTH_CLAMP, DEPTH_CLAMP);
            }
        }
        out.scalars = [s_m.max(1e-6).ln() as f32, ((uc - img.cx) / f) as f32, ((vc - img.cy) / f) as f32];
        true
    }
}

/// Sign-free observable of a unit axis: `aaᵀ`'s entries xx, yy, zz, √2 xy, √2 xz, √2 yz
/// (the Euclidean norm of the six is the Frobenius norm of the matrix).
pub fn outer6(a: &[f64; 3]) -> [f64; 6] {
    let r2 = std::f64::consts::SQRT_2;
    [a[0] * a[0], a[1] * a[1], a[2] * a[2], r2 * a[0] * a[1], r2 * a[0] * a[2], r2 * a[1] * a[2]]
}

fn sym6(m: &[f64; 6]) -> Matrix3<f64> {
    let r = std::f64::consts::FRAC_1_SQRT_2;
    Matrix3::new(m[0], r * m[3], r * m[4], r * m[3], m[1], r * m[5], r * m[4], r * m[5], m[2])
}

fn plane6(a: &[f64; 3]) -> [f64; 6] {
    // (I − aaᵀ)/2
    let o = outer6(a);
    [0.5 * (1.0 - o[0]), 0.5 * (1.0 - o[1]), 0.5 * (1.0 - o[2]), -0.5 * o[3], -0.5 * o[4], -0.5 * o[5]]
}

const ISO6: [f64; 6] = [1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0, 0.0, 0.0, 0.0];

/// The observables of an object whose body-to-frame rotation is `r_obj` (rows) and whose
/// half extents along its body axes are `ext`, seen by a camera whose camera-to-frame
/// rotation is `r_cam` (rows): `[a₀a₀ᵀ, a₂a₂ᵀ]` in camera axes, each replaced by its average
/// over the shape's symmetry where the shape leaves it undefined.
pub fn targets(r_cam: &[[f64; 3]; 3], r_obj: &[[f64; 3]; 3], ext: &[f64; 3]) -> [f64; N_OBS] {
    let mut idx = [0usize, 1, 2];
    idx.sort_by(|&a, &b| ext[b].total_cmp(&ext[a]));
    let axis = |i: usize| -> [f64; 3] {
        // Body axis i in the frame (column i of r_obj), then in camera axes (r_camᵀ ·).
        let a = [r_obj[0][i], r_obj[1][i], r_obj[2][i]];
        std::array::from_fn(|k| r_cam[0][k] * a[0] + r_cam[1][k] * a[1] + r_cam[2][k] * a[2])
    };
    let (e0, e1, e2) = (ext[idx[0]], ext[idx[1]], ext[idx[2]]);
    let long = (e0 > DISTINCT * e1).then(|| axis(idx[0]));
    let short = (e2 * DISTINCT < e1).then(|| axis(idx[2]));
    let m0 = match (long, short) {
        (Some(a), _) => outer6(&a),
        (None, Some(c)) => plane6(&c),
        (None, None) => ISO6,
    };
    let m2 = match (short, long) {
        (Some(c), _) => outer6(&c),
        (None, Some(a)) => plane6(&a),
        (None, None) => ISO6,
    };
    let mut y = [0.0; N_OBS];
    y[..6].copy_from_slice(&m0);
    y[6..].copy_from_slice(&m2);
    y
}

/// Axes read from predicted observables (camera axes): each the top eigenvector of its
/// matrix when the top eigenvalue exceeds [`SURE`]; with the eigenvalues.
pub fn decode(y: &[f64]) -> (SeenAxes, [f64; 2]) {
    let mut out = SeenAxes::default();
    let mut lam = [0.0; 2];
    for (h, slot) in [0usize, 1].into_iter().zip([&mut out.long, &mut out.short]) {
        let m: [f64; 6] = std::array::from_fn(|i| y[6 * h + i]);
        let e = SymmetricEigen::new(sym6(&m));
        let (mut bi, mut bv) = (0, f64::NEG_INFINITY);
        for i in 0..3 {
            if e.eigenvalues[i] > bv {
                (bi, bv) = (i, e.eigenvalues[i]);
            }
        }
        lam[h] = bv;
        if bv > SURE {
            let v = e.eigenvectors.column(bi);
            let n = v.norm().max(1e-12);
            *slot = Some([v[0] / n, v[1] / n, v[2] / n]);
        }
    }
    (out, lam)
}

/// f_θ on fixed arrays: weights laid out as candle holds them (convolutions
/// `(c_out, c_in, 3, 3)`, dense `(in, out)` row-major), and the Koopman matrix `K` (`P × P`,
/// row-major: `ξ(t+1) = K ξ(t)`). Scratch buffers are owned, so [`forward`](Self::forward)
/// allocates nothing.
#[derive(Debug, Clone, PartialEq)]
pub struct VisualNet {
    pub w1: Vec<f32>,
    pub b1: Vec<f32>,
    pub w2: Vec<f32>,
    pub b2: Vec<f32>,
    pub w3: Vec<f32>,
    pub b3: Vec<f32>,
    pub d1w: Vec<f32>,
    pub d1b: Vec<f32>,
    pub d2w: Vec<f32>,
    pub d2b: Vec<f32>,
    pub k: Vec<f64>,
    scratch: Box<Scratch>,
}

#[derive(Debug, Clone, PartialEq)]
struct Scratch {
    a1: [f32; C1 * S1 * S1],
    a2: [f32; C2 * S2 * S2],
    a3: [f32; FLAT],
    h: [f32; HIDDEN],
}

/// Sizes of the parameter tensors, in [`VisualNet`] field order (without `k`).
pub const PARAM_SIZES: [usize; 10] =
    [C1 * IN_CH * 9, C1, C2 * C1 * 9, C2, C3 * C2 * 9, C3, FLAT * HIDDEN, HIDDEN, HIDDEN * N_OUT, N_OUT];

/// Names of the parameter tensors (for errors), in [`PARAM_SIZES`] order.
pub const PARAM_NAMES: [&str; 10] = ["w1", "b1", "w2", "b2", "w3", "b3", "d1w", "d1b", "d2w", "d2b"];

impl VisualNet {
    /// From parameter vectors in [`PARAM_SIZES`] order and `K`; `None` when a size is wrong.
    pub fn from_parts(params: Vec<Vec<f32>>, k: Vec<f64>) -> Option<Self> {
        if params.len() != PARAM_SIZES.len() || k.len() != P * P {
            return None;
        }
        if params.iter().zip(PARAM_SIZES).any(|(p, n)| p.len() != n) {
            return None;
        }
        let mut it = params.into_iter();
        let mut nx = || it.next().expect("checked length");
        Some(VisualNet {
            w1: nx(),
            b1: nx(),
            w2: nx(),
            b2: nx(),
            w3: nx(),
            b3: nx(),
            d1w: nx(),
            d1b: nx(),
            d2w: nx(),
            d2b: nx(),
            k,
            scratch: Box::new(Scratch {
                a1: [0.0; C1 * S1 * S1],
                a2: [0.0; C2 * S2 * S2],
                a3: [0.0; FLAT],
                h: [0.0; HIDDEN],
            }),
        })
    }

    /// The parameter vectors in [`PARAM_SIZES`] order.
    pub fn params(&self) -> [&[f32]; 10] {
        [
            &self.w1, &self.b1, &self.w2, &self.b2, &self.w3, &self.b3, &self.d1w, &self.d1b, &self.d2w,
            &self.d2b,
        ]
    }

    /// ξ̂ = f_θ(current, previous) into `out` (allocation-free).
    pub fn forward(&mut self, cur: &View, prev: &View, out: &mut [f64; N_OUT]) {
        let s = &mut *self.scratch;
        let input = |c: usize, y: usize, x: usize| -> f32 {
            let v = if c < VIEW_CH { cur } else { prev };
            v.px[(c % VIEW_CH) * CROP * CROP + y * CROP + x]
        };
        conv(&self.w1, &self.b1, IN_CH, CROP, C1, &input, &mut s.a1);
        let a1 = s.a1;
        conv(&self.w2, &self.b2, C1, S1, C2, &|c, y, x| a1[(c * S1 + y) * S1 + x], &mut s.a2);
        let a2 = s.a2;
        conv(&self.w3, &self.b3, C2, S2, C3, &|c, y, x| a2[(c * S2 + y) * S2 + x], &mut s.a3[..C3 * S3 * S3]);
        s.a3[C3 * S3 * S3..].copy_from_slice(&cur.scalars);
        for j in 0..HIDDEN {
            let mut acc = self.d1b[j];
            for i in 0..FLAT {
                acc += s.a3[i] * self.d1w[i * HIDDEN + j];
            }
            s.h[j] = acc.max(0.0);
        }
        for (j, o) in out.iter_mut().enumerate() {
            let mut acc = self.d2b[j];
            for i in 0..HIDDEN {
                acc += s.h[i] * self.d2w[i * N_OUT + j];
            }
            *o = acc as f64;
        }
    }

    /// One Koopman step of the features: `ξ(t+1) = K [ξ(t); 1]` (without the constant).
    pub fn advance(&self, xi: &[f64; N_OUT], out: &mut [f64; N_OUT]) {
        for (i, o) in out.iter_mut().enumerate() {
            let row = &self.k[i * P..(i + 1) * P];
            *o = row[N_OUT] + row[..N_OUT].iter().zip(xi).map(|(a, b)| a * b).sum::<f64>();
        }
    }
}

/// A 3 × 3, stride 2, padding 1 convolution with ReLU: `c_in` channels of `n × n` (read by
/// `input(c, y, x)`) to `c_out` channels of `n/2 × n/2` in `out`.
fn conv(
    w: &[f32],
    b: &[f32],
    c_in: usize,
    n: usize,
    c_out: usize,
    input: &dyn Fn(usize, usize, usize) -> f32,
    out: &mut [f32],
) {
    let m = n / 2;
    for co in 0..c_out {
        for y in 0..m {
            for x in 0..m {
                let mut acc = b[co];
                for ci in 0..c_in {
                    let wk = &w[(co * c_in + ci) * 9..(co * c_in + ci) * 9 + 9];
                    for ky in 0..3 {
                        let iy = (2 * y + ky) as isize - 1;
                        if iy < 0 || iy >= n as isize {
                            continue;
                        }
                        for kx in 0..3 {
                            let ix = (2 * x + kx) as isize - 1;
                            if ix < 0 || ix >= n as isize {
                                continue;
                            }
                            acc += wk[ky * 3 + kx] * input(ci, iy as usize, ix as usize);
                        }
                    }
                }
                out[(co * m + y) * m + x] = acc.max(0.0);
            }
        }
    }
}

/// Objects whose previous view is remembered.
pub const MAX_REMEMBERED: usize = 128;

#[derive(Debug, Clone)]
struct Memory {
    id: u32,
    /// The camera (its position and orientation) the view was taken by.
    camera: [f64; 7],
    stamp_ns: u64,
    view: View,
}

/// The learned front end's axis reader: f_θ on each object's crop, with the object's
/// previous view from the same camera (its current view again when there is none within
/// [`PREV_MAX_AGE_NS`]). Allocation-free after construction.
pub struct LearnedAxes {
    net: VisualNet,
    scan: FrameScan,
    scanned: Option<(u64, [f64; 7])>,
    memory: Box<heapless::Vec<Memory, MAX_REMEMBERED>>,
    cur: Box<View>,
    /// Frames whose crop could not be made (no valid pixel).
    pub empty: u64,
}

/// A previous view older than this is not used (the current one stands in for it), ns.
pub const PREV_MAX_AGE_NS: u64 = 150_000_000;

impl LearnedAxes {
    pub fn new(net: VisualNet) -> Self {
        LearnedAxes {
            net,
            scan: FrameScan::default(),
            scanned: None,
            memory: Box::new(heapless::Vec::new()),
            cur: Box::default(),
            empty: 0,
        }
    }

    /// The features ξ̂ of instance `inst` (object `id`) of `img` into `out`, remembering this
    /// view; false when the instance has no valid pixel.
    pub fn features(&mut self, img: &DepthImage, inst: u8, id: u32, out: &mut [f64; N_OUT]) -> bool {
        let cam = camera_key(img);
        if self.scanned != Some((img.header.stamp_ns, cam)) {
            self.scan.scan(img);
            self.scanned = Some((img.header.stamp_ns, cam));
        }
        if !self.scan.crop(img, inst, &mut self.cur) {
            self.empty += 1;
            return false;
        }
        let stamp = img.header.stamp_ns;
        let slot = match self.memory.iter().position(|m| m.id == id) {
            Some(i) => i,
            None => {
                let fresh = Memory { id, camera: cam, stamp_ns: stamp, view: *self.cur };
                if self.memory.push(fresh).is_err() {
                    let (i, _) = self
                        .memory
                        .iter()
                        .enumerate()
                        .min_by_key(|(_, m)| m.stamp_ns)
                        .expect("full, so not empty");
                    self.memory[i] = Memory { id, camera: cam, stamp_ns: stamp, view: *self.cur };
                }
                self.memory.iter().position(|m| m.id == id).expect("just stored")
            }
        };
        let m = &mut self.memory[slot];
        let fresh = m.camera == cam && stamp > m.stamp_ns && stamp - m.stamp_ns <= PREV_MAX_AGE_NS;
        let prev = if fresh { &m.view } else { &*self.cur };
        self.net.forward(&self.cur, prev, out);
        m.view = *self.cur;
        m.camera = cam;
        m.stamp_ns = stamp;
        true
    }
}

/// A learned axis within this angle of the principal axis of the view's points that the
/// points define well is replaced by it (the points' axis is the finer measure; f_θ says which
/// body axis it is, and reads the axes the points get wrong), rad.
pub const SNAP_RAD: f64 = 0.6;

/// `learned`, or the principal axis `pca` when it is `defined` and within [`SNAP_RAD`]
/// (sign-free).
pub fn snap(learned: [f64; 3], pca: &[f64; 3], defined: bool) -> [f64; 3] {
    let d = learned[0] * pca[0] + learned[1] * pca[1] + learned[2] * pca[2];
    if defined && d.abs() >= SNAP_RAD.cos() {
        *pca
    } else {
        learned
    }
}

/// The camera's pose as a key (position, orientation).
fn camera_key(img: &DepthImage) -> [f64; 7] {
    let (p, q) = (img.position_m, img.orientation);
    [p[0], p[1], p[2], q[0], q[1], q[2], q[3]]
}

/// The fewest valid pixels of a view f_θ learns from and reads.
pub const MIN_VIEW_PIXELS: usize = 20;

impl AxisModel for LearnedAxes {
    fn min_points(&self) -> usize {
        MIN_VIEW_PIXELS
    }

    fn axes(&mut self, img: &DepthImage, cam: &Intrinsics, e: &PoseEstimate, id: u32) -> SeenAxes {
        let mut xi = [0.0; N_OUT];
        if !self.features(img, e.instance, id, &mut xi) {
            return SeenAxes::default();
        }
        let (seen, _) = decode(&xi[..N_OBS]);
        // Camera axes → the frame: a = R_cam a_c.
        let r = &cam.rotation;
        let to_frame = |a: [f64; 3]| -> [f64; 3] {
            std::array::from_fn(|i| r[i][0] * a[0] + r[i][1] * a[1] + r[i][2] * a[2])
        };
        let long =
            seen.long.map(to_frame).map(|a| snap(a, &e.axes[0], e.spread[0] > PCA_DEFINED * e.spread[1]));
        let short =
            seen.short.map(to_frame).map(|c| snap(c, &e.axes[2], e.spread[2] * PCA_DEFINED < e.spread[1]));
        SeenAxes { long, short }
    }
}
