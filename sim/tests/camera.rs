//! The sim's depth camera: its plant-clock schedule and latency, the rendered message's
//! geometry against the scene it was taken of (debris and the occluding arm, base frame vs
//! LVLH), and no allocation per tick.

use dkrrt_camera::CameraConfig;
use dkrrt_config::Scenario;
use dkrrt_model::{ArmModel, NJ};
use dkrrt_msg::{ContractLimits, DepthImage, Validate, Zeroed, DEPTH_ARM, DEPTH_BACKGROUND};
use dkrrt_sim::camera::{CameraSide, Renderer, Snapshot};
use dkrrt_sim::debris::DebrisSide;
use parry3d_f64::glamx::DQuat;
use parry3d_f64::math::{Pose, Vector as PVec};

#[global_allocator]
static ALLOC: dkrrt_rt::alloc_count::CountingAlloc = dkrrt_rt::alloc_count::CountingAlloc;

const BASE: [f64; 3] = [0.7, -1.3, 0.4];
const Q: [f64; NJ] = [0.3, -0.5, 1.0, 0.0, 0.5, 0.0];

fn scenario(scene: &str, cam: CameraConfig) -> Scenario {
    let mut sc = Scenario::default_scenario();
    sc.debris.scene = scene.into();
    sc.debris.base_lvlh = BASE;
    sc.camera = cam;
    sc
}

/// An exact camera 2.5 m behind the base and 0.6 m up, looking along +x at the arm, with a
/// wide view (noise and dropout off).
fn exact() -> CameraConfig {
    CameraConfig {
        enabled: true,
        position_m: [-2.5, 0.0, 0.6],
        fov_y_rad: 1.6,
        noise_base_m: 0.0,
        noise_quad_per_m: 0.0,
        dropout: 0.0,
        range_max_m: 40.0,
        ..CameraConfig::single()
    }
}

/// Pixel (u, v) at depth `z` (m) of `img`, back-projected into the arm's base frame.
fn back_project(img: &DepthImage, u: usize, v: usize, z: f64) -> [f64; 3] {
    let c = [(u as f64 + 0.5 - img.cx) / img.focal_px * z, (v as f64 + 0.5 - img.cy) / img.focal_px * z, z];
    let [w, x, y, zq] = img.orientation;
    let r = [
        [1.0 - 2.0 * (y * y + zq * zq), 2.0 * (x * y - w * zq), 2.0 * (x * zq + w * y)],
        [2.0 * (x * y + w * zq), 1.0 - 2.0 * (x * x + zq * zq), 2.0 * (y * zq - w * x)],
        [2.0 * (x * zq - w * y), 2.0 * (y * zq + w * x), 1.0 - 2.0 * (x * x + y * y)],
    ];
    std::array::from_fn(|i| img.position_m[i] + r[i][0] * c[0] + r[i][1] * c[1] + r[i][2] * c[2])
}

fn seg_dist(p: &[f64; 3], a: &[f64; 3], b: &[f64; 3]) -> f64 {
    let ab: [f64; 3] = std::array::from_fn(|i| b[i] - a[i]);
    let ap: [f64; 3] = std::array::from_fn(|i| p[i] - a[i]);
    let l2: f64 = ab.iter().map(|x| x * x).sum();
    let s = if l2 > 0.0 {
        (ap.iter().zip(&ab).map(|(x, y)| x * y).sum::<f64>() / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (0..3).map(|i| (p[i] - a[i] - s * ab[i]).powi(2)).sum::<f64>().sqrt()
}

/// Every labelled pixel back-projects onto the surface it is labelled with, in the scene the
/// frame was taken of: debris (LVLH − base) and the arm, which hides what is behind it.
#[test]
fn a_rendered_frame_lies_on_the_scene_it_was_taken_of() {
    let sc = scenario("dense", exact());
    let model = ArmModel::default_arm();
    let mut side = DebrisSide::new(&sc, &model).unwrap();
    let mut renderer = Renderer::new(&sc.camera, BASE).unwrap();
    let mut snap = Snapshot::default();
    let mut img = Box::new(<DepthImage as Zeroed>::zeroed());
    let lim = ContractLimits { debris_range_m: 100.0, ..ContractLimits::symmetric(3.0, 3.0, 100.0) };
    let (mut debris_px, mut arm_px) = (0usize, 0usize);
    for step in 0..4 {
        for _ in 0..250 {
            side.step(1e-3);
        }
        snap.take(&mut side, &Q);
        renderer.render(&snap, &mut img);
        img.validate(&lim).unwrap();
        assert_eq!(img.header.stamp_ns, ((step + 1) as f64 * 0.25 * 1e9).round() as u64);
        assert_eq!(img.n_instances as usize, side.world().debris().len().min(64));
        for (k, id) in img.ids[..img.n_instances as usize].iter().enumerate() {
            assert_eq!(*id, side.world().debris()[k].id, "instance {} names object {id}", k + 1);
        }
        let (w, h) = (img.width as usize, img.height as usize);
        for v in 0..h {
            for u in 0..w {
                let (mm, inst) = (img.depth_mm[v * w + u], img.instance[v * w + u]);
                if inst == DEPTH_BACKGROUND {
                    assert_eq!(mm, 0);
                    continue;
                }
                let pb = back_project(&img, u, v, mm as f64 * 1e-3);
                let pl = PVec::new(pb[0] + BASE[0], pb[1] + BASE[1], pb[2] + BASE[2]);
                let d = if inst == DEPTH_ARM {
                    arm_px += 1;
                    snap.arm
                        .iter()
                        .map(|c| seg_dist(&[pl.x, pl.y, pl.z], &c.a, &c.b) - c.r)
                        .fold(f64::INFINITY, f64::min)
                        .abs()
                } else {
                    debris_px += 1;
                    let (_, shape, p, q, _) = &snap.objects[inst as usize - 1];
                    let pose = Pose::from_parts(
                        PVec::new(p[0], p[1], p[2]),
                        DQuat::from_xyzw(q[1], q[2], q[3], q[0]),
                    );
                    shape.distance_to_point(&pose, pl, false)
                };
                // 0.5 mm of depth quantisation along a ray at most ~2.3× the axis depth.
                assert!(d < 2e-3, "pixel ({u}, {v}) instance {inst}: {d} m off its surface");
            }
        }
    }
    assert!(debris_px > 100 && arm_px > 100, "debris pixels {debris_px}, arm pixels {arm_px}");
}

/// Captures every 1 / rate_hz of plant time, each delivered latency_s later, stamped with its
/// capture time; the inline tick allocates nothing.
#[test]
fn frames_come_on_the_plant_clock_after_the_latency_and_the_tick_allocates_nothing() {
    let cam = CameraConfig { rate_hz: 15.0, latency_s: 0.1, ..exact() };
    let sc = scenario("sparse-slow", cam);
    let mut side = DebrisSide::new(&sc, &ArmModel::default_arm()).unwrap();
    let mut cs = CameraSide::new(&sc.camera).unwrap();
    let mut renderer = Renderer::new(&sc.camera, BASE).unwrap();
    let mut snap = Snapshot::default();
    let mut got: Vec<(u64, f64)> = Vec::with_capacity(64);
    let mut tick = |side: &mut DebrisSide, cs: &mut CameraSide, got: &mut Vec<(u64, f64)>| {
        side.step(1e-3);
        let t = side.world().time();
        cs.tick::<()>(side, &Q, &mut snap, std::slice::from_mut(&mut renderer), |m| {
            got.push((m.header.stamp_ns, t));
            Ok(())
        })
        .unwrap();
    };
    for _ in 0..200 {
        tick(&mut side, &mut cs, &mut got);
    }
    let (_, stats) = dkrrt_rt::alloc_count::count(|| {
        for _ in 0..1800 {
            tick(&mut side, &mut cs, &mut got);
        }
    });
    assert_eq!(stats.allocs, 0, "{stats:?}");
    // Captures at k/15 s for k = 0..=30 (the first at the first tick, 1 ms), on the next
    // tick at or after it; delivered 0.1 s later: those captured by 1.9 s.
    assert_eq!(cs.stats.overrun, 0);
    assert_eq!(cs.stats.captured, 31);
    assert_eq!(got.len() as u64, cs.stats.delivered);
    for (i, &(stamp, at)) in got.iter().enumerate() {
        let capture = (i as f64 / 15.0 * 1e3 - 1e-6).ceil().max(1.0) * 1e-3;
        assert!((stamp as f64 * 1e-9 - capture).abs() < 1e-6, "frame {i}: stamp {stamp}, capture {capture}");
        let due = stamp as f64 * 1e-9 + 0.1;
        assert!(at + 1e-9 >= due && at < due + 1e-3 - 1e-9, "frame {i} delivered at {at}, due {due}");
    }
    assert_eq!(got.len(), 29);
}

/// A bad camera in the scenario is refused naming the field.
#[test]
fn a_bad_camera_is_refused_naming_the_field() {
    let e = CameraSide::new(&CameraConfig { rate_hz: 500.0, ..exact() }).err().unwrap();
    assert!(e.contains("camera.rate_hz"), "{e}");
    let e = Renderer::new(&CameraConfig { width: 0, ..exact() }, BASE).err().unwrap();
    assert!(e.contains("camera.width"), "{e}");
}
