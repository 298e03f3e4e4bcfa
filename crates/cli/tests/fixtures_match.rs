//! The shipped example task files are the `armature-arm` fixtures: `armature demo` and the
//! library's tests, benches and examples solve one formulation.

use armature_arm::{ArmTask, fixtures};
use armature_cli::task::{Source, parse};

fn from_file(name: &str, text: &str) -> ArmTask {
    let src = Source { name, text };
    let task = parse(src).unwrap();
    armature_cli::pipeline::arm_task(&task, src, None).unwrap()
}

#[test]
fn the_seed_example_is_the_seed_fixture() {
    let file =
        from_file("pick-and-place.toml", include_str!("../../../examples/pick-and-place.toml"));
    assert_eq!(file, fixtures::pick_and_place());
}

#[test]
fn the_collision_example_is_the_collision_fixture() {
    let file = from_file(
        "pick-and-place-collision.toml",
        include_str!("../../../examples/pick-and-place-collision.toml"),
    );
    assert_eq!(file, fixtures::pick_and_place_collision());
}

#[test]
fn the_ur5e_example_is_the_rigid_body_fixture() {
    let file =
        from_file("ur5e-rigid-body.toml", include_str!("../../../examples/ur5e-rigid-body.toml"));
    assert_eq!(file, fixtures::ur5e_rigid_body());
}

/// The UR5e-like URDF task of the fixtures folder, with `extra` added to its `[robot]`.
fn ur_task(extra: &str) -> Result<ArmTask, String> {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures");
    let text = std::fs::read_to_string(format!("{dir}/ur5e-like-pick.toml"))
        .unwrap()
        .replace("[robot]\n", &format!("[robot]\n{extra}\n"));
    let path = std::path::PathBuf::from(format!("{dir}/ur5e-like-pick.toml"));
    let src = Source { name: "ur.toml", text: &text };
    let task = parse(src).map_err(|e| e.to_string())?;
    armature_cli::pipeline::arm_task(&task, src, Some(&path)).map_err(|e| e.to_string())
}

#[test]
fn keypoints_by_link_name_and_a_tool_centre_point() {
    let plain = ur_task("").unwrap();
    let task = ur_task(
        "keypoints = [\"base_link\", \"upper_arm_link\", \"forearm_link\", \"tool0\"]\ntool = { position = [0.0, 0.0, 0.1] }",
    )
    .unwrap();
    let names: Vec<&str> = task.chain.keypoint_names().collect();
    assert_eq!(names, ["base_link", "upper_arm_link", "forearm_link", "tool0", "tool"]);
    // The end effector is 10 cm out along the flange's z axis.
    let (a, b) = (plain.chain.home(), task.chain.home());
    let z = a.rotation().matrix().column(2).into_owned();
    assert!((b.translation() - a.translation() - 0.1 * z).norm() < 1e-12);
    // A link off the chain, or not in the URDF, is an error at `keypoints` naming the links.
    let e = ur_task("keypoints = [\"base_link\", \"gripper\"]").unwrap_err();
    assert!(e.starts_with("ur.toml:") && e.contains("no link named 'gripper'"), "{e}");
    assert!(e.contains("base_link → tool0: base_link, shoulder_link"), "{e}");
    assert!(e.starts_with("ur.toml:6:13:"), "at the keypoints value: {e}");
    let e =
        ur_task("tool = { position = [0.0, 0.0, 0.1], quaternion_wxyz = [0.0, 0.0, 0.0, 0.0] }")
            .unwrap_err();
    assert!(e.contains("tool"), "{e}");
}

/// The first trust-region weight is the dynamics model's default (0.25 for the seed's
/// decoupled model, the solver's own 1 for the rigid-body UR5e) unless `[settings] lam_tr`
/// gives one.
#[test]
fn the_first_trust_region_weight_is_the_models_unless_the_file_gives_one() {
    let text = include_str!("../../../examples/pick-and-place.toml");
    assert_eq!(from_file("pp.toml", text).settings.lam_tr, 0.25);
    let given = text.replacen("[settings]\n", "[settings]\nlam_tr = 1.0\n", 1);
    assert_ne!(given, text);
    assert_eq!(from_file("pp.toml", &given).settings.lam_tr, 1.0);
    let ur5e = include_str!("../../../examples/ur5e-rigid-body.toml");
    let rigid = from_file("ur5e.toml", ur5e).settings.lam_tr;
    assert_eq!(rigid, armature_scvx::PtrSettings::default().lam_tr);
}

/// `[nodes] refine`: the model's factor when not given (2 decoupled, 1 rigid-body), the
/// file's when given, and one stage where the model's would pass the node limit (a factor
/// the file gives past it is an error at its value).
#[test]
fn the_refinement_is_the_models_unless_the_file_gives_one() {
    let factor = |text: &str| {
        let src = Source { name: "t.toml", text };
        let task = parse(src).unwrap();
        let arm = armature_cli::pipeline::arm_task(&task, src, None).unwrap();
        armature_cli::pipeline::refinement(&task, src, &arm).map_err(|e| e.to_string())
    };
    let seed = include_str!("../../../examples/pick-and-place.toml");
    assert_eq!(factor(seed), Ok(2));
    assert_eq!(factor(include_str!("../../../examples/ur5e-rigid-body.toml")), Ok(1));
    let once = seed.replacen("per_segment = 3 ", "refine = 1\nper_segment = 3 ", 1);
    assert_ne!(once, seed);
    assert_eq!(factor(&once), Ok(1));
    // 5 segments of 300 intervals: 1501 nodes, 3001 once refined, past the limit of 2000.
    let dense = seed.replacen("per_segment = 3 ", "per_segment = 300 ", 1);
    assert_eq!(factor(&dense), Ok(1));
    let asked = dense.replacen("per_segment = 300 ", "refine = 2\nper_segment = 300 ", 1);
    let e = factor(&asked).unwrap_err();
    assert!(e.contains("refine 2: need 1 to 16, and at most 2000 nodes"), "{e}");
}
