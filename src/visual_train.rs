//! `dkrrt train --visual`: the learned visual features f_θ (issue #15, Algorithm 1) trained on
//! depth views of simulated runs, and the depth view of `dkrrt predict-eval` that reads the
//! attitudes through them.
//!
//! Data: perturbed runs of every scene ([`perturbed_scene`]) with seeds from
//! [`VISUAL_SEED`] (disjoint from `predict-eval`'s runs, below 1 000 000, and the deep model's,
//! from 1 000 000), seen by the cube rig of [`cube_rig`]. Training runs and validation runs
//! are different runs. Per capture and camera, every instance with at least [`MIN_VIEW_PIXELS`]
//! valid pixels is one view; the views of one object by one camera in consecutive captures
//! form a sequence.

use std::path::Path;

use dkrrt_camera::CameraConfig;
use dkrrt_collision::pose::rotation_matrix;
use dkrrt_debris::DebrisWorld;
use dkrrt_predictor::eval::perturbed_scene;
use dkrrt_visual::train::{Sample, Sequence, VisualTrainConfig};
use dkrrt_visual::{targets, FrameScan, View, MIN_VIEW_PIXELS, N_OBS};

use crate::depth_view::{cube_rig, each_capture};

/// First seed of the visual training runs.
pub const VISUAL_SEED: u64 = 2_000_000;
/// The shipped model file (relative to the repository).
pub const SHIPPED: &str = "models/visual.dkv";

/// How much data to make.
#[derive(Debug, Clone, PartialEq)]
pub struct DataSize {
    pub train_runs: usize,
    pub valid_runs: usize,
    pub duration_s: f64,
}

/// The views of `runs` runs per scene (seeds `seed0 + 10 000 · scene + run`).
pub fn sequences(
    scenes: &[&str],
    runs: std::ops::Range<u64>,
    seed0: u64,
    duration: f64,
    cams: &[CameraConfig],
) -> Result<Vec<Sequence>, String> {
    let mut out = Vec::new();
    // One set of renderers for all runs (their noise streams run on from run to run).
    let mut rdr = crate::depth_view::renderers(cams)?;
    let rate = cams[0].rate_hz;
    let mut scan = Box::<FrameScan>::default();
    let mut view = Box::<View>::default();
    for (si, name) in scenes.iter().enumerate() {
        for r in runs.clone() {
            let seed = seed0 + 10_000 * si as u64 + r;
            let sc = perturbed_scene(name, seed, 1.0).map_err(|e| e.to_string())?;
            let mut world = DebrisWorld::new(&sc).map_err(|e| e.to_string())?;
            // Open sequences: (camera, id) → (last capture, sequence).
            let mut open: Vec<((usize, u32), u64, Sequence)> = Vec::new();
            each_capture(&mut world, duration, 0.01, rate, &mut rdr, |capture, _, c, img, world| {
                scan.scan(img);
                let r_cam = rotation_matrix(&img.orientation);
                for inst in 1..=img.n_instances as u8 {
                    let id = img.ids[inst as usize - 1];
                    let Some(d) = world.debris().iter().find(|d| d.id == id) else { continue };
                    if scan.pixels(inst) < MIN_VIEW_PIXELS || !scan.crop(img, inst, &mut view) {
                        continue;
                    }
                    let qq = d.state.q.quaternion();
                    let r_obj = rotation_matrix(&[qq.w, qq.i, qq.j, qq.k]);
                    let he = d.props.shape.compute_local_aabb().half_extents();
                    let y = targets(&r_cam, &r_obj, &[he.x, he.y, he.z]);
                    let sample =
                        Sample { view: *view, y: std::array::from_fn::<f32, N_OBS, _>(|i| y[i] as f32) };
                    match open.iter_mut().find(|o| o.0 == (c, id)) {
                        Some(o) if o.1 + 1 == capture => {
                            o.1 = capture;
                            o.2.samples.push(sample);
                        }
                        Some(o) => {
                            out.push(std::mem::take(&mut o.2));
                            o.1 = capture;
                            o.2.samples.push(sample);
                        }
                        None => open.push(((c, id), capture, Sequence { samples: vec![sample] })),
                    }
                }
            });
            out.extend(open.into_iter().map(|o| o.2));
        }
    }
    Ok(out)
}

/// Makes the data, trains, prints the validation per horizon, saves the model file.
pub fn train_visual(out: &Path, quick: bool, epochs: Option<usize>) -> Result<(), String> {
    let t0 = std::time::Instant::now();
    let size = if quick {
        DataSize { train_runs: 1, valid_runs: 1, duration_s: 4.0 }
    } else {
        DataSize { train_runs: 6, valid_runs: 1, duration_s: 20.0 }
    };
    let mut cfg = VisualTrainConfig::default();
    if quick {
        cfg.epochs = 2;
        cfg.max_windows = 512;
    }
    if let Some(e) = epochs {
        if e == 0 {
            return Err("--epochs must be >= 1".into());
        }
        cfg.epochs = e;
    }
    crate::train::check_outputs(out, None)?;
    let rig = cube_rig(&dkrrt_config::Scenario::default_scenario().camera);
    let scenes = dkrrt_debris::SCENE_NAMES;
    let tr = size.train_runs as u64;
    let train = sequences(&scenes, 0..tr, VISUAL_SEED, size.duration_s, &rig)?;
    let valid = sequences(&scenes, tr..tr + size.valid_runs as u64, VISUAL_SEED, size.duration_s, &rig)?;
    let views = |s: &[Sequence]| s.iter().map(|q| q.samples.len()).sum::<usize>();
    println!(
        "visual data: {} training views in {} sequences ({} runs per scene), {} validation views ({} other runs per scene), {:.1} s",
        views(&train),
        train.len(),
        size.train_runs,
        views(&valid),
        size.valid_runs,
        t0.elapsed().as_secs_f64()
    );
    let (net, rep) = dkrrt_visual::train::train(&train, &valid, &cfg, &mut crate::train::progress_bar)
        .map_err(|e| e.to_string())?;
    eprintln!();
    println!(
        "trained {} epochs (K re-solved every {}), best epoch {}, {:.1} s; validation loss {:.4} -> {:.4}",
        cfg.epochs,
        cfg.resolve_every,
        rep.best_epoch,
        rep.seconds,
        rep.initial_valid_loss,
        rep.valid_loss.get(rep.best_epoch.max(1) - 1).copied().unwrap_or(rep.initial_valid_loss)
    );
    println!("validation RMSE of the attitude observables per horizon (captures ahead through K):");
    for (k, v) in rep.valid_rmse.iter().enumerate() {
        println!("  {k}: {v:.4}");
    }
    println!(
        "validation axis error now (median, where the view and the truth both show the axis): long {:.3} rad, short {:.3} rad",
        rep.valid_axis_err_rad[0], rep.valid_axis_err_rad[1]
    );
    dkrrt_visual::file::save(out, &net).map_err(|e| format!("write {}: {e}", out.display()))?;
    println!("model: {}", out.display());
    Ok(())
}
