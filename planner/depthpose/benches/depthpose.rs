//! The classical front end per depth frame (a face of the default rig, 128 × 96, with its
//! depth noise) of 32 objects 2–8 m ahead: the extractor alone, without and with the depth
//! noise taken out, and the whole conversion into an observation frame.
//! `cargo bench -p dkrrt-depthpose`.

use criterion::{criterion_group, criterion_main, Criterion};
use dkrrt_camera::scene::objects_ahead;
use dkrrt_camera::CameraConfig;
use dkrrt_depthpose::perception::{intrinsics, DepthPerception};
use dkrrt_depthpose::{Extractor, PoseEstimate};
use dkrrt_msg::{DebrisObservation, DepthImage, Zeroed, DEPTH_MAX_INSTANCES};
use dkrrt_sim::camera::{Renderer, Snapshot};

fn frame(cfg: &CameraConfig) -> Box<DepthImage> {
    let mut snap = Snapshot::default();
    snap.t_s = 1.0;
    for o in objects_ahead(32, 3) {
        let _ = snap.objects.push(o);
    }
    let mut r = Renderer::new(cfg, [0.0; 3]).unwrap();
    let mut img = Box::new(<DepthImage as Zeroed>::zeroed());
    r.render(&snap, &mut img);
    img
}

fn bench(c: &mut Criterion) {
    let cfg = CameraConfig { enabled: true, ..CameraConfig::default() }.rig()[0];
    let mut img = frame(&cfg);
    let cam = intrinsics(&img);
    let n_px = img.width as usize * img.height as usize;
    let mut est = Box::new([PoseEstimate::default(); DEPTH_MAX_INSTANCES]);
    let mut ex = Extractor::default();
    let n = ex.extract_with(&cam, |k| img.depth_mm[k] as f64 * 1e-3, &img.instance[..n_px], &mut est[..]);
    assert!(n >= 10, "{n} objects in view");
    c.bench_function("depthpose/extract_frame_no_noise_model", |b| {
        b.iter(|| {
            ex.extract_with(&cam, |k| img.depth_mm[k] as f64 * 1e-3, &img.instance[..n_px], &mut est[..])
        })
    });
    ex.depth_noise = [cfg.noise_base_m, cfg.noise_quad_per_m];
    c.bench_function("depthpose/extract_frame_noise_taken_out", |b| {
        b.iter(|| {
            ex.extract_with(&cam, |k| img.depth_mm[k] as f64 * 1e-3, &img.instance[..n_px], &mut est[..])
        })
    });
    let mut per = DepthPerception::default();
    per.set_depth_noise(cfg.noise_base_m, cfg.noise_quad_per_m);
    let mut out = Box::new(<DebrisObservation as Zeroed>::zeroed());
    c.bench_function("depthpose/convert_frame", |b| {
        b.iter(|| {
            // A new capture each time (the same one would be a repeat).
            img.header.stamp_ns += 50_000_000;
            per.convert(std::hint::black_box(&img), &mut out)
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
