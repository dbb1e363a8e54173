//! The predictor core without IPC: item-wise validation of observation frames, forecasts
//! on the common grid in the base frame against the simulated truth, no allocation.

use dkrrt_config::Scenario;
use dkrrt_msg::{ContractLimits, DebrisForecast, DebrisObservation, Validate, Zeroed, MAX_DEBRIS};
use dkrrt_planner::predict::{fit_models, PredictorCore};
use dkrrt_sim::debris::DebrisSide;

fn lim() -> ContractLimits {
    ContractLimits::symmetric(1.0, 1.0, 1.0)
}

fn scenario(scene: &str, method: &str) -> Scenario {
    let mut sc = Scenario::default_scenario();
    sc.debris.scene = scene.into();
    sc.debris.base_lvlh = [0.7, -1.3, 0.4];
    sc.predictor.method = method.into();
    sc.predictor.fit_runs = 2;
    sc
}

/// Runs the debris side for `ticks` ms, feeding every frame to the core.
fn feed(side: &mut DebrisSide, core: &mut PredictorCore, ticks: usize) {
    let mut frame = <DebrisObservation as Zeroed>::zeroed();
    let l = lim();
    for _ in 0..ticks {
        side.step(1e-3);
        side.drain_observations::<()>(&mut frame, |f| {
            core.observe_frame(f, &l);
            Ok(())
        })
        .unwrap();
    }
}

#[test]
fn one_bad_item_does_not_lose_the_good_ones() {
    let mut sc = scenario("sparse-slow", "constant-velocity");
    sc.debris.latency_jitter_s = 0.0; // every record of a sample in one frame
    sc.debris.dropout = 0.0;
    let mut core = PredictorCore::new(fit_models(&sc).unwrap(), &sc);
    let mut side = DebrisSide::new(&sc, &dkrrt_model::ArmModel::default_arm()).unwrap();
    let mut frame = <DebrisObservation as Zeroed>::zeroed();
    for _ in 0..40 {
        side.step(1e-3);
        side.drain_observations::<()>(&mut frame, |_| Ok(())).unwrap();
    }
    assert!(frame.count >= 4, "a real frame to corrupt");
    let n = frame.count as u64;
    frame.items[1].p[0] = f64::NAN;
    frame.items[2].q = [0.5, 0.0, 0.0, 0.0]; // not unit
    core.observe_frame(&frame, &lim());
    let c = core.counters;
    assert_eq!((c.frames, c.items, c.items_invalid, c.items_gated), (1, n, 2, 0));
    assert_eq!(core.gate().accepted, n - 2);
    assert_eq!(c.rejected(), 2);

    // An impossible jump of a tracked object is rejected by the gate and counted.
    let mut next = frame;
    for it in next.items[..frame.count as usize].iter_mut() {
        it.t_meas_ns += 20_000_000;
    }
    next.items[0].p[1] += 30.0; // 1500 m/s
    next.items[1].p[0] = 1.0; // valid again (new track)
    core.observe_frame(&next, &lim());
    assert_eq!(core.counters.items_gated, 1);
    assert_eq!(core.gate().pos_jump, 1);
    assert_eq!(core.counters.items_invalid, 3, "item 2 still has its bad quaternion");

    // A frame whose count exceeds the capacity is rejected whole.
    let mut bad = frame;
    bad.count = MAX_DEBRIS as u32 + 1;
    core.observe_frame(&bad, &lim());
    assert_eq!(core.counters.frames_rejected, 1);
    assert_eq!(core.counters.rejected(), 3 + 1 + 1);
}

#[test]
fn forecasts_are_on_a_common_grid_in_the_base_frame_and_match_the_truth() {
    let sc = scenario("sparse-slow", "dual-data");
    let mut core = PredictorCore::new(fit_models(&sc).unwrap(), &sc);
    let mut side = DebrisSide::new(&sc, &dkrrt_model::ArmModel::default_arm()).unwrap();
    feed(&mut side, &mut core, 3000);
    let mut msg = Box::new(<DebrisForecast as Zeroed>::zeroed());
    let n = core.forecast_into(&mut msg);
    let objects = side.world().debris().len();
    assert_eq!(n, objects, "every object is forecast");
    assert!(msg.validate(&lim()).is_ok());
    assert_eq!(msg.steps, 40);
    assert!((msg.dt_s - 0.1).abs() < 1e-12);
    // t0 = the newest estimate: the last measurement (latency 30-40 ms, 50 Hz grid).
    let t0 = msg.t0_ns as f64 * 1e-9;
    assert!((2.92..=2.99).contains(&t0), "t0 {t0}");
    // Advance the truth to t0 + 1 s (step index 9) and compare, in the base frame.
    let t1 = t0 + 1.0;
    let ticks = ((t1 - side.world().time()) * 1000.0).round() as usize;
    let mut frame = <DebrisObservation as Zeroed>::zeroed();
    for _ in 0..ticks {
        side.step(1e-3);
        side.drain_observations::<()>(&mut frame, |_| Ok(())).unwrap();
    }
    assert!((side.world().time() - t1).abs() < 1e-3);
    let b = sc.debris.base_lvlh;
    let mut worst: f64 = 0.0;
    for tr in &msg.tracks[..n] {
        let d = side.world().debris().iter().find(|d| d.id == tr.id).unwrap();
        let p = tr.steps[9].p;
        let err = ((p[0] + b[0] - d.state.p.x).powi(2)
            + (p[1] + b[1] - d.state.p.y).powi(2)
            + (p[2] + b[2] - d.state.p.z).powi(2))
        .sqrt();
        worst = worst.max(err);
        assert!(tr.bounding_radius > 0.0);
        // The bound grows with the horizon.
        assert!(tr.steps[39].sigma_m >= tr.steps[0].sigma_m);
    }
    // Sensor noise 1 cm, slow objects: 1 s ahead within a few centimetres.
    assert!(worst < 0.08, "worst 1 s position error {worst} m");
}

#[test]
fn observe_and_forecast_allocate_nothing() {
    let sc = scenario("dense", "koopman-online");
    let mut core = PredictorCore::new(fit_models(&sc).unwrap(), &sc);
    let mut side = DebrisSide::new(&sc, &dkrrt_model::ArmModel::default_arm()).unwrap();
    feed(&mut side, &mut core, 500);
    let mut msg = Box::new(<DebrisForecast as Zeroed>::zeroed());
    core.forecast_into(&mut msg);
    let mut frames = Vec::new();
    let mut frame = <DebrisObservation as Zeroed>::zeroed();
    for _ in 0..2000 {
        side.step(1e-3);
        side.drain_observations::<()>(&mut frame, |f| {
            frames.push(*f);
            Ok(())
        })
        .unwrap();
    }
    let l = lim();
    let (_, s) = dkrrt_rt::alloc_count::count(|| {
        for f in &frames {
            core.observe_frame(f, &l);
            core.forecast_into(&mut msg);
        }
    });
    assert!(core.counters.items > 1000);
    assert!(msg.count > 20);
    assert_eq!(s.allocs, 0, "{s:?}");
}

#[test]
fn an_unknown_method_names_the_field() {
    let sc = scenario("sparse-slow", "crystal-ball");
    let e = fit_models(&sc).err().unwrap();
    assert!(e.contains("predictor.method") && e.contains("crystal-ball"), "{e}");
    // The scenario's own check (before any process starts) knows the same methods.
    let names: Vec<&str> = dkrrt_predictor::Method::ALL.iter().map(|m| m.name()).collect();
    assert_eq!(names, dkrrt_config::PREDICTOR_METHODS);
    let arm = sc.load_arm().err().expect("an unknown method is refused").to_string();
    assert!(arm.contains("predictor.method = \"crystal-ball\"") && arm.contains("deep-koopman"), "{arm}");
}

#[global_allocator]
static ALLOC: dkrrt_rt::alloc_count::CountingAlloc = dkrrt_rt::alloc_count::CountingAlloc;

#[test]
fn each_planning_method_forecasts_with_its_own_model() {
    let mut sc = scenario("sparse-slow", "deep-koopman-online");
    for (m, want) in [
        ("dk-rrt", "deep-koopman-online"),
        ("straight", "deep-koopman-online"),
        ("cv-rrt", "constant-velocity"),
        ("edmd-rrt", dkrrt_config::EDMD_BASELINE),
        ("rrt-static", "constant-velocity"),
    ] {
        sc.planner.method = m.into();
        assert_eq!(sc.predictor_method(), want, "{m}");
    }
    sc.planner.method = "edmd-rrt".into();
    assert_eq!(fit_models(&sc).unwrap().method.name(), dkrrt_config::EDMD_BASELINE);
}

#[test]
fn rrt_static_holds_the_latest_estimate_with_no_uncertainty() {
    let mut sc = scenario("sparse-slow", "deep-koopman-online");
    sc.planner.method = "rrt-static".into();
    let mut core = PredictorCore::new(fit_models(&sc).unwrap(), &sc);
    let mut side = DebrisSide::new(&sc, &dkrrt_model::ArmModel::default_arm()).unwrap();
    feed(&mut side, &mut core, 1500);
    let mut msg = Box::new(<DebrisForecast as Zeroed>::zeroed());
    let n = core.forecast_into(&mut msg);
    assert!(n >= 3, "tracks: {n}");
    let b = sc.debris.base_lvlh;
    for tr in &msg.tracks[..n] {
        let first = tr.steps[0];
        // Every step the same pose, no bound: the debris are held where they were last seen.
        for st in &tr.steps[..msg.steps as usize] {
            assert_eq!(st, &first);
        }
        assert_eq!((first.sigma_m, first.sigma_pos_m), (0.0, 0.0));
        // ... and that pose is the predictor's latest estimate (base frame), near the truth now.
        let est = core.predictor().track(tr.id).unwrap().state;
        assert_eq!(first.p, [est[0] - b[0], est[1] - b[1], est[2] - b[2]]);
        let w = side.world();
        let d = &w.debris()[w.index_of(tr.id).unwrap()];
        let err = ((d.state.p.x - b[0] - first.p[0]).powi(2)
            + (d.state.p.y - b[1] - first.p[1]).powi(2)
            + (d.state.p.z - b[2] - first.p[2]).powi(2))
        .sqrt();
        assert!(err < 0.1, "id {}: held pose {err} m from the truth", tr.id);
    }
    msg.validate(&lim()).unwrap();
}

/// Depth frames reach the predictor through the core's front end: a frame's objects become
/// tracks; a bad frame is rejected whole and counted, and loses nothing else.
#[test]
fn depth_frames_make_tracks_and_a_bad_one_is_rejected_and_counted() {
    let mut sc = scenario("sparse-slow", "constant-velocity");
    sc.predictor.input = "depth".into();
    sc.camera.faces = 6;
    sc.camera.fov_y_rad = std::f64::consts::FRAC_PI_2;
    sc.camera.position_m = [-0.7, 1.3, -0.4]; // at the LVLH origin
    let mut core = PredictorCore::new(fit_models(&sc).unwrap(), &sc);
    let model = dkrrt_model::ArmModel::default_arm();
    let mut side = DebrisSide::new(&sc, &model).unwrap();
    let mut cam = dkrrt_sim::camera::CameraSide::new(&sc.camera).unwrap();
    let mut renderers = dkrrt_sim::camera::Renderer::rig(&sc.camera, sc.debris.base_lvlh).unwrap();
    let mut snap = Box::<dkrrt_sim::camera::Snapshot>::default();
    let l = ContractLimits { debris_range_m: 100.0, ..lim() };
    let q = [0.0; dkrrt_model::NJ];
    let mut last = Box::new(<dkrrt_msg::DepthImage as Zeroed>::zeroed());
    for _ in 0..1500 {
        side.step(1e-3);
        cam.tick::<()>(&mut side, &q, &mut snap, &mut renderers, |img| {
            core.observe_depth(img, &l);
            *last = *img;
            Ok(())
        })
        .unwrap();
    }
    let c = core.counters;
    assert_eq!(c.frames, cam.stats.delivered);
    assert_eq!(c.frames_rejected, 0);
    let objects = side.world().debris().len() as u64;
    assert!(core.gate().tracks_created >= objects.min(3), "{:?} of {objects}", core.gate());
    let mut msg = Box::new(<DebrisForecast as Zeroed>::zeroed());
    assert!(core.forecast_into(&mut msg) >= 3);
    // A pixel labelled with an instance the frame does not have: the whole frame is refused.
    last.instance[10] = (last.n_instances + 1) as u8;
    let before = core.gate().accepted;
    core.observe_depth(&last, &l);
    assert_eq!((core.counters.frames, core.counters.frames_rejected), (c.frames + 1, 1));
    assert_eq!(core.gate().accepted, before);
}

/// The predictor's word on an empty sky: an empty sensor frame with nothing tracked makes the
/// due forecasts empty ones, to publish (`Some(0)`); an empty frame while a track is held says
/// nothing new (the track's forecasts go on); a track too young to forecast publishes nothing.
#[test]
fn an_empty_sky_is_forecast_and_a_young_track_is_not_hidden_behind_it() {
    let sc = scenario("sparse-slow", "constant-velocity");
    let mut core = PredictorCore::new(fit_models(&sc).unwrap(), &sc);
    let l = lim();
    let mut msg = Box::new(<DebrisForecast as Zeroed>::zeroed());
    let mut empty = <DebrisObservation as Zeroed>::zeroed();
    let mut published = Vec::new();
    for k in 1..=10u64 {
        empty.header.stamp_ns = k * 20_000_000;
        published.push(core.observe_then_forecast(&empty, &l, sc.predictor.rate_hz, &mut msg));
    }
    assert!(published.iter().all(|p| *p == Some(0)), "{published:?}");
    assert_eq!((msg.count, msg.t0_ns), (0, 200_000_000), "empty, stamped with the frames' clock");
    // The real-time shell forecasts every wake: an empty sky is said once per frame that saw
    // it, so a sensor that falls silent does not keep the sky empty.
    let n = core.forecast_into(&mut msg);
    assert!(n == 0 && !core.publishable(n), "no frame since the last empty forecast");
    empty.header.stamp_ns = 220_000_000;
    core.observe_frame(&empty, &l);
    let n = core.forecast_into(&mut msg);
    assert!(core.publishable(n) && !core.publishable(n), "once per frame");
    // One object seen: a young track (fewer observations than a forecast needs) publishes
    // nothing, even on an empty frame; once old enough, its forecasts.
    let mut side = DebrisSide::new(&sc, &dkrrt_model::ArmModel::default_arm()).unwrap();
    let mut frame = <DebrisObservation as Zeroed>::zeroed();
    let mut first: Option<DebrisObservation> = None;
    for _ in 0..40 {
        side.step(1e-3);
        side.drain_observations::<()>(&mut frame, |f| {
            first.get_or_insert(*f);
            Ok(())
        })
        .unwrap();
    }
    let mut one = first.expect("a frame in 40 ms");
    one.count = 1;
    one.header.stamp_ns = 300_000_000;
    one.items[0].t_meas_ns = 270_000_000;
    assert_eq!(core.observe_then_forecast(&one, &l, sc.predictor.rate_hz, &mut msg), None, "young");
    empty.header.stamp_ns = 400_000_000;
    assert_eq!(core.observe_then_forecast(&empty, &l, sc.predictor.rate_hz, &mut msg), None, "not empty");
    let mut n = None;
    for k in 1..=10u64 {
        one.header.stamp_ns = 300_000_000 + k * 20_000_000;
        one.items[0].t_meas_ns = 270_000_000 + k * 20_000_000;
        n = n.or(core.observe_then_forecast(&one, &l, sc.predictor.rate_hz, &mut msg));
    }
    assert_eq!(n, Some(1), "the track's forecast once it is old enough");
}

/// On the depth input the sky is empty when a whole capture (every frame with its stamp: a
/// rig's faces) labels no object; a capture with a label is not, even when the front end makes
/// no pose of it (a view not yet whole). A capture is whole once a frame of the next arrives.
#[test]
fn a_depth_capture_labelling_nothing_is_an_empty_sky_and_one_label_is_not() {
    let mut sc = scenario("sparse-slow", "constant-velocity");
    sc.predictor.input = "depth".into();
    let mut core = PredictorCore::new(fit_models(&sc).unwrap(), &sc);
    let l = lim();
    let mut msg = Box::new(<DebrisForecast as Zeroed>::zeroed());
    let mut img = Box::new(<dkrrt_msg::DepthImage as Zeroed>::zeroed());
    (img.width, img.height, img.focal_px, img.cx, img.cy) = (4, 4, 2.0, 2.0, 2.0);
    (img.orientation, img.range_min_m, img.range_max_m) = ([1.0, 0.0, 0.0, 0.0], 0.2, 15.0);
    assert!(img.validate(&l).is_ok());
    let rate = sc.predictor.rate_hz;
    let mut feed = |core: &mut PredictorCore, stamp_ms: u64, labels: u32| {
        img.header.stamp_ns = stamp_ms * 1_000_000;
        img.n_instances = labels;
        core.observe_depth_then_forecast(&img, &l, rate, &mut msg)
    };
    // Capture 0: two faces, nothing labelled; whole when capture 50's first face arrives.
    assert_eq!(feed(&mut core, 0, 0), None);
    assert_eq!(feed(&mut core, 0, 0), None);
    assert_eq!(feed(&mut core, 50, 0), Some(0), "capture 0 labelled nothing: an empty sky");
    // Capture 100: one face labels an object (no whole view of it): not an empty sky.
    assert_eq!(feed(&mut core, 100, 0), Some(0), "capture 50 labelled nothing either");
    assert_eq!(feed(&mut core, 100, 1), None);
    assert_eq!(feed(&mut core, 150, 0), None, "capture 100 labelled an object");
    assert_eq!(feed(&mut core, 200, 0), Some(0), "capture 150 labelled nothing");
}

/// Poses from depth frames are heavy-tailed: their tracks are forecast from the fifth pose,
/// the pose sensor's from the second; both hold the filter's own deviations in the bound.
#[test]
fn depth_tracks_wait_for_five_poses_and_pose_tracks_for_two() {
    let mut sc = scenario("dense", "deep-koopman-online");
    let poses = dkrrt_planner::predict::predictor_config(&sc);
    assert_eq!(poses.min_obs_for_forecast, 2);
    sc.predictor.input = "depth".into();
    let depth = dkrrt_planner::predict::predictor_config(&sc);
    assert_eq!(depth.min_obs_for_forecast, 5);
    assert_eq!(poses.track_sigmas, depth.track_sigmas);
    assert!(poses.track_sigmas > 3.0);
}

#[test]
fn a_track_that_lags_the_newest_is_read_past_its_own_horizon_as_the_planner_reads_it() {
    // One object goes unseen for its last 0.6 s: on the common grid (t0 = the newest track's
    // time) its forecast runs ~6 steps past its own horizon. There its bounds keep growing
    // (`ForecastBuffer::continued`), not frozen at its horizon's, and they hold the truth.
    let mut sc = scenario("sparse-slow", "dual-data");
    sc.debris.dropout = 0.0;
    let mut core = PredictorCore::new(fit_models(&sc).unwrap(), &sc);
    let mut side = DebrisSide::new(&sc, &dkrrt_model::ArmModel::default_arm()).unwrap();
    feed(&mut side, &mut core, 2400);
    let hidden = side.world().debris()[0].id;
    let mut frame = <DebrisObservation as Zeroed>::zeroed();
    let l = lim();
    for _ in 0..600 {
        side.step(1e-3);
        side.drain_observations::<()>(&mut frame, |f| {
            let mut g = *f;
            let kept: Vec<_> =
                f.items[..f.count as usize].iter().filter(|it| it.id != hidden).copied().collect();
            g.items[..kept.len()].copy_from_slice(&kept);
            g.count = kept.len() as u32;
            core.observe_frame(&g, &l);
            Ok(())
        })
        .unwrap();
    }
    let mut msg = Box::new(<DebrisForecast as Zeroed>::zeroed());
    let n = core.forecast_into(&mut msg);
    let tr = msg.tracks[..n].iter().find(|t| t.id == hidden).expect("the hidden track is still forecast");
    let (s, last) = (&tr.steps, msg.steps as usize - 1);
    // Past its own horizon (the last ~6 steps) each bound keeps growing.
    for k in last - 4..=last {
        assert!(s[k].sigma_pos_m > s[k - 1].sigma_pos_m, "step {k}: {:?} {:?}", s[k - 1], s[k]);
        assert!(s[k].sigma_m > s[k - 1].sigma_m, "step {k}");
    }
    // The truth at the last step is within the position bound.
    let t_end = msg.t0_ns as f64 * 1e-9 + msg.steps as f64 * msg.dt_s;
    let ticks = ((t_end - side.world().time()) * 1000.0).round() as usize;
    for _ in 0..ticks {
        side.step(1e-3);
        side.drain_observations::<()>(&mut frame, |_| Ok(())).unwrap();
    }
    let b = sc.debris.base_lvlh;
    let d = side.world().debris().iter().find(|d| d.id == hidden).unwrap();
    let p = s[last].p;
    let err = ((p[0] + b[0] - d.state.p.x).powi(2)
        + (p[1] + b[1] - d.state.p.y).powi(2)
        + (p[2] + b[2] - d.state.p.z).powi(2))
    .sqrt();
    assert!(err <= s[last].sigma_pos_m, "error {err} m, bound {} m", s[last].sigma_pos_m);
}

/// One frame stamped far ahead would, by its stamp alone, age every track out (and its
/// object's later poses would be refused as out of order): it is refused and counted, the
/// tracks and their forecasts go on; an item measured after its frame was sent is refused as
/// invalid. A clock that really jumped (a sensor back after an outage) is followed once
/// `STAMP_CONFIRM` frames in a row say so.
#[test]
fn a_frame_stamped_far_ahead_is_refused_and_loses_no_track() {
    use dkrrt_planner::predict::{FrameClock, STAMP_CONFIRM};
    let mut sc = scenario("sparse-slow", "constant-velocity");
    sc.debris.latency_jitter_s = 0.0;
    sc.debris.dropout = 0.0;
    let mut core = PredictorCore::new(fit_models(&sc).unwrap(), &sc);
    let mut side = DebrisSide::new(&sc, &dkrrt_model::ArmModel::default_arm()).unwrap();
    let mut last = <DebrisObservation as Zeroed>::zeroed();
    let l = lim();
    // `ms` of the sensor's frames, read (or, `read` false, lost: a gap).
    let mut run = |core: &mut PredictorCore, ms: usize, last: &mut DebrisObservation, read: bool| {
        let mut frame = <DebrisObservation as Zeroed>::zeroed();
        for _ in 0..ms {
            side.step(1e-3);
            side.drain_observations::<()>(&mut frame, |f| {
                if read {
                    core.observe_frame(f, &l);
                    *last = *f;
                }
                Ok(())
            })
            .unwrap();
        }
    };
    run(&mut core, 2000, &mut last, true);
    let tracks = core.predictor().n_tracks();
    assert!(tracks >= 4, "{tracks}");
    let before = core.counters;
    // One item of the last frame, frame and item stamped `ns` ahead.
    let ahead = |ns: u64| {
        let mut f = last;
        f.count = 1;
        f.header.stamp_ns += ns;
        f.items[0].t_meas_ns += ns;
        f
    };
    core.observe_frame(&ahead(1_000_000_000_000), &l);
    assert_eq!(core.counters.frames_ahead, 1);
    assert_eq!(core.counters.frames_rejected, before.frames_rejected + 1);
    assert_eq!(core.predictor().n_tracks(), tracks, "no track aged out at once");
    // 0.9 s ahead, within the track timeout: admitted, its object would be refused as out of
    // order for 0.9 s of real frames (and tracks not seen for 0.1 s aged out): refused too.
    assert!(core.stamp_lead_s() <= 0.25 && core.stamp_lead_s() >= 2.0 / sc.debris.sensor_rate_hz);
    core.observe_frame(&ahead(900_000_000), &l);
    assert_eq!(core.counters.frames_ahead, 2);
    assert_eq!(core.predictor().n_tracks(), tracks, "no track aged out");
    // An item measured after its frame was sent.
    let mut late = last;
    late.count = 1;
    late.items[0].t_meas_ns = late.header.stamp_ns + 1;
    core.observe_frame(&late, &l);
    assert_eq!(core.counters.items_invalid, before.items_invalid + 1);
    // The run goes on: every object still tracked, none refused as out of order.
    run(&mut core, 500, &mut last, true);
    assert_eq!(core.predictor().n_tracks(), tracks);
    assert_eq!((core.gate().out_of_order, core.gate().tracks_dropped), (0, 0), "{:?}", core.gate());
    let mut msg = Box::new(<DebrisForecast as Zeroed>::zeroed());
    assert_eq!(core.forecast_into(&mut msg), tracks);

    // The clock alone: behind or within the lead, admitted; far ahead, refused until
    // `STAMP_CONFIRM` frames in a row confirm the jump.
    let s = 1_000_000_000u64;
    let mut c = FrameClock::default();
    assert!([10 * s, 9 * s, 11 * s].iter().all(|&t| c.admit(t, s) == Some(0)));
    assert_eq!(c.admit(100 * s, s), None, "one frame 89 s ahead");
    assert_eq!(c.admit(11 * s + 20_000_000, s), Some(0), "the real clock goes on");
    for k in 0..STAMP_CONFIRM as u64 {
        let got = c.admit(50 * s + k * 20_000_000, s);
        let want = (k + 1 == STAMP_CONFIRM as u64).then_some(STAMP_CONFIRM - 1);
        assert_eq!(got, want, "frame {k} of a real jump");
    }
    assert_eq!(c.newest_ns(), Some(50 * s + (STAMP_CONFIRM as u64 - 1) * 20_000_000));
    // A jump "confirmed" by frames far apart from each other is not.
    let mut c = FrameClock::default();
    assert_eq!(c.admit(0, s), Some(0));
    assert!([10 * s, 20 * s, 30 * s].iter().all(|&t| c.admit(t, s).is_none()));

    // A sensor back after a gap of 2 s: its first frames are refused, then confirmed, and
    // counted as lost to the gap, not rejected.
    let (rejected, ahead) = (core.counters.frames_rejected, core.counters.frames_ahead);
    run(&mut core, 2000, &mut last, false);
    run(&mut core, 200, &mut last, true);
    assert_eq!(core.counters.frames_before_jump, (STAMP_CONFIRM - 1) as u64);
    assert_eq!((core.counters.frames_rejected, core.counters.frames_ahead), (rejected, ahead));
}

/// The first frame's stamp has nothing to be checked against: one stamped 1000 s ahead (with
/// its items) would have made every later frame look 1000 s old, its objects' poses refused
/// as out of order for 1000 s and the check of stamps ahead blind. The frames after it
/// outvote it (`STAMP_CONFIRM` in a row), the tracks it made are dropped, and the run goes on
/// as a clean one: the same objects tracked, nothing refused as out of order, forecasts on
/// the real clock. The clock alone: frames far behind are refused until confirmed; the faces
/// of one capture (one stamp) confirm nothing.
#[test]
fn a_first_frame_stamped_wrong_is_outvoted_by_the_frames_after_it() {
    use dkrrt_planner::predict::{FrameClock, STAMP_CONFIRM};
    let mut sc = scenario("sparse-slow", "constant-velocity");
    sc.debris.latency_jitter_s = 0.0;
    sc.debris.dropout = 0.0;
    let models = fit_models(&sc).unwrap();
    let l = lim();
    let run = |first_ahead_ns: u64| {
        let mut core = PredictorCore::new(models.clone(), &sc);
        let mut side = DebrisSide::new(&sc, &dkrrt_model::ArmModel::default_arm()).unwrap();
        let (mut frame, mut first, mut t) = (<DebrisObservation as Zeroed>::zeroed(), true, 0);
        for _ in 0..2000 {
            side.step(1e-3);
            side.drain_observations::<()>(&mut frame, |f| {
                let mut f = *f;
                if std::mem::take(&mut first) {
                    f.header.stamp_ns += first_ahead_ns;
                    f.items[..f.count as usize].iter_mut().for_each(|it| it.t_meas_ns += first_ahead_ns);
                }
                t = f.header.stamp_ns;
                core.observe_frame(&f, &l);
                Ok(())
            })
            .unwrap();
        }
        let mut msg = Box::new(<DebrisForecast as Zeroed>::zeroed());
        let n = core.forecast_into(&mut msg);
        (core, n, msg.t0_ns as i64 - t as i64)
    };
    let (clean, n_clean, _) = run(0);
    let (core, n, lag_ns) = run(1_000_000_000_000);
    assert!(n_clean >= 4 && n == n_clean, "{n} tracks forecast, {n_clean} in the clean run");
    let c = core.counters;
    assert_eq!((c.clock_jumps_back, c.frames_before_jump), (1, (STAMP_CONFIRM - 1) as u64), "{c:?}");
    assert_eq!((c.frames_rejected, c.frames_behind, c.frames_ahead), (0, 0, 0), "{c:?}");
    assert_eq!(core.gate().out_of_order, 0, "{:?}", core.gate());
    assert!(core.gate().tracks_dropped >= 1, "the first frame's tracks: {:?}", core.gate());
    assert!(lag_ns.abs() < 200_000_000, "forecast t0 {lag_ns} ns from the last frame");
    assert_eq!(clean.counters.clock_jumps_back, 0);

    let s = 1_000_000_000u64;
    let mut c = FrameClock::default();
    assert_eq!(c.admit(1000 * s, s), Some(0), "the first frame: nothing to check it against");
    assert_eq!(c.admit(2 * s, s), None, "998 s behind");
    assert_eq!(c.admit(2 * s, s), None, "a second frame of the same capture");
    assert_eq!(c.admit(2 * s, s), None, "and a third: still one stamp");
    assert_eq!(c.admit(2 * s + 50_000_000, s), None);
    assert_eq!(c.admit(2 * s + 100_000_000, s), Some(4), "three stamps in a row: 4 frames confirmed");
    assert_eq!(c.newest_ns(), Some(2 * s + 100_000_000));
    assert_eq!(c.admit(s + 200_000_000, s), Some(0), "within the lead behind: admitted");
    assert_eq!(c.admit(0, s), None, "one frame far behind");
    assert_eq!(c.admit(2 * s + 150_000_000, s), Some(0), "the real clock goes on");
}

/// A track whose object the frames stop showing is dropped at the track timeout even when no
/// other object is seen (the frames, not only the poses, move the predictor's clock): the pose
/// sensor's empty frames here; the depth input's frames go through the same
/// `PredictorCore::observe_items`.
#[test]
fn a_track_goes_at_the_timeout_when_nothing_at_all_is_seen_any_more() {
    let sc = scenario("sparse-slow", "constant-velocity");
    let mut core = PredictorCore::new(fit_models(&sc).unwrap(), &sc);
    let l = lim();
    let mut side = DebrisSide::new(&sc, &dkrrt_model::ArmModel::default_arm()).unwrap();
    let mut frame = <DebrisObservation as Zeroed>::zeroed();
    let mut last = frame;
    for _ in 0..1000 {
        side.step(1e-3);
        side.drain_observations::<()>(&mut frame, |f| {
            core.observe_frame(f, &l);
            last = *f;
            Ok(())
        })
        .unwrap();
    }
    let tracks = core.predictor().n_tracks();
    assert!(tracks >= 4, "{tracks}");
    // Then empty frames every 20 ms: the sky is empty from here.
    let mut empty = <DebrisObservation as Zeroed>::zeroed();
    let t_last = last.header.stamp_ns;
    let mut left = Vec::new();
    for k in 1..=100u64 {
        empty.header.stamp_ns = t_last + k * 20_000_000;
        core.observe_frame(&empty, &l);
        left.push((k as f64 * 0.02, core.predictor().n_tracks()));
    }
    // The poses were measured up to the sensor's latency (30–40 ms) before the last frame.
    let gone = left.iter().find(|x| x.1 == 0).map(|x| x.0);
    assert!(gone.is_some_and(|g| (0.9..1.05).contains(&g)), "all gone after {gone:?} s: {left:?}");
    assert!(left.iter().filter(|x| x.0 < 0.9).all(|x| x.1 == tracks), "none before the timeout");
    let mut msg = Box::new(<DebrisForecast as Zeroed>::zeroed());
    let n = core.forecast_into(&mut msg);
    assert!(n == 0 && core.publishable(n), "an empty forecast, to publish: the sky is empty");
}
