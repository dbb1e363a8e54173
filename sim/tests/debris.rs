//! The simulator's debris side without IPC: contact checks against the arm's link
//! capsules, observation frames (base frame, plant clock), no allocation per tick.

use dkrrt_config::Scenario;
use dkrrt_model::{ArmModel, JVec};
use dkrrt_msg::{ContractLimits, DebrisObservation, Validate, Zeroed};
use dkrrt_sim::debris::DebrisSide;

fn q0(sc: &Scenario) -> JVec {
    JVec::from_column_slice(&sc.sim.initial_q)
}

/// A scene file with one sphere of `radius` at LVLH position `p`, at rest.
fn sphere_scene(tag: &str, p: [f64; 3], radius: f64) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("dkrrt-debris-test-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("scene.toml");
    let text = format!(
        "name = \"{tag}\"\n[[debris]]\nid = 42\nshape = {{ kind = \"sphere\", radius = {radius} }}\nmass = 5.0\n\
         p = [{}, {}, {}]\nv = [0.0, 0.0, 0.0]\nw = [0.0, 0.0, 0.0]\n",
        p[0], p[1], p[2]
    );
    std::fs::write(&path, text).unwrap();
    path
}

/// Midpoint of link `i`'s capsule at the scenario's initial pose, LVLH (base at `base`).
fn link_mid(sc: &Scenario, model: &ArmModel, i: usize) -> ([f64; 3], [f64; 3]) {
    let poses = model.link_poses(&q0(sc));
    let c = &model.collision_capsules()[i];
    let (a, b) = c.world_segment(&poses[c.link]);
    let m = (a.coords + b.coords) * 0.5;
    let d = (b.coords - a.coords).normalize();
    let o = sc.debris.base_lvlh;
    ([m.x + o[0], m.y + o[1], m.z + o[2]], [d.x, d.y, d.z])
}

#[test]
fn a_debris_object_on_a_link_is_a_collision_and_a_distant_one_is_not() {
    let model = ArmModel::default_arm();
    let mut sc = Scenario::default_scenario();
    sc.debris.base_lvlh = [0.5, -1.0, 2.0];
    let (mid, _) = link_mid(&sc, &model, 2);
    let path = sphere_scene("hit", mid, 0.2);
    sc.debris.scene = path.display().to_string();
    let mut side = DebrisSide::new(&sc, &dkrrt_model::ArmModel::default_arm()).unwrap();
    assert!(side.check(&q0(&sc).into()), "sphere on link 2 must touch it");
    let c = side.stats.first_contact.expect("first contact recorded");
    assert_eq!(c.debris_id, 42);
    assert_eq!(c.distance_m, 0.0);
    assert!(side.stats.collided());
    assert_eq!(side.stats.contact_ticks, 1);

    // Same sphere 3 m along the radial axis beyond the whole arm: no contact, and the
    // reported closest distance is below the centre distance and positive.
    let far = [mid[0] + 10.0, mid[1], mid[2]];
    let miss = sphere_scene("miss", far, 0.2);
    sc.debris.scene = miss.display().to_string();
    let mut side = DebrisSide::new(&sc, &dkrrt_model::ArmModel::default_arm()).unwrap();
    assert!(!side.check(&q0(&sc).into()));
    let d = side.stats.min_distance_m.unwrap();
    assert!(d > 5.0 && d < 10.0, "min distance {d}");
    assert!(side.stats.first_contact.is_none());
    // A margin larger than the gap turns it into a contact.
    sc.debris.contact_margin_m = d + 0.01;
    let mut side = DebrisSide::new(&sc, &dkrrt_model::ArmModel::default_arm()).unwrap();
    assert!(side.check(&q0(&sc).into()));
    let _ = std::fs::remove_dir_all(path.parent().unwrap());
    let _ = std::fs::remove_dir_all(miss.parent().unwrap());
}

/// A sample that sees nothing (every object beyond the sensor's range) is still delivered, as
/// an empty frame after the latency: "looked, saw nothing" is said, so an empty sky can be told
/// from a silent sensor. A sample that saw something sends its items, never an empty frame too.
#[test]
fn a_sample_that_sees_nothing_is_an_empty_frame() {
    let mut sc = Scenario::default_scenario();
    sc.debris.latency_s = 0.03;
    sc.debris.latency_jitter_s = 0.0;
    sc.debris.dropout = 0.0;
    // Beyond the sensor's range (500 m; within the scene's 1000 m bound: nothing seen), then
    // near (seen).
    for (tag, p, seen) in [("empty-far", [800.0, 0.0, 0.0], false), ("empty-near", [3.0, 2.0, 0.0], true)] {
        sc.debris.scene = sphere_scene(tag, p, 0.2).display().to_string();
        let mut side = DebrisSide::new(&sc, &ArmModel::default_arm()).unwrap();
        let mut frame = <DebrisObservation as Zeroed>::zeroed();
        let mut frames: Vec<(u64, u32)> = Vec::new();
        for _ in 0..200u64 {
            side.step(1e-3);
            side.drain_observations::<()>(&mut frame, |f| {
                frames.push((f.header.stamp_ns, f.count));
                Ok(())
            })
            .unwrap();
        }
        // Samples at 0, 20, ..., 180 ms, each delivered 30 ms later: 9 by 200 ms.
        let stamps: Vec<u64> = frames.iter().map(|f| f.0).collect();
        let want: Vec<u64> = (0..9).map(|k| 30_000_000 + k * 20_000_000).collect();
        assert_eq!(stamps, want, "{tag}");
        assert!(frames.iter().all(|f| f.1 == seen as u32), "{tag}: {frames:?}");
        assert_eq!(side.stats.observation_frames, 9, "{tag}");
    }
}

#[test]
fn observations_are_base_frame_poses_on_the_plant_clock() {
    let mut sc = Scenario::default_scenario();
    sc.debris.scene = "tumbling-rods".into();
    sc.debris.base_lvlh = [1.0, 2.0, 3.0];
    sc.debris.pos_sigma_m = 0.0;
    sc.debris.att_sigma_rad = 0.0;
    sc.debris.dropout = 0.0;
    sc.debris.latency_s = 0.03;
    sc.debris.latency_jitter_s = 0.0;
    let mut side = DebrisSide::new(&sc, &dkrrt_model::ArmModel::default_arm()).unwrap();
    let n = side.world().debris().len();
    let lim = ContractLimits::symmetric(1.0, 1.0, 1.0);
    let mut frame = <DebrisObservation as Zeroed>::zeroed();
    let mut frames: Vec<DebrisObservation> = Vec::new();
    // Truth of every sample instant (t = 0, 20, 40 ms ...) to compare against.
    let mut truth: Vec<(u64, Vec<(u32, [f64; 3], [f64; 4])>)> = Vec::new();
    let snap = |side: &DebrisSide| -> Vec<(u32, [f64; 3], [f64; 4])> {
        side.world()
            .debris()
            .iter()
            .map(|d| {
                let q = d.state.q.quaternion();
                let mut qq = [q.w, q.i, q.j, q.k];
                if qq[0] < 0.0 {
                    qq.iter_mut().for_each(|x| *x = -*x);
                }
                (d.id, [d.state.p.x, d.state.p.y, d.state.p.z], qq)
            })
            .collect()
    };
    for tick in 1..=200u64 {
        side.step(1e-3);
        if tick % 20 == 0 {
            truth.push((tick * 1_000_000, snap(&side)));
        }
        side.drain_observations::<()>(&mut frame, |f| {
            frames.push(*f);
            Ok(())
        })
        .unwrap();
    }
    assert!(frames.len() >= 7, "{} frames in 0.2 s at 50 Hz with 30 ms latency", frames.len());
    for f in &frames {
        assert!(f.validate(&lim).is_ok());
        assert_eq!(f.count as usize, n, "one frame per sample, every object");
        for it in &f.items[..n] {
            // Sent 30 ms after the measurement, on the plant clock.
            assert_eq!(f.header.stamp_ns - it.t_meas_ns, 30_000_000);
            assert_eq!(it.t_meas_ns % 20_000_000, 0);
            assert!(it.bounding_radius > 0.0);
            if let Some((_, objs)) = truth.iter().find(|(t, _)| *t == it.t_meas_ns) {
                let (_, p, q) = objs.iter().find(|o| o.0 == it.id).unwrap();
                for k in 0..3 {
                    assert!((it.p[k] - (p[k] - sc.debris.base_lvlh[k])).abs() < 1e-12);
                }
                for k in 0..4 {
                    assert!((it.q[k] - q[k]).abs() < 1e-12);
                }
            }
        }
    }
    assert_eq!(side.stats.observation_frames, frames.len() as u64);
}

#[test]
fn tick_check_and_drain_allocate_nothing() {
    let model = ArmModel::default_arm();
    let mut sc = Scenario::default_scenario();
    sc.debris.scene = "dense".into();
    let mut side = DebrisSide::new(&sc, &model).unwrap();
    let mut frame = <DebrisObservation as Zeroed>::zeroed();
    let q = q0(&sc);
    side.step(1e-3); // first-use paths
    let mut sent = 0u32;
    let (_, s) = dkrrt_rt::alloc_count::count(|| {
        for _ in 0..2000 {
            side.step(1e-3);
            side.check(&q.into());
            sent += side.drain_observations::<()>(&mut frame, |_| Ok(())).unwrap();
        }
    });
    assert!(sent > 50, "{sent} frames");
    assert_eq!(s.allocs, 0, "{s:?}");
}

#[global_allocator]
static ALLOC: dkrrt_rt::alloc_count::CountingAlloc = dkrrt_rt::alloc_count::CountingAlloc;
