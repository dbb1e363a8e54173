//! The classical pose-from-depth baseline (issue #15): per instance of a segmented depth
//! frame, the valid pixels are back-projected to 3-D points in the frame the camera is posed
//! in, and their centroid, covariance and principal axes are the object's pose estimate.
//!
//! What it is and is not:
//! * The centroid is that of the **visible surface**, each pixel weighted by the square of its
//!   depth (the area it covers), so a rod or panel reaching towards the camera is not pulled
//!   to its near end by perspective. For a convex object it lies between the object's centre
//!   and the camera (a ball's about 2/3 of its radius out: its pixels sample the surface
//!   evenly over its image, not over its area). The covariance says how the points spread
//!   (extent, not uncertainty of the centre), with the same weights, less the expected
//!   share of the sensor's depth noise when its model is given ([`Extractor::depth_noise`]).
//! * The principal axes are sign-free directions (an axis and its opposite are the same): a
//!   rod's first axis is its axis, a panel's last axis its normal. A symmetric shape's axes
//!   are as ambiguous as the shape.
//! * One pass over the pixels with fixed per-instance sums, then a 3 × 3 symmetric
//!   eigen-decomposition per instance: allocation-free.
//!
//! This is what the learned features f_θ of the paper's Algorithm 1 must beat.

pub mod perception;

use nalgebra::{Matrix3, SymmetricEigen, Vector3};

/// Instances a frame can carry (values 1..=254; 0 is background, 255 the arm).
pub const MAX_INSTANCES: usize = 254;

/// A pinhole camera's intrinsics and pose: pixel (u, v)'s centre is at image coordinates
/// (u + 0.5, v + 0.5); camera axes x right, y down, z along the optical axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    pub width: usize,
    pub height: usize,
    /// Focal length and principal point, pixels.
    pub f: f64,
    pub cx: f64,
    pub cy: f64,
    /// Optical centre in the frame, m.
    pub position: [f64; 3],
    /// Camera-to-frame rotation, rows.
    pub rotation: [[f64; 3]; 3],
}

/// The estimate for one instance (`Default`: none, all zero).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PoseEstimate {
    /// The instance value in the frame.
    pub instance: u8,
    /// Valid pixels used.
    pub points: usize,
    /// Centroid of the visible surface, m.
    pub centroid: [f64; 3],
    /// Covariance of the points about the centroid, m².
    pub covariance: [[f64; 3]; 3],
    /// Principal axes (unit, sign-free), by decreasing spread.
    pub axes: [[f64; 3]; 3],
    /// Standard deviation of the points along each axis, m.
    pub spread: [f64; 3],
    /// Valid pixels on the image's border: the frame may cut the object there.
    pub cut: usize,
    /// Valid pixels next to a valid pixel of another instance (or the arm) that is nearer by
    /// more than [`OCCLUSION_STEP`]: something in front may hide part of the object there.
    pub occluded: usize,
    /// The weighted moments of the pixels whose rays lie in the camera's own 90° × 90° square
    /// pyramid about its optical axis, about its optical centre: the six faces of a cube rig
    /// (optical axes along ±x, ±y, ±z, turned by right angles) split the directions around
    /// their common centre into these pyramids without overlap, so the parts of an object
    /// several faces cut add up to its view from that centre, each point once ([`Moments::add`]).
    pub own: Moments,
}

/// Weighted point moments about a fixed origin: `w = Σ wᵢ`, `s = Σ wᵢ dᵢ`, `ss = Σ wᵢ dᵢ dᵢᵀ`
/// (`dᵢ` the point less the origin).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Moments {
    pub w: f64,
    pub s: [f64; 3],
    pub ss: [[f64; 3]; 3],
    /// `Σ wᵢ Nᵢ`: the depth noise's share of `ss` ([`Extractor::depth_noise`]).
    pub nn: [[f64; 3]; 3],
}

impl Moments {
    /// No points.
    pub const ZERO: Moments = Moments { w: 0.0, s: [0.0; 3], ss: [[0.0; 3]; 3], nn: [[0.0; 3]; 3] };

    /// Adds another set of points' moments about the same origin.
    pub fn add(&mut self, o: &Moments) {
        self.w += o.w;
        for i in 0..3 {
            self.s[i] += o.s[i];
            for j in 0..3 {
                self.ss[i][j] += o.ss[i][j];
                self.nn[i][j] += o.nn[i][j];
            }
        }
    }

    /// The points' centroid (`origin` added back), covariance, principal axes and spreads
    /// (the fields of a [`PoseEstimate`] these give; the rest left at `Default`), or `None`
    /// without weight.
    pub fn estimate(&self, origin: &[f64; 3]) -> Option<PoseEstimate> {
        if self.w <= 0.0 {
            return None;
        }
        let n = self.w;
        let mean = [self.s[0] / n, self.s[1] / n, self.s[2] / n];
        let cov = Matrix3::from_fn(|i, j| (self.ss[i][j] - self.nn[i][j]) / n - mean[i] * mean[j]);
        let (axes, spread) = principal(&cov);
        Some(PoseEstimate {
            centroid: std::array::from_fn(|i| origin[i] + mean[i]),
            covariance: std::array::from_fn(|i| std::array::from_fn(|j| cov[(i, j)])),
            axes,
            spread,
            ..PoseEstimate::default()
        })
    }
}

/// Principal axes (by decreasing spread) and spreads (standard deviations) of a covariance.
fn principal(cov: &Matrix3<f64>) -> ([[f64; 3]; 3], [f64; 3]) {
    let eig = SymmetricEigen::new(*cov);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let axis = |k: usize| -> [f64; 3] {
        let c: Vector3<f64> = eig.eigenvectors.column(order[k]).into();
        [c[0], c[1], c[2]]
    };
    ([axis(0), axis(1), axis(2)], std::array::from_fn(|k| eig.eigenvalues[order[k]].max(0.0).sqrt()))
}

/// Depth step (m) by which a neighbouring pixel of another instance must be nearer for a
/// pixel to count as [`PoseEstimate::occluded`] (depth noise of touching objects is smaller).
pub const OCCLUSION_STEP: f64 = 0.05;

#[derive(Debug, Clone, Copy, Default)]
struct Sums {
    n: usize,
    /// Sum of the weights (z²: the area a pixel covers grows with the square of its depth).
    w: f64,
    s: [f64; 3],
    ss: [[f64; 3]; 3],
    /// First point (a shift that keeps the sums well conditioned).
    origin: [f64; 3],
    cut: usize,
    occluded: usize,
    own: Moments,
    /// The depth noise's share of `ss` ([`Extractor::depth_noise`]), in the camera's frame
    /// (turned into the base frame once per instance), and its share of `own.ss`.
    nn_cam: [[f64; 3]; 3],
    own_nn_cam: [[f64; 3]; 3],
}

/// The fewest valid pixels an instance needs to be estimated ([`Extractor::min_points`]'s
/// default). Three give a centroid. A small object far away, or one mostly hidden behind the
/// arm, shows only a few pixels. With six needed, a 0.16 m object crossing at 2 m/s was seen
/// too late to be avoided, and a 0.2 m one mostly hidden behind the arm only 0.5 s before it
/// hit (`dkrrt study` through the camera, 100 episodes per scene: a collision in sparse-slow
/// and one in fast-crossing). Its spreads mean little at that size; the front end's class
/// and shape come from the largest spreads the object shows as it nears.
pub const MIN_POINTS: usize = 3;

/// Per-instance sums, preallocated.
#[derive(Debug, Clone)]
pub struct Extractor {
    sums: Box<[Sums; 256]>,
    /// The instances the last frame summed, `n_touched` of them (only their sums are cleared
    /// for the next frame).
    touched: [u8; 256],
    n_touched: usize,
    /// Instances with fewer valid pixels are not estimated.
    pub min_points: usize,
    /// The sensor's depth noise, σ(z) = `depth_noise[0]` + `depth_noise[1]`·z² (m; z the
    /// depth): it moves each point along its ray and so spreads the points of a far object
    /// along the line of sight (a 0.15 m ball 9 m out, σ = 0.12 m, spread 0.17 m instead of
    /// 0.075 m). Its expected share is taken out of the covariance. Zero: none known.
    pub depth_noise: [f64; 2],
}

impl Default for Extractor {
    fn default() -> Self {
        Extractor {
            sums: Box::new([Sums::default(); 256]),
            touched: [0; 256],
            n_touched: 0,
            min_points: MIN_POINTS,
            depth_noise: [0.0; 2],
        }
    }
}

impl Extractor {
    /// Estimates every instance 1..=254 with at least `min_points` valid pixels of the frame
    /// (`depth` in m along the optical axis, 0 = no return; row-major), in increasing instance
    /// order, into `out`; returns how many were written.
    pub fn extract(
        &mut self,
        cam: &Intrinsics,
        depth: &[f32],
        instance: &[u8],
        out: &mut [PoseEstimate],
    ) -> usize {
        self.extract_with(cam, |k| depth[k] as f64, instance, out)
    }

    /// As [`Extractor::extract`], with pixel `k`'s depth (m, 0 = no return) from `depth(k)`
    /// (e.g. a message's millimetres).
    pub fn extract_with(
        &mut self,
        cam: &Intrinsics,
        depth: impl Fn(usize) -> f64,
        instance: &[u8],
        out: &mut [PoseEstimate],
    ) -> usize {
        for &inst in &self.touched[..self.n_touched] {
            self.sums[inst as usize] = Sums::default();
        }
        self.n_touched = 0;
        let r = &cam.rotation;
        for v in 0..cam.height {
            for u in 0..cam.width {
                let k = v * cam.width + u;
                let (z, inst) = (depth(k), instance[k]);
                if z <= 0.0 || inst == 0 || inst as usize > MAX_INSTANCES {
                    continue;
                }
                let c = [(u as f64 + 0.5 - cam.cx) / cam.f * z, (v as f64 + 0.5 - cam.cy) / cam.f * z, z];
                let p: [f64; 3] = std::array::from_fn(|i| {
                    cam.position[i] + r[i][0] * c[0] + r[i][1] * c[1] + r[i][2] * c[2]
                });
                let (w_px, h_px) = (cam.width, cam.height);
                let border = u == 0 || v == 0 || u + 1 == w_px || v + 1 == h_px;
                // A nearer valid pixel of another instance (or the arm) beside this one.
                let hidden = |k2: usize| {
                    let i2 = instance[k2];
                    if i2 == 0 || i2 == inst {
                        return false;
                    }
                    let z2 = depth(k2);
                    z2 > 0.0 && z2 < z - OCCLUSION_STEP
                };
                let occluded = (u > 0 && hidden(k - 1))
                    || (u + 1 < w_px && hidden(k + 1))
                    || (v > 0 && hidden(k - w_px))
                    || (v + 1 < h_px && hidden(k + w_px));
                let s = &mut self.sums[inst as usize];
                if s.n == 0 {
                    s.origin = p;
                    self.touched[self.n_touched] = inst;
                    self.n_touched += 1;
                }
                s.cut += border as usize;
                s.occluded += occluded as usize;
                let d = [p[0] - s.origin[0], p[1] - s.origin[1], p[2] - s.origin[2]];
                let w = z * z;
                s.n += 1;
                s.w += w;
                // Upper triangles only (the moments are symmetric; mirrored once per instance).
                for i in 0..3 {
                    s.s[i] += w * d[i];
                    for j in i..3 {
                        s.ss[i][j] += w * d[i] * d[j];
                    }
                }
                // The noise moves the point by δz along a = (x/z, y/z, 1) in the camera's frame:
                // its second moment there is σ(z)² a aᵀ (turned into the base frame once).
                let sig = self.depth_noise[0] + self.depth_noise[1] * z * z;
                let own = c[0].abs() <= z && c[1].abs() <= z;
                if sig > 0.0 {
                    let a = [c[0] / z, c[1] / z, 1.0];
                    let ws = w * sig * sig;
                    for i in 0..3 {
                        for j in i..3 {
                            let m = ws * a[i] * a[j];
                            s.nn_cam[i][j] += m;
                            if own {
                                s.own_nn_cam[i][j] += m;
                            }
                        }
                    }
                }
                if own {
                    let d: [f64; 3] = std::array::from_fn(|i| p[i] - cam.position[i]);
                    let o = &mut s.own;
                    o.w += w;
                    for i in 0..3 {
                        o.s[i] += w * d[i];
                        for j in i..3 {
                            o.ss[i][j] += w * d[i] * d[j];
                        }
                    }
                }
            }
        }
        let mut n_out = 0;
        // In increasing instance order (an in-place sort: nothing allocated).
        self.touched[..self.n_touched].sort_unstable();
        for &inst in &self.touched[..self.n_touched] {
            let inst = inst as usize;
            let mut s = self.sums[inst];
            if s.n < self.min_points.max(1) || n_out >= out.len() {
                continue;
            }
            mirror(&mut s.ss);
            mirror(&mut s.own.ss);
            let nn = to_base(r, &s.nn_cam);
            s.own.nn = to_base(r, &s.own_nn_cam);
            let n = s.w;
            let mean = [s.s[0] / n, s.s[1] / n, s.s[2] / n];
            let cov = Matrix3::from_fn(|i, j| (s.ss[i][j] - nn[i][j]) / n - mean[i] * mean[j]);
            let (axes, spread) = principal(&cov);
            out[n_out] = PoseEstimate {
                instance: inst as u8,
                points: s.n,
                centroid: std::array::from_fn(|i| s.origin[i] + mean[i]),
                covariance: std::array::from_fn(|i| std::array::from_fn(|j| cov[(i, j)])),
                axes,
                spread,
                cut: s.cut,
                occluded: s.occluded,
                own: s.own,
            };
            n_out += 1;
        }
        n_out
    }
}

/// Copies the upper triangle of `m` onto its lower one.
fn mirror(m: &mut [[f64; 3]; 3]) {
    (m[1][0], m[2][0], m[2][1]) = (m[0][1], m[0][2], m[1][2]);
}

/// `R M Rᵀ` for `M` given by its upper triangle (in the camera's frame, `r` its rotation into
/// the base frame).
fn to_base(r: &[[f64; 3]; 3], upper: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut m = *upper;
    mirror(&mut m);
    let rm: [[f64; 3]; 3] =
        std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| r[i][k] * m[k][j]).sum()));
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| rm[i][k] * r[j][k]).sum()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A camera turned about a skew axis, so the camera and base frames differ on every axis.
    fn camera() -> Intrinsics {
        let r = nalgebra::Rotation3::from_axis_angle(
            &nalgebra::Unit::new_normalize(Vector3::new(0.3, -0.8, 0.5)),
            1.1,
        );
        Intrinsics {
            width: 16,
            height: 12,
            f: 6.0,
            cx: 8.0,
            cy: 6.0,
            position: [0.4, -1.2, 2.0],
            rotation: std::array::from_fn(|i| std::array::from_fn(|j| r[(i, j)])),
        }
    }

    /// The estimate of instance `inst` and its own moments, summed pixel by pixel in the base
    /// frame as the module docs define them (no shortcuts).
    fn reference(
        cam: &Intrinsics,
        depth: &[f64],
        ids: &[u8],
        noise: [f64; 2],
        inst: u8,
    ) -> (PoseEstimate, Moments) {
        let (mut all, mut own) = (Moments::ZERO, Moments::ZERO);
        let mut pts = Vec::new();
        for v in 0..cam.height {
            for u in 0..cam.width {
                let k = v * cam.width + u;
                let z = depth[k];
                if ids[k] != inst || z <= 0.0 {
                    continue;
                }
                let a = [(u as f64 + 0.5 - cam.cx) / cam.f, (v as f64 + 0.5 - cam.cy) / cam.f, 1.0];
                let r = &cam.rotation;
                let g: [f64; 3] = std::array::from_fn(|i| (0..3).map(|j| r[i][j] * a[j]).sum());
                let p: [f64; 3] = std::array::from_fn(|i| cam.position[i] + z * g[i]);
                let d: [f64; 3] = std::array::from_fn(|i| p[i] - cam.position[i]);
                let (w, sig) = (z * z, noise[0] + noise[1] * z * z);
                let one = Moments {
                    w,
                    s: d.map(|x| w * x),
                    ss: std::array::from_fn(|i| std::array::from_fn(|j| w * d[i] * d[j])),
                    nn: std::array::from_fn(|i| std::array::from_fn(|j| w * sig * sig * g[i] * g[j])),
                };
                all.add(&one);
                if a[0].abs() <= 1.0 && a[1].abs() <= 1.0 {
                    own.add(&one);
                }
                pts.push(p);
            }
        }
        let mut e = all.estimate(&cam.position).unwrap();
        e.instance = inst;
        e.points = pts.len();
        (e, own)
    }

    fn close(a: f64, b: f64, scale: f64) -> bool {
        (a - b).abs() <= 1e-9 * scale.max(1.0)
    }

    /// The per-instance sums (upper triangles, the noise in the camera's frame turned once, only
    /// the instances a frame shows cleared for the next) give what summing every pixel's full
    /// moments in the base frame gives, frame after frame.
    #[test]
    fn the_sums_match_a_pixel_by_pixel_reference_over_frames() {
        let cam = camera();
        let n = cam.width * cam.height;
        let noise = [0.002, 0.0015];
        let mut ex = Extractor { depth_noise: noise, ..Extractor::default() };
        // Frame 1: instances 3 and 9; frame 2: instances 9 and 200 (3 gone, its sums must not
        // linger); depths vary across each object.
        let frames: [(u8, u8); 2] = [(3, 9), (200, 9)];
        for (f, (left, right)) in frames.into_iter().enumerate() {
            let (mut depth, mut ids) = (vec![0.0; n], vec![0u8; n]);
            for v in 1..cam.height - 1 {
                for u in 1..cam.width - 1 {
                    let k = v * cam.width + u;
                    ids[k] = if u < 7 { left } else { right };
                    depth[k] = 4.0 + 0.3 * u as f64 - 0.2 * v as f64
                        + 0.5 * f as f64
                        + 0.01 * ((k * 7919) % 13) as f64;
                }
            }
            let mut out = [PoseEstimate::default(); 4];
            let got = ex.extract_with(&cam, |k| depth[k], &ids, &mut out);
            let mut want = [left, right];
            want.sort();
            assert_eq!(got, 2);
            for (e, inst) in out[..2].iter().zip(want) {
                let (r, own) = reference(&cam, &depth, &ids, noise, inst);
                assert_eq!((e.instance, e.points), (r.instance, r.points));
                for i in 0..3 {
                    assert!(
                        close(e.centroid[i], r.centroid[i], 10.0),
                        "{:?} vs {:?}",
                        e.centroid,
                        r.centroid
                    );
                    assert!(close(e.spread[i], r.spread[i], 1.0), "{:?} vs {:?}", e.spread, r.spread);
                    for j in 0..3 {
                        assert!(close(e.covariance[i][j], r.covariance[i][j], 1.0));
                        assert!(close(e.own.ss[i][j], own.ss[i][j], own.ss[i][j].abs()));
                        assert!(
                            close(e.own.nn[i][j], own.nn[i][j], own.nn[i][j].abs()),
                            "{:?} vs {:?}",
                            e.own.nn,
                            own.nn
                        );
                    }
                    assert!(close(e.own.s[i], own.s[i], own.s[i].abs()));
                }
                assert!(close(e.own.w, own.w, own.w));
            }
        }
    }
}
