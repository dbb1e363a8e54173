//! Renders one depth frame of a named debris scene with the arm in view and writes it as a
//! PNG: `cargo run --release -p dkrrt-camera --example frame -- [SCENE] [T_S] [OUT.png]`
//! (default: dense, 3 s, docs/figures/depth-frame.png). Prints the render time.

use dkrrt_camera::*;
use dkrrt_collision::{ArmPoser, PosedCapsule};
use dkrrt_debris::{DebrisWorld, Scene};
use dkrrt_model::{ArmModel, NJ};

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let scene = args.first().map_or("dense", |s| s.as_str());
    let t: f64 = args.get(1).map_or(Ok(3.0), |s| s.parse().map_err(|e| format!("T_S: {e}")))?;
    let out = args.get(2).map_or("docs/figures/depth-frame.png", |s| s.as_str());
    let mut world =
        DebrisWorld::new(&Scene::named(scene).map_err(|e| e.to_string())?).map_err(|e| e.to_string())?;
    for _ in 0..(t / 0.01).round() as usize {
        world.step(0.01);
    }
    // The arm at its base (LVLH origin), seen from 5 m behind and 1 m above it.
    let poser = ArmPoser::new(ArmModel::default_arm());
    let mut arm = [PosedCapsule::default(); NJ];
    poser.pose(&[0.3, -0.6, 1.1, 0.0, 0.6, 0.0], &mut arm);
    let cfg = CameraConfig { position_m: [-5.0, 0.0, 1.0], ..CameraConfig::single() };
    let mut cam = Camera::new(cfg).map_err(|e| e.to_string())?;
    let targets: Vec<Target> = world
        .debris()
        .iter()
        .map(|d| {
            let q = d.state.q.quaternion();
            Target {
                id: d.id,
                shape: d.props.shape.as_ref(),
                p: [d.state.p.x, d.state.p.y, d.state.p.z],
                q: [q.w, q.i, q.j, q.k],
                bound: d.props.bounding_radius,
            }
        })
        .collect();
    let mut frame = DepthFrame::default();
    cam.render(&targets, &arm, &mut frame);
    let n = 200;
    let t0 = std::time::Instant::now();
    for _ in 0..n {
        cam.render(&targets, &arm, &mut frame);
    }
    let per = t0.elapsed().as_secs_f64() / n as f64;
    let seen = (1..=frame.n_instances as u8).filter(|&k| frame.count(k) > 0).count();
    println!(
        "{scene} at {t} s: {} objects, {seen} in view, arm {} px; render {:.3} ms per frame (mean of {n})",
        targets.len(),
        frame.count(ARM),
        per * 1e3
    );
    let title = format!("Depth camera, {scene} scene at {t} s: 128 x 96, 60 deg, {seen} objects in view");
    dkrrt_figures::depth_frame_png(
        std::path::Path::new(out),
        &title,
        frame.width as usize,
        frame.height as usize,
        &frame.depth_m,
        &frame.instance,
        ARM,
    )?;
    println!("wrote {out}");
    Ok(())
}
