//! Benchmarks: world step, sensor poll (arm–debris distances: the dkrrt-collision bench).

use criterion::{criterion_group, criterion_main, Criterion};
use dkrrt_debris::*;
use std::hint::black_box;
use std::time::Duration;

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("debris");
    for name in ["dense", "tumbling-rods"] {
        let mut w = DebrisWorld::new(&Scene::named(name).unwrap()).unwrap();
        g.bench_function(format!("step_10ms_{name}_{}obj", w.debris().len()), |b| {
            b.iter(|| w.step(black_box(0.01)))
        });
    }
    let mut scene =
        Scene::random(7, 32, &RandomSceneParams { min_range: 0.5, max_range: 4.0, ..Default::default() });
    scene.perturbation.accel_noise_sigma = 1e-4;
    let w = DebrisWorld::new(&scene).unwrap();
    let mut sensor =
        Sensor::new(SensorConfig { rate_hz: 100.0, report_rates: true, ..Default::default() }, 1).unwrap();
    let mut buf = ObsBuffer::new();
    let mut t = 0.0;
    g.bench_function("sensor_poll_100hz_32obj", |b| {
        b.iter(|| {
            t += 0.01;
            buf.clear();
            black_box(sensor.poll(t, w.debris(), &mut buf))
        })
    });
    g.finish();
}

fn config() -> Criterion {
    Criterion::default()
        .measurement_time(Duration::from_secs(3))
        .warm_up_time(Duration::from_secs(1))
        .sample_size(20)
}

criterion_group! { name = benches; config = config(); targets = bench }
criterion_main!(benches);
