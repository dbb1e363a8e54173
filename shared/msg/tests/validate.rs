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
