//! The in-process lockstep evaluation: deterministic and accurate.

use dkrrt_config::Scenario;

#[test]
fn lockstep_reaches_the_goal_and_is_deterministic() {
    let sc = Scenario::default_scenario();
    let a = dkrrt::lockstep::run(&sc).unwrap();
    let b = dkrrt::lockstep::run(&sc).unwrap();
    assert_eq!(a.final_q, b.final_q, "same scenario, same result");
    assert_eq!(a.tracking_error_rad_rms, b.tracking_error_rad_rms);
    // Measured 2.2e-8 rad RMS and 3.7e-14 rad final (2026-11-24): bounds with margin for
    // floating point, not for a regression.
    assert!(a.tracking_error_rad_rms < 1e-7, "{}", a.tracking_error_rad_rms);
    assert!(a.final_error_rad < 1e-10, "{}", a.final_error_rad);
    assert_eq!(a.safe_hold_entries, 0);
    assert!(a.trajectory_duration_s > 1.0 && a.trajectory_duration_s < sc.run.duration_s);
    // The default scene's debris runs in the same lockstep: observed, forecast, no contact.
    let (da, db) = (a.debris.unwrap(), b.debris.unwrap());
    assert_eq!(da, db, "debris side deterministic");
    assert!(!da.collided());
    assert!(da.min_distance_m.unwrap() > 0.5);
    assert_eq!(da.ticks_checked, sc.ticks() + 1, "every tick and the start");
    let (pa, pb) = (a.predictor.unwrap(), b.predictor.unwrap());
    assert_eq!((pa.forecasts, pa.gate.accepted), (pb.forecasts, pb.gate.accepted));
    // One forecast per 20 ms of plant time once tracks are mature (~0.1 s of data).
    let expect = sc.run.duration_s * sc.predictor.rate_hz;
    assert!(pa.forecasts as f64 > 0.9 * expect && pa.forecasts as f64 <= expect + 1.0, "{}", pa.forecasts);
    assert_eq!(pa.tracks as usize, da.objects);
    assert_eq!(pa.observations.rejected(), 0);
    // It did what was asked: every in-process check passed.
    let names: Vec<&str> = a.checks.iter().map(|c| c.name).collect();
    assert_eq!(names, ["goal_reached", "no_collision", "joint_limits", "safe_holds"]);
    assert!(a.ok && a.checks.iter().all(|c| c.ok), "{:?}", a.checks);
}

/// A scene with no object: the sensor says it sees nothing (the camera's captures label no
/// object), the predictor forecasts an empty sky, and the planner moves at once (it waited 2 s
/// for a forecast that could not come, then moved without one). The same run from the process
/// set: `tests/e2e.rs`.
#[test]
fn an_empty_sky_is_said_and_the_arm_goes_at_once() {
    let dir = std::env::temp_dir().join(format!("dkrrt-empty-sky-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("empty.toml");
    std::fs::write(&scene, "name = \"empty\"\n").unwrap();
    for input in ["poses", "depth"] {
        let mut sc = Scenario::default_scenario();
        sc.debris.scene = scene.display().to_string();
        sc.predictor.input = input.into();
        let r = dkrrt::lockstep::run(&sc).unwrap();
        assert!(r.ok, "{input}: {:?}", r.checks);
        let p = r.predictor.unwrap();
        // Poses: a forecast per 1/rate from the first frame (after the 30 ms latency); depth:
        // one per capture (20 Hz), once the next capture shows the last one whole.
        let expect = sc.run.duration_s
            * sc.predictor.rate_hz.min(if input == "depth" { sc.camera.rate_hz } else { f64::INFINITY });
        assert!(p.forecasts as f64 > 0.95 * expect && p.tracks == 0, "{input}: {} forecasts", p.forecasts);
        let plan = r.planner.unwrap();
        assert!(plan.cycles_waiting_for_forecast <= 1, "{input}: {}", plan.cycles_waiting_for_forecast);
        let start =
            r.events.iter().find(|e| e.to == dkrrt_msg::ControllerMode::Track).expect("the arm moved");
        assert!(start.plant_ns < 300_000_000, "{input}: moved at {} ns", start.plant_ns);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A run is `ok` only when it did what was asked (`dkrrt eval` exits 1 otherwise): the
/// default episode driven straight collides; a run too short for the motion misses its goal.
#[test]
fn a_run_that_collides_or_misses_its_goal_is_not_ok() {
    let failed = |r: &dkrrt::lockstep::EvalReport| -> Vec<&str> {
        r.checks.iter().filter(|c| !c.ok).map(|c| c.name).collect()
    };
    let mut sc = Scenario::default_scenario();
    dkrrt_episodes::resolve(&mut sc).unwrap().expect("the default scenario is an episode");
    sc.planner.method = "straight".into();
    let r = dkrrt::lockstep::run(&sc).unwrap();
    assert!(r.debris.unwrap().collided());
    assert!(!r.ok && failed(&r).contains(&"no_collision"), "{:?}", r.checks);
    let mut sc = Scenario::default_scenario();
    sc.run.duration_s = 0.5;
    let r = dkrrt::lockstep::run(&sc).unwrap();
    assert!(!r.ok && failed(&r) == ["goal_reached"], "{:?}", r.checks);
}

#[test]
fn lockstep_with_noise_and_delay_still_tracks() {
    let mut sc = Scenario::default_scenario();
    sc.sim.noise_q_std = 1e-5;
    sc.sim.noise_qd_std = 1e-4;
    sc.sim.delay_ticks = 2;
    let r = dkrrt::lockstep::run(&sc).unwrap();
    // Measured 1.0e-5 rad RMS (the noise itself is 1e-5 rad) and 9.3e-7 rad final.
    assert!(r.tracking_error_rad_rms < 2e-5, "{}", r.tracking_error_rad_rms);
    assert!(r.final_error_rad < 5e-6, "{}", r.final_error_rad);
}

#[test]
fn the_straight_source_reissues_its_goal_after_a_safe_hold() {
    use dkrrt::lockstep::{Lockstep, TrajSource};
    let mut sc = Scenario::default_scenario();
    sc.episode = None;
    sc.debris.scene.clear();
    sc.planner.method = "straight".into();
    let mut ls = Lockstep::new(&sc).unwrap();
    // 1 s of motion, then 20 lost states mid-motion (the tracker's stale limit is 10): safe hold.
    for _ in 0..1000 {
        ls.tick(true);
    }
    for _ in 0..20 {
        ls.tick(false);
    }
    let m = ls.tracker.mode();
    assert!(matches!(m, dkrrt_msg::ControllerMode::Brake | dkrrt_msg::ControllerMode::Hold), "{m:?}");
    // States flow again: the goal is re-issued from where the arm rests, and reached.
    for _ in 0..15_000 {
        ls.tick(true);
    }
    let TrajSource::Straight { core, .. } = &ls.source else { panic!("straight source") };
    assert_eq!(core.reissues, 1, "one re-issue, none once at the goal");
    let r = ls.report(&sc);
    assert!(r.safe_hold_entries >= 1);
    assert!(ls.goal_reached_s.is_some(), "{:?}", r.final_q);
}

#[test]
fn a_pose_goal_is_solved_and_reached_by_both_sources() {
    // The default threat episode with its goal given as the end-effector pose of its goal
    // configuration: each source solves it by IK from the start and the run ends with the end
    // effector on the pose (the dk-rrt planner around the debris, goto straight on).
    let model = dkrrt_model::ArmModel::default_arm();
    for method in ["dk-rrt", "straight"] {
        let mut sc = Scenario::default_scenario();
        sc.episode.as_mut().unwrap().pose_goal = true;
        sc.planner.method = method.into();
        dkrrt_episodes::resolve(&mut sc).unwrap();
        assert!(sc.goal.q.is_none());
        let Some(dkrrt_config::GoalRequest::Pose(p, r)) = sc.goal.request() else { panic!("a pose goal") };
        let rep = dkrrt::lockstep::run(&sc).unwrap();
        let (dp, da) = dkrrt::lockstep::ee_error(&model, &rep.final_q, &p, &r);
        assert!(dp < 0.01 && da < 0.02, "{method}: end effector {dp} m, {da} rad off the pose");
        assert!(rep.goal_reached_s.is_some(), "{method}");
        if method == "dk-rrt" {
            assert!(!rep.debris.unwrap().collided(), "the planner avoids the debris");
        }
    }
    // An unreachable pose is refused before anything moves.
    let mut sc = Scenario::default_scenario();
    dkrrt_episodes::resolve(&mut sc).unwrap();
    sc.goal = dkrrt_config::GoalCfg { q: None, pose: Some([5.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]) };
    let e = dkrrt::lockstep::run(&sc).err().expect("out of reach");
    assert!(e.contains("out of reach"), "{e}");
}

/// `predictor.input = "depth"`: the camera turns on, and the predictor sees the debris only
/// through its frames (the front end's observations), never the pose sensor's; the run is
/// deterministic and reaches its goal without contact.
#[test]
fn the_predictor_can_see_through_the_depth_camera() {
    let mut sc = Scenario::default_scenario();
    sc.predictor.input = "depth".into();
    assert!(!sc.camera.enabled && sc.camera_on(), "the depth input turns the camera on");
    let a = dkrrt::lockstep::run(&sc).unwrap();
    let b = dkrrt::lockstep::run(&sc).unwrap();
    assert_eq!(a.final_q, b.final_q, "deterministic");
    let cam = a.camera.expect("camera figures");
    assert_eq!(cam.overrun, 0);
    // The default rig: six frames per capture; the last capture's may be in flight.
    let faces = sc.camera.faces as u64;
    assert_eq!((faces, cam.captured % faces), (6, 0), "{cam:?}");
    assert!(
        cam.delivered + faces >= cam.captured
            && cam.captured as f64 >= a.ticks as f64 * 1e-3 * sc.camera.rate_hz * faces as f64,
        "{cam:?}"
    );
    let p = a.predictor.unwrap();
    // Every camera frame, and nothing else, reached the predictor.
    assert_eq!(p.observations.frames, cam.delivered);
    assert!(p.observations.items > 50 && p.gate.accepted > 50, "{:?}", p.observations);
    assert!(p.forecasts > 10);
    assert!(!a.debris.unwrap().collided());
    assert!(a.goal_reached_s.is_some(), "goal not reached");
    // With poses the predictor reads the sensor's frames instead, and no camera runs.
    let mut poses = sc.clone();
    poses.predictor.input = "poses".into();
    let c = dkrrt::lockstep::run(&poses).unwrap();
    assert!(c.camera.is_none());
    assert_eq!(c.predictor.unwrap().observations.frames, c.debris.unwrap().observation_frames);
    assert_eq!(p.observations.learned_views, 0, "the classical front end");
}

/// The camera rig (`camera-rig.toml`): objects straddling two of its cameras are cut by both
/// frames; they reach the predictor as partial views (a loose position, no attitude) instead
/// of being lost, and the rig's episode is reached without contact.
#[test]
fn a_rigs_cut_views_reach_the_predictor_as_partial_views() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/shared/config/scenarios/camera-rig.toml");
    let sc = Scenario::load(path).unwrap();
    let a = dkrrt::lockstep::run(&sc).unwrap();
    let p = a.predictor.unwrap();
    assert!(p.observations.partial_views > 0, "{:?}", p.observations);
    assert!(p.observations.partial_views < p.observations.items);
    assert!(p.gate.partial > 0 && p.gate.partial <= p.observations.partial_views, "{:?}", p.gate);
    assert!(!a.debris.unwrap().collided() && a.goal_reached_s.is_some());
}

/// `predictor.front_end = "learned"`: the shipped visual features f_θ read the camera's views
/// of the objects (every view large enough), the run reaches its goal without contact; a bad
/// model file is refused naming the field and the file.
#[test]
fn the_learned_front_end_reads_the_camera_views_through_f_theta() {
    let mut sc = Scenario::default_scenario();
    sc.predictor.input = "depth".into();
    sc.predictor.front_end = "learned".into();
    let a = dkrrt::lockstep::run(&sc).unwrap();
    let p = a.predictor.unwrap();
    assert!(p.observations.learned_views > 20, "{:?}", p.observations);
    assert!(p.observations.learned_views <= p.observations.items);
    assert!(!a.debris.unwrap().collided() && a.goal_reached_s.is_some());
    let dir = std::env::temp_dir().join(format!("dkrrt-lockstep-visual-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("bad.dkv"), b"DKRRTVIS and then nothing").unwrap();
    sc.predictor.visual_model = "bad.dkv".into();
    sc.base_dir = Some(dir.clone());
    let e = dkrrt::lockstep::run(&sc).err().expect("a bad model file");
    assert!(e.contains("predictor.visual_model") && e.contains("bad.dkv"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The lockstep builds only the forecasts the planner reads (the others only do their
/// calibration, [`dkrrt_planner::predict::PredictorCore::observe_then_forecast_if`]): the run
/// is the one that builds them all, as the predictor process does, tick for tick.
#[test]
fn forecasts_nobody_reads_are_not_built_and_the_run_is_the_same() {
    let mut sc = Scenario::default_scenario();
    dkrrt_episodes::resolve(&mut sc).unwrap();
    let run = |lazy: bool| {
        let mut ls = dkrrt::lockstep::Lockstep::new(&sc).unwrap();
        ls.predictor.as_mut().unwrap().lazy = lazy;
        for _ in 0..sc.ticks() {
            ls.tick(true);
        }
        ls.report(&sc)
    };
    let (a, b) = (run(true), run(false));
    assert_eq!(a.final_q, b.final_q);
    assert_eq!(a.goal_reached_s, b.goal_reached_s);
    assert!(a.goal_reached_s.is_some());
    assert_eq!(a.debris.unwrap(), b.debris.unwrap());
    let (sa, sb) = (a.planner.unwrap(), b.planner.unwrap());
    assert_eq!((sa.cycles, sa.replans, sa.iterations), (sb.cycles, sb.replans, sb.iterations));
    assert_eq!(sa.min_predicted_clearance_m, sb.min_predicted_clearance_m);
    let (pa, pb) = (a.predictor.unwrap(), b.predictor.unwrap());
    let key = |p: &dkrrt::lockstep::PredictorFigures| (p.forecasts, p.gate.events, p.gate.accepted);
    assert_eq!(key(&pa), key(&pb));
    // At 50 Hz against a 10 Hz planner four in five are read by no cycle; those within the
    // read window before a cycle are built.
    assert!(pa.deferred as f64 > 0.5 * pa.forecasts as f64, "{} of {}", pa.deferred, pa.forecasts);
    assert_eq!((pa.stale_reads, pb.deferred, pb.stale_reads), (0, 0, 0));
}

/// The debris side stepped ahead on a second thread ([`dkrrt::lockstep::Lockstep::run_ahead`])
/// gives the serial run, tick for tick: the same final state, goal time, contact figures,
/// planner cycles and predictor figures; with the straight source too, up to its contact.
#[test]
fn a_run_ahead_is_the_serial_run() {
    let mut sc = Scenario::default_scenario();
    dkrrt_episodes::resolve(&mut sc).unwrap();
    let mut straight = sc.clone();
    straight.planner.method = "straight".into();
    for sc in [&sc, &straight] {
        let run = |ahead: bool| {
            let mut ls = dkrrt::lockstep::Lockstep::new(sc).unwrap();
            if ahead {
                assert!(ls.run_ahead(sc).unwrap());
                assert!(!ls.run_ahead(sc).unwrap(), "once only");
            }
            let mut ticks = 0;
            for _ in 0..sc.ticks() {
                ls.tick(true);
                ticks += 1;
                if ls.collided() {
                    break;
                }
            }
            (ls.report(sc), ticks)
        };
        let ((a, ta), (b, tb)) = (run(true), run(false));
        let m = &sc.planner.method;
        assert_eq!(ta, tb, "{m}");
        assert_eq!(a.final_q, b.final_q, "{m}");
        assert_eq!(a.goal_reached_s, b.goal_reached_s, "{m}");
        assert_eq!(a.debris.unwrap(), b.debris.unwrap(), "{m}");
        assert_eq!(a.plant, b.plant, "{m}");
        match (a.planner, b.planner) {
            (Some(sa), Some(sb)) => {
                assert_eq!((sa.cycles, sa.replans, sa.iterations), (sb.cycles, sb.replans, sb.iterations));
                assert_eq!(sa.min_predicted_clearance_m, sb.min_predicted_clearance_m);
                assert_eq!(sa.fallbacks, sb.fallbacks);
                assert!(a.goal_reached_s.is_some() && a.debris.unwrap().first_contact.is_none());
            }
            (None, None) => assert!(a.debris.unwrap().first_contact.is_some(), "the straight motion is hit"),
            _ => panic!("one run planned, the other did not"),
        }
        let (pa, pb) = (a.predictor.unwrap(), b.predictor.unwrap());
        let key = |p: &dkrrt::lockstep::PredictorFigures| {
            (p.forecasts, p.tracks, p.deferred, p.stale_reads, p.gate, p.observations)
        };
        assert_eq!(key(&pa), key(&pb), "{m}");
        assert!(pa.forecasts > 0);
    }
}
