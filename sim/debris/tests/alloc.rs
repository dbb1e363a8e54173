//! The hot paths (world step incl. events and noise, sensor poll) never allocate.

use dkrrt_debris::{DebrisWorld, ObsBuffer, Scene, Sensor, SensorConfig};
use dkrrt_rt::alloc_count::{count, CountingAlloc};

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc;

#[test]
fn hot_paths_do_not_allocate() {
    let mut scene = Scene::named("tumbling-rods").unwrap();
    scene.perturbation.accel_noise_sigma = 1e-4;
    scene.perturbation.accel_bias_sigma = 1e-4;
    let mut world = DebrisWorld::new(&scene).unwrap();
    let mut sensor = Sensor::new(SensorConfig { report_rates: true, ..Default::default() }, 1).unwrap();
    let mut buf = ObsBuffer::new();
    let n0 = world.debris().len();
    let (_, stats) = count(|| {
        // 20 s: crosses the impulse (10 s) and the split (15 s) events.
        for _ in 0..1000 {
            world.step(0.02);
            buf.clear();
            sensor.poll(world.time(), world.debris(), &mut buf);
        }
    });
    assert_eq!(world.events_fired(), 2);
    assert_eq!(world.debris().len(), n0 + 1);
    assert_eq!(stats.allocs, 0, "{stats:?}");
    assert_eq!(stats.reallocs, 0, "{stats:?}");
    assert_eq!(stats.deallocs, 0, "{stats:?}");
}
