//! The pose-from-depth baseline on frames of known poses rendered by the depth camera.

use dkrrt_camera::{Camera, CameraConfig, DepthFrame, Target};
use dkrrt_depthpose::*;
use dkrrt_rt::alloc_count::{count, CountingAlloc};
use parry3d_f64::shape::SharedShape;

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc;

fn intrinsics(cam: &Camera) -> Intrinsics {
    let c = cam.config();
    let (cx, cy) = cam.principal_point();
    Intrinsics {
        width: c.width as usize,
        height: c.height as usize,
        f: cam.focal_px(),
        cx,
        cy,
        position: c.position_m,
        rotation: cam.rotation(),
    }
}

/// The unit quaternion (w, x, y, z) turning local z onto `to`.
fn z_onto(to: [f64; 3]) -> [f64; 4] {
    let n = (to[0] * to[0] + to[1] * to[1] + to[2] * to[2]).sqrt();
    let t = [to[0] / n, to[1] / n, to[2] / n];
    // Half-way vector between z and t.
    let h = [t[0], t[1], t[2] + 1.0];
    let hn = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
    let h = [h[0] / hn, h[1] / hn, h[2] / hn];
    // q = (z·h, z × h)
    [h[2], -h[1], h[0], 0.0]
}

fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn unit(a: [f64; 3]) -> [f64; 3] {
    let n = dot(&a, &a).sqrt();
    [a[0] / n, a[1] / n, a[2] / n]
}

fn exact() -> CameraConfig {
    CameraConfig { noise_base_m: 0.0, noise_quad_per_m: 0.0, dropout: 0.0, ..CameraConfig::single() }
}

fn estimate(cfg: CameraConfig, targets: &[Target]) -> Vec<PoseEstimate> {
    let mut cam = Camera::new(cfg).unwrap();
    let mut frame = DepthFrame::default();
    cam.render(targets, &[], &mut frame);
    let mut out = [PoseEstimate::default(); 8];
    let n = Extractor::default().extract(&intrinsics(&cam), &frame.depth_m, &frame.instance, &mut out);
    out[..n].to_vec()
}

#[test]
fn a_rod_a_panel_and_a_ball_are_recovered() {
    let rod = SharedShape::capsule_z(0.6, 0.03);
    let panel = SharedShape::cuboid(0.4, 0.3, 0.01);
    let ball = SharedShape::ball(0.4);
    let rod_axis = unit([0.3, 1.0, 0.8]);
    let normal = unit([-1.0, 0.4, 0.3]); // facing the camera, 27° off its axis
    let (pr, pp, pb) = ([4.0, 0.6, -0.3], [5.0, -1.2, 0.5], [3.0, 0.0, -1.0]);
    for cfg in [exact(), CameraConfig::single()] {
        let t = [
            Target { id: 1, shape: rod.as_ref(), p: pr, q: z_onto(rod_axis), bound: 0.63 },
            Target { id: 2, shape: panel.as_ref(), p: pp, q: z_onto(normal), bound: 0.51 },
            Target { id: 3, shape: ball.as_ref(), p: pb, q: [1.0, 0.0, 0.0, 0.0], bound: 0.4 },
        ];
        let e = estimate(cfg, &t);
        assert_eq!(e.iter().map(|x| x.instance).collect::<Vec<_>>(), [1, 2, 3]);
        // Rod: its axis is the first principal axis; the centroid is within its radius of
        // the axis (the visible half of its surface).
        let cos = dot(&e[0].axes[0], &rod_axis).abs();
        assert!(cos > 3f64.to_radians().cos(), "rod axis off by {:.2}°", cos.acos().to_degrees());
        let d = [e[0].centroid[0] - pr[0], e[0].centroid[1] - pr[1], e[0].centroid[2] - pr[2]];
        let along = dot(&d, &rod_axis);
        let off = (dot(&d, &d) - along * along).sqrt();
        assert!(along.abs() < 0.05 && off < 0.04, "rod centroid along {along} off {off}");
        // Rod length: a uniform 1.2 m segment spreads 1.2 / √12 = 0.35 m.
        assert!((e[0].spread[0] - 1.2 / 12f64.sqrt()).abs() < 0.03, "{}", e[0].spread[0]);
        // Panel: its normal is the last axis; the centroid lies on its face.
        let cos = dot(&e[1].axes[2], &normal).abs();
        assert!(cos > 3f64.to_radians().cos(), "panel normal off by {:.2}°", cos.acos().to_degrees());
        let d = [e[1].centroid[0] - pp[0], e[1].centroid[1] - pp[1], e[1].centroid[2] - pp[2]];
        assert!(dot(&d, &d).sqrt() < 0.03, "panel centroid off by {}", dot(&d, &d).sqrt());
        // Ball: the visible cap's centroid lies between the centre and the camera, about two
        // thirds of the radius out (pixels sample the surface evenly over its image disc,
        // where the surface stands sqrt(r² − ρ²) out: 2r/3 on average).
        let d = [e[2].centroid[0] - pb[0], e[2].centroid[1] - pb[1], e[2].centroid[2] - pb[2]];
        let to_cam = unit([-pb[0], -pb[1], -pb[2]]);
        let out = dot(&d, &to_cam);
        let side = (dot(&d, &d) - out * out).max(0.0).sqrt();
        assert!((out - 0.8 / 3.0).abs() < 0.03 && side < 0.03, "ball centroid out {out} side {side}");
    }
}

#[test]
fn small_instances_are_left_out_and_extraction_allocates_nothing() {
    let speck = SharedShape::ball(0.01);
    let ball = SharedShape::ball(0.3);
    let t = [
        Target { id: 1, shape: speck.as_ref(), p: [8.0, 0.0, 0.0], q: [1.0, 0.0, 0.0, 0.0], bound: 0.01 },
        Target { id: 2, shape: ball.as_ref(), p: [3.0, 0.5, 0.0], q: [1.0, 0.0, 0.0, 0.0], bound: 0.3 },
    ];
    let e = estimate(exact(), &t);
    assert_eq!(e.len(), 1);
    assert_eq!(e[0].instance, 2);
    let mut cam = Camera::new(CameraConfig::single()).unwrap();
    let mut frame = DepthFrame::default();
    cam.render(&t, &[], &mut frame);
    let mut ex = Extractor::default();
    let mut out = [e[0]; 4];
    let cam_i = intrinsics(&cam);
    let (n, s) = count(|| ex.extract(&cam_i, &frame.depth_m, &frame.instance, &mut out));
    assert_eq!(n, 1);
    assert_eq!((s.allocs, s.reallocs), (0, 0), "{s:?}");
}

/// Valid pixels on the image border count as `cut`; pixels beside a nearer pixel of another
/// instance or of the arm (by more than `OCCLUSION_STEP`) as `occluded`.
#[test]
fn cut_and_occluded_pixels_are_counted() {
    let (w, h) = (10, 8);
    let mut depth = vec![0.0f32; w * h];
    let mut inst = vec![0u8; w * h];
    let mut put = |u: usize, v: usize, z: f32, i: u8| {
        depth[v * w + u] = z;
        inst[v * w + u] = i;
    };
    // Instance 1 in the middle at 5 m; instance 3 beside it at 4 m (nearer) and instance 4
    // beside it at 4.98 m (touching: not nearer by the step); the arm below it at 2 m.
    for v in 3..5 {
        for u in 4..7 {
            put(u, v, 5.0, 1);
        }
        put(7, v, 4.0, 3);
        put(3, v, 4.98, 4);
    }
    put(4, 5, 2.0, 255);
    // Instance 2 in the top left corner at 3 m.
    for v in 0..2 {
        for u in 0..2 {
            put(u, v, 3.0, 2);
        }
    }
    let cam = Intrinsics {
        width: w,
        height: h,
        f: 10.0,
        cx: 5.0,
        cy: 4.0,
        position: [0.0; 3],
        rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
    };
    let mut ex = Extractor::default();
    ex.min_points = 1;
    let mut out = [PoseEstimate::default(); 8];
    let n = ex.extract(&cam, &depth, &inst, &mut out);
    let got: Vec<_> = out[..n].iter().map(|e| (e.instance, e.points, e.cut, e.occluded)).collect();
    // 1: the two pixels beside instance 3 and the one above the arm; 2: three of its four
    // pixels on the border; 3 and 4 are in front of (or level with) their neighbours.
    assert_eq!(got, [(1, 6, 0, 3), (2, 4, 3, 0), (3, 2, 0, 0), (4, 2, 0, 0)]);
}
