//! One 128 × 96 frame of 32 objects of every kind in view, and the arm in front of them
//! (target: ≤ 5 ms per frame; the camera runs at 10–30 Hz).

use criterion::{criterion_group, criterion_main, Criterion};
use dkrrt_camera::scene::{arm_ahead, objects_ahead, targets};
use dkrrt_camera::*;
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let objects = objects_ahead(32, 5);
    let targets = targets(&objects);
    let arm = arm_ahead();
    let mut cam = Camera::new(CameraConfig::single()).unwrap();
    let mut frame = DepthFrame::default();
    let mut g = c.benchmark_group("camera");
    g.bench_function("render_128x96_32obj_arm", |b| {
        b.iter(|| cam.render(black_box(&targets), black_box(&arm), &mut frame))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
