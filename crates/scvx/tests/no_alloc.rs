//! A PTR iteration allocates nothing of ours once running: a counting global allocator
//! watches `step()` on this thread, with serial discretization, for both subproblem solvers.
//! With the native interior point a step allocates nothing at all once the KKT patterns it
//! meets have been analysed: the collision variant switches far segments' peak rows off, and
//! the interior point analyses each set of switched-off rows once (a first solve of the same
//! problem and a first pass over the counted steps do it here), then reuses it. The one allocation left
//! per step with Clarabel is Clarabel's: each `solve()` rebuilds its timer map (a `HashMap` keyed by phase
//! name), which no setting turns off. (Parallel discretization adds rayon's boxed job per
//! spawned lane; `rayon::join` would not allocate but, called from outside the pool, made
//! the seed solve 10 % slower.)

mod seed;

use armature_scvx::{Merit, Ptr, PtrSettings, SubproblemSolver};
use armature_testing::{Counting, allocations_during};

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn ptr_steps_are_allocation_free() {
    let plain = seed::build();
    // With interval bounds the discretization also fills its grid and the peak rows are
    // refreshed each step.
    let interval = seed::build_with(seed::Variant { interval_bounds: true, ..Default::default() });
    // The collision variant evaluates its clearances on the grid for their peak rows (values
    // everywhere, Jacobians at the stencils).
    let collision = seed::build_collision();
    // The task's defaults: time-scaled torques (their bounds rows, the dilation column's
    // extra terms, the transformed curvature) on 3 nodes per segment.
    let scaled = seed::build_with(seed::Variant { task_defaults: true, ..Default::default() });
    let scaled_collision = seed::build_with(seed::Variant {
        collision: true,
        task_defaults: true,
        ..Default::default()
    });
    // (problem, quasi-Newton, exact Hessian, second-order correction, solver)
    for (s, quasi_newton, exact, soc, solver) in [
        (&plain, false, false, false, SubproblemSolver::Clarabel),
        (&plain, true, false, false, SubproblemSolver::Clarabel),
        (&plain, false, false, false, SubproblemSolver::InteriorPoint),
        (&plain, true, false, false, SubproblemSolver::InteriorPoint),
        (&plain, false, true, false, SubproblemSolver::InteriorPoint),
        (&plain, false, true, true, SubproblemSolver::InteriorPoint),
        (&interval, false, false, false, SubproblemSolver::InteriorPoint),
        (&interval, true, false, false, SubproblemSolver::InteriorPoint),
        (&interval, true, true, false, SubproblemSolver::InteriorPoint),
        (&interval, false, true, true, SubproblemSolver::InteriorPoint),
        (&collision, false, false, false, SubproblemSolver::InteriorPoint),
        (&collision, false, true, false, SubproblemSolver::InteriorPoint),
        (&collision, false, false, true, SubproblemSolver::InteriorPoint),
        (&scaled, false, true, true, SubproblemSolver::InteriorPoint),
        (&scaled_collision, false, true, true, SubproblemSolver::InteriorPoint),
    ] {
        let settings = {
            let mut s = PtrSettings::default();
            s.subproblem.solver = solver;
            s.quasi_newton = quasi_newton;
            s.exact_hessian = exact;
            s.second_order_correction = soc;
            s.merit = if quasi_newton || exact {
                Merit::Lagrangian { sigma: 0.5 }
            } else {
                Merit::ExactPenalty
            };
            s.discretization.parallel = false;
            s
        };
        let mut ptr = Ptr::new(s.ocp.clone(), settings).unwrap();
        ptr.solve(&s.x, &s.u, &s.s).unwrap();
        // The walk is deterministic: the steps counted below meet the row-switch patterns
        // these first ones met (each analysed once, on its first meeting).
        ptr.start(&s.x, &s.u, &s.s).unwrap();
        for _ in 0..7 {
            ptr.step().unwrap();
        }
        ptr.start(&s.x, &s.u, &s.s).unwrap();
        ptr.step().unwrap();
        ptr.step().unwrap();
        for _ in 0..5 {
            let count = allocations_during(|| {
                ptr.step().unwrap();
            });
            // Clarabel's timer map; the native solver allocates nothing.
            let allowed = usize::from(solver == SubproblemSolver::Clarabel);
            assert!(
                count <= allowed,
                "quasi_newton {quasi_newton}, exact {exact}, soc {soc}, {solver:?}, interval bounds {}, interval \
                 constraints {}: {count} allocations",
                !s.ocp.interval_bounds.is_empty(),
                s.ocp.interval_constraints.len()
            );
        }
    }
    assert!(allocations_during(|| drop(std::hint::black_box(vec![0u8; 16]))) > 0);
}
