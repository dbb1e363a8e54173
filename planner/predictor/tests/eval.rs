//! The accuracy study, small version.

use dkrrt_predictor::eval::markdown_table;
use dkrrt_predictor::{run_study, StudyConfig, StudyRow};

fn row<'a>(rows: &'a [StudyRow], scene: &str, method: &str, h: f64) -> &'a StudyRow {
    rows.iter().find(|r| r.scene == scene && r.method == method && r.horizon_s == h).unwrap()
}

#[test]
fn small_study() {
    let cfg = StudyConfig::small();
    let t = std::time::Instant::now();
    let rows = run_study(&cfg).unwrap();
    eprintln!("small study: {:.1} s\n{}", t.elapsed().as_secs_f64(), markdown_table(&rows));
    assert_eq!(rows.len(), cfg.scenes.len() * cfg.methods.len() * cfg.horizons.len());
    for r in &rows {
        assert!(r.pos_err_m.is_finite() && r.att_err_rad.is_finite() && r.n > 20, "{r:?}");
    }
    let json = serde_json::to_string(&rows).unwrap();
    assert!(json.contains("\"pos_err_m\"") && json.contains("\"contained\""));
    // Calibration columns: a share, positive bounds and errors, every sample scored.
    for r in &rows {
        assert!((0.0..=1.0).contains(&r.contained), "{r:?}");
        assert!(r.bound_m > 0.0 && r.surface_err_m >= 0.0 && r.bound_ratio > 0.0, "{r:?}");
        assert!(r.surface_err_p99_m >= r.surface_err_m, "{r:?}");
        assert!(r.oracle_track_ratio > 0.0 && r.oracle_local_ratio > 0.0, "{r:?}");
    }
    // The online-calibrated bound of the shipped method contains the true shape (it measures
    // 98-100 % per scene and horizon in this small, seeded study; the README's medium study
    // states the figures), and is not just huge: at most 40x the median surface error where
    // the training runs have no events (it measures 6-19x). Tumbling-rods' training runs
    // have the impulse at 10 s (0.11 m/s, 0.58 rad/s), and the bound carries it
    // (`dkrrt_predictor::events`): there the ratio is against how far the true shape leaves
    // the bounding sphere, which a rod's tumbling hardly does (67x at 4 s), so the bound
    // itself is checked: under 1 m, less than half the longest rod (2.4 m).
    for scene in &cfg.scenes {
        for &h in &cfg.horizons {
            let r = row(&rows, scene, "deep-koopman-online", h);
            assert!(r.contained >= 0.97, "{r:?}");
            if scene == "tumbling-rods" {
                assert!(r.bound_m <= 1.0, "{r:?}");
            } else {
                assert!(r.bound_ratio <= 40.0, "{r:?}");
            }
        }
    }
    // Young tracks (each run's first second, forecast every 0.05 s): scored apart, and the
    // bound holds them too: the filter's own deviations cover the velocity and body rate a
    // few poses leave uncertain (in this study 98.5-100 % per scene and horizon; without them,
    // the next test).
    for scene in &cfg.scenes {
        for &h in &cfg.horizons {
            let r = row(&rows, scene, "deep-koopman-online", h);
            assert!(r.young_n >= 20, "{r:?}");
            assert!(r.young_contained >= 0.95, "{r:?}");
        }
    }
    // Past the horizon, read as the planner reads it (the last interval's motion continued,
    // each bound grown at its rate): on each scene's last row only, and the bound holds there
    // too (the medium study: 100 %).
    for scene in &cfg.scenes {
        for (i, &h) in cfg.horizons.iter().enumerate() {
            let r = row(&rows, scene, "deep-koopman-online", h);
            assert_eq!(r.past.is_some(), i + 1 == cfg.horizons.len(), "{r:?}");
            if let Some(p) = &r.past {
                assert!(p.n >= 20, "{p:?}");
                assert!(p.contained.iter().all(|&c| c >= 0.97), "{scene}: {p:?}");
                assert!(p.bound_m[1] >= p.bound_m[0], "the bounds grow past the horizon: {p:?}");
            }
        }
    }
    let cal = dkrrt_predictor::eval::calibration_text(&rows, "deep-koopman-online");
    assert!(cal.contains("tumbling-rods: contained >= "), "{cal}");
    assert!(cal.contains("young tracks (first 1 s of a run"), "{cal}");
    assert!(cal.contains("past the horizon, read as the planner reads it"), "{cal}");
    // Constant velocity: errors grow with the horizon on the tumbling scenes.
    for scene in ["tumbling-rods", "sparse-slow"] {
        for w in cfg.horizons.windows(2) {
            let (a, b) =
                (row(&rows, scene, "constant-velocity", w[0]), row(&rows, scene, "constant-velocity", w[1]));
            assert!(b.pos_err_m > a.pos_err_m && b.att_err_rad > a.att_err_rad, "{a:?} {b:?}");
        }
    }
    // Attitude at 2 s on tumbling-rods: the online-refined Koopman methods beat constant
    // velocity (per-track RLS learns each body's rotation). The fixed global EDMD fits do
    // not (they are not asserted; see the README table).
    let cv = row(&rows, "tumbling-rods", "constant-velocity", 2.0).att_err_rad;
    for m in ["koopman-online", "dual-data"] {
        let k = row(&rows, "tumbling-rods", m, 2.0).att_err_rad;
        assert!(k < 0.9 * cv, "{m}: {k} vs constant velocity {cv}");
    }
}

/// Without the track filter's own deviations (`track_sigmas = 0`, the pose sensor's setting
/// before), a young track's bound is the model's, fitted on converged tracks: here (the small
/// study, dense and fast-crossing) it holds 48-67 % of the forecasts of each run's first
/// second (the medium study: 41-61 %), against 99.6-100 % with them.
#[test]
fn young_tracks_need_the_filters_own_deviations() {
    use dkrrt_predictor::Method;
    let mut cfg = StudyConfig::small();
    cfg.scenes = vec!["dense".into(), "fast-crossing".into()];
    cfg.methods = vec![Method::DeepKoopmanOnline];
    let with = run_study(&cfg).unwrap();
    cfg.predictor.track_sigmas = 0.0;
    let without = run_study(&cfg).unwrap();
    for (a, b) in with.iter().zip(&without) {
        assert_eq!((&a.scene, a.horizon_s, a.young_n), (&b.scene, b.horizon_s, b.young_n));
        assert!(a.young_contained >= 0.95, "{a:?}");
        assert!(b.young_contained < 0.8, "{b:?}");
    }
}

#[test]
fn the_hindsight_bound_scales_each_sample_by_its_tracks_error() {
    use dkrrt_predictor::eval::oracle_ratio;
    // Two tracks erring 1 and 10 at every forecast: sized by its track's median error, a
    // bound holds every sample at its own error (ratio 1), where one bound for all would be
    // 10 against the median error of 5.5.
    let mut sf = Vec::new();
    let mut of = Vec::new();
    for k in 0..10 {
        sf.push((0.0, 1.0));
        of.push((0, 3, 0.25 * k as f64));
        sf.push((0.0, 10.0));
        of.push((1, 3, 0.25 * k as f64)); // same id, another recording: another track
    }
    assert_eq!(oracle_ratio(&sf, &of, f64::INFINITY, 5.5), 1.0);
    // A track erring 1 and 3 in turn: its median (2) must be stretched by 1.5 to hold the 3s
    // (ratio 1.5); sized within a window holding the sample alone, each sample is its own size.
    let sf: Vec<(f64, f64)> = (0..20).map(|k| (0.0, if k % 2 == 0 { 1.0 } else { 3.0 })).collect();
    let of: Vec<(u32, u32, f64)> = (0..20).map(|k| (0, 7, k as f64)).collect();
    assert!((oracle_ratio(&sf, &of, f64::INFINITY, 2.0) - 1.5).abs() < 1e-12);
    assert!((oracle_ratio(&sf, &of, 0.5, 2.0) - 1.0).abs() < 1e-12);
}

#[test]
fn deep_vs_edmd_takes_the_best_fixed_edmd_per_channel() {
    use dkrrt_predictor::eval::{deep_vs_edmd, deep_vs_edmd_text};
    let r = |scene: &str, method: &str, h: f64, pos: f64, att: f64| StudyRow {
        scene: scene.into(),
        method: method.into(),
        horizon_s: h,
        pos_err_m: pos,
        att_err_rad: att,
        att_sym_err_rad: att,
        pub_att_err_rad: att,
        n: 100,
        contained: 1.0,
        bound_m: 0.1,
        surface_err_m: 0.05,
        bound_ratio: 2.0,
        surface_err_p99_m: 0.2,
        oracle_track_ratio: 3.0,
        oracle_local_ratio: 2.5,
        young_n: 50,
        young_contained: 1.0,
        past: None,
        obs_pos_err_m: None,
        obs_axis_err_rad: None,
    };
    let rows = vec![
        r("tumbling-rods", "edmd-poly", 2.0, 0.04, 0.6),
        r("tumbling-rods", "edmd-rbf", 2.0, 0.03, 1.2),
        r("tumbling-rods", "deep-koopman-online", 2.0, 0.003, 0.4),
        r("tumbling-rods", "deep-koopman-online", 1.0, 0.001, 0.1),
        r("dense", "edmd-rbf", 2.0, 0.01, 0.2),
        r("dense", "deep-koopman-online", 2.0, 0.01, 0.1),
        r("sparse-slow", "constant-velocity", 2.0, 0.01, 0.1),
    ];
    let c = deep_vs_edmd(&rows, 2.0);
    assert_eq!(c.len(), 2, "scenes without deep or EDMD rows are left out: {c:?}");
    assert_eq!(c[0].scene, "tumbling-rods");
    // Attitude: edmd-poly is the better EDMD (0.6 < 1.2); position: edmd-rbf (0.03 < 0.04).
    assert_eq!(c[0].att_edmd, ("edmd-poly".to_string(), 0.6));
    assert_eq!(c[0].pos_edmd, ("edmd-rbf".to_string(), 0.03));
    assert!((c[0].att_ratio() - 1.5).abs() < 1e-12 && (c[0].pos_ratio() - 10.0).abs() < 1e-12);
    assert!((c[1].att_ratio() - 2.0).abs() < 1e-12);
    let text = deep_vs_edmd_text(&c);
    assert!(
        text.contains("target (>= 2x at 2 s on tumbling-rods): attitude 1.50x NOT met, position 10.00x met"),
        "{text}"
    );
    assert!(deep_vs_edmd(&rows, 4.0).is_empty());
}

mod dual_ridge {
    use dkrrt_koopman::debris_state::N;
    use dkrrt_koopman::Lifting;
    use dkrrt_predictor::filter::cw_propagate;
    use dkrrt_predictor::models::DUAL_RIDGES;
    use dkrrt_predictor::{FitConfig, Method, Models, Segment, TrainingSet};

    const N_LEO: f64 = 1.1314e-3;

    /// Exact (noise-free) states of 12 objects on the 0.1 s grid: Clohessy–Wiltshire plus an
    /// unmodelled constant along-track acceleration `accel` (drag-like), fixed attitude.
    fn data(accel: f64) -> TrainingSet {
        let (dt, h, len) = (0.1, 40, 200);
        let mut segments = Vec::new();
        for i in 0..12u32 {
            let f = i as f64;
            let mut x = [3.0 - 0.5 * f, 0.3 * f - 2.0, 1.0 - 0.1 * f, 0.02 * f - 0.1, 0.05 - 0.01 * f, 0.01];
            let mut states = Vec::new();
            for _ in 0..len + h {
                let mut s = [0.0; N];
                s[0..6].copy_from_slice(&x);
                s[6] = 1.0;
                states.push(s);
                cw_propagate(N_LEO, dt, &mut x);
                x[1] += 0.5 * accel * dt * dt;
                x[4] += accel * dt;
            }
            segments.push(Segment {
                id: i,
                t0: 0.0,
                est: states[..len].to_vec(),
                truth: states,
                events: Vec::new(),
            });
        }
        TrainingSet { dt, horizon: h, segments }
    }

    /// Median 4 s position error of the translation model from the estimates.
    fn err_4s(m: &Models, ts: &TrainingSet) -> f64 {
        let mut phi = vec![0.0; m.trans_lift.dim()];
        let mut errs = Vec::new();
        for seg in &ts.segments {
            for s in (0..seg.est.len()).step_by(10) {
                let mut x = [0.0; 6];
                x.copy_from_slice(&seg.est[s][0..6]);
                for _ in 0..40 {
                    m.trans_lift.lift(&x, &mut phi);
                    let mut y = [0.0; 6];
                    m.trans.step_rows(6, &phi, &[], &mut y);
                    x = y;
                }
                let t = &seg.truth[s + 40];
                errs.push((0..3).map(|i| (x[i] - t[i]).powi(2)).sum::<f64>().sqrt());
            }
        }
        errs.sort_by(|a, b| a.total_cmp(b));
        errs[errs.len() / 2]
    }

    #[test]
    fn ridge_is_chosen_by_validation() {
        let cfg = FitConfig { frame_rate: N_LEO, ..FitConfig::default() };
        // The nominal physics is exact: whatever ridge is chosen, 4 s forecasts are exact.
        let exact = data(0.0);
        let m = Models::fit(Method::DualData, &exact, &cfg).unwrap();
        assert!(
            DUAL_RIDGES.contains(&m.dual_ridge[0]) && DUAL_RIDGES.contains(&m.dual_ridge[1]),
            "{:?}",
            m.dual_ridge
        );
        assert!(err_4s(&m, &exact) < 1e-6, "exact physics: {}", err_4s(&m, &exact));
        // An unmodelled acceleration: validation picks a correction, which beats the nominal
        // model alone.
        let drag = data(2e-3);
        let m = Models::fit(Method::DualData, &drag, &cfg).unwrap();
        let nominal = Models::fit(
            Method::DualData,
            &drag,
            &FitConfig { dual_ridge_auto: false, dual_ridge: f64::INFINITY, ..cfg },
        )
        .unwrap();
        let (e, e0) = (err_4s(&m, &drag), err_4s(&nominal, &drag));
        assert!(m.dual_ridge[0].is_finite(), "correction not chosen: {:?}", m.dual_ridge);
        assert!(e < 0.2 * e0, "chosen ridge {}: 4 s error {e} vs nominal only {e0}", m.dual_ridge[0]);
        // Methods without a dual-data model report none.
        assert!(Models::fit(Method::EdmdPoly, &drag, &cfg).unwrap().dual_ridge[0].is_nan());
    }
}

/// The attitude error modulo a shape's symmetry: what no camera can tell apart costs nothing.
#[test]
fn the_symmetric_attitude_error_ignores_what_the_shape_cannot_show() {
    use dkrrt_msg::DebrisShape;
    use dkrrt_predictor::eval::symmetric_angle;
    let about = |axis: [f64; 3], a: f64| {
        let s = (a / 2.0).sin();
        [(a / 2.0).cos(), axis[0] * s, axis[1] * s, axis[2] * s]
    };
    let t = about([0.6, 0.0, 0.8], 0.9);
    let mul = dkrrt_collision::pose::quat_mul;
    let pi = std::f64::consts::PI;
    // A ball: nothing. A rod: its spin and its end-for-end turn cost nothing; a tilt does.
    assert_eq!(symmetric_angle(&about([1.0, 0.0, 0.0], 2.0), &t, &DebrisShape::sphere(0.3)), 0.0);
    let rod = DebrisShape::capsule(0.5, 0.05);
    assert!(symmetric_angle(&mul(&t, &about([0.0, 0.0, 1.0], 2.5)), &t, &rod) < 1e-9);
    assert!(symmetric_angle(&mul(&t, &about([1.0, 0.0, 0.0], pi)), &t, &rod) < 1e-9);
    assert!((symmetric_angle(&mul(&t, &about([1.0, 0.0, 0.0], 0.2)), &t, &rod) - 0.2).abs() < 1e-9);
    // A box: its half turns cost nothing, a quarter turn does unless two sides are equal.
    let slab = DebrisShape::cuboid([0.6, 0.15, 0.05], [0.0; 3]);
    for axis in [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]] {
        assert!(symmetric_angle(&mul(&t, &about(axis, pi)), &t, &slab) < 1e-9);
    }
    let quarter = mul(&t, &about([0.0, 0.0, 1.0], pi / 2.0));
    assert!((symmetric_angle(&quarter, &t, &slab) - pi / 2.0).abs() < 1e-9);
    let square = DebrisShape::cuboid([0.5, 0.5, 0.005], [0.0; 3]);
    assert!(symmetric_angle(&quarter, &t, &square) < 1e-9);
    // The full angle bounds it.
    let q = about([0.3, -0.4, 0.5], 1.3);
    assert!(symmetric_angle(&q, &t, &slab) <= dkrrt_predictor::filter::quat_angle(&q, &t) + 1e-12);
}

/// A convex fragment's true surface is its hull, not the box its descriptor gives: sparse-slow
/// object 4 is one. A ball about its centre of mass as large as its farthest vertex holds it;
/// judged by its box, it would stick out by the box's empty corners.
#[test]
fn a_fragment_is_judged_by_its_hull() {
    use dkrrt_debris::{Scene, SensorConfig};
    use dkrrt_msg::DebrisShape;
    use dkrrt_predictor::eval::{record, TrueBody};
    let rec = record(&Scene::named("sparse-slow").unwrap(), SensorConfig::default(), 0.1, 0.01, 1).unwrap();
    let ids: Vec<u32> = rec.hulls.iter().map(|h| h.0).collect();
    assert_eq!(ids, vec![4], "only the convex fragment has a hull");
    let (_, desc, r) = rec.shapes.iter().find(|s| s.0 == 4).unwrap();
    let v = &rec.hulls[0].1;
    let far = v.iter().map(|x| (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt()).fold(0.0, f64::max);
    assert!(far < r - 0.05, "the box's corners lie beyond the hull: {far} vs {r}");
    let (p, q) = ([1.0, -2.0, 0.5], [0.9, 0.1, -0.3, 0.3]);
    let n = q.iter().map(|x: &f64| x * x).sum::<f64>().sqrt();
    let q = q.map(|x| x / n);
    let ball = DebrisShape::sphere(far);
    let hull = TrueBody { shape: desc, radius: *r, hull: Some(v) };
    let boxed = TrueBody { shape: desc, radius: *r, hull: None };
    assert!(hull.excess(&ball, far, &p, &q, &p, &q) < 1e-12);
    assert!(boxed.excess(&ball, far, &p, &q, &p, &q) > 0.05);
    // Moved 0.1 m, the hull sticks out by at most that.
    let moved = [p[0] + 0.1, p[1], p[2]];
    let e = hull.excess(&ball, far, &moved, &q, &p, &q);
    assert!(e > 0.0 && e <= 0.1 + 1e-12, "{e}");
}
