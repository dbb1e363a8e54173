//! f_θ's inference per object view (the shipped model): the crop of one instance from a
//! 128 × 96 frame, and the network on it. `cargo bench -p dkrrt-visual`.

use criterion::{criterion_group, criterion_main, Criterion};
use dkrrt_msg::{DepthImage, Zeroed};
use dkrrt_visual::{FrameScan, View, N_OUT};

fn frame() -> Box<DepthImage> {
    let mut img = Box::new(<DepthImage as Zeroed>::zeroed());
    (img.width, img.height, img.focal_px, img.cx, img.cy) = (128, 96, 110.0, 64.0, 48.0);
    img.orientation = [1.0, 0.0, 0.0, 0.0];
    (img.range_min_m, img.range_max_m, img.n_instances) = (0.1, 20.0, 1);
    for v in 30..60 {
        for u in 40..90 {
            let k = v * 128 + u;
            img.instance[k] = 1;
            img.depth_mm[k] = (4000 + 7 * u + 3 * v) as u16;
        }
    }
    img
}

fn bench(c: &mut Criterion) {
    let mut net = dkrrt_visual::file::from_bytes(include_bytes!("../../../models/visual.dkv")).unwrap();
    let img = frame();
    let mut scan = Box::<FrameScan>::default();
    let mut view = View::default();
    c.bench_function("visual/scan_frame_128x96", |b| b.iter(|| scan.scan(std::hint::black_box(&img))));
    scan.scan(&img);
    c.bench_function("visual/crop_one_object", |b| b.iter(|| scan.crop(&img, 1, &mut view)));
    let prev = view;
    let mut out = [0.0; N_OUT];
    c.bench_function("visual/f_theta_forward_one_object", |b| {
        b.iter(|| net.forward(std::hint::black_box(&view), &prev, &mut out))
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
