//! A depth camera as a core (no IPC): a pinhole camera fixed on the servicer renders what a
//! depth sensor with a segmentation front end would deliver, by casting one ray per pixel
//! against the debris' true shapes and the arm's link capsules (the arm occludes).
//!
//! * **Geometry**: camera axes x right, y down, z along the optical axis (the usual optical
//!   frame); [`CameraConfig::orientation`] rotates camera axes into the frame the shapes are
//!   posed in. Square pixels; the vertical field of view sets the focal length. A pixel's
//!   depth is the hit's distance along the optical axis (not along the ray), as depth
//!   sensors report it.
//! * **Instances**: every pixel carries the instance that returned it: 0 background,
//!   [`ARM`] the arm, `k` = the `k`-th rendered target, whose object id is
//!   [`DepthFrame::ids`]`[k - 1]` (what a segmentation front end delivers).
//! * **Sensor model**: returns closer than `range_min_m` or beyond `range_max_m` are no
//!   returns (depth 0, background); a return's depth gets Gaussian noise of
//!   σ(z) = `noise_base_m` + `noise_quad_per_m`·z² (the quadratic growth of stereo and
//!   structured-light sensors); a fraction `dropout` of returns is dropped (depth 0, the
//!   instance kept: the segmentation still sees the object, the depth sensor does not).
//! * **Cost**: a target is only tested in the pixel rectangle its bounding sphere projects
//!   to (exact bounds of the sphere's projection), and a ray only when it enters the bounding
//!   sphere before the nearest hit so far; everything is preallocated, [`Camera::render`]
//!   allocates nothing.

pub mod scene;

use dkrrt_collision::pose::{quat_mul, rotation_matrix as rotation};
use dkrrt_collision::PosedCapsule;
use parry3d_f64::glamx::DQuat;
use parry3d_f64::math::{Pose, Vector as PVec};
use parry3d_f64::query::{Ray, RayCast};
use parry3d_f64::shape::{Capsule, Shape};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

/// Largest image: the message carries at most this many pixels.
pub const MAX_WIDTH: usize = 128;
pub const MAX_HEIGHT: usize = 96;
pub const MAX_PIXELS: usize = MAX_WIDTH * MAX_HEIGHT;
/// Instance of a pixel nothing returned.
pub const BACKGROUND: u8 = 0;
/// Instance of the arm's pixels.
pub const ARM: u8 = 255;
/// Targets one frame can label (instances 1..=254).
pub const MAX_INSTANCES: usize = 254;

/// The camera (the scenario's `[camera]` table; every field has a default).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CameraConfig {
    /// The sim renders and publishes frames (`dkrrt/depth_image`).
    pub enabled: bool,
    /// Frames per second (plant clock), 1–60.
    pub rate_hz: f64,
    /// Time from capture to delivery, s (the frame is stamped with its capture time).
    pub latency_s: f64,
    /// Cameras: 1 (this one), or 6 at `position_m` looking along ±x, ±y, ±z of the frame
    /// (a cube rig; `orientation` is then ignored; use a field of view of at least 90°).
    pub faces: u32,
    /// Image size, pixels (≤ [`MAX_WIDTH`] × [`MAX_HEIGHT`]).
    pub width: u32,
    pub height: u32,
    /// Vertical field of view, rad.
    pub fov_y_rad: f64,
    /// Optical centre in the frame the shapes are posed in, m.
    #[serde(deserialize_with = "dkrrt_io::exact::array")]
    pub position_m: [f64; 3],
    /// Camera-to-frame rotation as a unit quaternion (w, x, y, z).
    #[serde(deserialize_with = "dkrrt_io::exact::array")]
    pub orientation: [f64; 4],
    /// Returns nearer or farther than these are none, m.
    pub range_min_m: f64,
    pub range_max_m: f64,
    /// Depth noise σ(z) = `noise_base_m` + `noise_quad_per_m` · z², m.
    pub noise_base_m: f64,
    pub noise_quad_per_m: f64,
    /// Fraction of returns dropped (depth 0).
    pub dropout: f64,
    /// Seed of the noise.
    pub seed: u64,
}

impl Default for CameraConfig {
    /// The servicer's camera rig, off: six 90° cameras ([`CameraConfig::rig`]) 0.8 m below
    /// the arm's base (on the servicer, where the arm hides little and every direction is
    /// seen), each [`CameraConfig::single`]'s image, range, noise, rate and latency.
    fn default() -> Self {
        CameraConfig {
            faces: 6,
            fov_y_rad: std::f64::consts::FRAC_PI_2,
            position_m: [0.0, 0.0, -0.8],
            ..CameraConfig::single()
        }
    }
}

impl CameraConfig {
    /// One camera, off: 20 frames/s delivered 30 ms after capture; 128 × 96, 60° vertical
    /// field of view, at the frame's origin looking along +x with +z up in the image,
    /// 0.2–15 m, σ = 2 mm + 1.5 mm/m², 1 % dropped.
    pub fn single() -> Self {
        CameraConfig {
            enabled: false,
            rate_hz: 20.0,
            latency_s: 0.03,
            faces: 1,
            width: MAX_WIDTH as u32,
            height: MAX_HEIGHT as u32,
            fov_y_rad: 60f64.to_radians(),
            position_m: [0.0; 3],
            orientation: LOOK_ALONG_X,
            range_min_m: 0.2,
            range_max_m: 15.0,
            noise_base_m: 0.002,
            noise_quad_per_m: 0.0015,
            dropout: 0.01,
            seed: 1,
        }
    }
}

/// Camera z along frame +x, camera x along frame −y, camera y along frame −z (frame z up in
/// the image).
pub const LOOK_ALONG_X: [f64; 4] = [0.5, -0.5, 0.5, -0.5];

impl CameraConfig {
    /// The cameras this configuration stands for: itself (`faces = 1`), or the six of a cube
    /// rig at its position (`faces = 6`; seeds `seed + k`).
    pub fn rig(&self) -> Vec<CameraConfig> {
        if self.faces != 6 {
            return vec![*self];
        }
        // LOOK_ALONG_X turned about z by 0, 90°, 180°, −90° (along +x, +y, −x, −y, frame z
        // up in the images), and about y by −90°, 90° (along +z, −z).
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let turns = [
            [1.0, 0.0, 0.0, 0.0],
            [h, 0.0, 0.0, h],
            [0.0, 0.0, 0.0, 1.0],
            [h, 0.0, 0.0, -h],
            [h, 0.0, -h, 0.0],
            [h, 0.0, h, 0.0],
        ];
        turns
            .iter()
            .enumerate()
            .map(|(k, t)| CameraConfig {
                faces: 1,
                orientation: quat_mul(t, &LOOK_ALONG_X),
                seed: self.seed + k as u64,
                ..*self
            })
            .collect()
    }
}

/// A configuration value out of its range (the field is named as in the scenario).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("camera.{field} = {value}: {reason}")]
pub struct CameraError {
    pub field: &'static str,
    pub value: f64,
    pub reason: &'static str,
}

impl CameraConfig {
    /// Checks every field.
    pub fn validate(&self) -> Result<(), CameraError> {
        let fail = |field, value: f64, reason| Err(CameraError { field, value, reason });
        if !(1.0..=60.0).contains(&self.rate_hz) {
            return fail("rate_hz", self.rate_hz, "must be within [1, 60] frames/s");
        }
        if !(0.0..1.0).contains(&self.latency_s) {
            return fail("latency_s", self.latency_s, "must be within [0, 1) s");
        }
        if self.faces != 1 && self.faces != 6 {
            return fail("faces", self.faces as f64, "must be 1 or 6 (a cube rig)");
        }
        if self.width == 0 || self.width as usize > MAX_WIDTH {
            return fail("width", self.width as f64, "must be 1..=128");
        }
        if self.height == 0 || self.height as usize > MAX_HEIGHT {
            return fail("height", self.height as f64, "must be 1..=96");
        }
        if !(self.fov_y_rad > 0.0 && self.fov_y_rad < 3.0) {
            return fail("fov_y_rad", self.fov_y_rad, "must be in (0, 3) rad");
        }
        // A cube rig's faces meet only if each sees at least 90° both ways.
        let half_x = (self.width as f64 / self.height as f64) * (0.5 * self.fov_y_rad).tan();
        if self.faces == 6 && (self.fov_y_rad < std::f64::consts::FRAC_PI_2 - 1e-9 || half_x < 1.0 - 1e-9) {
            return fail(
                "fov_y_rad",
                self.fov_y_rad,
                "a cube rig (faces = 6) needs at least 90° vertically and horizontally, or its faces leave gaps",
            );
        }
        for (i, &x) in self.position_m.iter().enumerate() {
            if !x.is_finite() {
                return fail(["position_m[0]", "position_m[1]", "position_m[2]"][i], x, "must be finite");
            }
        }
        let n = self.orientation.iter().map(|x| x * x).sum::<f64>().sqrt();
        if !((n - 1.0).abs() <= 1e-6) {
            return fail("orientation", n, "must be a unit quaternion (w, x, y, z); this is its norm");
        }
        if !(self.range_min_m >= 0.0 && self.range_min_m.is_finite()) {
            return fail("range_min_m", self.range_min_m, "must be >= 0");
        }
        if !(self.range_max_m > self.range_min_m && self.range_max_m <= 65.535) {
            return fail(
                "range_max_m",
                self.range_max_m,
                "must be above range_min_m and at most 65.535 m (u16 mm)",
            );
        }
        // A metre of depth noise is no depth camera (and 1e300 m overflowed the f32 depths).
        if !(0.0..=1.0).contains(&self.noise_base_m) {
            return fail("noise_base_m", self.noise_base_m, "must be within [0, 1] m");
        }
        if !(0.0..=1.0).contains(&self.noise_quad_per_m) {
            return fail("noise_quad_per_m", self.noise_quad_per_m, "must be within [0, 1] 1/m");
        }
        if !(0.0..=1.0).contains(&self.dropout) {
            return fail("dropout", self.dropout, "must be in [0, 1]");
        }
        Ok(())
    }
}

/// One rendered frame (fixed capacity; row-major, `v · width + u`).
#[derive(Debug, Clone, PartialEq)]
pub struct DepthFrame {
    pub width: u32,
    pub height: u32,
    /// Depth along the optical axis, m; 0: no return.
    pub depth_m: Box<[f32]>,
    /// Instance per pixel: [`BACKGROUND`], [`ARM`], or `k` (object `ids[k - 1]`).
    pub instance: Box<[u8]>,
    /// Object id of instance `k` at index `k - 1`.
    pub ids: [u32; MAX_INSTANCES],
    pub n_instances: usize,
}

impl Default for DepthFrame {
    fn default() -> Self {
        DepthFrame {
            width: 0,
            height: 0,
            depth_m: vec![0.0; MAX_PIXELS].into_boxed_slice(),
            instance: vec![BACKGROUND; MAX_PIXELS].into_boxed_slice(),
            ids: [0; MAX_INSTANCES],
            n_instances: 0,
        }
    }
}

impl DepthFrame {
    /// Depth and instance of pixel (`u`, `v`).
    pub fn at(&self, u: usize, v: usize) -> (f32, u8) {
        let k = v * self.width as usize + u;
        (self.depth_m[k], self.instance[k])
    }

    /// The object id of instance `k` (`None`: background, the arm, or unused).
    pub fn id_of(&self, k: u8) -> Option<u32> {
        (k != BACKGROUND && k != ARM && (k as usize) <= self.n_instances).then(|| self.ids[k as usize - 1])
    }

    /// Pixels of instance `k`.
    pub fn count(&self, k: u8) -> usize {
        let n = (self.width * self.height) as usize;
        self.instance[..n].iter().filter(|&&i| i == k).count()
    }
}

/// A shape to render: object `id`, its exact shape posed at `p` (m) with attitude `q`
/// (w, x, y, z), and the radius of a sphere about `p` that holds it.
#[derive(Clone, Copy)]
pub struct Target<'a> {
    pub id: u32,
    pub shape: &'a dyn Shape,
    pub p: [f64; 3],
    pub q: [f64; 4],
    pub bound: f64,
}

/// The camera: intrinsics, the rays of its pixels, its scratch depth buffer and noise stream.
#[derive(Debug, Clone)]
pub struct Camera {
    cfg: CameraConfig,
    f: f64,
    cx: f64,
    cy: f64,
    /// Camera-to-frame rotation, rows.
    rot: [[f64; 3]; 3],
    /// Per pixel: the ray's unit direction in the frame, and its optical-axis component.
    dirs: Box<[[f64; 3]]>,
    cos_axis: Box<[f64]>,
    /// Distance along each pixel's ray of the nearest hit so far.
    zbuf: Box<[f64]>,
    rng: SmallRng,
}

impl Camera {
    pub fn new(cfg: CameraConfig) -> Result<Camera, CameraError> {
        cfg.validate()?;
        let (w, h) = (cfg.width as usize, cfg.height as usize);
        let f = 0.5 * h as f64 / (0.5 * cfg.fov_y_rad).tan();
        let (cx, cy) = (0.5 * w as f64, 0.5 * h as f64);
        let rot = rotation(&cfg.orientation);
        let mut dirs = vec![[0.0; 3]; w * h].into_boxed_slice();
        let mut cos_axis = vec![0.0; w * h].into_boxed_slice();
        for v in 0..h {
            for u in 0..w {
                let d = [(u as f64 + 0.5 - cx) / f, (v as f64 + 0.5 - cy) / f, 1.0];
                let n = (d[0] * d[0] + d[1] * d[1] + 1.0).sqrt();
                let dc = [d[0] / n, d[1] / n, 1.0 / n];
                dirs[v * w + u] = mat_vec(&rot, &dc);
                cos_axis[v * w + u] = dc[2];
            }
        }
        Ok(Camera {
            cfg,
            f,
            cx,
            cy,
            rot,
            dirs,
            cos_axis,
            zbuf: vec![0.0; w * h].into_boxed_slice(),
            rng: SmallRng::seed_from_u64(cfg.seed),
        })
    }

    pub fn config(&self) -> &CameraConfig {
        &self.cfg
    }

    /// Focal length, pixels.
    pub fn focal_px(&self) -> f64 {
        self.f
    }

    /// Principal point (image coordinates of the optical axis; pixel (u, v)'s centre is at
    /// (u + 0.5, v + 0.5)), pixels.
    pub fn principal_point(&self) -> (f64, f64) {
        (self.cx, self.cy)
    }

    /// Camera-to-frame rotation, rows.
    pub fn rotation(&self) -> [[f64; 3]; 3] {
        self.rot
    }

    /// The unit ray of pixel (`u`, `v`) in the frame.
    pub fn ray_dir(&self, u: usize, v: usize) -> [f64; 3] {
        self.dirs[v * self.cfg.width as usize + u]
    }

    /// Renders `targets` (the first [`MAX_INSTANCES`]) and the arm's capsules into `out`.
    /// Allocation-free.
    pub fn render(&mut self, targets: &[Target], arm: &[PosedCapsule], out: &mut DepthFrame) {
        let (w, h) = (self.cfg.width as usize, self.cfg.height as usize);
        let n = w * h;
        out.width = self.cfg.width;
        out.height = self.cfg.height;
        out.n_instances = 0;
        out.instance[..n].fill(BACKGROUND);
        for k in 0..n {
            // Nothing farther than the range along the optical axis returns.
            self.zbuf[k] = self.cfg.range_max_m / self.cos_axis[k];
        }
        for (i, t) in targets.iter().take(MAX_INSTANCES).enumerate() {
            out.ids[i] = t.id;
            out.n_instances = i + 1;
            let pose = Pose::from_parts(
                PVec::new(t.p[0], t.p[1], t.p[2]),
                DQuat::from_xyzw(t.q[1], t.q[2], t.q[3], t.q[0]),
            );
            self.splat(&t.p, t.bound, (i + 1) as u8, &mut out.instance[..n], |ray, max| {
                t.shape.cast_ray(&pose, ray, max, true)
            });
        }
        for c in arm {
            let cap = Capsule::new(PVec::new(c.a[0], c.a[1], c.a[2]), PVec::new(c.b[0], c.b[1], c.b[2]), c.r);
            self.splat(&c.centre, c.bound, ARM, &mut out.instance[..n], |ray, max| {
                cap.cast_ray(&Pose::IDENTITY, ray, max, true)
            });
        }
        let cfg = self.cfg;
        for k in 0..n {
            let range = self.cfg.range_max_m / self.cos_axis[k];
            let z = self.zbuf[k] * self.cos_axis[k];
            if out.instance[k] == BACKGROUND || self.zbuf[k] >= range || z < cfg.range_min_m {
                out.instance[k] = BACKGROUND;
                out.depth_m[k] = 0.0;
                continue;
            }
            let sigma = cfg.noise_base_m + cfg.noise_quad_per_m * z * z;
            let noisy = if sigma > 0.0 { z + sigma * gauss(&mut self.rng) } else { z };
            let dropped = cfg.dropout > 0.0 && self.rng.random::<f64>() < cfg.dropout;
            out.depth_m[k] = if dropped { 0.0 } else { noisy.max(0.0) as f32 };
        }
    }

    /// Casts the rays of the pixels the sphere (`centre`, `bound`) projects to, keeping hits
    /// nearer than the nearest so far.
    fn splat(
        &mut self,
        centre: &[f64; 3],
        bound: f64,
        inst: u8,
        instance: &mut [u8],
        cast: impl Fn(&Ray, f64) -> Option<f64>,
    ) {
        let pos = self.cfg.position_m;
        let rel = [centre[0] - pos[0], centre[1] - pos[1], centre[2] - pos[2]];
        // In camera axes (the rotation's transpose).
        let pc = [
            self.rot[0][0] * rel[0] + self.rot[1][0] * rel[1] + self.rot[2][0] * rel[2],
            self.rot[0][1] * rel[0] + self.rot[1][1] * rel[1] + self.rot[2][1] * rel[2],
            self.rot[0][2] * rel[0] + self.rot[1][2] * rel[1] + self.rot[2][2] * rel[2],
        ];
        if pc[2] + bound <= 0.0 || pc[2] - bound > self.cfg.range_max_m {
            return; // behind the camera, or beyond the range
        }
        let (w, h) = (self.cfg.width as usize, self.cfg.height as usize);
        let (u0, u1) = self.pixel_span(pc[0], pc[2], bound, self.cx, w);
        let (v0, v1) = self.pixel_span(pc[1], pc[2], bound, self.cy, h);
        let r2 = bound * bound;
        let oc = [-rel[0], -rel[1], -rel[2]];
        let c = oc[0] * oc[0] + oc[1] * oc[1] + oc[2] * oc[2] - r2;
        let origin = PVec::new(pos[0], pos[1], pos[2]);
        for v in v0..v1 {
            for u in u0..u1 {
                let k = v * w + u;
                let d = self.dirs[k];
                // Entry into the bounding sphere, before the nearest hit so far?
                let b = oc[0] * d[0] + oc[1] * d[1] + oc[2] * d[2];
                let disc = b * b - c;
                if disc < 0.0 {
                    continue;
                }
                let s = disc.sqrt();
                let (enter, exit) = (-b - s, -b + s);
                if exit < 0.0 || enter >= self.zbuf[k] {
                    continue;
                }
                let ray = Ray::new(origin, PVec::new(d[0], d[1], d[2]));
                if let Some(t) = cast(&ray, self.zbuf[k]) {
                    if t < self.zbuf[k] {
                        self.zbuf[k] = t;
                        instance[k] = inst;
                    }
                }
            }
        }
    }

    /// The pixels (half-open range) whose centres can see a sphere of radius `r` at lateral
    /// offset `x` and depth `z` along one image axis (the exact angular interval of the
    /// sphere's outline; the whole axis when the sphere reaches the camera's plane).
    fn pixel_span(&self, x: f64, z: f64, r: f64, c: f64, n: usize) -> (usize, usize) {
        let d = (x * x + z * z).sqrt();
        if z <= 0.0 || d <= r {
            return (0, n);
        }
        let (a, b) = (x.atan2(z), (r / d).asin());
        let half = std::f64::consts::FRAC_PI_2;
        if a - b <= -half || a + b >= half {
            return (0, n);
        }
        // Pixel i's centre is at image coordinate i + 0.5.
        let lo = self.f * (a - b).tan() + c;
        let hi = self.f * (a + b).tan() + c;
        let i0 = (lo - 0.5).ceil().max(0.0);
        let i1 = (hi - 0.5).floor() + 1.0;
        if i1 <= 0.0 || i0 >= n as f64 {
            return (0, 0);
        }
        (i0 as usize, (i1 as usize).min(n))
    }
}

fn mat_vec(m: &[[f64; 3]; 3], v: &[f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2])
}

/// A standard normal draw (Box–Muller).
fn gauss(rng: &mut SmallRng) -> f64 {
    let u1: f64 = rng.random::<f64>().max(1e-300);
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}
