//! What an infeasible task says before anything is solved: the part of the task at fault
//! ([`armature_arm::TaskItem`]) and why.
//!
//! `cargo run -p armature-arm --example infeasible`

use armature_arm::{TaskItem, fixtures};

/// Runs the example (its asserts are its test: `tests/gallery.rs`).
pub(crate) fn main() {
    let mut task = fixtures::pick_and_place();
    task.waypoints[5].position = [1.5, 0.25, 0.05]; // beyond the arm's reach
    let e = task.plan().unwrap_err();
    println!("{:?}: {}", e.item, e.message);
    assert_eq!(e.item, TaskItem::Waypoint(5));
    assert!(e.message.contains("out of reach"));
}
