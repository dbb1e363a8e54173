//! Recorded observations: the file format round trip and its errors, the filtered attitude
//! trajectories against the simulated truth, and training on them.

use dkrrt_debris::{Observation, Scene, SensorConfig};
use dkrrt_predictor::eval::{record, Recording};
use dkrrt_predictor::filter::quat_angle;
use dkrrt_predictor::recorded::{
    attitude_trajectories, read_observations, train_from_observations, write_observation,
};
use dkrrt_predictor::{PredictorConfig, TrainOptions};

fn tumbling(duration: f64, seed: u64) -> Recording {
    let mut sc = Scene::named("tumbling-rods").unwrap();
    sc.events.clear();
    record(&sc, SensorConfig::default(), duration, 0.01, seed).unwrap()
}

fn to_text(obs: &[Observation]) -> String {
    let mut buf = Vec::new();
    for o in obs {
        write_observation(&mut buf, o).unwrap();
    }
    String::from_utf8(buf).unwrap()
}

#[test]
fn file_round_trip_and_errors_name_the_line() {
    let mut obs = tumbling(2.0, 1).obs;
    assert!(obs.len() > 100);
    obs[3].has_rates = true;
    obs[3].v = [0.1, -0.2, 0.3];
    obs[3].w = [1.0, 2.0, -3.0];
    let text = to_text(&obs);
    assert_eq!(text.lines().count(), obs.len());
    let back = read_observations(text.as_bytes(), "rec.jsonl").unwrap();
    assert_eq!(back.len(), obs.len());
    for (a, b) in obs.iter().zip(&back) {
        assert_eq!((a.id, a.t, a.p, a.has_rates), (b.id, b.t, b.p, b.has_rates));
        for i in 0..4 {
            assert!((a.q[i] - b.q[i]).abs() < 1e-15);
        }
    }
    assert_eq!((back[3].v, back[3].w), (obs[3].v, obs[3].w));
    assert!(!back[4].has_rates && !text.lines().nth(4).unwrap().contains("\"v\""));
    // A depth front end's flags go with the line (and only when set).
    let mut flagged = obs.clone();
    flagged[5].partial = true;
    flagged[6].restart = true;
    (flagged[7].axis_only, flagged[7].partial) = (true, true);
    let text_f = to_text(&flagged);
    let back = read_observations(text_f.as_bytes(), "rec.jsonl").unwrap();
    for (a, b) in flagged.iter().zip(&back) {
        assert_eq!((a.partial, a.restart, a.axis_only), (b.partial, b.restart, b.axis_only));
    }
    assert!(text_f.lines().nth(7).unwrap().contains("\"flags\":10"));
    assert!(!text_f.lines().nth(4).unwrap().contains("flags"));

    let bad = |line: &str| {
        let t = format!("{}\n\n{line}\n", text.lines().next().unwrap());
        read_observations(t.as_bytes(), "rec.jsonl").unwrap_err()
    };
    let e = bad(r#"{"t": 1.0, "id": 2, "p": [0, 0, 0]}"#);
    assert!(e.starts_with("rec.jsonl:3:") && e.contains("q"), "{e}");
    let e = bad(r#"{"t": 1.0, "id": 2, "p": [0, 0, 0], "q": [0, 0, 0, 0]}"#);
    assert!(e.starts_with("rec.jsonl:3:") && e.contains("unit quaternion"), "{e}");
    let e = bad(r#"{"t": 1.0, "id": 2, "p": [0, 0, 0], "q": [1, 0, 0, 0], "v": [0, 0, 0]}"#);
    assert!(e.contains("\"v\" and \"w\" go together"), "{e}");
    let e = bad(r#"{"t": 1.0, "id": 2, "p": [0, 0, 1e999], "q": [1, 0, 0, 0]}"#);
    assert!(e.starts_with("rec.jsonl:3:"), "{e}");
    let e = bad(r#"{"t": 1.0, "id": 2, "p": [0, 0, 0], "q": [1, 0, 0, 0], "flags": 1}"#);
    assert!(e.starts_with("rec.jsonl:3:") && e.contains("flags 1"), "{e}");
    let e = bad(r#"{"t": 1.0, "id": 2, "p": [0, 0, 0], "q": [1, 0, 0, 0], "extra": 1}"#);
    assert!(e.contains("extra"), "{e}");
}

#[test]
fn filtered_trajectories_follow_the_true_attitude() {
    let rec = tumbling(20.0, 3);
    let dt = 0.1;
    let tracks = attitude_trajectories(&rec.obs, rec.mean_motion, dt, &PredictorConfig::default(), 1.0, 0.5);
    let ids: std::collections::BTreeSet<u32> = rec.obs.iter().map(|o| o.id).collect();
    assert!(tracks.len() >= ids.len(), "{} tracks for {} objects", tracks.len(), ids.len());
    let (mut att, mut rate) = (Vec::new(), Vec::new());
    for tr in &tracks {
        assert!(((tr.t0 / dt).round() * dt - tr.t0).abs() < 1e-9, "on the grid: {}", tr.t0);
        assert!(tr.t0 >= 1.0 - 1e-9, "after the warm-up: {}", tr.t0);
        for (k, x) in tr.x.chunks(7).enumerate() {
            let t = tr.t0 + k as f64 * dt;
            let truth = rec
                .truth
                .at(tr.id, t)
                .unwrap_or_else(|| panic!("truth of {} at {t}, {} frames", tr.id, rec.truth.frames.len()));
            att.push(quat_angle(&x[..4], &truth[6..10]));
            rate.push((0..3).map(|i| (x[4 + i] - truth[10 + i]).powi(2)).sum::<f64>().sqrt());
            if k > 0 {
                let prev = &tr.x[(k - 1) * 7..k * 7];
                let dot: f64 = (0..4).map(|i| prev[i] * x[i]).sum();
                assert!(dot > 0.0, "sign-continuous quaternions");
            }
        }
    }
    att.sort_by(f64::total_cmp);
    rate.sort_by(f64::total_cmp);
    let (ma, mr) = (att[att.len() / 2], rate[rate.len() / 2]);
    // Sensor noise 0.01 rad per axis: the filter does better than one raw measurement.
    assert!(ma < 0.01, "median attitude error {ma} rad over {} samples", att.len());
    assert!(mr < 0.1, "median rate error {mr} rad/s");
}

#[test]
fn training_on_recorded_observations_gives_a_model_and_a_held_out_validation() {
    let recs = vec![tumbling(20.0, 5).obs, tumbling(20.0, 6).obs];
    let opts = TrainOptions::tiny();
    let mut epochs = 0;
    let m =
        train_from_observations(&recs, 1.1314e-3, &PredictorConfig::default(), &opts, &mut |_| epochs += 1)
            .unwrap();
    assert_eq!(epochs, opts.deep.epochs);
    assert_eq!(m.attitude.model.n, 7);
    assert_eq!(m.validation.len(), opts.valid_horizons.len());
    for v in &m.validation {
        assert!(v.n > 0 && v.att_err_rad.is_finite() && v.cv_att_err_rad.is_finite(), "{v:?}");
    }
    // Too little data: a clear error, not a panic.
    let short = vec![tumbling(1.5, 7).obs];
    let e = train_from_observations(&short, 1.1314e-3, &PredictorConfig::default(), &opts, &mut |_| {})
        .unwrap_err();
    assert!(e.contains("no object was tracked"), "{e}");
}
