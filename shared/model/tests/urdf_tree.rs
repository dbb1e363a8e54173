//! Real-arm URDFs: trees, fixed frames and side branches, meshes on `package://` paths,
//! links without collision geometry (fixtures in `tests/fixtures/`, written for these tests).

mod common;

use std::path::{Path, PathBuf};

use common::{random_q, random_vec, rel, rng};
use dkrrt_model::mesh::fit_capsule;
use dkrrt_model::{ArmModel, JVec, ModelError, UrdfOptions, DEFAULT_ARM_URDF, NJ};
use nalgebra::{Point3, Vector3};
use rand::Rng;

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures")
}

fn ur_urdf() -> PathBuf {
    fixtures().join("pkgs/ur_like_description/urdf/ur_like.urdf")
}

fn ur_opts(tip: Option<&str>) -> UrdfOptions {
    UrdfOptions {
        tip_link: tip.map(str::to_string),
        package_path: vec![fixtures().join("pkgs")],
        ..UrdfOptions::default()
    }
}

fn seg_dist(p: &Point3<f64>, a: &Point3<f64>, b: &Point3<f64>) -> f64 {
    let ab = b - a;
    let t =
        if ab.norm_squared() > 0.0 { ((p - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0) } else { 0.0 };
    (p - (a + ab * t)).norm()
}

/// The properties every loaded model must have: M symmetric positive definite, inverse and
/// forward dynamics inverse to each other, RNEA = M q̈ + h, and the end-effector Jacobian equal
/// to finite differences of FK.
fn assert_dynamics_consistent(m: &ArmModel) {
    let mut r = rng(7);
    for _ in 0..20 {
        let q = random_q(m, &mut r);
        let qd = random_vec(&mut r, 1.0);
        let qdd = random_vec(&mut r, 2.0);
        let mm = m.mass_matrix(&q);
        assert!(rel(&mm, &mm.transpose()) < 1e-12, "M symmetric");
        assert!(mm.symmetric_eigen().eigenvalues.min() > 0.0, "M positive definite");
        let tau = m.rnea(&q, &qd, &qdd);
        assert!(rel(&tau, &(mm * qdd + m.nonlinear_effects(&q, &qd))) < 1e-10);
        assert!(rel(&m.forward_dynamics(&q, &qd, &tau), &qdd) < 1e-8);
        let j = m.jacobian(&q);
        let eps = 1e-6;
        for i in 0..NJ {
            let mut qp = q;
            let mut qm = q;
            qp[i] += eps;
            qm[i] -= eps;
            let dp = (m.fk(&qp).translation.vector - m.fk(&qm).translation.vector) / (2.0 * eps);
            for k in 0..3 {
                assert!((j[(k, i)] - dp[k]).abs() < 1e-6, "J[{k},{i}] {} vs {}", j[(k, i)], dp[k]);
            }
        }
    }
}

#[test]
fn a_ur_like_tree_with_package_meshes_loads_as_pinocchio_would() {
    let m = ArmModel::from_urdf_file_with(ur_urdf(), &ur_opts(None)).unwrap();
    let notes = m.load_notes().join("\n");
    assert_eq!(m.joint_names()[0], "shoulder_pan_joint");
    assert_eq!(m.joint_names()[5], "wrist_3_joint");
    // The default tip: wrist_3_link, where the fixed frames ee_link and tool0 branch (noted).
    assert_eq!(m.ee_link_name(), "wrist_3_link");
    assert!(notes.contains("tip link `wrist_3_link`") && notes.contains("tool0"), "{notes}");
    assert!(notes.contains("2 <transmission> element(s) ignored"), "{notes}");
    // The prismatic finger is off the chain: ignored, noted, not a refusal.
    assert!(notes.contains("finger_joint") && notes.contains("ignored"), "{notes}");
    // Moving mass: the six links, the camera on the forearm and the gripper base on tool0
    // (fixed, lumped); not the base (fixed) and not the finger (behind its prismatic joint).
    let want = 3.7 + 8.393 + 2.275 + 0.5 + 1.219 + 1.219 + 0.1879 + 0.3;
    assert!((m.total_mass() - want).abs() < 1e-12, "{} vs {want}", m.total_mass());
    let forearm = m.link_inertials()[2];
    assert!((forearm.mass - 2.775).abs() < 1e-12);
    // The camera moves the forearm's centre of mass towards it (0.5 kg at (0.06, 0, 0.2)).
    let com = (Vector3::new(0.0, 0.0, 0.25) * 2.275 + Vector3::new(0.06, 0.0, 0.2) * 0.5) / 2.775;
    assert!((forearm.com - com).norm() < 1e-12, "{}", forearm.com);

    // FK at zero, by hand from the joint origins (UR5's zero pose, ROS convention).
    let p = m.fk(&JVec::zeros()).translation.vector;
    assert!((p - Vector3::new(0.81725, 0.10915, -0.005491)).norm() < 1e-6, "{p}");
    let with_tool = ArmModel::from_urdf_file_with(ur_urdf(), &ur_opts(Some("tool0"))).unwrap();
    assert_eq!(with_tool.ee_link_name(), "tool0");
    let t = with_tool.fk(&JVec::zeros());
    assert!((t.translation.vector - Vector3::new(0.81725, 0.19145, -0.005491)).norm() < 1e-6, "{t}");
    // tool0's z axis points along +y of the base at zero (rpy -pi/2 about x after R_y(pi)).
    let z = t.rotation * Vector3::z();
    assert!((z - Vector3::new(0.0, 1.0, 0.0)).norm() < 1e-6, "{z}");
    // And at a second, hand-computable pose: shoulder pan by +90 deg turns the arm about z.
    let mut q = JVec::zeros();
    q[0] = std::f64::consts::FRAC_PI_2;
    let p = with_tool.fk(&q).translation.vector;
    assert!((p - Vector3::new(-0.19145, 0.81725, -0.005491)).norm() < 1e-6, "{p}");
    // Dynamics: the same whichever end frame is chosen (tool0 and the gripper are lumped
    // either way).
    let mut r = rng(3);
    for _ in 0..5 {
        let q = random_q(&m, &mut r);
        assert!(rel(&m.mass_matrix(&q), &with_tool.mass_matrix(&q)) < 1e-12);
    }
    assert_dynamics_consistent(&m);
    assert_dynamics_consistent(&with_tool);

    // Collision capsules from the meshes, in metres (the millimetre STL is scaled). Mesh
    // vertices are f32: corners are checked to 1e-6 m.
    let c = m.collision_capsules();
    // wrist_1: a 90 x 175 x 100 mm box -> a capsule along its long side (y), radius ~ 67 mm.
    assert!(c[3].radius > 0.06 && c[3].radius < 0.08, "{:?}", c[3]);
    // wrist_2 has only a visual box: fitted to it, noted.
    assert!(c[4].radius > 0.05 && c[4].radius < 0.07, "{:?}", c[4]);
    assert!(notes.contains("wrist_2_link") && notes.contains("visual"), "{notes}");
    // The shoulder's ASCII STL box encloses (0.06, 0.19, 0.07).
    assert!(seg_dist(&Point3::new(0.06, 0.19, 0.07), &c[0].a, &c[0].b) <= c[0].radius + 1e-6);
    // The upper arm's OBJ box: its far corner at z = 0.445 lies inside.
    assert!(seg_dist(&Point3::new(0.06, 0.06, 0.445), &c[1].a, &c[1].b) <= c[1].radius + 1e-6, "{:?}", c[1]);
    // wrist_3: its relative-path OBJ plus ee_link's box, one capsule around both.
    assert!(seg_dist(&Point3::new(0.04, 0.08, 0.04), &c[5].a, &c[5].b) <= c[5].radius + 1e-6);
}

#[test]
fn package_paths_resolve_through_the_search_path_and_ros_package_path() {
    // Without a search path the package is found among the URDF's own folders (it holds the
    // URDF, in `urdf/`).
    let m = ArmModel::from_urdf_file_with(ur_urdf(), &UrdfOptions::default()).unwrap();
    assert_eq!(m.ee_link_name(), "wrist_3_link");
    // A copy of the URDF outside its package cannot find it: a clear error naming link and
    // package.
    let dir = std::env::temp_dir().join(format!("dkrrt-urdf-alone-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let alone = dir.join("ur_like.urdf");
    std::fs::copy(ur_urdf(), &alone).unwrap();
    let e = ArmModel::from_urdf_file_with(&alone, &UrdfOptions::default()).unwrap_err();
    let _ = std::fs::remove_dir_all(&dir);
    match &e {
        ModelError::Mesh { link, reason } => {
            assert_eq!(link, "shoulder_link");
            assert!(reason.contains("ur_like_description") && reason.contains("not found"), "{reason}");
        }
        e => panic!("{e:?}"),
    }
    // The package folder itself on the search path works too.
    let o = UrdfOptions {
        package_path: vec![fixtures().join("pkgs/ur_like_description")],
        ..UrdfOptions::default()
    };
    assert!(ArmModel::from_urdf_file_with(ur_urdf(), &o).is_ok());
    // ROS_PACKAGE_PATH (the only test in this binary that sets it; the others pass the path,
    // and find it with or without the variable).
    std::env::set_var("ROS_PACKAGE_PATH", fixtures().join("pkgs"));
    let r = ArmModel::from_urdf_file_with(ur_urdf(), &UrdfOptions::default());
    std::env::remove_var("ROS_PACKAGE_PATH");
    assert_eq!(r.unwrap().ee_link_name(), "wrist_3_link");
}

#[test]
fn chains_are_chosen_by_base_and_tip_and_wrong_ones_are_refused_by_name() {
    let f = |base: Option<&str>, tip: Option<&str>| {
        let o = UrdfOptions {
            base_link: base.map(str::to_string),
            tip_link: tip.map(str::to_string),
            package_path: vec![fixtures().join("pkgs")],
            ..UrdfOptions::default()
        };
        ArmModel::from_urdf_file_with(ur_urdf(), &o)
    };
    // Base at base_link instead of world: the same (world_joint is the identity).
    let a = f(Some("base_link"), Some("tool0")).unwrap();
    let b = f(None, Some("tool0")).unwrap();
    let q = JVec::from_column_slice(&[0.1, -0.7, 1.1, 0.3, -0.2, 0.5]);
    assert_eq!(a.fk(&q), b.fk(&q));
    // A tip with five actuated joints before it.
    assert!(matches!(f(None, Some("wrist_2_link")), Err(ModelError::WrongDof { found: 5, .. })));
    // The finger: the prismatic joint lies on that chain.
    match f(None, Some("finger")) {
        Err(ModelError::UnsupportedJoint { joint, kind }) => {
            assert_eq!((joint.as_str(), kind.as_str()), ("finger_joint", "prismatic"))
        }
        r => panic!("{r:?}"),
    }
    match f(None, Some("tool9")) {
        Err(ModelError::NoSuchLink { field, link }) => {
            assert_eq!((field, link.as_str()), ("robot.tip_link", "tool9"))
        }
        r => panic!("{r:?}"),
    }
    match f(Some("forearm_link"), Some("shoulder_link")) {
        Err(e @ ModelError::TipNotBelowBase { .. }) => assert!(e.to_string().contains("shoulder_link")),
        r => panic!("{r:?}"),
    }
    // Two equally deep actuated branches: the tip must be named.
    let two_arms = DEFAULT_ARM_URDF.replacen(
        "</robot>",
        r#"<link name="spare"><inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
        <joint name="spare_joint" type="revolute"><parent link="wrist_pitch_link"/><child link="spare"/>
        <axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="0.2" effort="60"/></joint>
        <link name="spare2"><inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
        <joint name="spare2_joint" type="revolute"><parent link="spare"/><child link="spare2"/>
        <axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="0.2" effort="60"/></joint></robot>"#,
        1,
    );
    match ArmModel::from_urdf_str(&two_arms) {
        Err(ModelError::AmbiguousTip { candidates, dof }) => {
            assert_eq!(dof, 6);
            assert!(candidates.contains(&"spare2".to_string()), "{candidates:?}");
        }
        r => panic!("{r:?}"),
    }
    // Choosing the tip resolves it; the other branch is ignored with a note.
    let o = UrdfOptions { tip_link: Some("tool0".into()), ..UrdfOptions::default() };
    let m = ArmModel::from_urdf_str_with(&two_arms, &o).unwrap();
    assert!(m.load_notes().iter().any(|n| n.contains("spare_joint")), "{:?}", m.load_notes());
    let d = ArmModel::default_arm();
    assert_eq!(m.fk(&q), d.fk(&q));
    assert!(rel(&m.mass_matrix(&q), &d.mass_matrix(&q)) < 1e-12);
}

#[test]
fn an_arm_without_collision_geometry_loads_with_notes() {
    let mut xml = DEFAULT_ARM_URDF.to_string();
    while let Some(i) = xml.find("<collision>") {
        let j = xml[i..].find("</collision>").unwrap() + i + "</collision>".len();
        xml.replace_range(i..j, "");
    }
    let m = ArmModel::from_urdf_str(&xml).unwrap();
    assert!(m.collision_capsules().iter().all(|c| c.radius == 0.0));
    assert_eq!(
        m.load_notes().iter().filter(|n| n.contains("not checked")).count(),
        NJ,
        "{:?}",
        m.load_notes()
    );
    let d = ArmModel::default_arm();
    let q = JVec::from_column_slice(&[0.3, -0.4, 0.9, 0.1, 0.5, -0.2]);
    assert_eq!((m.fk(&q), m.mass_matrix(&q)), (d.fk(&q), d.mass_matrix(&q)));
    assert!(d.load_notes().is_empty(), "{:?}", d.load_notes());
}

#[test]
fn mesh_errors_name_the_link_and_the_file() {
    let dir = std::env::temp_dir().join(format!("dkrrt-mesh-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("bad.stl"), b"solid x\n facet normal 0 0 oops\n").unwrap();
    std::fs::write(dir.join("thing.dae"), b"<COLLADA/>").unwrap();
    let with = |file: &str| {
        DEFAULT_ARM_URDF.replacen(
            r#"<geometry><cylinder radius="0.09" length="1.20"/></geometry>"#,
            &format!(r#"<geometry><mesh filename="{file}"/></geometry>"#),
            1,
        )
    };
    let o = UrdfOptions { urdf_dir: Some(dir.clone()), ..UrdfOptions::default() };
    for (file, says) in [("bad.stl", "bad.stl"), ("thing.dae", ".dae"), ("missing.obj", "missing.obj")] {
        match ArmModel::from_urdf_str_with(&with(file), &o) {
            Err(e @ ModelError::Mesh { .. }) => {
                let s = e.to_string();
                assert!(s.contains("lower_boom") && s.contains(says), "{s}");
            }
            r => panic!("{file}: {r:?}"),
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_fitted_capsule_encloses_every_inflated_point() {
    let mut r = rng(11);
    for case in 0..300 {
        let n = r.random_range(1..40);
        let scale =
            Vector3::new(r.random_range(0.01..2.0), r.random_range(0.01..2.0), r.random_range(0.01..2.0));
        let pts: Vec<(Point3<f64>, f64)> = (0..n)
            .map(|_| {
                let p = Point3::new(
                    r.random_range(-1.0..1.0) * scale.x,
                    r.random_range(-1.0..1.0) * scale.y,
                    r.random_range(-1.0..1.0) * scale.z,
                );
                (p, if r.random_bool(0.5) { r.random_range(0.0..0.3) } else { 0.0 })
            })
            .collect();
        let (a, b, radius) = fit_capsule(&pts);
        for (p, pr) in &pts {
            assert!(
                seg_dist(p, &a, &b) + pr <= radius + 1e-9,
                "case {case}: {p} r {pr} outside ({a}, {b}, {radius})"
            );
        }
    }
    // A long thin box: the capsule lies along it and is as thin as its cross-section allows.
    let corners: Vec<(Point3<f64>, f64)> = (0..8)
        .map(|i| {
            let s = |k: usize| if i >> k & 1 == 1 { 1.0 } else { -1.0 };
            (Point3::new(0.6 * s(0), 0.05 * s(1), 0.05 * s(2)), 0.0)
        })
        .collect();
    let (a, b, radius) = fit_capsule(&corners);
    assert!((radius - 0.05 * 2f64.sqrt()).abs() < 1e-12 && ((b - a).norm() - 1.2).abs() < 1e-12);
}
