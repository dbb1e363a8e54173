//! One 128 × 96 frame of 32 objects of every kind in view, and the arm in front of them
//! (target: ≤ 5 ms per frame; the camera runs at 10–30 Hz).

use criterion::{criterion_group, criterion_main, Criterion};
use dkrrt_camera::scene::objects_ahead;
use dkrrt_camera::*;
use dkrrt_collision::{ArmPoser, PosedCapsule};
use dkrrt_model::{ArmModel, NJ};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let objects = objects_ahead(32, 5);
    let targets: Vec<Target> = objects
        .iter()
        .map(|(id, s, p, q, b)| Target { id: *id, shape: s.as_ref(), p: *p, q: *q, bound: *b })
        .collect();
    let poser = ArmPoser::with_offset(ArmModel::default_arm(), [2.0, 0.0, -0.8]);
    let mut arm = [PosedCapsule::default(); NJ];
    poser.pose(&[0.3, -0.5, 1.0, 0.0, 0.5, 0.0], &mut arm);
    let mut cam = Camera::new(CameraConfig::default()).unwrap();
    let mut frame = DepthFrame::default();
    let mut g = c.benchmark_group("camera");
    g.bench_function("render_128x96_32obj_arm", |b| {
        b.iter(|| cam.render(black_box(&targets), black_box(&arm), &mut frame))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
