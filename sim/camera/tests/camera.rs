//! The depth camera core: known depths for known shapes, occlusion by the arm, the culling
//! against casting every ray at everything, the sensor model, configuration errors, and an
//! allocation-free render.

use dkrrt_camera::scene::{arm_ahead, objects_ahead, targets};
use dkrrt_camera::*;
use dkrrt_collision::PosedCapsule;
use dkrrt_rt::alloc_count::{count, CountingAlloc};
use parry3d_f64::glamx::DQuat;
use parry3d_f64::math::{Pose, Vector as PVec};
use parry3d_f64::query::{Ray, RayCast};
use parry3d_f64::shape::{Capsule, SharedShape};

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc;

const ID: [f64; 4] = [1.0, 0.0, 0.0, 0.0];

/// The default camera without noise or dropped pixels.
fn exact() -> CameraConfig {
    CameraConfig { noise_base_m: 0.0, noise_quad_per_m: 0.0, dropout: 0.0, ..CameraConfig::single() }
}

fn target<'a>(id: u32, shape: &'a SharedShape, p: [f64; 3], bound: f64) -> Target<'a> {
    Target { id, shape: shape.as_ref(), p, q: ID, bound }
}

#[test]
fn a_sphere_ahead_is_seen_exactly_where_and_as_far_as_its_rays_meet_it() {
    let mut cam = Camera::new(exact()).unwrap();
    let (c, r) = ([3.0, 0.4, -0.3], 0.5);
    let ball = SharedShape::ball(r);
    let mut frame = DepthFrame::default();
    cam.render(&[target(7, &ball, c, r)], &[], &mut frame);
    let mut hits = 0;
    for v in 0..96 {
        for u in 0..128 {
            let d = cam.ray_dir(u, v);
            // |t d − c|² = r² from the origin.
            let b = d[0] * c[0] + d[1] * c[1] + d[2] * c[2];
            let disc = b * b - (c[0] * c[0] + c[1] * c[1] + c[2] * c[2] - r * r);
            let (depth, inst) = frame.at(u, v);
            if disc > 1e-9 {
                let t = b - disc.sqrt();
                // The optical axis is +x: depth is the hit's x.
                assert_eq!(inst, 1, "pixel ({u}, {v})");
                assert!((depth as f64 - t * d[0]).abs() < 1e-5, "{depth} vs {}", t * d[0]);
                hits += 1;
            } else if disc < -1e-9 {
                assert_eq!((depth, inst), (0.0, BACKGROUND), "pixel ({u}, {v})");
            }
        }
    }
    assert!(hits > 300, "{hits}");
    assert_eq!(frame.id_of(1), Some(7));
    assert_eq!(frame.id_of(2), None);
    // Frame z is up in the image, frame y to the left: the ball is up and left of centre.
    let (su, sv) = (0..96)
        .flat_map(|v| (0..128).map(move |u| (u, v)))
        .filter(|&(u, v)| frame.at(u, v).1 == 1)
        .fold((0.0, 0.0), |a, (u, v)| (a.0 + u as f64, a.1 + v as f64));
    assert!(
        su / (hits as f64) < 64.0 && sv / (hits as f64) > 48.0,
        "{} {}",
        su / hits as f64,
        sv / hits as f64
    );
}

#[test]
fn a_box_face_on_returns_the_depth_of_its_face() {
    let mut cam = Camera::new(exact()).unwrap();
    let b = SharedShape::cuboid(0.1, 0.5, 0.5);
    let mut frame = DepthFrame::default();
    cam.render(&[target(3, &b, [4.0, 0.0, 0.0], 0.75)], &[], &mut frame);
    let n = frame.count(1);
    // A 1 m square at 3.9 m: (f / 3.9)² pixels.
    let want = (cam.focal_px() / 3.9).powi(2);
    assert!((n as f64 - want).abs() < 0.1 * want, "{n} vs {want}");
    for k in 0..128 * 96 {
        if frame.instance[k] == 1 {
            assert!((frame.depth_m[k] - 3.9).abs() < 1e-5, "{}", frame.depth_m[k]);
        }
    }
}

#[test]
fn the_arm_occludes_what_lies_behind_it() {
    let mut cam = Camera::new(exact()).unwrap();
    let wall = SharedShape::cuboid(0.1, 3.0, 3.0);
    let rod = [PosedCapsule::new([2.0, -0.6, 0.0], [2.0, 0.6, 0.0], 0.05)];
    let mut frame = DepthFrame::default();
    cam.render(&[target(9, &wall, [5.0, 0.0, 0.0], 4.3)], &rod, &mut frame);
    let (arm, wall_px) = (frame.count(ARM), frame.count(1));
    assert!(arm > 50 && wall_px > 1000, "{arm} {wall_px}");
    for k in 0..128 * 96 {
        match frame.instance[k] {
            ARM => assert!(frame.depth_m[k] >= 1.95 - 1e-5 && frame.depth_m[k] < 2.0, "{}", frame.depth_m[k]),
            1 => assert!((frame.depth_m[k] - 4.9).abs() < 1e-5),
            _ => {}
        }
    }
    // The rod is horizontal through the image's centre row.
    assert_eq!(frame.at(64, 48).1, ARM);
    assert_eq!(frame.at(64, 10).1, 1);
    // Without the arm the wall fills those pixels.
    cam.render(&[target(9, &wall, [5.0, 0.0, 0.0], 4.3)], &[], &mut frame);
    assert_eq!(frame.count(1), arm + wall_px);
}

#[test]
fn culling_misses_nothing_that_casting_every_ray_at_everything_finds() {
    let objects = objects_ahead(32, 11);
    let targets = targets(&objects);
    let arm = arm_ahead();
    let mut cam = Camera::new(exact()).unwrap();
    let mut frame = DepthFrame::default();
    cam.render(&targets, &arm, &mut frame);
    let mut seen = [0usize; 256];
    for v in 0..96 {
        for u in 0..128 {
            let d = cam.ray_dir(u, v);
            let ray = Ray::new(PVec::ZERO, PVec::new(d[0], d[1], d[2]));
            let mut best = (15.0 / d[0], BACKGROUND);
            for (i, (_, s, p, q, _)) in objects.iter().enumerate() {
                let pose =
                    Pose::from_parts(PVec::new(p[0], p[1], p[2]), DQuat::from_xyzw(q[1], q[2], q[3], q[0]));
                if let Some(t) = s.cast_ray(&pose, &ray, f64::MAX, true) {
                    if t < best.0 {
                        best = (t, (i + 1) as u8);
                    }
                }
            }
            for c in &arm {
                let cap =
                    Capsule::new(PVec::new(c.a[0], c.a[1], c.a[2]), PVec::new(c.b[0], c.b[1], c.b[2]), c.r);
                if let Some(t) = cap.cast_ray(&Pose::IDENTITY, &ray, f64::MAX, true) {
                    if t < best.0 {
                        best = (t, ARM);
                    }
                }
            }
            let (depth, inst) = frame.at(u, v);
            assert_eq!(inst, best.1, "pixel ({u}, {v})");
            if inst != BACKGROUND {
                assert!((depth as f64 - best.0 * d[0]).abs() < 1e-5);
            }
            seen[inst as usize] += 1;
        }
    }
    let objects_seen = seen[1..=32].iter().filter(|&&n| n > 0).count();
    assert!(
        seen[ARM as usize] > 100 && objects_seen >= 20,
        "arm {} objects {objects_seen}",
        seen[ARM as usize]
    );
}

#[test]
fn range_noise_and_dropped_pixels_follow_the_configuration() {
    let wall = SharedShape::cuboid(0.01, 20.0, 20.0);
    let mut frame = DepthFrame::default();
    // Beyond the range: nothing returns.
    let mut cam = Camera::new(exact()).unwrap();
    cam.render(&[target(1, &wall, [15.5, 0.0, 0.0], 30.0)], &[], &mut frame);
    assert_eq!(frame.count(BACKGROUND), 128 * 96);
    // Nearer than the range: nothing either.
    cam.render(&[target(1, &wall, [0.1, 0.0, 0.0], 30.0)], &[], &mut frame);
    assert_eq!(frame.count(BACKGROUND), 128 * 96);
    // At 2 m: σ = 1 cm + 2.5 mm/m² · 4 m² = 2 cm, 10 % dropped.
    let cfg =
        CameraConfig { noise_base_m: 0.01, noise_quad_per_m: 0.0025, dropout: 0.1, ..CameraConfig::single() };
    let mut cam = Camera::new(cfg).unwrap();
    cam.render(&[target(1, &wall, [2.01, 0.0, 0.0], 30.0)], &[], &mut frame);
    assert_eq!(frame.count(1), 128 * 96, "the wall fills the image; dropped pixels keep their instance");
    let valid: Vec<f64> = frame.depth_m.iter().filter(|&&d| d > 0.0).map(|&d| d as f64).collect();
    let dropped = 1.0 - valid.len() as f64 / (128.0 * 96.0);
    assert!((dropped - 0.1).abs() < 0.015, "{dropped}");
    let mean = valid.iter().sum::<f64>() / valid.len() as f64;
    let sd = (valid.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / valid.len() as f64).sqrt();
    assert!((mean - 2.0).abs() < 1e-3 && (sd - 0.02).abs() < 0.002, "mean {mean} sd {sd}");
    // Seeded: the same frame again from a new camera.
    let mut again = DepthFrame::default();
    Camera::new(cfg).unwrap().render(&[target(1, &wall, [2.01, 0.0, 0.0], 30.0)], &[], &mut again);
    assert_eq!(frame, again);
}

#[test]
fn the_camera_sees_along_its_orientation_from_its_position() {
    let ball = SharedShape::ball(0.3);
    let mut frame = DepthFrame::default();
    // Default: along +x; a ball on +y is not seen.
    let mut cam = Camera::new(exact()).unwrap();
    cam.render(&[target(1, &ball, [0.0, 3.0, 0.0], 0.3)], &[], &mut frame);
    assert_eq!(frame.count(1), 0);
    // Turned 90° about z (looking along +y) and moved 1 m back along −y: at the centre, 3.7 m.
    let (s, c) = (std::f64::consts::FRAC_PI_4.sin(), std::f64::consts::FRAC_PI_4.cos());
    let turn = [c, 0.0, 0.0, s]; // 90° about z
    let l = LOOK_ALONG_X;
    let q = [
        turn[0] * l[0] - turn[3] * l[3],
        turn[0] * l[1] - turn[3] * l[2],
        turn[0] * l[2] + turn[3] * l[1],
        turn[0] * l[3] + turn[3] * l[0],
    ];
    let cfg = CameraConfig { orientation: q, position_m: [0.0, -1.0, 0.0], ..exact() };
    let mut cam = Camera::new(cfg).unwrap();
    cam.render(&[target(1, &ball, [0.0, 3.0, 0.0], 0.3)], &[], &mut frame);
    let (d, i) = frame.at(64, 48);
    assert_eq!(i, 1);
    assert!((d - 3.7).abs() < 0.01, "{d}");
}

#[test]
fn a_bad_configuration_is_refused_naming_the_field() {
    let bad = |c: CameraConfig| Camera::new(c).unwrap_err().to_string();
    let d = CameraConfig::single();
    assert!(bad(CameraConfig { width: 0, ..d }).starts_with("camera.width"));
    assert!(bad(CameraConfig { height: 97, ..d }).starts_with("camera.height"));
    assert!(bad(CameraConfig { fov_y_rad: f64::NAN, ..d }).starts_with("camera.fov_y_rad"));
    assert!(bad(CameraConfig { orientation: [1.0, 1.0, 0.0, 0.0], ..d }).starts_with("camera.orientation"));
    assert!(
        bad(CameraConfig { position_m: [0.0, f64::INFINITY, 0.0], ..d }).starts_with("camera.position_m[1]")
    );
    assert!(bad(CameraConfig { range_max_m: 0.1, ..d }).starts_with("camera.range_max_m"));
    assert!(bad(CameraConfig { noise_base_m: -1.0, ..d }).starts_with("camera.noise_base_m"));
    assert!(bad(CameraConfig { noise_base_m: 1e300, ..d }).starts_with("camera.noise_base_m"));
    assert!(bad(CameraConfig { noise_quad_per_m: 2.0, ..d }).starts_with("camera.noise_quad_per_m"));
    assert!(bad(CameraConfig { dropout: 1.5, ..d }).starts_with("camera.dropout"));
    assert!(bad(CameraConfig { rate_hz: 0.0, ..d }).starts_with("camera.rate_hz"));
    assert!(bad(CameraConfig { latency_s: -0.1, ..d }).starts_with("camera.latency_s"));
    assert!(bad(CameraConfig { range_max_m: 70.0, ..d }).starts_with("camera.range_max_m"));
    assert!(Camera::new(d).is_ok());
}

#[test]
fn rendering_allocates_nothing() {
    let objects = objects_ahead(32, 3);
    let targets = targets(&objects);
    let arm = arm_ahead();
    let mut cam = Camera::new(CameraConfig::single()).unwrap();
    let mut frame = DepthFrame::default();
    cam.render(&targets, &arm, &mut frame);
    let (_, s) = count(|| {
        for _ in 0..5 {
            cam.render(&targets, &arm, &mut frame);
        }
    });
    assert_eq!((s.allocs, s.reallocs), (0, 0), "{s:?}");
    assert!(frame.count(ARM) > 0 && frame.count(BACKGROUND) < 128 * 96);
}

/// A cube rig: six cameras at one point whose optical axes are ±x, ±y, ±z, every one a
/// proper rotation; together they see a ball in every direction.
#[test]
fn a_cube_rig_looks_along_every_axis() {
    let base = CameraConfig { faces: 6, fov_y_rad: std::f64::consts::FRAC_PI_2, ..exact() };
    base.validate().unwrap();
    let rig = base.rig();
    assert_eq!(rig.len(), 6);
    let mut axes = Vec::new();
    for c in &rig {
        let cam = Camera::new(*c).unwrap();
        let r = cam.rotation();
        let z = [r[0][2], r[1][2], r[2][2]];
        axes.push(z.map(|v| v.round() as i32));
        // Proper rotation: columns orthonormal, determinant +1.
        let det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
            - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
            + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
        assert!((det - 1.0).abs() < 1e-9);
    }
    axes.sort();
    assert_eq!(axes, vec![[-1, 0, 0], [0, -1, 0], [0, 0, -1], [0, 0, 1], [0, 1, 0], [1, 0, 0]]);
    let ball = SharedShape::ball(0.3);
    for dir in [[4.0, 0.0, 0.0], [0.0, -4.0, 0.0], [0.0, 0.0, 4.0], [-2.5, 2.5, 1.0]] {
        let t = [Target { id: 1, shape: ball.as_ref(), p: dir, q: [1.0, 0.0, 0.0, 0.0], bound: 0.3 }];
        let seen: usize = rig
            .iter()
            .map(|c| {
                let mut f = DepthFrame::default();
                Camera::new(*c).unwrap().render(&t, &[], &mut f);
                f.count(1)
            })
            .sum();
        assert!(seen > 20, "a ball at {dir:?}: {seen} pixels");
    }
    assert!(CameraConfig { faces: 2, ..exact() }
        .validate()
        .unwrap_err()
        .to_string()
        .starts_with("camera.faces"));
    // A rig whose faces leave gaps between them is refused: 60° vertically, or 90°
    // vertically on an image narrower than it is tall.
    let gap = |c: CameraConfig| c.validate().unwrap_err().to_string();
    assert!(gap(CameraConfig { fov_y_rad: 60f64.to_radians(), ..base }).contains("gaps"));
    assert!(gap(CameraConfig { width: 64, ..base }).contains("gaps"));
    // The default is such a rig, and valid.
    let d = CameraConfig::default();
    assert_eq!((d.faces, d.fov_y_rad), (6, std::f64::consts::FRAC_PI_2));
    d.validate().unwrap();
    assert_eq!(d.rig().len(), 6);
}
