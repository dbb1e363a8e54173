//! Recording: the arm-side payloads round-trip exactly, every payload has a schema with its
//! fields, and an interrupted file reads up to its last flush.

use dkrrt_msg::*;
use dkrrt_recording::*;

fn tmp(name: &str) -> std::path::PathBuf {
    let p = std::env::temp_dir().join(format!("dkrrt-rec-{}-{name}", std::process::id()));
    let _ = std::fs::remove_file(&p);
    p
}

fn state(k: u64) -> RobotState {
    let mut s = <RobotState as Zeroed>::zeroed();
    s.header = Header { seq: k, stamp_ns: k * 1_000_000, mono_ns: 17 + k, source: 1, flags: 4 };
    for i in 0..6 {
        s.q[i] = (k as f64 * 0.1 + i as f64).sin() * std::f64::consts::PI;
        s.qd[i] = 1.0 / (3.0 + i as f64 + k as f64);
        s.tau[i] = -1e-17 * i as f64;
    }
    s
}

fn frame() -> DebrisObservation {
    let mut f = <DebrisObservation as Zeroed>::zeroed();
    f.header.seq = 3;
    f.count = 2;
    for (i, it) in f.items[..2].iter_mut().enumerate() {
        it.id = 7 + i as u32;
        it.flags = DEBRIS_HAS_VELOCITY;
        it.t_meas_ns = 123_456_789;
        it.p = [0.1, -2.0 / 3.0, 1e-300];
        it.q = [0.5, 0.5, -0.5, 0.5];
        it.v = [1.0, 2.0, 3.0];
        it.w = [0.25, 0.0, -0.125];
        it.bounding_radius = 0.6;
        it.shape = DebrisShape::sphere(0.6);
    }
    f
}

#[test]
fn arm_side_payloads_round_trip_exactly() {
    let s = state(5);
    assert_eq!(RobotState::from_json(&s.to_json()), Some(s));
    let mut c = <TorqueCommand as Zeroed>::zeroed();
    c.tau = [1.5, -2.25, 1e-9, 0.0, 3.0, -4.0];
    c.state_seq = 99;
    c.mode = 3;
    c.traj_id = 1_000_002;
    assert_eq!(TorqueCommand::from_json(&c.to_json()), Some(c));
    let f = frame();
    assert_eq!(DebrisObservation::from_json(&f.to_json()), Some(f));
    let mut g = <Goal as Zeroed>::zeroed();
    g.kind = 1;
    g.pose_p = [0.5, 0.1, 0.6];
    g.pose_q = [0.0, 1.0, 0.0, 0.0];
    assert_eq!(Goal::from_json(&g.to_json()), Some(g));
    // A frame whose count disagrees with its items is not decoded.
    let mut v = f.to_json();
    v["count"] = serde_json::json!(3);
    assert_eq!(DebrisObservation::from_json(&v), None);
}

#[test]
fn only_the_used_part_is_written_and_schemas_list_the_fields() {
    let v = frame().to_json();
    assert_eq!(v["items"].as_array().unwrap().len(), 2, "2 of the 32 slots");
    let mut fc = Box::new(<DebrisForecast as Zeroed>::zeroed());
    fc.count = 1;
    fc.steps = 3;
    fc.dt_s = 0.1;
    let v = fc.to_json();
    assert_eq!(v["tracks"][0]["steps"].as_array().unwrap().len(), 3);
    let s = schema_of(&state(1).to_json());
    assert_eq!(s["type"], "object");
    assert_eq!(s["properties"]["q"]["type"], "array");
    assert_eq!(s["properties"]["header"]["properties"]["stamp_ns"]["type"], "integer");
    assert_eq!(s["properties"]["qd"]["items"]["type"], "number");
}

#[test]
fn a_recording_reads_back_and_an_interrupted_one_up_to_its_break() {
    let p = tmp("full.mcap");
    let mut r = Recorder::create(&p).unwrap();
    for k in 0..200 {
        r.record(&state(k), 1_000 + k).unwrap();
        if k % 10 == 0 {
            r.record(&frame(), 1_000 + k).unwrap();
        }
    }
    assert!(Recorder::create(&p).is_err(), "an existing recording is never overwritten");
    assert_eq!(r.finish().unwrap(), 220);
    let (msgs, complete) = read(&p).unwrap();
    assert!(complete);
    assert_eq!(msgs.len(), 220);
    let states: Vec<RobotState> = msgs
        .iter()
        .filter(|m| m.topic == "/dkrrt/robot_state")
        .map(|m| RobotState::from_json(&m.json).unwrap())
        .collect();
    assert_eq!(states.len(), 200);
    assert!(states.iter().enumerate().all(|(k, s)| *s == state(k as u64)));
    // Cut mid-file (a killed recorder): the messages before the cut are read, then it stops.
    let bytes = std::fs::read(&p).unwrap();
    let cut = tmp("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let (part, complete) = read(&cut).unwrap();
    assert!(!complete);
    assert!(part.len() > 50 && part.len() < 220, "{}", part.len());
    for (a, b) in part.iter().zip(&msgs) {
        assert_eq!(a.json, b.json);
    }
    // A file that is no recording at all (text, JSON, an empty file, a recording's tail) is
    // an error naming it, not an empty interrupted recording.
    let other = tmp("other.mcap");
    for text in [&b"# notes\n"[..], b"{\"rows\": []}", b"", &bytes[8..]] {
        std::fs::write(&other, text).unwrap();
        let e = read(&other).unwrap_err();
        assert!(e.contains("other.mcap") && e.contains("not an MCAP recording"), "{e}");
    }
    let _ = std::fs::remove_file(p);
    let _ = std::fs::remove_file(cut);
    let _ = std::fs::remove_file(other);
}
