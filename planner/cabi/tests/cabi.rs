//! The C ABI, called as C calls it: errors that name the file and the field, null arguments
//! refused, the checks and the timing those of `dkrrt plan`.

use std::ffi::{c_char, CStr, CString};
use std::path::{Path, PathBuf};

use dkrrt_model::{ArmModel, NJ};
use dkrrt_plan_cabi::*;
use dkrrt_rrt::problem::{solve, Problem, ProblemObstacle, ProblemPose, ProblemShape};

const START: [f64; NJ] = [0.0, -0.5, 1.0, 0.0, 0.5, 0.0];
/// A turn of the base by 1 rad: link 4 sweeps an arc of about 1.5 m.
const TURNED: [f64; NJ] = [1.0, -0.5, 1.0, 0.0, 0.5, 0.0];
const MID: [f64; NJ] = [0.5, -0.5, 1.0, 0.0, 0.5, 0.0];

fn link4_at(q: &[f64; NJ]) -> [f64; 3] {
    let poser = dkrrt_collision::ArmPoser::new(ArmModel::default_arm());
    let mut caps = [dkrrt_collision::PosedCapsule::default(); NJ];
    poser.pose(q, &mut caps);
    caps[4].centre
}

fn problem(poses: Vec<ProblemPose>, r: f64) -> Problem {
    Problem {
        urdf: String::new(),
        start: START,
        goal: TURNED,
        v_max: Some([0.5; NJ]),
        margin_m: 0.0,
        time_limit_s: 0.2,
        seed: 3,
        obstacles: vec![ProblemObstacle { shape: ProblemShape::Sphere { radius: r }, poses }],
    }
}

fn still_at(p: [f64; 3]) -> Vec<ProblemPose> {
    vec![ProblemPose { t: 0.0, p, q: [1.0, 0.0, 0.0, 0.0] }]
}

fn write(name: &str, text: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dkrrt-cabi-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let f = dir.join(name);
    std::fs::write(&f, text).unwrap();
    f
}

fn open_file(f: &Path) -> Result<*mut DkProblem, String> {
    let c = CString::new(f.to_str().unwrap()).unwrap();
    let mut err = [0 as c_char; 1024];
    // SAFETY: a NUL-terminated path and a buffer of err.len() bytes.
    let h = unsafe { dk_problem_open(c.as_ptr(), 0.0, err.as_mut_ptr(), err.len()) };
    if h.is_null() {
        // SAFETY: dk_problem_open NUL-terminates its message within the buffer.
        Err(unsafe { CStr::from_ptr(err.as_ptr()) }.to_string_lossy().into_owned())
    } else {
        Ok(h)
    }
}

fn open(name: &str, p: &Problem) -> *mut DkProblem {
    open_file(&write(name, &serde_json::to_string(p).unwrap())).unwrap()
}

#[test]
fn errors_name_the_file_and_the_field() {
    let mut p = problem(still_at([3.0, 0.0, 0.0]), 0.1);
    p.margin_m = 2.0;
    let f = write("bad-margin.json", &serde_json::to_string(&p).unwrap());
    let e = open_file(&f).unwrap_err();
    assert!(e.contains(f.to_str().unwrap()) && e.contains("margin_m"), "{e}");

    let mut p = problem(still_at([3.0, 0.0, 0.0]), 0.1);
    p.start[1] = 9.0;
    let f = write("bad-start.json", &serde_json::to_string(&p).unwrap());
    let e = open_file(&f).unwrap_err();
    assert!(e.contains("bad-start.json") && e.contains("start[1]") && e.contains("joint limits"), "{e}");

    let missing = std::env::temp_dir().join("dkrrt-cabi-no-such-file.json");
    let e = open_file(&missing).unwrap_err();
    assert!(e.contains("dkrrt-cabi-no-such-file.json"), "{e}");

    // A short buffer gets the message cut, NUL-terminated inside it.
    let c = CString::new(missing.to_str().unwrap()).unwrap();
    let mut err = [1 as c_char; 8];
    // SAFETY: as above, with an 8-byte buffer.
    let h = unsafe { dk_problem_open(c.as_ptr(), 0.0, err.as_mut_ptr(), err.len()) };
    assert!(h.is_null());
    assert_eq!(err[7], 0);
    assert_eq!(unsafe { CStr::from_ptr(err.as_ptr()) }.to_bytes().len(), 7);
}

#[test]
fn null_arguments_are_refused() {
    let q = [0.0; NJ];
    let mut info = DkInfo::default();
    let mut counts = DkCounts::default();
    let mut err = [0 as c_char; 64];
    // SAFETY: every call below is given a null pointer somewhere, which it must refuse.
    unsafe {
        assert!(dk_problem_open(std::ptr::null(), 0.0, err.as_mut_ptr(), err.len()).is_null());
        assert!(CStr::from_ptr(err.as_ptr()).to_string_lossy().contains("null"));
        assert!(dk_problem_open(std::ptr::null(), 0.0, std::ptr::null_mut(), 0).is_null());
        assert_eq!(dk_problem_info(std::ptr::null(), &mut info), -1);
        assert_eq!(dk_state_clear(std::ptr::null_mut(), q.as_ptr()), -1);
        assert_eq!(dk_segment_clear(std::ptr::null_mut(), q.as_ptr(), q.as_ptr()), -1);
        assert_eq!(
            dk_path_duration(std::ptr::null_mut(), q.as_ptr(), 2, std::ptr::null_mut(), std::ptr::null_mut()),
            -1.0
        );
        assert_eq!(dk_problem_counts(std::ptr::null(), &mut counts), -1);
        dk_problem_close(std::ptr::null_mut());
    }
    let h = open("nulls.json", &problem(still_at([3.0, 0.0, 0.0]), 0.1));
    // SAFETY: a live handle with null arrays, which the calls must refuse.
    unsafe {
        assert_eq!(dk_problem_info(h, std::ptr::null_mut()), -1);
        assert_eq!(dk_state_clear(h, std::ptr::null()), -1);
        assert_eq!(dk_segment_clear(h, q.as_ptr(), std::ptr::null()), -1);
        assert_eq!(
            dk_path_duration(h, std::ptr::null(), 2, std::ptr::null_mut(), std::ptr::null_mut()),
            -1.0
        );
        assert_eq!(dk_path_duration(h, q.as_ptr(), 1, std::ptr::null_mut(), std::ptr::null_mut()), -1.0);
        assert_eq!(dk_problem_counts(h, std::ptr::null_mut()), -1);
        dk_problem_close(h);
    }
}

#[test]
fn the_checks_see_the_obstacle_and_count_themselves() {
    // A sphere on link 4 halfway along the base's turn: the straight segment crosses it.
    let h = open("blocked.json", &problem(still_at(link4_at(&MID)), 0.15));
    let mut info = DkInfo::default();
    let far = [0.0, -0.5, 1.0, 0.0, 0.5, 0.4];
    // SAFETY: a live handle and arrays of NJ values.
    unsafe {
        assert_eq!(dk_problem_info(h, &mut info), 0);
        assert_eq!((info.start, info.goal, info.still), (START, TURNED, 1));
        assert!(info.start_clear_m > 0.1 && info.goal_clear_m > 0.1, "{info:?}");
        assert!(info.delta_m > 0.0 && info.q_min[0] < 0.0 && info.q_max[0] > 0.0);
        assert_eq!(dk_state_clear(h, START.as_ptr()), 1);
        assert_eq!(dk_state_clear(h, TURNED.as_ptr()), 1);
        assert_eq!(dk_state_clear(h, MID.as_ptr()), 0, "link 4 is inside the sphere");
        let mut outside = START;
        outside[1] = 50.0;
        assert_eq!(dk_state_clear(h, outside.as_ptr()), 0, "outside the joint limits");
        assert_eq!(dk_segment_clear(h, START.as_ptr(), TURNED.as_ptr()), 0, "the turn crosses the sphere");
        assert_eq!(dk_segment_clear(h, START.as_ptr(), far.as_ptr()), 1, "a wrist turn away from it");
        let mut c = DkCounts::default();
        assert_eq!(dk_problem_counts(h, &mut c), 0);
        assert_eq!((c.states, c.segments), (4, 2));
        // The clear segment needed more than one sample (0.4 rad of wrist turn at δ apart).
        assert!(c.configs > c.states + 2, "{c:?}");
        assert!(c.check_s > 0.0);
        dk_problem_close(h);
    }
    let mut p = problem(still_at(link4_at(&MID)), 0.15);
    p.obstacles[0].poses.push(ProblemPose { t: 1.0, p: [3.0, 0.0, 0.0], q: [1.0, 0.0, 0.0, 0.0] });
    let h = open("moving.json", &p);
    // SAFETY: a live handle.
    unsafe {
        assert_eq!(dk_problem_info(h, &mut info), 0);
        assert_eq!(info.still, 0, "a moving obstacle is not a joint-space problem");
        dk_problem_close(h);
    }
}

#[test]
fn a_path_is_timed_and_judged_as_dkrrt_plan_judges_its_own() {
    // With the sphere far away, `dkrrt plan` drives the straight motion: the same two-point
    // path through the C ABI gets the same duration and the same clearance.
    let p = problem(still_at([2.5, 0.0, 0.0]), 0.1);
    let m = dkrrt_config::Scenario::default_scenario().motion;
    let sol = solve(&p, ArmModel::default_arm(), m.v_max, m.a_max, m.j_max).unwrap();
    assert!(sol.solved && sol.path.len() == 2, "{:?}", sol.path);
    let h = open("clear.json", &p);
    let path = [START, TURNED];
    let (mut clear, mut passed) = (f64::NAN, -1);
    // SAFETY: a live handle, 2 × NJ values, valid outputs.
    let d = unsafe { dk_path_duration(h, path.as_ptr().cast(), 2, &mut clear, &mut passed) };
    assert_eq!(passed, 1);
    assert!((d - sol.duration_s).abs() < 1e-9, "{d} vs {}", sol.duration_s);
    assert!((clear - sol.min_clearance_m.unwrap()).abs() < 1e-9, "{clear} vs {:?}", sol.min_clearance_m);
    // SAFETY: a live handle.
    unsafe { dk_problem_close(h) };

    // Through the sphere: timed, and failed, with the depth it goes in.
    let h = open("through.json", &problem(still_at(link4_at(&MID)), 0.15));
    // SAFETY: as above.
    let d = unsafe { dk_path_duration(h, path.as_ptr().cast(), 2, &mut clear, &mut passed) };
    assert!(d > 0.0);
    assert_eq!(passed, 0);
    assert!(clear < -0.05, "{clear}");
    // A waypoint that is no configuration (NaN, or beyond the joint limits) is never a timed
    // path that passed.
    for bad in [[f64::NAN; NJ], [9.0, 0.0, 0.0, 0.0, 0.0, 0.0]] {
        let path = [START, bad, TURNED];
        (clear, passed) = (f64::NAN, -1);
        // SAFETY: a live handle, 3 × NJ values, valid outputs.
        let d = unsafe { dk_path_duration(h, path.as_ptr().cast(), 3, &mut clear, &mut passed) };
        assert!(d == -2.0 || (passed == 0 && d.is_finite()), "{bad:?}: duration {d}, passed {passed}");
    }
    // SAFETY: a live handle.
    unsafe { dk_problem_close(h) };
}
