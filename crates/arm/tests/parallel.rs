//! Work split over threads changes no number: the seed (its 0.1° orientation ranges held at
//! every grid point) and the UR5e rigid-body task solved with the discretization and the
//! constraints' grid evaluations on the rayon pool and on one thread walk the same iterates,
//! bit for bit.

use armature_arm::{ArmTask, fixtures};

fn solve(mut task: ArmTask, parallel: bool) -> armature_scvx::Solution {
    task.settings.discretization.parallel = parallel;
    task.settings.max_iterations = 12;
    task.retime_stall = None;
    task.plan().unwrap().compile().unwrap().solve().unwrap()
}

#[test]
fn parallel_and_serial_solves_walk_the_same_iterates() {
    // The pool needs two workers for the split to happen on a one-core machine too.
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    for task in [fixtures::pick_and_place(), fixtures::ur5e_rigid_body()] {
        let (serial, parallel) =
            pool.install(|| (solve(task.clone(), false), solve(task.clone(), true)));
        assert_eq!(serial.iterations, parallel.iterations);
        for (a, b) in serial.history.iter().zip(&parallel.history) {
            assert_eq!(a.cost.to_bits(), b.cost.to_bits(), "iteration {}", a.iteration);
            assert_eq!(a.rho.to_bits(), b.rho.to_bits(), "iteration {}", a.iteration);
        }
        assert_eq!(serial.nodes, parallel.nodes);
    }
}
