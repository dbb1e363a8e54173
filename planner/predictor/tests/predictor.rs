//! Behaviour of the online predictor: gating, convergence, events, track table.

mod common;

use common::{fitted, free_rods, obs};
use dkrrt_debris::{DebrisWorld, ObsBuffer, Sensor, SensorConfig};
use dkrrt_predictor::eval::record;
use dkrrt_predictor::filter::quat_angle;
use dkrrt_predictor::{
    DebrisPredictor, ForecastBuffer, Method, Models, ObserveOutcome, PredictorConfig, RejectReason,
    MAX_TRACKS,
};

fn cv_predictor() -> DebrisPredictor {
    DebrisPredictor::new(Models::constant_velocity(0.1, 40, 0.0, 0.05, 0.05), PredictorConfig::default())
}

/// Straight-line object at 0.2 m/s spinning at 0.5 rad/s about z.
fn pose(t: f64) -> ([f64; 3], [f64; 4]) {
    let a = 0.25 * t; // half angle
    ([1.0 + 0.2 * t, 2.0, -0.5], [a.cos(), 0.0, 0.0, a.sin()])
}

#[test]
fn gating_rejects_and_counts_invalid_jumps_and_out_of_order() {
    let mut pr = cv_predictor();
    let dt = 0.02;
    for k in 0..50 {
        let (p, q) = pose(k as f64 * dt);
        let r = pr.observe(&obs(3, k as f64 * dt, p, q));
        assert_eq!(r, if k == 0 { ObserveOutcome::NewTrack } else { ObserveOutcome::Accepted });
    }
    let t = 50.0 * dt;
    let (p, q) = pose(t);
    // NaN / Inf / degenerate quaternion.
    let mut bad = obs(3, t, p, q);
    bad.p[1] = f64::NAN;
    assert_eq!(pr.observe(&bad), ObserveOutcome::Rejected(RejectReason::Invalid));
    bad = obs(3, t, p, q);
    bad.q[0] = f64::INFINITY;
    assert_eq!(pr.observe(&bad), ObserveOutcome::Rejected(RejectReason::Invalid));
    assert_eq!(pr.observe(&obs(3, f64::NAN, p, q)), ObserveOutcome::Rejected(RejectReason::Invalid));
    assert_eq!(pr.observe(&obs(3, t, p, [0.0; 4])), ObserveOutcome::Rejected(RejectReason::Invalid));
    // Rates are checked when the observation carries them.
    bad = obs(3, t, p, q);
    bad.has_rates = true;
    bad.w[2] = f64::NAN;
    assert_eq!(pr.observe(&bad), ObserveOutcome::Rejected(RejectReason::Invalid));
    // Position jump: 1 m in 20 ms = 50 m/s > 5 m/s.
    assert_eq!(
        pr.observe(&obs(3, t, [p[0] + 1.0, p[1], p[2]], q)),
        ObserveOutcome::Rejected(RejectReason::PositionJump)
    );
    // Attitude jump: 90° about x in 20 ms ≈ 78 rad/s > 15 rad/s.
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let qj = dkrrt_koopman::debris_state::quat_mul(&q, &[h, h, 0.0, 0.0]);
    assert_eq!(pr.observe(&obs(3, t, p, qj)), ObserveOutcome::Rejected(RejectReason::AttitudeJump));
    // Sign-flipped quaternion is the same attitude: accepted.
    let qn = [-q[0], -q[1], -q[2], -q[3]];
    assert_eq!(pr.observe(&obs(3, t, p, qn)), ObserveOutcome::Accepted);
    // Out of order and duplicate timestamps.
    let (p0, q0) = pose(t - 0.1);
    assert_eq!(pr.observe(&obs(3, t - 0.1, p0, q0)), ObserveOutcome::Rejected(RejectReason::OutOfOrder));
    assert_eq!(pr.observe(&obs(3, t, p, q)), ObserveOutcome::Rejected(RejectReason::OutOfOrder));
    let s = *pr.stats();
    assert_eq!((s.invalid, s.pos_jump, s.att_jump, s.out_of_order), (5, 1, 1, 2));
    assert_eq!(s.accepted, 51);
    // The rejected samples did not corrupt the estimate.
    let tr = pr.track(3).unwrap();
    assert!((0..3).all(|i| (tr.state[i] - p[i]).abs() < 1e-4), "{:?}", tr.state);
    assert!((tr.state[3] - 0.2).abs() < 1e-3 && (tr.state[12] - 0.5).abs() < 1e-3, "{:?}", tr.state);
    assert!(quat_angle(&tr.state[6..10], &q) < 1e-4);
}

#[test]
fn repeated_jumps_reinitialise_the_track() {
    let mut pr = cv_predictor();
    let cfg = *pr.config();
    for k in 0..20 {
        let (p, q) = pose(k as f64 * 0.02);
        pr.observe(&obs(1, k as f64 * 0.02, p, q));
    }
    // The object is really somewhere else now (e.g. re-identified): after
    // `reinit_after_rejects` consecutive jump rejections the track restarts there.
    let mut last = ObserveOutcome::Accepted;
    for j in 0..cfg.reinit_after_rejects {
        let t = 0.4 + 0.02 * (j + 1) as f64;
        last = pr.observe(&obs(1, t, [10.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]));
        if j + 1 < cfg.reinit_after_rejects {
            assert_eq!(last, ObserveOutcome::Rejected(RejectReason::PositionJump));
        }
    }
    assert_eq!(last, ObserveOutcome::NewTrack);
    assert_eq!(pr.stats().reinit, 1);
    assert_eq!(pr.track(1).unwrap().state[0], 10.0);
}

#[test]
fn free_tumbling_forecast_converges_as_observations_accumulate() {
    for method in [Method::ConstantVelocity, Method::KoopmanOnline] {
        let models = if method == Method::ConstantVelocity {
            Models::constant_velocity(0.1, 40, 1.1314e-3, 0.05, 0.05)
        } else {
            fitted(method)
        };
        let rec = record(&free_rods(7), SensorConfig::default(), 8.0, 0.01, 7).unwrap();
        let mut pr = DebrisPredictor::new(models, PredictorConfig::default());
        let mut buf = ForecastBuffer::for_predictor(&pr);
        let mut errs = Vec::new();
        // Forecast every 0.5 s; mean combined error (m + rad) over all 8 objects.
        for step in 1..=12 {
            let t = 0.1 + 0.5 * (step - 1) as f64;
            let mut sum = 0.0;
            let mut n = 0;
            for o in rec.obs.iter().filter(|o| o.t <= t + 1e-9 && o.t > t - 0.5 + 1e-9) {
                pr.observe(o);
            }
            pr.forecast(&mut buf);
            for id in 0..8 {
                if let Some(i) = buf.index_of(id) {
                    let truth = rec.truth.at(id, buf.t0(i) + 1.0).unwrap();
                    let x = buf.state(i, 10);
                    sum += (0..3).map(|j| (x[j] - truth[j]).powi(2)).sum::<f64>().sqrt()
                        + quat_angle(&x[6..10], &truth[6..10]);
                    n += 1;
                }
            }
            assert!(n == 8, "all 8 objects forecast at t = {t}");
            errs.push(sum / n as f64);
        }
        let early = errs[0];
        let late = errs[6..].iter().sum::<f64>() / 6.0;
        eprintln!(
            "{method:?}: 1 s error after 0.1 s of data {early:.3}, after 3–5.6 s {late:.3}; all {errs:.3?}"
        );
        assert!(late < 0.5 * early, "{method:?}: {errs:?}");
        assert!(errs.iter().all(|e| e.is_finite()));
    }
}

#[test]
fn impulse_event_grows_bound_and_forecasts_stay_finite() {
    let mut med = Vec::new();
    for method in [Method::ConstantVelocity, Method::EdmdPoly, Method::KoopmanOnline, Method::DualData] {
        let models = if method == Method::ConstantVelocity {
            Models::constant_velocity(0.1, 40, 1.1314e-3, 0.05, 0.05)
        } else {
            fitted(method)
        };
        med.push(impulse_case(method, models));
    }
    // The fixed EDMD translational model (fitted on filtered estimates at cm/s) extrapolates
    // badly to a 1 m/s object; the dual-data model (ridge towards the nominal CW generator)
    // does not. (The translational RLS is deliberately slow, p0 = 1e-5: faster settings
    // repair this case but cost accuracy on dense / fast-crossing — see README.)
    assert!(med[3] < 0.2 * med[1], "dual-data {} vs fixed {}", med[3], med[1]);
    assert!(med[2] <= 1.05 * med[1], "online {} vs fixed {}", med[2], med[1]);
    // The baseline's straight line is exact for a translating object: centimetres.
    assert!(med[0] < 0.05, "{med:?}");
}

/// Median 1 s position error of the hit object 3–6 s after the impulse.
fn impulse_case(method: Method, models: Models) -> f64 {
    let mut world = DebrisWorld::new(&free_rods(9)).unwrap();
    let mut sensor = Sensor::new(SensorConfig::default(), 9).unwrap();
    let mut pr = DebrisPredictor::new(models, PredictorConfig::default());
    let mut buf = ForecastBuffer::for_predictor(&pr);
    let mut obs_buf = ObsBuffer::new();
    let id = 2u32;
    let (mut r_before, mut a_before, mut events_before) = (0.0, 0.0, 0);
    let mut post_err = Vec::new();
    let mut pending: Vec<(f64, [f64; 3])> = Vec::new();
    for k in 1..=1200 {
        world.step(0.01);
        let t = world.time();
        if k == 600 {
            // t = 6 s: a hard hit: Δv = 1 m/s, Δω = 3 rad/s.
            let tr = pr.track(id).unwrap();
            r_before = tr.pos_radius[1];
            a_before = tr.att_radius[1];
            events_before = tr.events;
            assert!(world.apply_impulse(id, [1.0, 0.0, 0.0].into(), [3.0, 0.0, 0.0].into()));
        }
        obs_buf.clear();
        sensor.poll(t, world.debris(), &mut obs_buf);
        for o in obs_buf.as_slice() {
            pr.observe(o);
        }
        if k % 10 == 0 {
            pr.forecast(&mut buf);
            for i in 0..buf.len() {
                assert!(buf.states(i).iter().all(|v| v.is_finite()), "non-finite forecast at t = {t}");
            }
            if let Some(i) = buf.index_of(id) {
                pending
                    .push((buf.t0(i) + 1.0, [buf.state(i, 10)[0], buf.state(i, 10)[1], buf.state(i, 10)[2]]));
            }
        }
        let d = world.debris().iter().find(|d| d.id == id).unwrap();
        pending.retain(|(tt, p)| {
            if (tt - t).abs() < 0.005 {
                if t > 9.0 {
                    post_err.push(((p[0] - d.state.p.x).powi(2) + (p[1] - d.state.p.y).powi(2)).sqrt());
                }
                false
            } else {
                *tt > t
            }
        });
        if k == 620 {
            let tr = pr.track(id).unwrap();
            eprintln!(
                "{method:?}: events {} → {}, H-step radius {:.3} → {:.3} m, {:.3} → {:.3} rad",
                events_before, tr.events, r_before, tr.pos_radius[1], a_before, tr.att_radius[1]
            );
            assert!(tr.events > events_before, "impulse not detected");
            assert!(tr.att_radius[1] > a_before + 0.1, "attitude bound did not grow");
            assert!(
                tr.pos_radius[1] > r_before + 0.05 || method == Method::ConstantVelocity,
                "position bound did not grow"
            );
        }
    }
    let tr = pr.track(id).unwrap();
    assert!(tr.state.iter().all(|v| v.is_finite()));
    // The filter re-converged: the estimated velocity includes the 1 m/s hit.
    assert!(tr.state[3] > 0.8, "vx = {}", tr.state[3]);
    post_err.sort_by(f64::total_cmp);
    let med = post_err[post_err.len() / 2];
    eprintln!(
        "{method:?}: median 1 s position error 3–6 s after the impulse: {med:.4} m (n = {})",
        post_err.len()
    );
    assert!(pr.stats().events >= 1);
    med
}

#[test]
fn tracks_time_out_and_slots_are_reused() {
    let mut pr = cv_predictor();
    let q = [1.0, 0.0, 0.0, 0.0];
    for id in 0..MAX_TRACKS as u32 {
        assert_eq!(pr.observe(&obs(id, 0.0, [id as f64, 0.0, 0.0], q)), ObserveOutcome::NewTrack);
    }
    assert_eq!(pr.n_tracks(), MAX_TRACKS);
    assert_eq!(pr.observe(&obs(99, 0.0, [0.0; 3], q)), ObserveOutcome::Rejected(RejectReason::TableFull));
    assert_eq!(pr.stats().table_full, 1);
    let slot5 = pr.slot_of(5).unwrap();
    // Everybody but id 5 keeps reporting for 1.5 s (timeout 1 s).
    for k in 1..=75 {
        let t = k as f64 * 0.02;
        for id in (0..MAX_TRACKS as u32).filter(|&i| i != 5) {
            assert_eq!(pr.observe(&obs(id, t, [id as f64, 0.0, 0.0], q)), ObserveOutcome::Accepted);
        }
    }
    assert!(pr.track(5).is_none(), "id 5 should have been dropped");
    assert_eq!(pr.stats().tracks_dropped, 1);
    assert_eq!(pr.n_tracks(), MAX_TRACKS - 1);
    assert_eq!(pr.observe(&obs(99, 1.6, [0.0; 3], q)), ObserveOutcome::NewTrack);
    assert_eq!(pr.slot_of(99), Some(slot5));
    // Id 5 coming back finds the table full again.
    assert_eq!(
        pr.observe(&obs(5, 1.6, [5.0, 0.0, 0.0], q)),
        ObserveOutcome::Rejected(RejectReason::TableFull)
    );
    // Explicit prune from a planner clock drops everything that went silent.
    assert_eq!(pr.prune(10.0), MAX_TRACKS);
    assert_eq!(pr.n_tracks(), 0);
}

#[test]
fn published_bounds_are_calibrated_online_and_monotone() {
    // An object on a straight line spinning steadily: the constant-velocity model is exact, so
    // once the track has scored its own forecasts the bound of the first steps shrinks to the
    // floors (far below the fitted 0.05 m / 0.05 rad); beyond the calibrated steps the fitted
    // bound holds, never below the last calibrated one.
    let mut pr = cv_predictor();
    let cfg = *pr.config();
    let mut buf = ForecastBuffer::for_predictor(&pr);
    let dt = 0.02;
    let mut young = None;
    for k in 0..400 {
        let t = k as f64 * dt;
        let (p, q) = pose(t);
        pr.observe(&obs(3, t, p, q));
        // Forecast at 50 Hz, as the predictor process does.
        if pr.forecast(&mut buf) == 0 {
            continue;
        }
        young.get_or_insert(buf.pos_radius(0, 1));
    }
    let (floor, factor) = (cfg.calib_floor, cfg.calib_factor);
    let young = young.unwrap();
    // A young track (forecast from its second pose, `min_obs_for_forecast`): the fitted bound
    // and the filter's own deviation over its two poses added in quadrature
    // (`PredictorConfig::track_sigmas`: 0.1 s ahead of poses 20 ms apart, 0.22 m).
    assert!(young > 0.15 && young < 0.3, "young track: the fitted bound and more ({young})");
    let p1 = buf.pos_radius(0, 1);
    assert!(p1 < 0.02 && p1 >= floor[0], "calibrated: {p1}");
    assert!(buf.att_radius(0, 1) < 0.03 && buf.att_radius(0, 1) >= floor[1]);
    for k in 2..=buf.horizon() {
        assert!(buf.pos_radius(0, k) >= buf.pos_radius(0, k - 1) - 1e-12, "monotone at {k}");
        assert!(buf.att_radius(0, k) >= buf.att_radius(0, k - 1) - 1e-12, "monotone at {k}");
    }
    assert!((buf.pos_radius(0, cfg.calib_steps + 1) - 0.05).abs() < 1e-9, "fitted beyond");
    assert!(factor > 1.0);
}

#[test]
fn a_calibrated_bound_is_never_below_the_event_allowance() {
    // The object of `published_bounds_are_calibrated_online_and_monotone`, with models whose
    // training forecasts all had an event from step 3 on (errors 0.03 m / 0.04 rad): the
    // allowance is 1.5 × those from step 3, and the calibrated bound of the first steps may not
    // go below it, though the object itself never shows an event.
    use dkrrt_predictor::events::{EventAllowance, Sample};
    let errs: Vec<[f64; 40]> =
        (0..50).map(|_| std::array::from_fn(|k| if k >= 2 { 0.03 } else { 0.0 })).collect();
    let atts: Vec<[f64; 40]> =
        (0..50).map(|_| std::array::from_fn(|k| if k >= 2 { 0.04 } else { 0.0 })).collect();
    let samples = errs.iter().zip(&atts).map(|(p, a)| Sample { first_event: Some(3), pos: p, att: a });
    let mut models = Models::constant_velocity(0.1, 40, 0.0, 0.05, 0.05);
    models.events = EventAllowance::fit(samples, 40, 0.005, 1.5);
    assert!((models.events.pos(3) - 0.045).abs() < 1e-12 && models.events.pos(2) == 0.0);
    let mut pr = DebrisPredictor::new(models.clone(), PredictorConfig::default());
    let mut buf = ForecastBuffer::for_predictor(&pr);
    for k in 0..400 {
        let t = k as f64 * 0.02;
        let (p, q) = pose(t);
        pr.observe(&obs(3, t, p, q));
        pr.forecast(&mut buf);
    }
    let cw = pr.config().calib_steps;
    assert!(buf.pos_radius(0, 1) < 0.02 && buf.att_radius(0, 1) < 0.03, "calibrated where no event falls");
    for k in 3..=cw {
        assert!(buf.pos_radius(0, k) >= models.events.pos(k) - 1e-12, "step {k}: {}", buf.pos_radius(0, k));
        assert!(buf.att_radius(0, k) >= models.events.att(k) - 1e-12, "step {k}: {}", buf.att_radius(0, k));
    }
}

#[test]
fn boxes_get_the_torque_free_attitude_beyond_the_calibrated_window() {
    // Tumbling boxes and panels (ids 2, 3, 5, 7) and rods; observed for 5.9 s, checked 4 s
    // later (before the scene's first event at 10 s).
    let scene = dkrrt_predictor::eval::perturbed_scene("tumbling-rods", 11, 1.0).unwrap();
    let rec = record(&scene, SensorConfig::default(), 10.0, 0.01, 5).unwrap();
    // Constant rate with an honest attitude bound (a tumbler can be anywhere by 4 s).
    let models = Models::constant_velocity(0.1, 40, rec.mean_motion, 0.05, 3.0);
    let run = |with_shapes: bool| {
        // The channels on, with the constant-rate model (which alone would not use them).
        let cfg = PredictorConfig { attitude_physics: Some(true), ..PredictorConfig::default() };
        let mut pr = DebrisPredictor::new(models.clone(), cfg);
        let mut buf = ForecastBuffer::for_predictor(&pr);
        for o in rec.obs.iter().filter(|o| o.t <= 5.9) {
            pr.observe(o);
            if with_shapes {
                for (id, shape, _) in &rec.shapes {
                    pr.set_shape(*id, shape);
                }
            }
        }
        pr.forecast(&mut buf);
        buf
    };
    let (plain, shaped) = (run(false), run(true));
    let cw = PredictorConfig::default().calib_steps;
    let mut boxes = 0;
    for (id, shape, _) in &rec.shapes {
        let (Some(i), Some(j)) = (plain.index_of(*id), shaped.index_of(*id)) else { continue };
        let is_box = dkrrt_predictor::euler::inertia_hint(shape).is_some();
        for k in 1..=40 {
            // Within the model's calibrated window and for other shapes: the model's forecast.
            if !is_box || k <= cw {
                let x = shaped.state(j, k);
                assert_eq!(shaped.attitude(j, k), [x[6], x[7], x[8], x[9]], "id {id} step {k}");
                assert_eq!(shaped.attitude_radius(j, k), shaped.att_radius(j, k), "id {id} step {k}");
            }
        }
        if !is_box {
            continue;
        }
        boxes += 1;
        let truth = rec.truth.at(*id, shaped.t0(j) + 4.0).unwrap();
        let e_model = quat_angle(&plain.state(i, 40)[6..10], &truth[6..10]);
        let e_euler = quat_angle(&shaped.attitude(j, 40), &truth[6..10]);
        assert!(e_euler <= shaped.attitude_radius(j, 40), "id {id}: {e_euler} outside its bound");
        assert!(
            shaped.attitude_radius(j, 40) < 0.5 * plain.att_radius(i, 40),
            "id {id}: bound {} vs the model's {}",
            shaped.attitude_radius(j, 40),
            plain.att_radius(i, 40)
        );
        assert!(
            e_euler < 0.1 && e_euler < e_model,
            "id {id}: torque-free {e_euler} vs constant rate {e_model}"
        );
    }
    assert_eq!(boxes, 4, "two boxes and two panels");
}

#[test]
fn the_baselines_forecast_attitude_with_their_model_alone() {
    // Constant rate (cv-rrt's forecasts): no torque-free box attitude, no precessing rod axis,
    // whatever the shapes; an online Koopman method gets them.
    let scene = dkrrt_predictor::eval::perturbed_scene("tumbling-rods", 12, 1.0).unwrap();
    let rec = record(&scene, SensorConfig::default(), 6.0, 0.01, 6).unwrap();
    let models = Models::constant_velocity(0.1, 40, rec.mean_motion, 0.05, 3.0);
    let mut pr = DebrisPredictor::new(models, PredictorConfig::default());
    assert!(!pr.attitude_physics());
    let mut buf = ForecastBuffer::for_predictor(&pr);
    for o in rec.obs.iter().filter(|o| o.t <= 5.9) {
        pr.observe(o);
        for (id, shape, _) in &rec.shapes {
            pr.set_shape(*id, shape);
        }
    }
    let n = pr.forecast(&mut buf);
    assert!(n >= 4);
    for j in 0..n {
        for k in 1..=40 {
            let x = buf.state(j, k);
            let q = [x[6], x[7], x[8], x[9]];
            assert_eq!(buf.attitude(j, k), q);
            assert_eq!(buf.attitude_radius(j, k), buf.att_radius(j, k));
            assert_eq!(buf.axis_radius(j, k), buf.att_radius(j, k));
            // The axis is the model attitude's body z axis.
            let z = dkrrt_collision::pose::quat_rotate(&q, &[0.0, 0.0, 1.0]);
            assert!((0..3).all(|i| (buf.axis(j, k)[i] - z[i]).abs() < 1e-12));
        }
    }
    assert!(Method::DeepKoopmanOnline.attitude_physics() && !Method::EdmdPoly.attitude_physics());
}

#[test]
fn a_forecast_nobody_reads_can_be_left_to_its_calibration() {
    // Two predictors read the same tumbling-rods observations (its impulse included) with
    // their shapes: one builds every forecast (as the predictor process, at
    // 50 Hz), the other only every fifth and does the rest for their calibration alone (as
    // the in-process lockstep between planner cycles). Every forecast the second builds is
    // the first's at that time, bit for bit: it went on exactly as if it had built them all.
    let scene = dkrrt_predictor::eval::perturbed_scene("tumbling-rods", 11, 1.0).unwrap();
    let rec = record(&scene, SensorConfig::default(), 14.0, 0.01, 5).unwrap();
    let models = fitted(Method::KoopmanOnline);
    let cfg = PredictorConfig { attitude_physics: Some(true), ..PredictorConfig::default() };
    let (mut full, mut lazy) = (DebrisPredictor::new(models.clone(), cfg), DebrisPredictor::new(models, cfg));
    let (mut a, mut b) = (ForecastBuffer::for_predictor(&full), ForecastBuffer::for_predictor(&lazy));
    let (mut due, mut built, mut i) = (0, 0, 0);
    while i < rec.obs.len() {
        // One sensor frame: the observations of one time.
        let t = rec.obs[i].t;
        while i < rec.obs.len() && rec.obs[i].t == t {
            full.observe(&rec.obs[i]);
            lazy.observe(&rec.obs[i]);
            i += 1;
        }
        for (id, shape, _) in &rec.shapes {
            full.set_shape(*id, shape);
            lazy.set_shape(*id, shape);
        }
        let n = full.forecast(&mut a);
        if n == 0 {
            continue;
        }
        due += 1;
        if due % 5 != 0 {
            assert_eq!(lazy.forecast_for_calibration(&mut b), n, "the tracks it would have written");
            assert_eq!(b.len(), 0, "nothing for a reader");
            continue;
        }
        assert_eq!(lazy.forecast(&mut b), n);
        built += 1;
        for j in 0..n {
            assert_eq!((a.id(j), a.t0(j)), (b.id(j), b.t0(j)));
            for k in 1..=a.horizon() {
                let same = a.state(j, k) == b.state(j, k)
                    && a.attitude(j, k) == b.attitude(j, k)
                    && a.attitude_radius(j, k) == b.attitude_radius(j, k)
                    && a.pos_radius(j, k) == b.pos_radius(j, k)
                    && a.axis(j, k) == b.axis(j, k)
                    && a.axis_radius(j, k) == b.axis_radius(j, k);
                assert!(same, "t = {t}: track {} step {k} differs", a.id(j));
            }
        }
    }
    // The impulse was seen (a manoeuvre of the translation filter).
    let st = lazy.stats();
    assert!(built > 100 && st.events + st.maneuvers > 0, "{built} forecasts built, {st:?}");
    assert_eq!((full.stats().events, full.stats().maneuvers), (st.events, st.maneuvers));
}

/// A partial view (`Observation::partial`: an object cut by a camera's frame) moves the
/// position estimate only loosely (its noise is `partial_sigma_per_m` of the object's size),
/// leaves the attitude to the prediction (a 90° turn in it is neither gated nor taken) and
/// trips no manoeuvre; the same pose seen whole pulls the estimate most of the way. A rod's
/// or a disc's partial view that shows its axis (flagged `axis_only`) measures that axis.
#[test]
fn a_partial_view_moves_the_position_loosely_and_leaves_the_attitude() {
    let run = |partial: bool| {
        let mut pr = cv_predictor();
        let dt = 0.05;
        let q0 = [1.0, 0.0, 0.0, 0.0];
        for k in 0..40 {
            pr.observe(&obs(4, k as f64 * dt, [2.0, 0.0, 0.0], q0));
            // A 1.8 × 0.2 × 0.2 m bar (bounding radius ≈ 0.91 m).
            pr.set_shape(4, &dkrrt_msg::DebrisShape::cuboid([0.9, 0.1, 0.1], [0.0; 3]));
        }
        let t = 40.0 * dt;
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let mut o = obs(4, t, [2.2, 0.0, 0.0], if partial { [h, h, 0.0, 0.0] } else { q0 });
        o.partial = partial;
        assert_eq!(pr.observe(&o), ObserveOutcome::Accepted);
        let tr = pr.track(4).unwrap();
        (tr.state[0] - 2.0, quat_angle(&tr.state[6..10], &q0), pr.stats().partial, pr.stats().maneuvers)
    };
    let (moved_whole, _, n_whole, _) = run(false);
    let (moved_partial, turned, n_partial, manoeuvres) = run(true);
    assert!(moved_whole > 0.1, "a whole view pulls: {moved_whole}");
    // σ = 0.3 × 1 m against the filter's few millimetres: the partial view barely moves it.
    assert!(moved_partial > 0.0 && moved_partial < 0.01, "a partial view pulls loosely: {moved_partial}");
    assert!(turned < 1e-9, "the attitude is not measured: turned {turned}");
    assert_eq!((n_whole, n_partial, manoeuvres), (0, 1, 0));
    // A rod or a disc: the axis of its partial view, tilted 0.1 rad, pulls the attitude when
    // the view says it shows it (`axis_only`), and not otherwise.
    for shape in [dkrrt_msg::DebrisShape::capsule(0.9, 0.1), dkrrt_msg::DebrisShape::disc(0.9, 0.01)] {
        for shows_axis in [true, false] {
            let mut pr = cv_predictor();
            let q0 = [1.0, 0.0, 0.0, 0.0];
            for k in 0..40 {
                pr.observe(&obs(4, k as f64 * 0.05, [2.0, 0.0, 0.0], q0));
                pr.set_shape(4, &shape);
            }
            let tilt = [0.05f64.cos(), 0.05f64.sin(), 0.0, 0.0];
            let mut o = obs(4, 2.0, [2.0, 0.0, 0.0], tilt);
            o.partial = true;
            o.axis_only = shows_axis;
            assert_eq!(pr.observe(&o), ObserveOutcome::Accepted);
            let turned = quat_angle(&pr.track(4).unwrap().state[6..10], &q0);
            if shows_axis {
                assert!(
                    turned > 0.02 && turned <= 0.1 + 1e-9,
                    "{shape:?}: the axis is measured: turned {turned}"
                );
            } else {
                assert!(turned < 1e-9, "{shape:?}: no axis shown, none measured: turned {turned}");
            }
        }
    }
}

/// A sensor that sees only the shape (a depth camera's front end) reports a box's attitude up
/// to its half turns, and which one can change from frame to frame. Told the shape, the
/// predictor takes each report as the equivalent attitude nearest to its prediction: every
/// report is accepted and the estimate follows the truth. Not told (or for a shape without
/// that symmetry), the turned reports are impossible jumps and are rejected.
#[test]
fn a_box_reported_up_to_its_half_turns_is_tracked_through_them() {
    use dkrrt_koopman::debris_state::quat_mul;
    let half = [[0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]];
    let run = |shape: Option<dkrrt_msg::DebrisShape>| {
        let mut pr = cv_predictor();
        let dt = 0.05;
        let mut worst = 0.0f64;
        for k in 0..120 {
            let t = k as f64 * dt;
            let (p, q) = pose(t);
            // Every third report turned by half about one of the body axes.
            let reported = if k % 3 == 2 { quat_mul(&q, &half[(k / 3) % 3]) } else { q };
            pr.observe(&obs(6, t, p, reported));
            if let Some(s) = &shape {
                pr.set_shape(6, s);
            }
            if k > 20 {
                worst = worst.max(quat_angle(&pr.track(6).unwrap().state[6..10], &q));
            }
        }
        (pr.stats().att_jump, worst)
    };
    let (jumps, worst) = run(Some(dkrrt_msg::DebrisShape::cuboid([0.6, 0.15, 0.05], [0.0; 3])));
    assert_eq!(jumps, 0);
    assert!(worst < 0.01, "the estimate follows the truth: {worst} rad");
    let (jumps_plain, _) = run(None);
    assert!(jumps_plain >= 30, "without the shape the turned reports are jumps: {jumps_plain}");
    // An off-centre box has no such symmetry.
    let (jumps_off, _) = run(Some(dkrrt_msg::DebrisShape::cuboid([0.6, 0.15, 0.05], [0.2, 0.0, 0.0])));
    assert_eq!(jumps_off, jumps_plain);
}

/// A pose flagged as a restart (`Observation::restart`: the front end saw the object larger
/// than ever before, so the earlier views showed part of it and their centres were off) sets
/// the position from itself: no event, no manoeuvre, no velocity from the jump, the position
/// bound not grown. The same jump unflagged is taken for a change of motion.
#[test]
fn a_restart_sets_the_position_without_an_event() {
    let run = |restart: bool| {
        let mut pr = cv_predictor();
        let dt = 0.05;
        let q0 = [1.0, 0.0, 0.0, 0.0];
        for k in 0..60 {
            pr.observe(&obs(4, k as f64 * dt, [2.0, 0.0, 0.0], q0));
        }
        // 0.25 m on, within the gate (5 m/s × 0.05 s + 0.05 m), and there it stays.
        for k in 60..70 {
            let mut o = obs(4, k as f64 * dt, [2.25, 0.0, 0.0], q0);
            o.restart = restart && k == 60;
            assert_ne!(pr.observe(&o), ObserveOutcome::Rejected(RejectReason::PositionJump));
        }
        let mut buf = ForecastBuffer::for_predictor(&pr);
        pr.forecast(&mut buf);
        let tr = pr.track(4).unwrap();
        let s = pr.stats();
        (tr.state[0], tr.state[3], s.events + s.maneuvers, s.restarts, buf.pos_radius(0, 10))
    };
    let (x, v, changes, restarts, bound) = run(true);
    assert!((x - 2.25).abs() < 0.01, "the position from the restart: {x}");
    assert!(v.abs() < 0.05, "no velocity from the jump: {v}");
    assert_eq!((changes, restarts), (0, 1));
    let (_, v_plain, changes_plain, restarts_plain, bound_plain) = run(false);
    assert_eq!(restarts_plain, 0);
    assert!(changes_plain > 0, "unflagged, the jump is a change of motion");
    assert!(bound_plain > bound, "and grows the bound: {bound_plain} vs {bound}");
    assert!(v_plain.abs() > v.abs(), "{v_plain} vs {v}");
}

/// Partial views (`Observation::partial`) move with the part in view, not with the object:
/// however far their centres jump, they trip no manoeuvre and no event.
#[test]
fn partial_views_trip_no_manoeuvre_and_no_event() {
    let mut pr = cv_predictor();
    let dt = 0.05;
    let q0 = [1.0, 0.0, 0.0, 0.0];
    for k in 0..60 {
        pr.observe(&obs(4, k as f64 * dt, [2.0, 0.0, 0.0], q0));
        pr.set_shape(4, &dkrrt_msg::DebrisShape::sphere(0.1));
    }
    // ±0.12 m: four deviations of the pose noise a partial view of a 0.1 m ball is given.
    for k in 60..80 {
        let y = if k % 2 == 0 { 0.12 } else { -0.12 };
        let mut o = obs(4, k as f64 * dt, [2.0, y, 0.0], q0);
        o.partial = true;
        assert_eq!(pr.observe(&o), ObserveOutcome::Accepted);
    }
    let s = pr.stats();
    assert_eq!((s.partial, s.maneuvers, s.events), (20, 0, 0));
    assert!(pr.track(4).unwrap().state[1].abs() < 0.05);
}

/// A rod's report that measures its axis alone (`Observation::axis_only`, the depth front
/// end's `DEBRIS_AXIS_ONLY`): its spin about the axis is anything (a front end's bookkeeping
/// drifts as the axis turns) and its axis's sign too. The predictor takes the axis onto its
/// own spin and gates on the angle between axes: no jump, and the axis follows the truth.
/// The same reports taken as full attitudes are jumps.
#[test]
fn an_axis_only_report_is_tracked_by_its_axis_whatever_its_spin() {
    use dkrrt_koopman::debris_state::quat_mul;
    let body_z = |q: &[f64]| dkrrt_predictor::axis::body_z(q);
    let run = |axis_only: bool| {
        let mut pr = cv_predictor();
        let dt = 0.05;
        let mut worst = 0.0f64;
        for k in 0..160 {
            let t = k as f64 * dt;
            // Tumbling end over end at 0.6 rad/s about x.
            let a = 0.3 * t;
            let q = [a.cos(), a.sin(), 0.0, 0.0];
            // Reported with a spin of 2 rad more each time, every fourth one end for end.
            let s = k as f64;
            let mut reported = quat_mul(&q, &[s.cos(), 0.0, 0.0, s.sin()]);
            if k % 4 == 3 {
                reported = quat_mul(&reported, &[0.0, 1.0, 0.0, 0.0]);
            }
            let mut o = obs(9, t, [2.0, 0.0, 0.5], reported);
            o.axis_only = axis_only;
            pr.observe(&o);
            pr.set_shape(9, &dkrrt_msg::DebrisShape::capsule(0.6, 0.03));
            if k > 40 {
                let est = body_z(&pr.track(9).unwrap().state[6..10]);
                worst = worst.max(dkrrt_predictor::axis::line_angle(&est, &body_z(&q)));
            }
        }
        (pr.stats().att_jump, pr.stats().events, worst)
    };
    let (jumps, events, worst) = run(true);
    assert_eq!((jumps, events), (0, 0));
    assert!(worst < 0.05, "the axis follows the truth: {worst} rad off");
    let (jumps_full, _, _) = run(false);
    assert!(jumps_full >= 30, "taken as full attitudes the reports jump: {jumps_full}");
}

/// A square panel a camera reports as the disc it sweeps (its normal alone, `axis_only`),
/// tumbling torque-free with a spin about its normal (moments 1, 1, 2): its normal precesses
/// about the fixed angular momentum on a cone, while the filter's constant body rate does not
/// describe that motion and its attitude trails the reports. The precession forecast starts
/// from the reported normal, not the filter's: it keeps the normal to a few hundredths of a
/// radian 1 and 2 s ahead (from the filter's attitude it trailed by about 0.1 rad at every
/// horizon).
#[test]
fn a_discs_normal_is_forecast_from_its_reports_not_from_the_lagging_filter() {
    use nalgebra::{UnitQuaternion, Vector3};
    let (ix, iz) = (1.0, 2.0);
    let w0 = Vector3::new(0.6, 0.6, 0.6);
    let q0 = UnitQuaternion::from_scaled_axis(Vector3::new(0.3, -0.7, 0.2));
    // Torque-free axisymmetric motion: q(t) = R(L/I_x · t) q0 R_z((1 − I_z/I_x) ω_z t).
    let l = q0 * Vector3::new(ix * w0.x, ix * w0.y, iz * w0.z);
    let truth = |t: f64| {
        UnitQuaternion::from_scaled_axis(l / ix * t)
            * q0
            * UnitQuaternion::from_scaled_axis(Vector3::z() * (1.0 - iz / ix) * w0.z * t)
    };
    // The filter as set for poses from depth frames: 5 cm and 0.05 rad of noise assumed.
    let mut cfg = PredictorConfig { attitude_physics: Some(true), ..PredictorConfig::default() };
    (cfg.filter.pos_sigma, cfg.filter.att_sigma, cfg.filter.outlier_sigmas) = (0.05, 0.05, 3.0);
    let mut pr = DebrisPredictor::new(Models::constant_velocity(0.1, 40, 0.0, 0.05, 0.05), cfg);
    let shape = dkrrt_msg::DebrisShape::disc(0.7, 0.01);
    let dt = 0.05;
    let mut worst = [0.0f64; 2];
    let mut buf = ForecastBuffer::for_predictor(&pr);
    for k in 0..400 {
        let t = k as f64 * dt;
        let q = truth(t);
        // The front end's spin about the normal is its own bookkeeping: anything.
        let r = q * UnitQuaternion::from_scaled_axis(Vector3::z() * (1.7 * k as f64));
        let mut o = obs(5, t, [3.0, 1.0, 0.5], [r.w, r.i, r.j, r.k]);
        o.axis_only = true;
        pr.observe(&o);
        pr.set_shape(5, &shape);
        if k >= 200 && k % 10 == 0 {
            assert_eq!(pr.forecast(&mut buf), 1);
            for (j, steps) in [10, 20].into_iter().enumerate() {
                let z = truth(t + steps as f64 * 0.1) * Vector3::z();
                let err = dkrrt_predictor::axis::line_angle(&buf.axis(0, steps), &[z.x, z.y, z.z]);
                worst[j] = worst[j].max(err);
            }
        }
    }
    assert!(worst[0] < 0.03 && worst[1] < 0.05, "normal 1 s / 2 s ahead off by {worst:?} rad");
}

/// A front end's error margin (`front_end_margin_m`: its shapes are its estimates of the
/// bodies) grows every published position bound by exactly that much, and nothing else.
#[test]
fn the_front_ends_margin_grows_every_published_position_bound() {
    let run = |margin: f64| {
        let cfg = PredictorConfig { front_end_margin_m: margin, ..PredictorConfig::default() };
        let mut pr = DebrisPredictor::new(Models::constant_velocity(0.1, 40, 0.0, 0.05, 0.05), cfg);
        for k in 0..60 {
            let t = k as f64 * 0.05;
            let (p, q) = pose(t);
            pr.observe(&obs(2, t, p, q));
        }
        let mut buf = ForecastBuffer::for_predictor(&pr);
        pr.forecast(&mut buf);
        assert_eq!(buf.len(), 1);
        let pos: Vec<f64> = (1..=40).map(|k| buf.pos_radius(0, k)).collect();
        let att: Vec<f64> = (1..=40).map(|k| buf.att_radius(0, k)).collect();
        (pos, att, buf.state(0, 20).to_vec())
    };
    let (p0, a0, x0) = run(0.0);
    let (p1, a1, x1) = run(0.15);
    for k in 0..40 {
        assert!((p1[k] - p0[k] - 0.15).abs() < 1e-12, "step {}: {} vs {}", k + 1, p1[k], p0[k]);
    }
    assert_eq!((a0, x0), (a1, x1));
}

/// A track whose online calibration has not started (its first second of poses) publishes its
/// filter's constant-rate attitude with the filter's own deviations in the bound
/// (`PredictorConfig::track_sigmas`): the model, refined online from a few poses, is not yet
/// scored. The boxes of six dense and fast-crossing runs (the shipped deep model), forecast
/// every 0.05 s over their first second: the bound holds the true attitude (up to the
/// shape's half turns) at all 28 600 steps to 4 s ahead; the model's attitude in the fitted
/// bound alone misses at 155.
#[test]
fn a_young_tracks_attitude_bound_holds_its_true_attitude() {
    use dkrrt_predictor::eval::symmetric_angle;
    let shipped =
        dkrrt_predictor::TrainedModels::load(std::path::Path::new(dkrrt_predictor::training::SHIPPED_MODEL))
            .unwrap();
    let models = common::fitted_deep(Method::DeepKoopmanOnline, &shipped.attitude);
    let misses = |track_sigmas: f64| {
        let (mut misses, mut steps) = (0, 0);
        for seed in 0..6 {
            let name = ["dense", "fast-crossing"][seed as usize % 2];
            let scene = dkrrt_predictor::eval::perturbed_scene(name, 300 + seed, 1.0).unwrap();
            let rec = record(&scene, SensorConfig::default(), 5.0, 0.01, 300 + seed).unwrap();
            let cfg = PredictorConfig { track_sigmas, ..PredictorConfig::default() };
            let mut pr = DebrisPredictor::new(models.clone(), cfg);
            let mut buf = ForecastBuffer::for_predictor(&pr);
            let mut next = 0.05;
            for o in &rec.obs {
                pr.observe(o);
                for (id, shape, _) in &rec.shapes {
                    pr.set_shape(*id, shape);
                }
                if o.t_avail < next {
                    continue;
                }
                next += 0.05;
                if next > 1.0 {
                    break;
                }
                pr.forecast(&mut buf);
                for (id, shape, _) in &rec.shapes {
                    let Some(j) = buf.index_of(*id) else { continue };
                    if dkrrt_predictor::euler::inertia_hint(shape).is_none() {
                        continue;
                    }
                    for k in 1..=buf.horizon() {
                        let truth = rec.truth.at(*id, buf.t0(j) + k as f64 * buf.dt()).unwrap();
                        let e = symmetric_angle(&buf.attitude(j, k), &truth[6..10], shape);
                        steps += 1;
                        misses += (e > buf.attitude_radius(j, k)) as usize;
                    }
                }
            }
        }
        (misses, steps)
    };
    let (with, steps) = misses(dkrrt_predictor::predictor::TRACK_SIGMAS);
    let (without, _) = misses(0.0);
    assert!(steps >= 1000, "{steps} steps");
    assert!(with * 100 <= steps, "{with} of {steps} steps outside the bound");
    assert!(without >= 10 * with.max(1), "without the filter's deviations: {without} vs {with}");
}

/// A track is forecast from its second pose (a velocity; the filter's uncertainty about it is
/// in the bound), not before: one pose says nothing of where the object goes.
#[test]
fn a_track_is_forecast_from_its_second_pose() {
    let mut pr = cv_predictor();
    assert_eq!(pr.config().min_obs_for_forecast, 2);
    let mut buf = ForecastBuffer::for_predictor(&pr);
    let (p, q) = pose(0.0);
    pr.observe(&obs(4, 0.0, p, q));
    assert_eq!(pr.forecast(&mut buf), 0, "one pose");
    let (p, q) = pose(0.02);
    pr.observe(&obs(4, 0.02, p, q));
    assert_eq!(pr.forecast(&mut buf), 1, "two poses");
    // Its bound holds the velocity two poses leave uncertain: a 1 cm pose noise over 20 ms
    // is 0.7 m/s, so the bound 4 s ahead is metres, not the fitted 0.05 m.
    assert!(buf.pos_radius(0, 40) > 1.0, "{}", buf.pos_radius(0, 40));
}

/// A rod's axis forecast (the precession channel) needs measured axes. After an attitude
/// event restarts that channel, a camera may report the rod only in parts that show no axis
/// for a while; its forecasts then fall back to the model's axis, with the model's bound.
/// (They were NaN: the channel's forecast started from its newest sample's time, and it had
/// none; the planner refused each such forecast as a contract violation.)
#[test]
fn a_rod_whose_axis_channel_restarted_and_sees_no_axis_is_forecast_finite() {
    let cfg = PredictorConfig { attitude_physics: Some(true), ..Default::default() };
    let mut pr = DebrisPredictor::new(Models::constant_velocity(0.1, 40, 0.0, 0.05, 0.05), cfg);
    let rod = dkrrt_msg::DebrisShape::capsule(0.9, 0.05);
    // Tumbling end over end about x at 0.5 rad/s, then at 3 rad/s (a collision, say).
    let (dt, t_event) = (0.02, 3.0);
    let angle = |t: f64| if t < t_event { 0.5 * t } else { 0.5 * t_event + 3.0 * (t - t_event) };
    let q = |t: f64| [(0.5 * angle(t)).cos(), (0.5 * angle(t)).sin(), 0.0, 0.0];
    let mut k = 0;
    while pr.stats().events == 0 {
        let t = k as f64 * dt;
        assert!(t < t_event + 1.0, "no attitude event by t = {t}");
        pr.observe(&obs(7, t, [2.0, 0.0, 0.0], q(t)));
        pr.set_shape(7, &rod);
        k += 1;
    }
    // Now parts only, none showing the axis.
    for _ in 0..5 {
        let t = k as f64 * dt;
        let mut o = obs(7, t, [2.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]);
        o.partial = true;
        assert_eq!(pr.observe(&o), ObserveOutcome::Accepted);
        k += 1;
    }
    let mut buf = ForecastBuffer::for_predictor(&pr);
    assert_eq!(pr.forecast(&mut buf), 1);
    for s in 1..=buf.horizon() {
        let (axis, q) = (buf.axis(0, s), buf.published_attitude(0, s, &rod));
        assert!(axis.iter().chain(&q).all(|v| v.is_finite()), "step {s}: axis {axis:?}, attitude {q:?}");
        assert!(buf.axis_radius(0, s).is_finite() && buf.axis_radius(0, s) > 0.0, "step {s}");
    }
}
