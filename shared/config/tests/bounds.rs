//! Every defect of the scenario's input the fail-safe issue found: each refused, naming the
//! file and the field.

use dkrrt_config::{Scenario, DEFAULT_SCENARIO};

/// A file in a directory of its own, removed with it when dropped.
struct Written(std::path::PathBuf);

impl std::ops::Deref for Written {
    type Target = std::path::Path;
    fn deref(&self) -> &std::path::Path {
        &self.0
    }
}

impl Drop for Written {
    fn drop(&mut self) {
        if let Some(dir) = self.0.parent() {
            let _ = std::fs::remove_dir_all(dir);
        }
    }
}

/// Writes `text` as `name` in a directory of its own (the tests run in parallel threads: a
/// shared path let one test read another's half-written file).
fn write(name: &str, text: &str) -> Written {
    static NEXT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let k = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("dkrrt-cfg-{}-{k}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    Written(p)
}

/// The error of loading the default scenario with `from` replaced by `to` (load + validate).
fn refused(from: &str, to: &str) -> String {
    assert!(DEFAULT_SCENARIO.contains(from), "{from}");
    let p = write("case.toml", &DEFAULT_SCENARIO.replacen(from, to, 1));
    let r = Scenario::load(p.to_str().unwrap()).and_then(|s| s.load_arm().map(|_| ()));
    let e = r.expect_err("refused").to_string();
    assert!(e.contains("case.toml"), "the error names the file: {e}");
    e
}

#[test]
fn arrays_of_the_wrong_length_are_refused() {
    let kp = "kp = [400.0, 400.0, 400.0, 400.0, 400.0, 400.0]";
    let e = refused(kp, "kp = [400.0, 400.0, 400.0, 400.0, 400.0, 400.0, -1.0, nan]");
    assert!(e.contains("kp") && e.contains("exactly 6"), "{e}");
    let e = refused(kp, "kp = [400.0, 400.0]");
    assert!(e.contains("kp") && e.contains("exactly 6"), "{e}");
    let e = refused("gravity = [0.0, 0.0, 0.0]", "gravity = [0.0, 0.0, 0.0, 1.0]");
    assert!(e.contains("gravity") && e.contains("exactly 3"), "{e}");
    let e = refused("q = [0.35, -0.2, 0.7, 0.3, 0.2, 0.4]", "q = [0.35, -0.2, 0.7, 0.3, 0.2, 0.4, 9.0]");
    assert!(e.contains("exactly 6"), "{e}");
}

#[test]
fn values_of_the_wrong_type_are_refused_by_their_path() {
    // The parser's own message shows the line; the path names the field before it (the
    // line alone would not say which `[section]` a key is in).
    let e = refused("v_max = [0.10, 0.10,", "v_max = [\"fast\", 0.10,");
    assert!(e.contains("motion.v_max[0]: ") && e.contains("invalid type"), "{e}");
    let e = refused("stale_ticks = 10", "stale_ticks = -3");
    assert!(e.contains("tracker.stale_ticks: ") && e.contains("expected u32"), "{e}");
    let e = refused("mode = \"realtime\"", "mode = \"fast\"");
    assert!(e.contains("run.mode: ") && e.contains("unknown variant `fast`"), "{e}");
    let e = refused("heartbeat_hz = 10.0", "heartbeatz = 10.0");
    assert!(e.contains("run.heartbeatz: ") && e.contains("unknown field"), "{e}");
    let e = refused("kp = [400.0, 400.0, 400.0, 400.0, 400.0, 400.0]", "kp = [400.0, 400.0]");
    assert!(e.contains("tracker.kp: "), "{e}");
}

#[test]
fn physically_senseless_values_are_refused_naming_the_field() {
    let kp = "kp = [400.0, 400.0, 400.0, 400.0, 400.0, 400.0]";
    for (from, to, field) in [
        (kp, "kp = [400000.0, 400000.0, 400000.0, 400000.0, 400000.0, 400000.0]", "tracker.kp[0]"),
        (
            "kd = [40.0, 40.0, 40.0, 40.0, 40.0, 40.0]",
            "kd = [40.0, 40.0, 4000.0, 40.0, 40.0, 40.0]",
            "tracker.kd[2]",
        ),
        ("noise_q_std = 0.0", "noise_q_std = 1e300", "sim.noise_q_std"),
        ("noise_qd_std = 0.0", "noise_qd_std = 5.0", "sim.noise_qd_std"),
        ("stale_ticks = 10", "stale_ticks = 4000000000", "tracker.stale_ticks"),
        ("command_timeout_ticks = 20", "command_timeout_ticks = 100000", "sim.command_timeout_ticks"),
        ("gravity = [0.0, 0.0, 0.0]", "gravity = [0.0, 0.0, 1e200]", "robot.gravity[2]"),
        ("duration_s = 8.0", "duration_s = 1e11", "run.duration_s"),
        ("heartbeat_hz = 10.0", "heartbeat_hz = 1e9", "run.heartbeat_hz"),
        ("brake_damping = 200.0", "brake_damping = 0.0", "sim.brake_damping"),
        ("pos_sigma_m = 0.01", "pos_sigma_m = 1e9", "debris.pos_sigma_m"),
        ("dt_s = 0.1", "dt_s = 1e9", "predictor.dt_s"),
        ("max_track_error_rad = 0.01", "max_track_error_rad = 5.0", "tracker.max_track_error_rad"),
        ("max_track_error_rad = 0.01", "max_track_error_rad = nan", "tracker.max_track_error_rad"),
        // Below the measurement noise it would trip on noise alone.
        ("noise_q_std = 0.0", "noise_q_std = 0.01", "tracker.max_track_error_rad"),
    ] {
        let e = refused(from, to);
        assert!(e.contains(field), "{to}: {e}");
    }
    // The gain bound is the stability bound at the control rate: the largest allowed gain
    // passes.
    let (kp_max, kd_max) = dkrrt_config::gain_limits(1000.0);
    let text =
        DEFAULT_SCENARIO.replacen(kp, &format!("kp = [{kp_max:.1}, 400.0, 400.0, 400.0, 400.0, 400.0]"), 1);
    let text = text.replacen("kd = [40.0,", &format!("kd = [{kd_max:.1},"), 1);
    let p = write("edge.toml", &text);
    Scenario::load(p.to_str().unwrap()).unwrap().load_arm().unwrap();
}

#[test]
fn errors_name_the_file_not_the_scenario_name_and_escape_control_characters() {
    let p = write(
        "named.toml",
        &DEFAULT_SCENARIO.replacen("name = \"default\"", "name = \"x\\u001b[31mred\"", 1).replacen(
            "stale_ticks = 10",
            "stale_ticks = 0",
            1,
        ),
    );
    let e = Scenario::load(p.to_str().unwrap()).unwrap().load_arm().unwrap_err().to_string();
    assert!(e.contains("named.toml") && e.contains("tracker.stale_ticks"), "{e}");
    assert!(!e.contains('\u{1b}'), "no raw escape: {e:?}");
    // A file name with a control character is shown escaped.
    let p = write("bad\u{7}name.toml", "not toml");
    let e = Scenario::load(p.to_str().unwrap()).unwrap_err().to_string();
    assert!(!e.contains('\u{7}') && e.contains("\\u{7}"), "{e:?}");
}

#[test]
fn devices_and_huge_files_are_not_read() {
    let e = Scenario::load("/dev/zero").unwrap_err().to_string();
    assert!(e.contains("/dev/zero") && e.contains("not a regular file"), "{e}");
    let big = write("big.toml", &"#".repeat(2 << 20));
    let e = Scenario::load(big.to_str().unwrap()).unwrap_err().to_string();
    assert!(e.contains("big.toml") && e.contains("limit"), "{e}");
    // A URDF that is a device.
    let p = write("urdf.toml", &DEFAULT_SCENARIO.replacen("urdf = \"\"", "urdf = \"/dev/zero\"", 1));
    let e = Scenario::load(p.to_str().unwrap()).unwrap().load_arm().unwrap_err().to_string();
    assert!(e.contains("robot.urdf") && e.contains("not a regular file"), "{e}");
}
