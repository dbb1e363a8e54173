//! Scenes, events and the sensor model (arm–debris distances: the dkrrt-collision tests).

use dkrrt_debris::{
    DebrisWorld, EventSpec, FiredKind, ObsBuffer, RandomSceneParams, Scene, SceneError, Sensor, SensorConfig,
    SCENE_NAMES,
};
use nalgebra::Vector3;

#[test]
fn named_scenes_load_and_run() {
    for name in SCENE_NAMES {
        let s = Scene::named(name).unwrap();
        assert_eq!(s.name, name);
        // The file on disk and the embedded copy agree.
        let disk = Scene::from_file(format!("{}/scenes/{name}.toml", env!("CARGO_MANIFEST_DIR"))).unwrap();
        assert_eq!(disk, s);
        let mut w = DebrisWorld::new(&s).unwrap();
        let n0 = w.debris().len();
        assert!(n0 >= 6);
        for _ in 0..50 {
            w.step(0.02);
        }
        assert!((w.time() - 1.0).abs() < 1e-9);
        for d in w.debris() {
            assert!(d.state.p.iter().all(|v| v.is_finite()) && (d.state.q.norm() - 1.0).abs() < 1e-12);
        }
    }
    assert_eq!(Scene::named("dense").unwrap().debris.len(), 28);
    assert!(matches!(Scene::named("nope"), Err(SceneError::UnknownName(_))));
}

#[test]
fn scene_errors_name_the_field() {
    let base = Scene::named("sparse-slow").unwrap().to_toml();
    let bad_mass = base.replacen("mass = 8.0", "mass = -8.0", 1);
    let e = Scene::from_toml(&bad_mass).unwrap_err().to_string();
    assert!(e.contains("debris[0]") && e.contains("mass"), "{e}");
    let unknown = base.replacen("[orbit]", "[orbit]\naltitude = 3.0", 1);
    let e = Scene::from_toml(&unknown).unwrap_err().to_string();
    assert!(e.contains("altitude"), "{e}");
    let dup = base.replacen("id = 1", "id = 0", 1);
    let e = Scene::from_toml(&dup).unwrap_err().to_string();
    assert!(e.contains("debris[1].id") && e.contains("duplicate"), "{e}");
    let e = Scene::from_toml(&base.replacen("eccentricity = 0.0", "eccentricity = 0.95", 1)).unwrap_err();
    assert!(e.to_string().contains("orbit.eccentricity"), "{e}");
    let missing_p =
        "name = \"x\"\n[[debris]]\nid = 0\nmass = 1.0\nshape = { kind = \"sphere\", radius = 0.1 }\n";
    let e = Scene::from_toml(missing_p).unwrap_err().to_string();
    assert!(e.contains("`p`") || e.contains(" p"), "{e}");
    // A vector of the wrong length is refused, not cut to size (`p = [0, 0, 0, 5]` was read
    // as an object at the LVLH origin), in the shapes too.
    let sphere = |extra: &str| {
        format!("name = \"x\"\n[[debris]]\nid = 0\nmass = 1.0\nshape = {{ kind = \"sphere\", radius = 0.1 }}\n{extra}\n")
    };
    for extra in ["p = [5.0, 0.0, 0.0, 9.0]", "p = [5.0, 0.0, 0.0]\nq = [1.0, 0.0, 0.0, 0.0, 0.0]"] {
        let e = Scene::from_toml(&sphere(extra)).unwrap_err().to_string();
        assert!(e.contains("exactly"), "{extra}: {e}");
    }
    let e = Scene::from_toml(&base.replacen("half_extents = [", "half_extents = [0.1, ", 1)).unwrap_err();
    assert!(e.to_string().contains("exactly"), "{e}");
    // States beyond the message contract's bounds (every observation of them rejected).
    for (extra, field) in [
        ("p = [1e300, 0.0, 0.0]", "debris[0].p"),
        ("p = [5.0, 0.0, 0.0]\nv = [0.0, 150.0, 0.0]", "debris[0].v"),
        ("p = [5.0, 0.0, 0.0]\nw = [0.0, 0.0, 1e300]", "debris[0].w"),
    ] {
        let e = Scene::from_toml(&sphere(extra)).unwrap_err().to_string();
        assert!(e.contains(field) && e.contains("exceeds"), "{extra}: {e}");
    }
    assert!(Scene::from_toml(&sphere("p = [999.0, 0.0, 0.0]\nv = [0.0, 99.0, 0.0]\nw = [49.0, 0.0, 0.0]"))
        .is_ok());
    // A shape beyond the largest size (its volume overflowed: "shape volume ... got 0").
    let e = Scene::from_toml(&sphere("p = [5.0, 0.0, 0.0]").replace("radius = 0.1", "radius = 1e300"))
        .unwrap_err();
    assert!(e.to_string().contains("debris[0].shape.radius") && e.to_string().contains("at most"), "{e}");
}

#[test]
fn scene_toml_round_trip() {
    for name in SCENE_NAMES {
        let s = Scene::named(name).unwrap();
        assert_eq!(Scene::from_toml(&s.to_toml()).unwrap(), s);
    }
}

#[test]
fn random_scene_is_seeded_and_valid() {
    let p = RandomSceneParams::default();
    let a = Scene::random(42, 20, &p);
    let b = Scene::random(42, 20, &p);
    let c = Scene::random(43, 20, &p);
    assert_eq!(a, b);
    assert_ne!(a, c);
    assert_eq!(a.debris.len(), 20);
    a.validate().unwrap();
    for d in &a.debris {
        let r = d.p.iter().map(|x| x * x).sum::<f64>().sqrt();
        assert!(r >= p.min_range - 1e-9 && r <= p.max_range + 1e-9);
        assert!(d.v.iter().map(|x| x * x).sum::<f64>().sqrt() <= p.max_speed + 1e-9);
    }
    assert_eq!(Scene::random(1, 100, &p).debris.len(), dkrrt_debris::MAX_DEBRIS);
    DebrisWorld::new(&a).unwrap();
}

#[test]
fn an_object_stepped_alone_moves_exactly_as_in_the_whole_world() {
    // Tumbling-rods has an impulse (object 2, 10 s) and a split (object 6, 15 s); the
    // perturbations are switched on so the random streams matter.
    let mut s = Scene::named("tumbling-rods").unwrap();
    s.perturbation.accel_noise_sigma = 1e-4;
    s.perturbation.accel_bias_sigma = 1e-5;
    let mut whole = DebrisWorld::new(&s).unwrap();
    let ids: Vec<u32> = whole.debris().iter().map(|d| d.id).collect();
    let mut alone: Vec<DebrisWorld> = ids
        .iter()
        .map(|id| {
            let mut w = DebrisWorld::new(&s).unwrap();
            w.set_only(Some(*id));
            w
        })
        .collect();
    // And stepped alone for its position only (attitudes held, but for the split's parent).
    let mut moving: Vec<DebrisWorld> = alone.clone();
    moving.iter_mut().for_each(|w| w.set_translation_only(true));
    let start = whole.debris().to_vec();
    while whole.time() < 16.0 {
        whole.step(0.01);
        alone.iter_mut().for_each(|w| w.step(0.01));
        moving.iter_mut().for_each(|w| w.step(0.01));
    }
    assert_eq!(whole.events_fired(), 2);
    for ((id, w), m) in ids.iter().zip(&alone).zip(&moving) {
        let (i, j) = (whole.index_of(*id).unwrap(), w.index_of(*id).unwrap());
        assert_eq!(whole.debris()[i].state, w.debris()[j].state, "object {id}");
        let (a, b) = (&whole.debris()[i].state, &m.debris()[m.index_of(*id).unwrap()].state);
        assert_eq!((a.p, a.v), (b.p, b.v), "object {id}, translation only");
        let split = matches!(
            s.events.iter().find(|e| matches!(e, EventSpec::Split { id: x, .. } if x == id)),
            Some(_)
        );
        let b0 = start.iter().find(|d| d.id == *id).unwrap().state.q;
        assert_eq!(b.q, if split { a.q } else { b0 }, "object {id}: attitude stepped only for a split");
        assert_eq!(whole.debris()[i].props.mass, w.debris()[j].props.mass, "object {id}");
        assert_eq!(w.events_fired(), 2);
        // The others stood still (but for what the events did to them).
        let evented = |d: u32| {
            s.events.iter().any(|e| match e {
                EventSpec::Impulse { id, .. } => *id == d,
                EventSpec::Split { id, .. } => *id == d,
            })
        };
        for (d, d0) in w.debris().iter().zip(&start) {
            if d.id != *id && !evented(d.id) {
                assert_eq!(d.state.p, d0.state.p, "object {} moved in {id}'s world", d.id);
            }
        }
    }
}

#[test]
fn impulse_and_split_events_fire_and_conserve_momentum() {
    let s = Scene::named("tumbling-rods").unwrap();
    let mut w = DebrisWorld::new(&s).unwrap();
    let i2 = w.index_of(2).unwrap();
    while w.time() < 9.99 {
        w.step(0.01);
    }
    let v_before = w.debris()[i2].state.v;
    w.step(0.02);
    let dv = w.debris()[i2].state.v - v_before;
    assert!((dv - Vector3::new(0.05, -0.1, 0.0)).norm() < 1e-4, "impulse dv {dv}");
    assert_eq!(w.events_fired(), 1);
    while w.time() < 14.99 {
        w.step(0.01);
    }
    w.step(15.0 - 1e-7 - w.time());
    assert_eq!(w.events_fired(), 1);
    let n = w.debris().len();
    let i6 = w.index_of(6).unwrap();
    let parent = w.debris()[i6].clone();
    let mom0 = parent.state.v * parent.props.mass;
    let com0 = parent.state.p * parent.props.mass;
    let m0 = parent.props.mass;
    // Cross the event time with a 0.2 µs step: dynamics in between are negligible.
    w.step(2e-7);
    assert_eq!(w.debris().len(), n + 1);
    assert_eq!(w.last_fired().unwrap().kind, FiredKind::Split { new_id: 100 });
    let p = &w.debris()[i6];
    let f = &w.debris()[w.index_of(100).unwrap()];
    assert!((p.props.mass + f.props.mass - m0).abs() < 1e-12);
    let mom1 = p.state.v * p.props.mass + f.state.v * f.props.mass;
    let com1 = p.state.p * p.props.mass + f.state.p * f.props.mass;
    // Only 0.2 µs of orbital dynamics separates the two snapshots.
    assert!((mom1 - mom0).norm() < 1e-8, "momentum {mom0} -> {mom1}");
    assert!((com1 - com0).norm() < 1e-6, "com {com0} -> {com1}");
    assert!((f.state.v - p.state.v - Vector3::new(0.1, 0.15, -0.05)).norm() < 1e-6);
    assert!((f.state.p - p.state.p).norm() > 0.85);
}

#[test]
fn rotated_box_distance_uses_attitude() {
    let s = Scene::named("tumbling-rods").unwrap();
    let mut w = DebrisWorld::new(&s).unwrap();
    // Rod 0 (half length 1.0, radius 0.05) aligned with LVLH x, at the origin.
    let d = &mut w.debris_mut()[0];
    d.state.p = Vector3::zeros();
    d.state.q = nalgebra::UnitQuaternion::from_axis_angle(&Vector3::y_axis(), std::f64::consts::FRAC_PI_2);
    let probe = dkrrt_collision::PosedCapsule::new([0.9, 0.5, 0.0], [0.9, 1.0, 0.0], 0.1);
    let d = &w.debris()[0];
    let q = d.state.q.quaternion();
    let o = dkrrt_collision::Obstacle::from_shape(
        d.id,
        &d.props.shape,
        d.props.bounding_radius,
        &[0.0; 3],
        &[q.w, q.i, q.j, q.k],
    );
    // GJK converges to ~1e-8 m on curved shapes.
    assert!((o.distance(&probe) - (0.5 - 0.05 - 0.1)).abs() < 1e-6, "{}", o.distance(&probe));
}

#[test]
fn sensor_rate_latency_noise_and_dropouts() {
    let s = Scene::named("dense").unwrap();
    let mut w = DebrisWorld::new(&s).unwrap();
    let cfg = SensorConfig {
        rate_hz: 50.0,
        pos_sigma: 0.02,
        att_sigma: 0.01,
        report_rates: true,
        dropout_prob: 0.1,
        latency: 0.04,
        latency_jitter: 0.01,
        ..Default::default()
    };
    let mut sensor = Sensor::new(cfg, 9).unwrap();
    let mut buf = ObsBuffer::new();
    let (mut n_obs, mut sq_err, mut max_seq) = (0usize, 0.0, 0u32);
    let dt = 0.005;
    for _ in 0..2000 {
        w.step(dt);
        buf.clear();
        sensor.poll(w.time(), w.debris(), &mut buf);
        for o in buf.as_slice() {
            assert!(o.t_avail - o.t >= 0.04 - 1e-9 && o.t_avail <= w.time() + 1e-9);
            assert!(o.t_avail - o.t <= 0.05 + dt + 1e-9, "latency {}", o.t_avail - o.t);
            assert!(o.has_rates);
            let qn: f64 = o.q.iter().map(|x| x * x).sum();
            assert!((qn - 1.0).abs() < 1e-12 && o.q[0] >= 0.0);
            max_seq = max_seq.max(o.seq);
            n_obs += 1;
            // Truth at measurement time is unknown here; the position error includes motion over
            // the latency, so check noise statistics separately below.
        }
    }
    // 10 s at 50 Hz = 500 samples × 28 objects, 10 % dropped; the last 2–3 samples are still
    // in flight (latency 40–50 ms).
    assert!((497..=499).contains(&(max_seq + 1)), "samples {}", max_seq + 1);
    assert!(sensor.pending() > 0);
    let expected = 500.0 * 28.0 * 0.9;
    assert!(((n_obs as f64) - expected).abs() < 0.03 * expected, "observations {n_obs}");
    let drop_rate = sensor.dropped as f64 / (500.0 * 28.0);
    assert!((drop_rate - 0.1).abs() < 0.015, "dropout rate {drop_rate}");
    // Noise statistics with zero latency: compare to truth at the same instant.
    let mut s2 =
        Sensor::new(SensorConfig { latency: 0.0, latency_jitter: 0.0, dropout_prob: 0.0, ..cfg }, 3).unwrap();
    let mut count = 0;
    for _ in 0..100 {
        w.step(0.02);
        buf.clear();
        s2.poll(w.time(), w.debris(), &mut buf);
        for o in buf.as_slice() {
            let d = &w.debris()[w.index_of(o.id).unwrap()];
            for k in 0..3 {
                sq_err += (o.p[k] - d.state.p[k]).powi(2);
            }
            count += 3;
        }
    }
    let sigma = (sq_err / count as f64).sqrt();
    assert!((sigma - 0.02).abs() < 0.002, "position noise sigma {sigma}");
}

#[test]
fn sensor_config_errors_name_the_field() {
    let e = Sensor::new(SensorConfig { rate_hz: 10.0, ..Default::default() }, 0).unwrap_err();
    assert_eq!(e.field, "rate_hz");
    let e = Sensor::new(SensorConfig { dropout_prob: 1.5, ..Default::default() }, 0).unwrap_err();
    assert_eq!(e.field, "dropout_prob");
    let e = Sensor::new(SensorConfig { latency: 5.0, ..Default::default() }, 0).unwrap_err();
    assert_eq!(e.field, "latency");
}

#[test]
fn objects_beyond_the_sensor_range_are_not_observed() {
    let s = Scene::named("dense").unwrap();
    let mut w = DebrisWorld::new(&s).unwrap();
    let cfg = SensorConfig {
        dropout_prob: 0.0,
        latency: 0.0,
        latency_jitter: 0.0,
        max_range: 1e-3,
        ..Default::default()
    };
    let mut sensor = Sensor::new(cfg, 1).unwrap();
    let mut buf = ObsBuffer::new();
    let mut seen = 0;
    for _ in 0..200 {
        w.step(0.005);
        seen += sensor.poll(w.time(), w.debris(), &mut buf);
    }
    assert_eq!(seen, 0, "everything is out of a 1 mm range");
    assert!(sensor.out_of_range > 0);
    assert!(Sensor::new(SensorConfig { max_range: 0.0, ..Default::default() }, 1).is_err());
}
