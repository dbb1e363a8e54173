//! The depth camera as a view of `dkrrt predict-eval`'s held-out runs (issue #15): the same
//! runs (same scene, same seed, same true motion) seen by a rig of depth cameras through the
//! classical front end (`dkrrt_depthpose::perception`) in place of the pose sensor.
//!
//! The rig: six cameras at the module's origin, one per cube face (the scenes' objects lie
//! all around it), each the scenario default's image and noise with a 90° vertical field of
//! view, capturing at `rate_hz` and delivering `latency_s` later; the arm is not in these runs.
//! An object two faces see in one capture is reported once, from the first face that shows it
//! whole (else its best partial view, one capture later, flagged partial).

use dkrrt_camera::CameraConfig;
use dkrrt_debris::{DebrisWorld, Observation, Scene, SensorConfig};
use dkrrt_depthpose::perception::DepthPerception;
use dkrrt_msg::{
    DebrisObservation, DepthImage, ShapeKind, Zeroed, DEBRIS_AXIS_ONLY, DEBRIS_PARTIAL, DEBRIS_RESTART,
};
use dkrrt_predictor::eval::{record, EvalError, Recording};
use dkrrt_sim::camera::{CaptureClock, Renderer, Snapshot};

/// The six cube-face cameras at the origin, with `base`'s image, range, noise, rate, latency
/// and a 90° vertical field of view ([`CameraConfig::rig`]).
pub fn cube_rig(base: &CameraConfig) -> Vec<CameraConfig> {
    CameraConfig {
        enabled: true,
        faces: 6,
        position_m: [0.0; 3],
        fov_y_rad: std::f64::consts::FRAC_PI_2,
        ..*base
    }
    .rig()
}

fn view_err(detail: impl ToString) -> EvalError {
    EvalError::View { view: "depth".into(), detail: detail.to_string() }
}

/// The run of `scene` (seed `seed`) as [`record`] simulates it, observed by the `cams` rig
/// through the depth front end `front_end()` makes (classical, or with the learned axis
/// model); with the medians of the observations' position error (m)
/// and body z axis error (rods' axes and panels' normals, sign-free; rad).
pub fn record_depth(
    scene: &Scene,
    seed: u64,
    duration: f64,
    sim_dt: f64,
    cams: &[CameraConfig],
    front_end: &dyn Fn() -> DepthPerception,
) -> Result<(Recording, [f64; 2]), EvalError> {
    // The truth (and true shapes, for the containment measure) of the same run.
    let mut rec = record(scene, SensorConfig::default(), duration, sim_dt, seed)?;
    let mut world = DebrisWorld::new(scene)?;
    let mut rdr = renderers(cams).map_err(view_err)?;
    let (rate, latency) = (cams[0].rate_hz, cams[0].latency_s);
    let mut frame = Box::new(<DebrisObservation as Zeroed>::zeroed());
    let mut per = front_end();
    per.set_depth_noise(cams[0].noise_base_m, cams[0].noise_quad_per_m);
    let (mut obs, mut obs_shapes) = (Vec::new(), Vec::new());
    let (mut ep, mut ea) = (Vec::new(), Vec::new());
    // The capture before this one (stamp, time, number): partial views come one capture late.
    let (mut prev, mut this) = ((u64::MAX, 0.0, 0u64), (u64::MAX, 0.0, 0u64));
    each_capture(&mut world, duration, sim_dt, rate, &mut rdr, |capture, t, _, img, _| {
        if img.header.stamp_ns != this.0 {
            (prev, this) = (this, (img.header.stamp_ns, t, capture));
        }
        let n = per.convert(img, &mut frame);
        for it in &frame.items[..n] {
            let partial = it.flags & DEBRIS_PARTIAL != 0;
            let (t, capture) = if it.t_meas_ns == prev.0 { (prev.1, prev.2) } else { (t, capture) };
            obs.push(Observation {
                id: it.id,
                t,
                t_avail: t + latency,
                p: it.p,
                q: it.q,
                v: [0.0; 3],
                w: [0.0; 3],
                has_rates: false,
                partial,
                restart: it.flags & DEBRIS_RESTART != 0,
                axis_only: it.flags & DEBRIS_AXIS_ONLY != 0,
                seq: capture as u32,
            });
            obs_shapes.push((it.shape, it.bounding_radius));
            // The front end's error on the views it saw whole.
            if partial {
                continue;
            }
            if let Some(x) = rec.truth.at(it.id, t) {
                ep.push(
                    ((it.p[0] - x[0]).powi(2) + (it.p[1] - x[1]).powi(2) + (it.p[2] - x[2]).powi(2)).sqrt(),
                );
                if matches!(
                    ShapeKind::from_u32(it.shape.kind),
                    Some(ShapeKind::Capsule | ShapeKind::Box | ShapeKind::Disc)
                ) {
                    let (a, b) = (body_z(&it.q), body_z(&[x[6], x[7], x[8], x[9]]));
                    ea.push((a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).abs().min(1.0).acos());
                }
            }
        }
    });
    rec.obs = obs;
    rec.obs_shapes = obs_shapes;
    let med = |v: &mut Vec<f64>| dkrrt_predictor::eval::median(v);
    Ok((rec, [med(&mut ep), med(&mut ea)]))
}

/// One renderer per camera of `cams`, the base at the LVLH origin.
pub fn renderers(cams: &[CameraConfig]) -> Result<Vec<Renderer>, String> {
    if cams.is_empty() {
        return Err("no camera".into());
    }
    cams.iter().map(|c| Renderer::new(c, [0.0; 3])).collect()
}

/// Steps `world` by `dt` for `duration` and renders it with every renderer at `rate_hz`:
/// `f(capture, t, camera, frame, world)` per camera and capture (captures numbered from 0).
pub fn each_capture(
    world: &mut DebrisWorld,
    duration: f64,
    dt: f64,
    rate_hz: f64,
    renderers: &mut [Renderer],
    mut f: impl FnMut(u64, f64, usize, &DepthImage, &DebrisWorld),
) {
    let mut clock = CaptureClock::new(rate_hz);
    let mut snap = Box::<Snapshot>::default();
    let mut img = Box::new(<DepthImage as Zeroed>::zeroed());
    let mut capture = 0;
    for k in 0..=(duration / dt).round() as usize {
        if k > 0 {
            world.step(dt);
        }
        let t = world.time();
        if !clock.due(t) {
            continue;
        }
        clock.taken(t);
        snap.of_world(world);
        for (c, r) in renderers.iter_mut().enumerate() {
            r.render(&snap, &mut img);
            f(capture, t, c, &img, world);
        }
        capture += 1;
    }
}

fn body_z(q: &[f64; 4]) -> [f64; 3] {
    let [w, x, y, z] = *q;
    [2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y)]
}
