//! `dkrrt train` and `dkrrt predict-eval` from the command line: a quick training writes a
//! model file that the study and the predictor load; a corrupt or mismatched file is a
//! clear error naming the file and the problem.

use std::process::Command;

fn exe() -> &'static str {
    env!("CARGO_BIN_EXE_dkrrt")
}

/// `dkrrt predict-eval` of the small study on tumbling-rods with `methods`.
fn small_study(methods: &str) -> Command {
    let mut c = Command::new(exe());
    c.args(["predict-eval", "--size", "small", "--scenes", "tumbling-rods", "--methods", methods]);
    c
}

/// Runs `cmd` with `--json path`: it must succeed; its stdout and the rows it wrote.
fn rows_of(cmd: &mut Command, path: &std::path::Path) -> (String, Vec<serde_json::Value>) {
    let out = cmd.arg("--json").arg(path).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let rows = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    (String::from_utf8_lossy(&out.stdout).to_string(), rows)
}

/// `dkrrt train --visual --quick`: f_θ trained on depth views (Algorithm 1) with a progress
/// bar and the validation per horizon, saved as a model file that `predict-eval` reads; a
/// corrupt one is refused naming the file and the field.
#[test]
fn train_visual_writes_a_model_that_predict_eval_reads() {
    let dir = std::env::temp_dir().join(format!("dkrrt-train-visual-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let model = dir.join("v.dkv");
    let out =
        Command::new(exe()).args(["train", "--visual", "--quick", "--out"]).arg(&model).output().unwrap();
    let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "{stdout}\n{stderr}");
    assert!(stderr.contains("epoch   2/2"), "progress bar: {stderr}");
    assert!(stdout.contains("training views") && stdout.contains("other runs per scene"), "{stdout}");
    assert!(stdout.contains("per horizon") && stdout.contains("  4: "), "{stdout}");
    assert_eq!(&std::fs::read(&model).unwrap()[..8], b"DKRRTVIS");
    let (_, rows) =
        rows_of(small_study("deep-koopman-online").arg("--visual-model").arg(&model), &dir.join("rows.json"));
    assert_eq!(rows.iter().filter(|r| r["method"] == "deep-koopman-online+visual").count(), 4);
    let mut bytes = std::fs::read(&model).unwrap();
    bytes[30] ^= 1;
    std::fs::write(&model, &bytes).unwrap();
    let out = small_study("deep-koopman-online").arg("--visual-model").arg(&model).output().unwrap();
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && e.contains("v.dkv") && e.contains("checksum"), "{e}");
    // --visual-model none: no learned view.
    let out = small_study("deep-koopman-online").args(["--visual-model", "none"]).output().unwrap();
    assert!(out.status.success() && !String::from_utf8_lossy(&out.stdout).contains("+visual"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn train_writes_a_model_that_predict_eval_uses_and_corruption_is_refused() {
    let dir = std::env::temp_dir().join(format!("dkrrt-train-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let model = dir.join("m.dkm");
    let out = Command::new(exe())
        .args(["train", "--quick", "--epochs", "2", "--out"])
        .arg(&model)
        .arg("--json")
        .arg(dir.join("train.json"))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("| 2 |"), "validation table per horizon: {stdout}");
    assert!(String::from_utf8_lossy(&out.stderr).contains("epoch   2/2"), "progress bar");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("train.json")).unwrap()).unwrap();
    assert_eq!(v["validation"].as_array().unwrap().len(), 4);
    let bytes = std::fs::read(&model).unwrap();
    assert_eq!(&bytes[..8], b"DKRRTDKM");

    // The study with that model: rows for every requested method and horizon.
    let (stdout, rows) = rows_of(
        small_study("constant-velocity,edmd-poly,deep-koopman-online").arg("--model").arg(&model),
        &dir.join("rows.json"),
    );
    // ... and the depth camera's views of the same runs for the planner's predictor (issue #15):
    // the classical front end and the learned one (the shipped f_θ), with their observations'
    // own errors.
    assert_eq!(rows.len(), (3 + 2) * 4);
    let camera = |r: &&serde_json::Value| r["method"].as_str().unwrap().contains('+');
    for view in ["deep-koopman-online+depth", "deep-koopman-online+visual"] {
        let rs: Vec<_> = rows.iter().filter(|r| r["method"] == view).collect();
        assert_eq!(rs.len(), 4, "{view}");
        for r in rs {
            let (p, a) = (r["obs_pos_err_m"].as_f64().unwrap(), r["obs_axis_err_rad"].as_f64().unwrap());
            assert!(p > 0.0 && p < 0.3 && a >= 0.0 && a < 0.5, "{r}");
            assert!(r["pos_err_m"].as_f64().unwrap() < 1.0, "{r}");
            let (full, sym) = (r["att_err_rad"].as_f64().unwrap(), r["att_sym_err_rad"].as_f64().unwrap());
            assert!(sym <= full + 1e-9, "modulo the shapes' symmetry no larger: {r}");
        }
    }
    assert!(rows.iter().filter(|r| !camera(r)).all(|r| r.get("obs_pos_err_m").is_none()));
    // The printed target check is the ratio of the JSON rows (EDMD / deep at 2 s).
    let att = |m: &str| {
        let r = rows.iter().find(|r| r["method"] == m && r["horizon_s"] == 2.0).unwrap();
        r["att_err_rad"].as_f64().unwrap()
    };
    let ratio = att("edmd-poly") / att("deep-koopman-online");
    let line = stdout
        .lines()
        .find(|l| l.starts_with("target (>= 2x at 2 s on tumbling-rods)"))
        .unwrap_or_else(|| panic!("target line printed: {stdout}"));
    let verdict = if ratio >= 2.0 { "met" } else { "NOT met" };
    assert!(line.contains(&format!("attitude {ratio:.2}x {verdict}")), "{line} vs ratio {ratio}");
    assert!(stdout.contains(", seed 7,"), "{stdout}");
    for r in &rows {
        assert_eq!(r["scene"], "tumbling-rods");
        assert!(
            r["pos_err_m"].as_f64().unwrap().is_finite() && r["att_err_rad"].as_f64().unwrap().is_finite()
        );
        assert!(r["n"].as_u64().unwrap() > 20);
    }
    assert!(rows.iter().any(|r| r["method"] == "deep-koopman-online" && r["horizon_s"] == 2.0));

    // Another seed: another set of runs (other errors); a seed that would reach the deep
    // model's training seeds is refused naming the option.
    let (_, rows2) =
        rows_of(small_study("constant-velocity").args(["--seed", "50007"]), &dir.join("rows2.json"));
    let cv = |rows: &[serde_json::Value]| -> Vec<f64> {
        rows.iter()
            .filter(|r| r["method"] == "constant-velocity")
            .map(|r| r["att_err_rad"].as_f64().unwrap())
            .collect()
    };
    assert_eq!(cv(&rows2).len(), 4);
    assert_ne!(cv(&rows2), cv(&rows), "another seed, other runs");
    let out = Command::new(exe()).args(["predict-eval", "--seed", "950000"]).output().unwrap();
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("--seed 950000"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    // A flipped byte: the checksum catches it, the error names the file.
    let mut bad = bytes.clone();
    let mid = bad.len() / 2;
    bad[mid] ^= 0x40;
    let corrupt = dir.join("corrupt.dkm");
    std::fs::write(&corrupt, &bad).unwrap();
    let out = Command::new(exe())
        .args(["predict-eval", "--size", "small", "--methods", "deep-koopman", "--model"])
        .arg(&corrupt)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr).to_lowercase();
    assert!(err.contains("corrupt.dkm") && err.contains("checksum"), "{err}");

    // The predictor process refuses a truncated model named in the scenario.
    std::fs::write(dir.join("short.dkm"), &bytes[..bytes.len() / 3]).unwrap();
    let sc = dkrrt_config::DEFAULT_SCENARIO.replace("model = \"\"", "model = \"short.dkm\"");
    assert_ne!(sc, dkrrt_config::DEFAULT_SCENARIO);
    std::fs::write(dir.join("sc.toml"), sc).unwrap();
    let out = Command::new(exe())
        .args(["predictor", "--run", &format!("trcli{}", std::process::id()), "--scenario"])
        .arg(dir.join("sc.toml"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr).to_lowercase();
    assert!(
        err.contains("predictor.model") && err.contains("short.dkm") && err.contains("truncated"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn predict_eval_refuses_unknown_methods_and_scenes() {
    let out = Command::new(exe()).args(["predict-eval", "--methods", "crystal-ball"]).output().unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("crystal-ball"));
    let out = Command::new(exe()).args(["predict-eval", "--scenes", "asteroid-belt"]).output().unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("asteroid-belt"));
    // A scene or method named twice would be evaluated, and its rows written, twice.
    for (flag, list) in
        [("--scenes", "dense,sparse-slow,dense"), ("--methods", "constant-velocity,constant-velocity")]
    {
        let out = Command::new(exe()).args(["predict-eval", "--size", "small", flag, list]).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(flag) && err.contains("twice"), "{err}");
    }
}

/// Every output is written after the work: a path that cannot take it is refused before the
/// work starts, naming the option, and nothing is trained or evaluated for nothing.
#[test]
fn outputs_that_cannot_be_written_are_refused_before_the_work() {
    let missing = std::env::temp_dir().join(format!("dkrrt-no-such-dir-{}", std::process::id())).join("f");
    let runs: [(&[&str], &str); 4] = [
        (&["train", "--quick", "--out"], "--out"),
        (&["train", "--visual", "--quick", "--out"], "--out"),
        (
            &[
                "predict-eval",
                "--size",
                "small",
                "--scenes",
                "dense",
                "--methods",
                "constant-velocity",
                "--json",
            ],
            "--json",
        ),
        (&["study", "--episodes", "1", "--scenes", "dense", "--methods", "straight", "--json"], "--json"),
    ];
    for (args, flag) in runs {
        let out = Command::new(exe()).args(args).arg(&missing).output().unwrap();
        let (stdout, err) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
        assert!(!out.status.success(), "{args:?}: {stdout}");
        assert!(err.contains(flag) && err.contains("dkrrt-no-such-dir"), "{args:?}: {err}");
        // No training report, validation table, study table or progress was printed.
        assert!(stdout.trim().is_empty(), "{args:?} worked before refusing: {stdout}");
    }
    // The report of a training too (its model path is fine).
    let dir = std::env::temp_dir().join(format!("dkrrt-train-outs-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let model = dir.join("m.dkm");
    let out = Command::new(exe())
        .args(["train", "--quick", "--out"])
        .arg(&model)
        .arg("--json")
        .arg(&missing)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("--json"), "{err}");
    assert!(!model.exists(), "the model was trained and written before the report's path was refused");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn train_on_recorded_observations_writes_a_model_and_bad_lines_are_named() {
    let dir = std::env::temp_dir().join(format!("dkrrt-train-rec-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // A recording as `dkrrt record` writes it: 20 s of the tumbling rods (events removed).
    let mut scene = dkrrt_debris::Scene::named("tumbling-rods").unwrap();
    scene.events.clear();
    let rec =
        dkrrt_predictor::eval::record(&scene, dkrrt_debris::SensorConfig::default(), 20.0, 0.01, 9).unwrap();
    let mut text = Vec::new();
    for o in &rec.obs {
        dkrrt_predictor::recorded::write_observation(&mut text, o).unwrap();
    }
    let file = dir.join("obs.jsonl");
    std::fs::write(&file, &text).unwrap();
    let model = dir.join("rec.dkm");
    let out = Command::new(exe())
        .args(["train", "--quick", "--epochs", "2", "--observations"])
        .arg(&file)
        .arg("--out")
        .arg(&model)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stdout}\n{stderr}");
    assert!(stderr.contains(&format!("{} observations from", rec.obs.len())), "{stderr}");
    assert!(stdout.contains("| 2 |"), "validation table: {stdout}");
    let m = dkrrt_predictor::TrainedModels::load(&model).unwrap();
    assert_eq!(m.attitude.model.n, 7);

    // A broken line: the error names the file and the line; nothing is written.
    let mut lines: Vec<&str> = std::str::from_utf8(&text).unwrap().lines().collect();
    lines[1] = r#"{"t": 0.02, "id": 1, "p": [0, 0, 0], "q": [0, 0, 0, 0]}"#;
    let bad = dir.join("bad.jsonl");
    std::fs::write(&bad, lines.join("\n")).unwrap();
    let out2 = dir.join("bad.dkm");
    let out = Command::new(exe())
        .args(["train", "--quick", "--observations"])
        .arg(&bad)
        .arg("--out")
        .arg(&out2)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains(&format!("{}:2:", bad.display())) && err.contains("unit quaternion"), "{err}");
    assert!(!out2.exists());
    let _ = std::fs::remove_dir_all(&dir);
}
