//! `dkrrt plan` and `dkrrt plan-problem` from the command line.

use std::process::Command;

use serde_json::Value;

fn exe() -> &'static str {
    env!("CARGO_BIN_EXE_dkrrt")
}

fn tmp(tag: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("dkrrt-plan-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn an_exported_episode_is_solved_and_the_output_has_every_field() {
    let d = tmp("ok");
    let prob = d.join("p.json");
    let out = Command::new(exe()).args(["plan-problem", "--out"]).arg(&prob).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let p: Value = serde_json::from_str(&std::fs::read_to_string(&prob).unwrap()).unwrap();
    assert!(p["obstacles"].as_array().unwrap().len() >= 2);
    assert!(p["obstacles"][0]["poses"].as_array().unwrap().len() > 100, "poses every 0.1 s");
    let sol = d.join("s.json");
    let out = Command::new(exe())
        .args(["plan", "--time-limit", "0.5", "--problem"])
        .arg(&prob)
        .arg("--json")
        .arg(&sol)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let s: Value = serde_json::from_str(&std::fs::read_to_string(&sol).unwrap()).unwrap();
    assert_eq!(s["solved"], true);
    assert!(s["min_clearance_m"].as_f64().unwrap() >= 0.0);
    let path = s["path"].as_array().unwrap();
    let times = s["times_s"].as_array().unwrap();
    assert_eq!(path.len(), times.len());
    assert_eq!(path[0], p["start"]);
    assert_eq!(path[path.len() - 1], p["goal"]);
    let tr = s["trajectory"].as_array().unwrap();
    let dur = s["duration_s"].as_f64().unwrap();
    assert_eq!(tr.len(), (dur / 0.01).ceil() as usize + 1, "every 10 ms");
    let last = tr.last().unwrap().as_array().unwrap();
    assert_eq!(last.len(), 7);
    for j in 0..6 {
        assert!((last[j + 1].as_f64().unwrap() - p["goal"][j].as_f64().unwrap()).abs() < 1e-9);
    }
    assert!(s["first_solution_s"].as_f64().unwrap() <= s["plan_time_s"].as_f64().unwrap());
    let _ = std::fs::remove_dir_all(d);
}

#[test]
fn a_malformed_problem_is_refused_naming_the_field() {
    let d = tmp("bad");
    let good = r#"{"urdf": "", "start": [0.0, -0.5, 1.0, 0.0, 0.5, 0.0], "goal": [0.35, -0.2, 0.7, 0.3, 0.2, 0.4],
        "margin_m": 0.0, "time_limit_s": 0.2, "seed": 1,
        "obstacles": [{"shape": {"kind": "sphere", "radius": 0.3}, "poses": [{"t": 0.0, "p": [5.0, 0.0, 0.0], "q": [1.0, 0.0, 0.0, 0.0]}]}]}"#;
    let cases = [
        (good.replace("\"radius\": 0.3", "\"radius\": -0.3"), "obstacles[0].shape.radius"),
        (good.replace("[1.0, 0.0, 0.0, 0.0]", "[1.3, 0.0, 0.0, 0.0]"), "obstacles[0].poses[0].q"),
        (good.replace("\"time_limit_s\": 0.2", "\"time_limit_s\": 0"), "time_limit_s"),
        (good.replace("[0.0, -0.5, 1.0, 0.0, 0.5, 0.0]", "[0.0, -0.5, 1.0, 9.0, 0.5, 0.0]"), "start[3]"),
        (good.replace("\"seed\": 1,", "\"seed\": 1, \"extra\": 2,"), "extra: unknown field"),
        (
            good.replace("\"kind\": \"sphere\"", "\"kind\": \"torus\""),
            "obstacles[0].shape.kind: unknown variant `torus`",
        ),
        (format!("{good} {{}}"), "trailing characters"),
        // Values of the wrong type, by the path to them.
        (good.replace("\"seed\": 1", "\"seed\": -1"), "seed: invalid value"),
        (good.replace("\"t\": 0.0", "\"t\": \"0\""), "obstacles[0].poses[0].t: invalid type"),
        (
            good.replace("\"radius\": 0.3", "\"radius\": 0.3, \"half_length\": 1"),
            "obstacles[0].shape: unknown field",
        ),
        // Vectors of the wrong length, with the number they need.
        (
            good.replace("[0.0, -0.5, 1.0, 0.0, 0.5, 0.0]", "[0.0, -0.5, 1.0, 0.0, 0.5, 0.0, 7.0]"),
            "start: invalid length 7, expected exactly 6 numbers",
        ),
        (
            good.replace("[5.0, 0.0, 0.0]", "[5.0, 0.0, 0.0, 1.0]"),
            "obstacles[0].poses[0].p: invalid length 4, expected exactly 3",
        ),
    ];
    for (i, (text, field)) in cases.iter().enumerate() {
        let f = d.join(format!("b{i}.json"));
        std::fs::write(&f, text).unwrap();
        let out = Command::new(exe()).args(["plan", "--problem"]).arg(&f).output().unwrap();
        assert!(!out.status.success(), "case {i} accepted");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(field) && err.contains(&format!("b{i}.json")), "case {i}: {err}");
    }
    // The well-formed one is solved (the sphere is far away).
    let f = d.join("good.json");
    std::fs::write(&f, good).unwrap();
    let out = Command::new(exe()).args(["plan", "--problem"]).arg(&f).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let _ = std::fs::remove_dir_all(d);
}
