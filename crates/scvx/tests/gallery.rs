//! The examples gallery, end to end: each example asserts what it teaches, so running its
//! `main` here is its test.

#[path = "../examples/minimum_time.rs"]
mod minimum_time;
#[path = "../examples/path_constraint.rs"]
mod path_constraint;
#[path = "../examples/resolve_parameter.rs"]
mod resolve_parameter;
#[path = "../examples/step_observer.rs"]
mod step_observer;

#[test]
fn minimum_time_reaches_the_bang_bang_optimum() {
    minimum_time::main();
}

#[test]
fn a_path_constraint_holds_on_the_dense_trajectory_with_peak_rows() {
    path_constraint::main();
}

#[test]
fn a_parameter_change_resolves_warm_without_recompiling() {
    resolve_parameter::main();
}

#[test]
fn the_step_api_observes_every_iteration() {
    step_observer::main();
}
