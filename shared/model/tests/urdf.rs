//! URDF loading: shipped file, fixed-joint merging, continuous joints and typed errors.

mod common;

use common::{random_q, random_vec, rel, rng};
use dkrrt_model::{ArmModel, JVec, ModelError, DEFAULT_ARM_URDF, NJ};
use nalgebra::{Matrix3, Vector3};

fn err(xml: &str) -> ModelError {
    ArmModel::from_urdf_str(xml).expect_err("URDF should be rejected")
}

/// Replace exactly one occurrence of `from` in the default URDF.
fn edit(from: &str, to: &str) -> String {
    assert_eq!(DEFAULT_ARM_URDF.matches(from).count(), 1, "pattern `{from}` must be unique");
    DEFAULT_ARM_URDF.replacen(from, to, 1)
}

#[test]
fn shipped_file_on_disk_equals_embedded_default() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/urdf/dkrrt_arm.urdf");
    assert_eq!(std::fs::read_to_string(path).unwrap(), DEFAULT_ARM_URDF);
    let a = ArmModel::from_urdf_file(path).unwrap();
    let b = ArmModel::default_arm();
    assert_eq!(a.name(), "dkrrt_arm");
    assert_eq!(a.name(), b.name());
    assert_eq!(a.joint_names(), b.joint_names());
    assert_eq!(a.link_names(), b.link_names());
    assert_eq!(a.limits(), b.limits());
    assert_eq!(a.collision_capsules(), b.collision_capsules());
    assert_eq!(a.link_inertials(), b.link_inertials());
    let mut r = rng(41);
    for _ in 0..5 {
        let (q, qd, qdd) = (random_q(&a, &mut r), random_vec(&mut r, 1.0), random_vec(&mut r, 1.0));
        assert_eq!(a.rnea(&q, &qd, &qdd), b.rnea(&q, &qd, &qdd));
        assert_eq!(a.fk(&q), b.fk(&q));
    }
}

#[test]
fn default_arm_metadata() {
    let m = ArmModel::default_arm();
    assert_eq!(
        m.joint_names().clone(),
        ["shoulder_yaw", "shoulder_pitch", "elbow_pitch", "wrist_pitch", "wrist_yaw", "wrist_roll"]
    );
    assert_eq!(m.ee_link_name(), "tool0");
    let l = m.limits();
    for i in 0..NJ {
        assert!(l.q_min[i] < 0.0 && l.q_max[i] > 0.0);
        assert!(l.v_max[i] > 0.0 && l.v_max[i] <= 0.2);
        assert!(l.tau_max[i] >= 60.0 && l.tau_max[i] <= 200.0);
    }
    // The end effector (8 kg) is merged into the wrist roll link (12 kg).
    let wr = m.link_inertials()[5];
    assert!((wr.mass - 20.0).abs() < 1e-12);
    let com_x = (12.0 * 0.12 + 8.0 * (0.25 + 0.075)) / 20.0;
    assert!((wr.com - Vector3::new(com_x, 0.0, 0.0)).norm() < 1e-12);
    // Physically valid inertias everywhere.
    for li in m.link_inertials() {
        let e = li.inertia.symmetric_eigen().eigenvalues;
        assert!(e.min() > 0.0);
        assert!(e[0] + e[1] >= e[2] && e[0] + e[2] >= e[1] && e[1] + e[2] >= e[0]);
    }
}

/// Merging a fixed child link must equal a hand-merged single link (parallel-axis theorem).
#[test]
fn fixed_child_inertia_is_merged_into_parent() {
    let (m1, c1, i1) =
        (12.0, Vector3::new(0.12, 0.0, 0.0), Matrix3::from_diagonal(&Vector3::new(0.06, 0.0925, 0.0925)));
    let (m2, c2, i2) =
        (8.0, Vector3::new(0.325, 0.0, 0.0), Matrix3::from_diagonal(&Vector3::new(0.04, 0.035, 0.035)));
    let m = m1 + m2;
    let c = (c1 * m1 + c2 * m2) / m;
    let shift =
        |mass: f64, d: Vector3<f64>| (Matrix3::identity() * d.norm_squared() - d * d.transpose()) * mass;
    let i = i1 + shift(m1, c1 - c) + i2 + shift(m2, c2 - c);
    let merged_inertial = format!(
        r#"<inertial>
      <origin xyz="{} 0 0"/>
      <mass value="{m}"/>
      <inertia ixx="{}" ixy="0" ixz="0" iyy="{}" iyz="0" izz="{}"/>
    </inertial>"#,
        c.x,
        i[(0, 0)],
        i[(1, 1)],
        i[(2, 2)]
    );
    let old_inertial = r#"<inertial>
      <origin xyz="0.12 0 0"/>
      <mass value="12.0"/>
      <inertia ixx="0.06" ixy="0" ixz="0" iyy="0.0925" iyz="0" izz="0.0925"/>
    </inertial>"#;
    let ee_inertial = r#"<inertial>
      <origin xyz="0.075 0 0"/>
      <mass value="8.0"/>
      <inertia ixx="0.04" ixy="0" ixz="0" iyy="0.035" iyz="0" izz="0.035"/>
    </inertial>"#;
    let xml = edit(old_inertial, &merged_inertial).replacen(ee_inertial, "", 1);
    let hand = ArmModel::from_urdf_str(&xml).unwrap();
    let auto = ArmModel::default_arm();
    let mut r = rng(42);
    for _ in 0..10 {
        let q = random_q(&auto, &mut r);
        assert!(rel(&hand.mass_matrix(&q), &auto.mass_matrix(&q)) < 1e-12);
        assert_eq!(hand.fk(&q), auto.fk(&q));
    }
    // And it does matter: dropping the end effector changes M.
    let light = ArmModel::from_urdf_str(&DEFAULT_ARM_URDF.replacen(ee_inertial, "", 1)).unwrap();
    let q = random_q(&auto, &mut r);
    assert!(rel(&light.mass_matrix(&q), &auto.mass_matrix(&q)) > 1e-3);
}

#[test]
fn continuous_joints_have_infinite_limits() {
    let xml = edit(
        r#"<joint name="wrist_roll" type="revolute">"#,
        r#"<joint name="wrist_roll" type="continuous">"#,
    );
    let m = ArmModel::from_urdf_str(&xml).unwrap();
    assert_eq!(m.limits().q_min[5], f64::NEG_INFINITY);
    assert_eq!(m.limits().q_max[5], f64::INFINITY);
    assert_eq!(m.limits().v_max[5], 0.20);
}

#[test]
fn random_urdfs_load() {
    for seed in 0..20 {
        let m = ArmModel::from_urdf_str(&common::random_urdf(seed))
            .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        assert_eq!(m.ee_link_name(), "tool");
        assert_eq!(m.link_names()[0], "l0");
    }
}

#[test]
fn missing_file_is_io_error() {
    let e = ArmModel::from_urdf_file("/dev/null/arm.urdf").unwrap_err();
    assert!(matches!(e, ModelError::Io { .. }), "{e:?}");
    assert!(e.to_string().contains("/dev/null/arm.urdf"));
}

#[test]
fn malformed_xml_is_parse_error() {
    assert!(matches!(err("<robot name='x'><link name='a'>"), ModelError::Parse(_)));
}

const J1_LIMIT: &str = r#"<limit lower="-4.71238898" upper="4.71238898" velocity="0.12" effort="200.0"/>"#;

#[test]
fn limit_errors_name_joint_and_field() {
    let cases = [
        (r#"<limit lower="-4.71238898" upper="4.71238898" velocity="0" effort="200.0"/>"#, "velocity"),
        (r#"<limit lower="-4.71238898" upper="4.71238898" velocity="0.12" effort="0"/>"#, "effort"),
        (r#"<limit lower="1.0" upper="-1.0" velocity="0.12" effort="200.0"/>"#, "upper"),
    ];
    for (limit, field) in cases {
        let xml = DEFAULT_ARM_URDF.replacen(J1_LIMIT, limit, 1);
        match err(&xml) {
            ModelError::InvalidLimit { joint, field: f, .. } => {
                assert_eq!(joint, "shoulder_yaw");
                assert_eq!(f, field);
            }
            e => panic!("{field}: unexpected {e:?}"),
        }
        let msg = err(&xml).to_string();
        assert!(msg.contains("shoulder_yaw") && msg.contains(field), "{msg}");
    }
    // A missing attribute is caught by the parser; the message names it.
    let xml = DEFAULT_ARM_URDF.replacen(J1_LIMIT, r#"<limit lower="-1" upper="1" effort="200.0"/>"#, 1);
    let msg = err(&xml).to_string();
    assert!(msg.contains("velocity"), "{msg}");
    // URDF 1.2 turns a missing bound into ±inf, which a revolute joint rejects.
    let xml = DEFAULT_ARM_URDF
        .replacen(r#"<robot name="dkrrt_arm">"#, r#"<robot name="dkrrt_arm" version="1.2">"#, 1)
        .replacen(J1_LIMIT, r#"<limit upper="1" velocity="0.1" effort="200.0"/>"#, 1);
    assert!(matches!(err(&xml), ModelError::InvalidLimit { field: "lower", .. }), "{:?}", err(&xml));
    // No <limit> at all.
    match err(&DEFAULT_ARM_URDF.replacen(J1_LIMIT, "", 1)) {
        ModelError::MissingLimit { joint } => assert_eq!(joint, "shoulder_yaw"),
        e => panic!("{e:?}"),
    }
}

#[test]
fn structural_errors_are_typed() {
    // Prismatic joint.
    match err(&edit(
        r#"<joint name="elbow_pitch" type="revolute">"#,
        r#"<joint name="elbow_pitch" type="prismatic">"#,
    )) {
        ModelError::UnsupportedJoint { joint, kind } => {
            assert_eq!(joint, "elbow_pitch");
            assert_eq!(kind, "prismatic");
        }
        e => panic!("{e:?}"),
    }
    // Five actuated joints.
    match err(&edit(
        r#"<joint name="wrist_roll" type="revolute">"#,
        r#"<joint name="wrist_roll" type="fixed">"#,
    )) {
        ModelError::WrongDof { found: 5, expected: 6 } => {}
        e => panic!("{e:?}"),
    }
    // A fixed side branch on upper_boom (a massless camera frame) is part of that body: the
    // model is the same.
    let branch = r#"<link name="camera"/><joint name="camera_mount" type="fixed"><parent link="upper_boom"/><child link="camera"/></joint></robot>"#;
    let m = ArmModel::from_urdf_str(&DEFAULT_ARM_URDF.replacen("</robot>", branch, 1)).unwrap();
    let d = ArmModel::default_arm();
    let q = JVec::from_column_slice(&[0.3, -0.4, 0.9, 0.1, 0.5, -0.2]);
    assert_eq!((m.fk(&q), m.mass_matrix(&q)), (d.fk(&q), d.mass_matrix(&q)));
    // A second root.
    match err(&DEFAULT_ARM_URDF.replacen("</robot>", r#"<link name="floating"/></robot>"#, 1)) {
        ModelError::MultipleRoots { links } => assert!(links.contains(&"floating".to_string())),
        e => panic!("{e:?}"),
    }
    // Unknown link.
    match err(&edit(r#"<child link="lower_boom"/>"#, r#"<child link="lower_bom"/>"#)) {
        ModelError::UnknownLink { joint, link } => {
            assert_eq!(joint, "elbow_pitch");
            assert_eq!(link, "lower_bom");
        }
        e => panic!("{e:?}"),
    }
    // Zero axis.
    match err(&DEFAULT_ARM_URDF.replacen(r#"<axis xyz="1 0 0"/>"#, r#"<axis xyz="0 0 0"/>"#, 1)) {
        ModelError::InvalidAxis { joint, .. } => assert_eq!(joint, "wrist_roll"),
        e => panic!("{e:?}"),
    }
}

#[test]
fn inertia_and_collision_errors_name_the_link() {
    // Triangle inequality violated (ixx > iyy + izz).
    let bad = edit(
        r#"<inertia ixx="0.0704" ixy="0" ixz="0" iyy="1.868533" iyz="0" izz="1.868533"/>"#,
        r#"<inertia ixx="5.0" ixy="0" ixz="0" iyy="1.868533" iyz="0" izz="1.868533"/>"#,
    );
    match err(&bad) {
        ModelError::InvalidInertia { link, reason } => {
            assert_eq!(link, "lower_boom");
            assert!(reason.contains("triangle"), "{reason}");
        }
        e => panic!("{e:?}"),
    }
    // Not positive semi-definite.
    let bad = edit(
        r#"<inertia ixx="0.0704" ixy="0" ixz="0" iyy="1.868533" iyz="0" izz="1.868533"/>"#,
        r#"<inertia ixx="0.0704" ixy="2.0" ixz="0" iyy="1.868533" iyz="0" izz="1.868533"/>"#,
    );
    assert!(matches!(err(&bad), ModelError::InvalidInertia { ref link, .. } if link == "lower_boom"));
    // Negative mass.
    let bad = edit(r#"<mass value="22.0"/>"#, r#"<mass value="-22.0"/>"#);
    assert!(matches!(err(&bad), ModelError::InvalidInertia { ref link, .. } if link == "lower_boom"));
    // A box collision gets a fitted capsule that encloses it (with a note).
    let boxed = edit(
        r#"<geometry><cylinder radius="0.09" length="1.20"/></geometry>"#,
        r#"<geometry><box size="0.1 0.1 1.2"/></geometry>"#,
    );
    let m = ArmModel::from_urdf_str(&boxed).unwrap();
    let c = m.collision_capsules()[2];
    assert!(
        m.load_notes().iter().any(|n| n.contains("lower_boom") && n.contains("fitted")),
        "{:?}",
        m.load_notes()
    );
    // The box's corners (origin 0.5 0 0, rotated so its long side lies along x).
    for corner in [[-0.1, -0.05, -0.05], [1.1, 0.05, 0.05], [1.1, -0.05, 0.05], [-0.1, 0.05, -0.05]] {
        let p = nalgebra::Point3::new(corner[0], corner[1], corner[2]);
        assert!(seg_dist(&p, &c.a, &c.b) <= c.radius + 1e-9, "corner {corner:?} outside {c:?}");
    }
    assert!(c.radius < 0.0708 + 1e-9 && (c.b - c.a).norm() <= 1.2 + 1e-9, "tight: {c:?}");
    // No collision on a moving link: not a refusal; no geometry at all is a point, with a note.
    let no_col = edit(
        r#"<collision>
      <origin xyz="0.50 0 0" rpy="0 1.5707963267948966 0"/>
      <geometry><cylinder radius="0.09" length="1.20"/></geometry>
    </collision>"#,
        "",
    );
    let m = ArmModel::from_urdf_str(&no_col).unwrap();
    assert_eq!(m.collision_capsules()[2].radius, 0.0);
    assert!(
        m.load_notes().iter().any(|n| n.contains("lower_boom") && n.contains("not checked")),
        "{:?}",
        m.load_notes()
    );
    // Collision on both the wrist roll link and its fixed end effector: one capsule around both.
    let two = edit(
        r#"<link name="end_effector">"#,
        r#"<link name="end_effector"><collision><geometry><sphere radius="0.1"/></geometry></collision>"#,
    );
    let m = ArmModel::from_urdf_str(&two).unwrap();
    let d = ArmModel::default_arm();
    let (c, old) = (m.collision_capsules()[5], d.collision_capsules()[5]);
    for p in [old.a, old.b] {
        assert!(seg_dist(&p, &c.a, &c.b) + old.radius <= c.radius + 1e-9, "{c:?} encloses {old:?}");
    }
    assert!(
        m.load_notes().iter().any(|n| n.contains("wrist_roll_link") && n.contains("2 collision")),
        "{:?}",
        m.load_notes()
    );
    // A massless last link has no inertia about its axis: singular M.
    let xml = r#"<robot name="massless">
      <link name="b"/>
      <joint name="j" type="revolute"><parent link="b"/><child link="l"/><axis xyz="0 0 1"/>
        <limit lower="-1" upper="1" velocity="1" effort="1"/></joint>
      <link name="l"><collision><geometry><sphere radius="0.1"/></geometry></collision></link>
    </robot>"#;
    assert!(matches!(err(xml), ModelError::WrongDof { found: 1, .. }));
    let massless_tip = DEFAULT_ARM_URDF
        .replacen(
            r#"<mass value="12.0"/>
      <inertia ixx="0.06" ixy="0" ixz="0" iyy="0.0925" iyz="0" izz="0.0925"/>"#,
            r#"<mass value="0"/>
      <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/>"#,
            1,
        )
        .replacen(
            r#"<mass value="8.0"/>
      <inertia ixx="0.04" ixy="0" ixz="0" iyy="0.035" iyz="0" izz="0.035"/>"#,
            r#"<mass value="0"/>
      <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/>"#,
            1,
        );
    match err(&massless_tip) {
        ModelError::SingularInertia { link, joint } => {
            assert_eq!(link, "wrist_roll_link");
            assert_eq!(joint, "wrist_roll");
        }
        e => panic!("{e:?}"),
    }
}

#[test]
fn sphere_and_capsule_collisions_become_capsules() {
    let xml = edit(
        r#"<geometry><cylinder radius="0.09" length="1.20"/></geometry>"#,
        r#"<geometry><capsule radius="0.09" length="1.00"/></geometry>"#,
    )
    .replacen(
        r#"<geometry><cylinder radius="0.10" length="0.20"/></geometry>"#,
        r#"<geometry><sphere radius="0.12"/></geometry>"#,
        1,
    );
    let m = ArmModel::from_urdf_str(&xml).unwrap();
    let c = m.collision_capsules();
    assert!((c[2].a.coords - Vector3::new(0.0, 0.0, 0.0)).norm() < 1e-12 || (c[2].b.coords).norm() < 1e-12);
    assert!(((c[2].b - c[2].a).norm() - 1.0).abs() < 1e-12);
    assert_eq!(c[3].a, c[3].b);
    assert_eq!(c[3].radius, 0.12);
    let _ = JVec::zeros();
}

/// Distance from `p` to the segment `a`-`b`.
fn seg_dist(p: &nalgebra::Point3<f64>, a: &nalgebra::Point3<f64>, b: &nalgebra::Point3<f64>) -> f64 {
    let ab = b - a;
    let t =
        if ab.norm_squared() > 0.0 { ((p - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0) } else { 0.0 };
    (p - (a + ab * t)).norm()
}
