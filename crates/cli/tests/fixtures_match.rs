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
