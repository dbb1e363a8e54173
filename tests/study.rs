//! `dkrrt study`: rows for every scene × episode × method, streamed as they finish.

use std::process::Command;

use serde_json::Value;

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
