//! `dkrrt study`: rows for every scene × episode × method, streamed as they finish.

use std::process::Command;

use serde_json::Value;

/// Runs `dkrrt study ARGS --json DIR/study.json` in `dir`, which must succeed: its stdout and
/// the rows of the JSON it wrote.
fn run_study(dir: &std::path::Path, args: &[&str]) -> (String, Vec<Value>) {
    let js = dir.join("study.json");
    let out = Command::new(env!("CARGO_BIN_EXE_dkrrt"))
        .current_dir(dir)
        .arg("study")
        .args(args)
        .arg("--json")
        .arg(&js)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    let doc: Value = serde_json::from_str(&std::fs::read_to_string(&js).unwrap()).unwrap();
    (stdout, doc["rows"].as_array().unwrap().clone())
}

#[test]
fn a_small_study_writes_every_row_and_the_planner_beats_the_straight_motion() {
    let d = std::env::temp_dir().join(format!("dkrrt-study-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let js = d.join("study.json");
    let out = Command::new(env!("CARGO_BIN_EXE_dkrrt"))
        .args([
            "study",
            "--scenes",
            "fast-crossing",
            "--episodes",
            "2",
            "--methods",
            "straight,dk-rrt",
            "--seed",
            "3",
            "--json",
        ])
        .arg(&js)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("fast-crossing  dk-rrt"), "{stdout}");
    // With the default threads (one per core) episodes share the cores: the table's lockstep
    // speed is said to be per episode, beside others.
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    assert_eq!(stdout.contains("note: the lockstep speed is each episode's"), cores > 1, "{stdout}");
    let doc: Value = serde_json::from_str(&std::fs::read_to_string(&js).unwrap()).unwrap();
    let rows = doc["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 4);
    for r in rows {
        for k in [
            "scene",
            "episode",
            "method",
            "completed",
            "collision",
            "time_to_goal_s",
            "min_distance_m",
            "replans",
            "plan_ms",
        ] {
            assert!(r.get(k).is_some(), "row lacks {k}: {r}");
        }
        assert!(r["error"].is_null(), "{r}");
        // Completed = goal reached with no contact.
        if r["completed"] == true {
            assert_eq!(r["collision"], false);
            assert!(r["time_to_goal_s"].as_f64().unwrap() <= r["time_limit_s"].as_f64().unwrap());
        }
    }
    let by = |m: &str| rows.iter().filter(|r| r["method"] == m).collect::<Vec<_>>();
    // The episodes aim debris at the straight motion; the planner avoids it.
    assert!(by("straight").iter().all(|r| r["collision"] == true), "{rows:?}");
    assert!(by("dk-rrt").iter().all(|r| r["collision"] == false), "{rows:?}");
    // Rows were also streamed as JSON lines while the study ran.
    let streamed = std::fs::read_to_string(js.with_extension("rows.jsonl")).unwrap();
    assert_eq!(streamed.lines().count(), 4);
    let _ = std::fs::remove_dir_all(d);
}

#[test]
fn every_method_runs_the_same_episodes_and_the_study_writes_its_report() {
    let d = std::env::temp_dir().join(format!("dkrrt-study-out-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    let out = Command::new(env!("CARGO_BIN_EXE_dkrrt"))
        .args(["study", "--size", "small", "--seed", "5", "--out"])
        .arg(&d)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    let doc: Value = serde_json::from_str(&std::fs::read_to_string(d.join("study.json")).unwrap()).unwrap();
    let rows = doc["rows"].as_array().unwrap();
    let methods = ["straight", "rrt-static", "cv-rrt", "edmd-rrt", "dk-rrt", "oracle-rrt"];
    // The small size: 2 episodes of each of the 4 scenes, every method (the default) on each.
    assert_eq!(rows.len(), 4 * 2 * methods.len());
    for m in methods {
        let rs: Vec<&Value> = rows.iter().filter(|r| r["method"] == m).collect();
        assert_eq!(rs.len(), 8, "{m}");
        for r in &rs {
            assert!(r["error"].is_null(), "{r}");
            for k in ["tracking_error_rad_rms", "ee_path_error_m_rms", "path_length_rad"] {
                assert!(r[k].as_f64().is_some_and(|v| v.is_finite() && v >= 0.0), "{m}: {k} in {r}");
            }
        }
    }
    let by = |m: &str| rows.iter().filter(|r| r["method"] == m).collect::<Vec<_>>();
    // The episodes aim debris at the straight motion (here it collides in all eight); the
    // true future avoids it every time, on a real motion; dk-rrt never collides.
    assert!(by("straight").iter().all(|r| r["collision"] == true));
    assert!(by("oracle-rrt").iter().all(|r| r["completed"] == true), "{:?}", by("oracle-rrt"));
    assert!(by("oracle-rrt").iter().all(|r| r["path_length_rad"].as_f64().unwrap() > 0.5));
    assert!(by("dk-rrt").iter().all(|r| r["collision"] == false));
    // The summary: one cell per method with its Wilson interval, dk-rrt paired with the others,
    // each method's fitting cost, the split and where it ran.
    let cells = doc["summary"]["cells"].as_array().unwrap();
    assert_eq!(cells.len(), 4 * 6);
    for c in cells {
        let (lo, hi) = (c["completion_ci"][0].as_f64().unwrap(), c["completion_ci"][1].as_f64().unwrap());
        let p = c["completion"].as_f64().unwrap();
        assert!(lo <= p && p <= hi && hi - lo > 0.5, "two episodes: a wide interval ({c})");
    }
    assert_eq!(doc["summary"]["comparisons"].as_array().unwrap().len(), 4 * 5);
    assert_eq!(doc["summary"]["fits"].as_array().unwrap().len(), 6);
    assert!(doc["split"].as_str().unwrap().contains("never"), "{}", doc["split"]);
    assert!(doc["run"]["git_revision"].is_string() && doc["run"]["machine"].is_string());
    let md = std::fs::read_to_string(d.join("study.md")).unwrap();
    for want in ["# dkrrt study", "Split (no leakage)", "| fast-crossing | oracle-rrt | 2 |", "McNemar"] {
        assert!(md.contains(want), "study.md lacks {want:?}:\n{md}");
    }
    // The four figures, as PNG and SVG, linked from study.md.
    for f in ["fig2-ee-path", "fig3-methods", "fig4-joint-profiles", "clearance"] {
        let png = std::fs::read(d.join("figures").join(format!("{f}.png"))).unwrap();
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "{f}.png");
        assert!(png.len() > 10_000, "{f}.png: {} bytes", png.len());
        let svg = std::fs::read_to_string(d.join("figures").join(format!("{f}.svg"))).unwrap();
        assert!(svg.starts_with("<svg"), "{f}.svg");
        assert!(md.contains(&format!("figures/{f}.png")), "study.md links {f}");
    }
    // Rows streamed as they finished.
    assert_eq!(std::fs::read_to_string(d.join("rows.jsonl")).unwrap().lines().count(), 48);
    let _ = std::fs::remove_dir_all(d);
}

#[test]
fn the_process_set_refuses_the_oracle() {
    let d = std::env::temp_dir().join(format!("dkrrt-oracle-{}.toml", std::process::id()));
    let sc = dkrrt_config::DEFAULT_SCENARIO.replace("method = \"dk-rrt\"", "method = \"oracle-rrt\"");
    assert!(sc.contains("method = \"oracle-rrt\""));
    std::fs::write(&d, sc).unwrap();
    let out =
        Command::new(env!("CARGO_BIN_EXE_dkrrt")).args(["launch", "--scenario"]).arg(&d).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("oracle-rrt") && err.contains("in-process"), "{err}");
    let _ = std::fs::remove_file(d);
}

#[test]
fn no_episode_reaches_the_models_the_study_plans_with() {
    // The study fits every method's models once, on generic random scenes: fitting for two
    // different episodes of different scenes gives the very same models as fitting for none.
    let base = dkrrt::study::base_scenario();
    assert_eq!(base.predictor.fit, "generic");
    let plain = dkrrt_planner::predict::fit_models(&base).unwrap();
    for (scene, index) in [("dense", 0), ("tumbling-rods", 3)] {
        let (sc, _) = dkrrt::study::episode_scenario(&base, scene, index, 11, false).unwrap();
        assert!(sc.scene_override.is_some(), "the episode carries its own debris");
        let m = dkrrt_planner::predict::fit_models(&sc).unwrap();
        assert_eq!(m.trans.ab, plain.trans.ab, "{scene} #{index}: translation model");
        assert_eq!(m.att.ab, plain.att.ab, "{scene} #{index}: attitude model");
    }
    // The split is stated with the output.
    let opts = dense_options(4, "dk-rrt", 11, None);
    let split = dkrrt::study_report::split_text(&opts, &dkrrt::study::base_scenario_of(&opts).unwrap());
    assert!(
        split.contains("seed 11") && split.contains("generic random scenes") && split.contains("never"),
        "{split}"
    );
}

#[test]
fn a_study_builds_its_episodes_on_the_scenario_file_it_is_given() {
    let rig = concat!(env!("CARGO_MANIFEST_DIR"), "/shared/config/scenarios/camera-rig.toml");
    let opts = |scenario: Option<&str>| dense_options(1, "dk-rrt-depth", 5, scenario);
    let base = dkrrt::study::base_scenario_of(&opts(Some(rig))).unwrap();
    // The file's camera and input, made a study base: lockstep, generic fits, no episode of
    // its own.
    assert_eq!((base.camera.faces, base.predictor.input.as_str()), (6, "depth"));
    assert_eq!(base.camera.position_m, [0.0, 0.0, -0.8]);
    assert_eq!(base.run.mode, dkrrt_config::Mode::Lockstep);
    assert_eq!(base.predictor.fit, "generic");
    assert!(base.episode.is_none());
    // Each episode replaces the debris, start and goal and keeps the rest of the file.
    let (sc, ep) = dkrrt::study::episode_scenario(&base, "dense", 0, 5, false).unwrap();
    let (plain, plain_ep) =
        dkrrt::study::episode_scenario(&dkrrt::study::base_scenario(), "dense", 0, 5, false).unwrap();
    assert_eq!((sc.camera.faces, sc.predictor.input.as_str()), (6, "depth"));
    assert_eq!(plain.predictor.input, "poses");
    assert_eq!(ep.straight_duration_s, plain_ep.straight_duration_s, "the same episode on either base");
    assert_eq!((ep.start, ep.goal), (plain_ep.start, plain_ep.goal));
    // Without a file: the embedded default.
    assert_eq!(dkrrt::study::base_scenario_of(&opts(None)).unwrap().predictor.input, "poses");
    // A file that is not there is named, before anything runs.
    let missing = std::env::temp_dir().join(format!("dkrrt-no-such-{}.toml", std::process::id()));
    let e = dkrrt::study::base_scenario_of(&opts(Some(missing.to_str().unwrap()))).unwrap_err();
    assert!(e.contains("--scenario") && e.contains("dkrrt-no-such"), "{e}");
    let out = Command::new(env!("CARGO_BIN_EXE_dkrrt"))
        .args(["study", "--episodes", "1", "--scenes", "dense", "--scenario"])
        .arg(&missing)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("dkrrt-no-such"), "{err}");
}

/// Study options of one method on the dense scene, one thread, joint goals.
fn dense_options(
    episodes: u64,
    method: &str,
    seed: u64,
    scenario: Option<&str>,
) -> dkrrt::study::StudyOptions {
    dkrrt::study::StudyOptions {
        scenes: vec!["dense".into()],
        episodes,
        methods: vec![method.into()],
        seed,
        threads: 1,
        pose_goals: false,
        train_deep: false,
        scenario: scenario.map(str::to_string),
    }
}

/// Options that cannot make a study are refused naming the option, before anything runs: no
/// episode or no worker, and a scene or method named twice (its episodes would be run and
/// counted twice).
#[test]
fn a_study_refuses_options_that_cannot_make_one() {
    let cases: [(&[&str], &str); 4] = [
        (&["--episodes", "0"], "--episodes"),
        (&["--episodes", "1", "--threads", "0"], "--threads"),
        (&["--episodes", "1", "--scenes", "dense,fast-crossing,dense"], "--scenes"),
        (&["--episodes", "1", "--scenes", "dense", "--methods", "straight,dk-rrt,straight"], "--methods"),
    ];
    for (args, flag) in cases {
        let out = Command::new(env!("CARGO_BIN_EXE_dkrrt")).arg("study").args(args).output().unwrap();
        let (stdout, err) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
        assert!(!out.status.success(), "{args:?}: {stdout}");
        assert!(err.contains(flag), "{args:?}: {err}");
        assert!(!stdout.contains("episodes x methods"), "{args:?} ran: {stdout}");
    }
}

/// `dkrrt faults --only` matching no case is an error listing the cases, not an empty pass.
#[test]
fn a_fault_filter_matching_nothing_is_refused() {
    let out = Command::new(env!("CARGO_BIN_EXE_dkrrt"))
        .args(["faults", "--only", "no-such-case"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("--only") && err.contains("no-such-case") && err.contains("kill -9 tracker"),
        "{err}"
    );
}

#[test]
fn a_study_runs_threat_episodes_on_a_scene_file() {
    // A scene of one's own (here fast-crossing at twice its speeds, under another name),
    // named relative to the working directory: its episodes run like a named scene's, and
    // the rows name the file.
    let d = std::env::temp_dir().join(format!("dkrrt-study-file-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let mut scene = dkrrt_debris::Scene::named("fast-crossing").unwrap();
    scene.name = "fast-crossing-2x".into();
    for o in &mut scene.debris {
        o.v = o.v.map(|v| 2.0 * v);
    }
    std::fs::write(d.join("mine.toml"), scene.to_toml()).unwrap();
    let args = ["--scenes", "mine.toml", "--episodes", "2", "--methods", "straight,dk-rrt", "--seed", "3"];
    let (_, rows) = run_study(&d, &[&args[..], &["--threads", "1"]].concat());
    assert_eq!(rows.len(), 4);
    let file = std::fs::canonicalize(d.join("mine.toml")).unwrap().display().to_string();
    for r in rows {
        assert_eq!(r["scene"], file.as_str(), "{r}");
        if r["method"] == "dk-rrt" {
            assert_eq!(r["collision"], false, "{r}");
        }
    }
    // Not a scene: refused, naming what a scene may be.
    std::fs::write(d.join("junk.toml"), "name = 3").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_dkrrt"))
        .current_dir(&d)
        .args(["study", "--scenes", "junk.toml", "--episodes", "1"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("--scenes") && err.contains("scene file"), "{err}");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn a_ur_sized_arm_has_threat_episodes_on_debris_of_its_size() {
    // The shipped UR-like scenario and the two scenes scaled to its size: every episode is
    // drawn, the planner completes it and the straight motion is hit.
    let root = env!("CARGO_MANIFEST_DIR");
    let scenes = format!(
        "{root}/sim/debris/scenes/small/fast-crossing-small.toml,{root}/sim/debris/scenes/small/sparse-slow-small.toml"
    );
    let d = std::env::temp_dir().join(format!("dkrrt-study-ur-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let scenario = format!("{root}/shared/config/scenarios/ur-like.toml");
    let (_, rows) = run_study(
        &d,
        &[
            "--scenario",
            &scenario,
            "--scenes",
            &scenes,
            "--episodes",
            "2",
            "--methods",
            "straight,dk-rrt",
            "--seed",
            "21",
            "--threads",
            "1",
        ],
    );
    assert_eq!(rows.len(), 8);
    for r in rows {
        assert!(r.get("error").is_none_or(|e| e.is_null()), "{r}");
        if r["method"] == "dk-rrt" {
            assert_eq!(
                (r["completed"].as_bool(), r["collision"].as_bool()),
                (Some(true), Some(false)),
                "{r}"
            );
        } else {
            assert_eq!(r["collision"], true, "{r}");
        }
    }
    let _ = std::fs::remove_dir_all(&d);
}
