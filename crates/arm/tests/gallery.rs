//! The examples, end to end: each asserts what it shows, so running its `main` is its test.

#[path = "../examples/custom_task.rs"]
mod custom_task;
#[path = "../examples/infeasible.rs"]
mod infeasible;

#[test]
fn a_task_written_in_rust_plans_solves_and_reads_back_by_name() {
    custom_task::main();
}

#[test]
fn an_infeasible_task_names_its_fault() {
    infeasible::main();
}

#[path = "../examples/mesh_refinement.rs"]
mod mesh_refinement;

#[test]
fn a_refined_grid_reaches_a_faster_motion() {
    mesh_refinement::main();
}

#[path = "../examples/multi_start.rs"]
mod multi_start;

#[test]
fn several_starts_keep_the_fastest_converged_solution() {
    multi_start::main();
}
