//! Threat episodes: deterministic, a real motion, threats on target, solvable by construction,
//! and the straight motion mostly hit.

use dkrrt_collision::{proximity, ArmPoser, ContactPair, Obstacle, PosedCapsule};
use dkrrt_config::{EpisodeCfg, Scenario};
use dkrrt_debris::DebrisWorld;
use dkrrt_episodes::{generate, resolve, straight, Episode, REST_CLEARANCE_M};
use dkrrt_model::{ArmModel, NJ};
use dkrrt_otg::Limits;

fn ep(scene: &str, index: u64) -> Episode {
    let sc = Scenario::default_scenario();
    generate(
        &EpisodeCfg {
            scene: scene.into(),
            index,
            seed: 77,
            duration_s: None,
            pose_goal: false,
            max_straight_s: None,
        },
        &sc,
    )
    .unwrap()
}

/// The smallest distance between the debris and the arm posed by `q_of(t)`, every 10 ms to
/// `t_end` (true shapes).
fn min_distance(e: &Episode, t_end: f64, q_of: impl Fn(f64) -> [f64; NJ]) -> f64 {
    min_distance_of(&ArmPoser::new(ArmModel::default_arm()), e, t_end, q_of)
}

/// [`min_distance`] for the arm `poser` poses.
fn min_distance_of(poser: &ArmPoser, e: &Episode, t_end: f64, q_of: impl Fn(f64) -> [f64; NJ]) -> f64 {
    let mut w = DebrisWorld::new(&e.scene).unwrap();
    let mut caps = [PosedCapsule::default(); NJ];
    let mut best = f64::INFINITY;
    let mut t = 0.0;
    while t <= t_end {
        poser.pose(&q_of(t), &mut caps);
        let obs: Vec<Obstacle> = w
            .debris()
            .iter()
            .map(|d| {
                let q = d.state.q.quaternion();
                Obstacle::from_shape(
                    d.id,
                    &d.props.shape,
                    d.props.bounding_radius,
                    &[d.state.p.x, d.state.p.y, d.state.p.z],
                    &[q.w, q.i, q.j, q.k],
                )
            })
            .collect();
        best = best.min(proximity(&caps, &obs, 0.0, &mut [ContactPair::default(); 1]).min_distance);
        w.step(0.01);
        t += 0.01;
    }
    best
}

#[test]
fn episodes_are_deterministic_real_motions_with_threats_on_target() {
    for scene in dkrrt_debris::SCENE_NAMES {
        let a = ep(scene, 3);
        let b = ep(scene, 3);
        assert_eq!((a.start, a.goal, a.time_limit_s), (b.start, b.goal, b.time_limit_s));
        assert_eq!(a.scene, b.scene, "{scene}: same debris");
        assert!((0..NJ).any(|i| (a.goal[i] - a.start[i]).abs() >= 0.5), "{scene}: a real motion");
        assert!((a.time_limit_s - (3.0 * a.straight_duration_s + 10.0)).abs() < 1e-9);
        assert!(!a.threats.is_empty());
        // Each threat's centre is where it was aimed, when it was aimed (true dynamics).
        for t in &a.threats {
            let mut w = DebrisWorld::new(&a.scene).unwrap();
            let n = (t.t_hit_s / 0.01).round() as usize;
            for _ in 0..n {
                w.step(t.t_hit_s / n as f64);
            }
            let d = &w.debris()[w.index_of(t.id).unwrap()];
            let miss = (d.state.p - nalgebra::Vector3::from(t.point)).norm();
            assert!(miss < 2e-3, "{scene}: threat {} misses its aim by {miss} m", t.id);
        }
        let other = ep(scene, 4);
        assert_ne!(a.start, other.start, "{scene}: episodes differ");
    }
}

#[test]
fn every_episode_is_solvable_by_waiting_at_the_start_or_the_goal() {
    for scene in dkrrt_debris::SCENE_NAMES {
        for i in 0..2 {
            let e = ep(scene, i);
            let (s, g) = (e.start, e.goal);
            let at_start = min_distance(&e, e.time_limit_s, |_| s);
            let at_goal = min_distance(&e, e.time_limit_s, |_| g);
            // 10 ms steps vs the generator's 20 ms: allow what 2 m/s covers in 10 ms.
            assert!(at_start >= REST_CLEARANCE_M - 0.02, "{scene} #{i}: {at_start}");
            assert!(at_goal >= REST_CLEARANCE_M - 0.02, "{scene} #{i}: {at_goal}");
        }
    }
}

#[test]
fn the_straight_motion_is_hit_in_most_episodes() {
    let sc = Scenario::default_scenario();
    let lim = Limits { v_max: sc.motion.v_max, a_max: sc.motion.a_max, j_max: sc.motion.j_max };
    for scene in ["dense", "fast-crossing", "tumbling-rods"] {
        let mut hit = 0;
        let n = 5;
        for i in 0..n {
            let e = ep(scene, 10 + i);
            let tr = straight(&e.start, &e.goal, &lim).unwrap();
            if min_distance(&e, tr.duration(), |t| tr.at(t).p) <= 0.0 {
                hit += 1;
            }
        }
        assert!(hit * 10 >= n * 6, "{scene}: the straight motion is hit in only {hit} of {n}");
    }
}

#[test]
fn resolving_puts_the_episode_into_the_scenario() {
    let mut sc = Scenario::default_scenario();
    sc.episode = Some(EpisodeCfg {
        scene: "dense".into(),
        index: 1,
        seed: 5,
        duration_s: Some(12.0),
        pose_goal: false,
        max_straight_s: None,
    });
    let e = resolve(&mut sc).unwrap().unwrap();
    assert_eq!(sc.sim.initial_q, e.start);
    assert_eq!(sc.goal.q, Some(e.goal));
    assert_eq!(sc.run.duration_s, 12.0);
    assert_eq!(sc.load_debris_scene().unwrap(), e.scene);
    let mut bad = Scenario::default_scenario();
    bad.episode = Some(EpisodeCfg {
        scene: "nowhere".into(),
        index: 0,
        seed: 1,
        duration_s: None,
        pose_goal: false,
        max_straight_s: None,
    });
    assert!(resolve(&mut bad).unwrap_err().contains("episode.scene"));
}

#[test]
fn a_capped_episode_is_a_short_real_motion_still_hit_and_solvable() {
    let sc = Scenario::default_scenario();
    let lim = Limits { v_max: sc.motion.v_max, a_max: sc.motion.a_max, j_max: sc.motion.j_max };
    let cfg = |index, cap| EpisodeCfg {
        scene: "fast-crossing".into(),
        index,
        seed: 4242,
        duration_s: None,
        pose_goal: false,
        max_straight_s: Some(cap),
    };
    let mut made = 0;
    for i in 0..4 {
        // A draw may find no solvable episode near so short a motion: a clear error, not a
        // long one.
        let e = match generate(&cfg(i, 3.5), &sc) {
            Ok(e) => e,
            Err(m) => {
                assert!(m.contains("no solvable draw"), "{m}");
                continue;
            }
        };
        made += 1;
        assert!(e.straight_duration_s <= 3.5 + 1e-9, "#{i}: {} s", e.straight_duration_s);
        assert!((0..NJ).any(|j| (e.goal[j] - e.start[j]).abs() >= 0.5 - 1e-12), "#{i}: a real motion");
        let tr = straight(&e.start, &e.goal, &lim).unwrap();
        assert!(min_distance(&e, tr.duration(), |t| tr.at(t).p) <= 0.0, "#{i}: the straight motion is hit");
        let (s, g) = (e.start, e.goal);
        assert!(min_distance(&e, e.time_limit_s, |_| s) >= REST_CLEARANCE_M - 0.02);
        assert!(min_distance(&e, e.time_limit_s, |_| g) >= REST_CLEARANCE_M - 0.02);
    }
    assert!(made >= 2, "only {made} of 4 capped draws succeeded");
    // No joint can move 0.5 rad in 1 s within the motion limits: refused, naming the field.
    let err = generate(&cfg(0, 1.0), &sc).unwrap_err();
    assert!(err.contains("episode.max_straight_s") && err.contains("fastest"), "{err}");
}

#[test]
fn a_scene_file_gives_threat_episodes_at_its_own_speeds() {
    // fast-crossing with every velocity tripled and another name, as a file beside a scenario
    // that names it relatively: deterministic episodes keyed by the scene's name, threats
    // aimed at the straight motion at its objects' speeds, solvable by waiting, and mostly
    // hitting the straight motion.
    let dir = std::env::temp_dir().join(format!("dkrrt-ep-file-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut scene = dkrrt_debris::Scene::named("fast-crossing").unwrap();
    scene.name = "fast-crossing-3x".into();
    for d in &mut scene.debris {
        d.v = d.v.map(|v| 3.0 * v);
    }
    let speeds: Vec<f64> = scene.debris.iter().map(|d| nalgebra::Vector3::from(d.v).norm()).collect();
    let (lo, hi) = (
        speeds.iter().cloned().filter(|v| *v > 0.0).fold(f64::INFINITY, f64::min),
        speeds.iter().cloned().fold(0.0, f64::max),
    );
    std::fs::write(dir.join("fast3x.toml"), scene.to_toml()).unwrap();
    let text = dkrrt_config::DEFAULT_SCENARIO.to_string();
    std::fs::write(dir.join("scenario.toml"), &text).unwrap();
    let sc = Scenario::load(dir.join("scenario.toml").to_str().unwrap()).unwrap();
    let cfg = |index| EpisodeCfg {
        scene: "fast3x.toml".into(),
        index,
        seed: 77,
        duration_s: None,
        pose_goal: false,
        max_straight_s: None,
    };
    let lim = Limits { v_max: sc.motion.v_max, a_max: sc.motion.a_max, j_max: sc.motion.j_max };
    let mut hit = 0;
    for i in 0..5 {
        let e = generate(&cfg(i), &sc).unwrap();
        let again = generate(&cfg(i), &sc).unwrap();
        assert_eq!((e.start, e.goal, &e.scene), (again.start, again.goal, &again.scene));
        assert!(!e.threats.is_empty());
        for t in &e.threats {
            assert!(
                t.speed_mps >= lo * 0.999 && t.speed_mps <= hi * 1.001,
                "{} outside {lo}–{hi}",
                t.speed_mps
            );
        }
        let (s, g) = (e.start, e.goal);
        assert!(min_distance(&e, e.time_limit_s, |_| s) >= REST_CLEARANCE_M - 0.06);
        assert!(min_distance(&e, e.time_limit_s, |_| g) >= REST_CLEARANCE_M - 0.06);
        let tr = straight(&e.start, &e.goal, &lim).unwrap();
        hit += usize::from(min_distance(&e, tr.duration(), |t| tr.at(t).p) <= 0.0);
    }
    assert!(hit >= 3, "the straight motion is hit in only {hit} of 5");
    // A scene file that is not there: refused, naming the field.
    let e = generate(&EpisodeCfg { scene: "missing.toml".into(), ..cfg(0) }, &sc).unwrap_err();
    assert!(e.contains("episode.scene") && e.contains("missing.toml"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_smaller_arm_keeps_a_clearance_to_its_size_at_rest() {
    // A UR5-sized arm (reach 1.29 m against the default arm's 3.35 m): 0.3 m from its rests
    // was more than a threat crossing its shorter motions could keep (no episode in 500
    // draws); 9 % of its reach is kept instead. The default arm keeps 0.3 m.
    let pkgs =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/model/tests/fixtures/pkgs");
    let urdf = pkgs.join("ur_like_description/urdf/ur_like.urdf");
    let dir = std::env::temp_dir().join(format!("dkrrt-ep-ur-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = dkrrt_config::DEFAULT_SCENARIO.replacen(
        "urdf = \"\"",
        &format!("urdf = \"{}\"\ntip_link = \"tool0\"", urdf.display()),
        1,
    );
    std::fs::write(dir.join("ur.toml"), text).unwrap();
    let sc = Scenario::load(dir.join("ur.toml").to_str().unwrap()).unwrap();
    let poser = ArmPoser::new(sc.load_arm().unwrap());
    let keep = dkrrt_episodes::rest_clearance_m(&poser);
    assert!((keep - 0.09 * 1.2938).abs() < 1e-3, "{keep}");
    assert_eq!(dkrrt_episodes::rest_clearance_m(&ArmPoser::new(ArmModel::default_arm())), REST_CLEARANCE_M);
    let lim = Limits { v_max: sc.motion.v_max, a_max: sc.motion.a_max, j_max: sc.motion.j_max };
    for index in 0..2 {
        let cfg = EpisodeCfg {
            scene: "sparse-slow".into(),
            index,
            seed: 8,
            duration_s: None,
            pose_goal: false,
            max_straight_s: None,
        };
        let e = generate(&cfg, &sc).unwrap();
        assert!(e.rest_clearance_m >= keep);
        let tr = straight(&e.start, &e.goal, &lim).unwrap();
        // Posed by the UR-sized arm: the straight motion is hit.
        let hit = min_distance_of(&poser, &e, tr.duration(), |t| tr.at(t).p) <= 0.0;
        assert!(hit, "episode {index}: the straight motion is not hit");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
