//! Validation of every payload type: non-finite and out-of-range values are
//! rejected with an error naming the field.

use dkrrt_msg::*;

fn lim() -> ContractLimits {
    ContractLimits::symmetric(3.0, 2.0, 100.0)
}

#[test]
fn robot_state_checks_every_field() {
    let mut s = <RobotState as Zeroed>::zeroed();
    assert!(s.validate(&lim()).is_ok());
    s.qd[3] = f64::INFINITY;
    assert_eq!(s.validate(&lim()), Err(ValidationError::NonFinite { field: "qd", index: 3 }));
    s.qd[3] = 3.1; // beyond 1.5 × v_max
    assert!(matches!(s.validate(&lim()), Err(ValidationError::OutOfRange { field: "qd", index: 3, .. })));
    s.qd[3] = 2.9 / 1.5 - 0.01;
    assert!(s.validate(&lim()).is_ok());
    s.tau[5] = -100.5;
    assert!(matches!(s.validate(&lim()), Err(ValidationError::OutOfRange { field: "tau", index: 5, .. })));
    s.tau[5] = 0.0;
    s.q[1] = 3.04; // inside the 0.05 margin
    assert!(s.validate(&lim()).is_ok());
    s.q[1] = 3.06;
    assert!(s.validate(&lim()).is_err());
}

#[test]
fn torque_command_checks_mode_and_torque() {
    let mut c = <TorqueCommand as Zeroed>::zeroed();
    assert!(c.validate(&lim()).is_ok());
    c.mode = 99;
    assert_eq!(c.validate(&lim()), Err(ValidationError::BadEnum { field: "mode", value: 99 }));
    c.mode = ControllerMode::Track as u32;
    c.tau[0] = f64::NAN;
    assert_eq!(c.validate(&lim()), Err(ValidationError::NonFinite { field: "tau", index: 0 }));
    c.tau[0] = 0.0;
    // The setpoints for servo-mode arms: finite, within the joint and velocity limits.
    c.qd_set[4] = f64::INFINITY;
    assert_eq!(c.validate(&lim()), Err(ValidationError::NonFinite { field: "qd_set", index: 4 }));
    c.qd_set[4] = 0.0;
    c.q_set[1] = 3.06;
    assert!(matches!(c.validate(&lim()), Err(ValidationError::OutOfRange { field: "q_set", index: 1, .. })));
    c.q_set[1] = 0.5;
    assert!(c.validate(&lim()).is_ok());
}

#[test]
fn trajectory_checks_counts_order_and_values() {
    let mut t = Trajectory::hold(&[0.0; NJ]);
    t.duration_s = 1.0;
    assert!(t.validate(&lim()).is_ok());
    t.n_seg[2] = 0;
    assert!(matches!(t.validate(&lim()), Err(ValidationError::Count { field: "n_seg", .. })));
    t.n_seg[2] = MAX_SEGMENTS as u32 + 1;
    assert!(t.validate(&lim()).is_err());
    t.n_seg[2] = 2;
    t.seg[2][1] = JerkSegment { t0: 0.0, p: 0.0, v: 0.0, a: 0.0, j: 0.0 }; // not increasing
    assert!(matches!(t.validate(&lim()), Err(ValidationError::Order { .. })));
    t.seg[2][1].t0 = 0.5;
    t.seg[2][1].j = f64::NAN;
    assert!(matches!(t.validate(&lim()), Err(ValidationError::NonFinite { field: "seg", .. })));
    t.seg[2][1].j = 1000.0; // ends far outside the joint range
    assert!(matches!(t.validate(&lim()), Err(ValidationError::OutOfRange { field: "end position", .. })));
    t.seg[2][1].j = 0.0;
    assert!(t.validate(&lim()).is_ok());
    t.duration_s = f64::NAN;
    assert!(t.validate(&lim()).is_err());
}

#[test]
fn goal_must_be_inside_the_joint_range() {
    let mut g = <Goal as Zeroed>::zeroed();
    assert!(g.validate(&lim()).is_ok());
    g.q[4] = 3.01; // goals get no margin
    assert!(matches!(g.validate(&lim()), Err(ValidationError::OutOfRange { field: "q", index: 4, .. })));
}

#[test]
fn a_pose_goal_needs_a_finite_position_and_a_unit_attitude() {
    let mut g = <Goal as Zeroed>::zeroed();
    g.kind = GoalKind::Pose as u32;
    g.q[4] = 3.01; // not used by a pose goal
    g.pose_p = [0.4, 0.1, 0.6];
    g.pose_q = [1.0, 0.0, 0.0, 0.0];
    assert!(g.validate(&lim()).is_ok());
    g.pose_q = [0.5, 0.0, 0.0, 0.0];
    assert!(matches!(g.validate(&lim()), Err(ValidationError::NotUnit { field: "pose_q", .. })));
    g.pose_q = [1.0, 0.0, 0.0, 0.0];
    g.pose_p[2] = f64::NAN;
    assert!(matches!(g.validate(&lim()), Err(ValidationError::OutOfRange { field: "pose_p", index: 2, .. })));
    g.pose_p[2] = 0.6;
    g.kind = 7;
    assert!(matches!(g.validate(&lim()), Err(ValidationError::BadEnum { field: "kind", value: 7 })));
}

#[test]
fn debris_messages_check_count_pose_and_speed() {
    let mut o = <DebrisObservation as Zeroed>::zeroed();
    o.count = 1;
    o.items[0].q = [1.0, 0.0, 0.0, 0.0];
    o.items[0].bounding_radius = 0.3;
    assert!(o.validate(&lim()).is_ok());
    o.items[0].q = [0.5, 0.0, 0.0, 0.0];
    assert!(matches!(o.validate(&lim()), Err(ValidationError::NotUnit { .. })));
    o.items[0].q = [1.0, 0.0, 0.0, 0.0];
    o.items[0].flags = DEBRIS_HAS_VELOCITY;
    o.items[0].v = [500.0, 0.0, 0.0];
    assert!(matches!(o.validate(&lim()), Err(ValidationError::OutOfRange { field: "items.v", .. })));
    o.items[0].v = [0.0; 3];
    o.items[0].p = [f64::NAN, 0.0, 0.0];
    assert!(matches!(o.validate(&lim()), Err(ValidationError::NonFinite { field: "items.p", .. })));
    o.items[0].p = [0.0; 3];
    o.count = MAX_DEBRIS as u32 + 1;
    assert!(matches!(o.validate(&lim()), Err(ValidationError::Count { field: "count", .. })));

    let mut f = <DebrisForecast as Zeroed>::zeroed();
    f.count = 1;
    f.steps = 2;
    f.dt_s = 0.05;
    for s in &mut f.tracks[0].steps {
        s.q = [1.0, 0.0, 0.0, 0.0];
    }
    assert!(f.validate(&lim()).is_ok());
    f.tracks[0].steps[1].sigma_m = -1.0;
    assert!(matches!(
        f.validate(&lim()),
        Err(ValidationError::OutOfRange { field: "tracks.steps.sigma_m", .. })
    ));
    f.tracks[0].steps[1].sigma_m = 0.0;
    f.steps = 0;
    assert!(f.validate(&lim()).is_err());
}

#[test]
fn heartbeat_checks_enums() {
    let mut h = <Heartbeat as Zeroed>::zeroed();
    h.header.source = Source::Tracker as u32;
    assert!(h.validate(&lim()).is_ok());
    h.state = 17;
    assert!(h.validate(&lim()).is_err());
}

/// A depth image is refused naming the field: its size, intrinsics, pose, range, and any
/// pixel labelled with an instance the frame does not have.
#[test]
fn a_bad_depth_image_is_refused_naming_the_field() {
    let lim = ContractLimits { debris_range_m: 100.0, ..ContractLimits::symmetric(3.0, 3.0, 100.0) };
    let mut ok = Box::new(<DepthImage as Zeroed>::zeroed());
    (ok.width, ok.height, ok.focal_px, ok.cx, ok.cy) = (128, 96, 83.1, 64.0, 48.0);
    ok.orientation = [0.5, -0.5, 0.5, -0.5];
    (ok.range_min_m, ok.range_max_m, ok.n_instances) = (0.2, 15.0, 2);
    ok.instance[5] = 2;
    ok.instance[6] = DEPTH_ARM;
    ok.depth_mm[5] = 4000;
    ok.validate(&lim).unwrap();
    let cases: [(&str, fn(&mut DepthImage)); 8] = [
        ("width", |m| m.width = 129),
        ("height", |m| m.height = 0),
        ("focal_px", |m| m.focal_px = f64::NAN),
        ("cx", |m| m.cx = 200.0),
        ("position_m", |m| m.position_m[2] = f64::INFINITY),
        ("orientation", |m| m.orientation = [1.0, 1.0, 0.0, 0.0]),
        ("range_max_m", |m| m.range_max_m = 70.0),
        ("instance", |m| m.instance[100] = 3),
    ];
    for (field, spoil) in cases {
        let mut m = ok.clone();
        spoil(&mut m);
        let e = m.validate(&lim).unwrap_err().to_string();
        assert!(e.starts_with(field), "{field}: {e}");
    }
    // A pixel beyond the image is not part of it.
    let mut m = ok.clone();
    (m.width, m.instance[128 * 96 - 1]) = (64, 9);
    m.validate(&lim).unwrap();
}
