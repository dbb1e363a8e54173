//! A scenario naming a real arm's URDF: a tree with `package://` meshes, its tip and its
//! package search path (relative to the scenario file).

use dkrrt_config::{Scenario, DEFAULT_SCENARIO};

fn fixture_pkgs() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../model/tests/fixtures/pkgs")
}

fn scenario_with(dir: &std::path::Path, robot: &str) -> std::path::PathBuf {
    scenario_of(dir, &fixture_pkgs().join("ur_like_description/urdf/ur_like.urdf"), robot)
}

fn scenario_of(dir: &std::path::Path, urdf: &std::path::Path, robot: &str) -> std::path::PathBuf {
    let from = "urdf = \"\"";
    assert!(DEFAULT_SCENARIO.contains(from));
    let text = DEFAULT_SCENARIO.replacen(from, &format!("urdf = \"{}\"\n{robot}", urdf.display()), 1);
    let p = dir.join("arm.toml");
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn a_scenario_loads_a_ur_like_tree_with_its_tip_and_package_path() {
    let dir = std::env::temp_dir().join(format!("dkrrt-cfg-arm-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // The package folder next to the scenario, named relative to it.
    let link = dir.join("pkgs");
    let _ = std::fs::remove_file(&link);
    std::os::unix::fs::symlink(fixture_pkgs(), &link).unwrap();
    let p = scenario_with(&dir, "tip_link = \"tool0\"\npackage_path = [\"pkgs\"]");
    let sc = Scenario::load(p.to_str().unwrap()).unwrap();
    let arm = sc.load_arm().unwrap();
    assert_eq!(arm.ee_link_name(), "tool0");
    assert_eq!(arm.joint_names()[0], "shoulder_pan_joint");
    assert!(arm.load_notes().iter().any(|n| n.contains("finger_joint")), "{:?}", arm.load_notes());
    // Without the search path the meshes are found in the package that holds the URDF.
    let p = scenario_with(&dir, "tip_link = \"tool0\"");
    assert_eq!(Scenario::load(p.to_str().unwrap()).unwrap().load_arm().unwrap().ee_link_name(), "tool0");
    // A copy of the URDF outside its package, without the search path: the mesh is not found,
    // and the error names the file, the field and the link.
    let alone = dir.join("ur_like.urdf");
    std::fs::copy(fixture_pkgs().join("ur_like_description/urdf/ur_like.urdf"), &alone).unwrap();
    let p = scenario_of(&dir, &alone, "tip_link = \"tool0\"");
    let e = Scenario::load(p.to_str().unwrap()).unwrap().load_arm().unwrap_err().to_string();
    assert!(e.contains("robot.urdf") && e.contains("shoulder_link") && e.contains("not found"), "{e}");
    // An unknown tip is refused naming it.
    let p = scenario_with(&dir, "tip_link = \"flange\"\npackage_path = [\"pkgs\"]");
    let e = Scenario::load(p.to_str().unwrap()).unwrap().load_arm().unwrap_err().to_string();
    assert!(e.contains("robot.tip_link") && e.contains("flange"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}
