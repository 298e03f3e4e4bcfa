//! Mesh refinement: the seed solved on its 16 nodes, then again from that solution on 31
//! nodes ([`ArmTask::refined`](armature_arm::ArmTask::refined),
//! [`armature_arm::set_refined_guess`]). The finer control reaches a faster motion than three
//! pieces per segment allow, every constraint still held on the dense trajectory; a refined
//! stage that did not converge would leave the first stage's result
//! ([`armature_arm::keep_refined`]). In a task file: `[nodes] refine = 2`.
//!
//! `cargo run --release -p armature-arm --example mesh_refinement`

use armature_arm::{Refinement, fixtures, keep_refined, set_refined_guess};
use armature_scvx::PtrStatus;

/// Runs the example (its asserts are its test: `tests/gallery.rs`).
pub(crate) fn main() {
    let seed = fixtures::pick_and_place();
    let coarse = seed.plan().unwrap().compile().unwrap().solve().unwrap();
    let fine_task = seed.refined(2);
    let mut fine = fine_task.plan().unwrap().compile().unwrap();
    set_refined_guess(&mut fine, &coarse, 2).unwrap();
    let Refinement::Refined(both) = keep_refined(coarse.clone(), fine.solve().unwrap()) else {
        panic!("the seed's refined stage converges");
    };
    println!(
        "{} nodes: T = {:.4} s after {} iterations; {} nodes: T = {:.4} s after {} in all ({})",
        seed.nodes,
        coarse.final_time,
        coarse.iterations,
        fine_task.nodes,
        both.final_time,
        both.iterations,
        both.status,
    );
    assert_eq!((coarse.status, both.status), (PtrStatus::Converged, PtrStatus::Converged));
    assert!(both.final_time < 0.99 * coarse.final_time);
    assert_eq!(both.nodes["time"].len(), fine_task.nodes);
}
