//! The seed tutorial's 7-DOF pick-and-place through the scvx core: builds the problem (the
//! arm crate's seed fixture, as the acceptance test), solves it and prints the iteration history and the
//! dense-trajectory checks.
//!
//! Run: `cargo run --release -p armature-scvx --example seed_pick_and_place [-- collision] [interval] [nopeaks] [defaults] [dp] [qn] [ipm|clarabel]`

#[path = "../tests/seed/mod.rs"]
mod seed;

use armature_scvx::{IterationTable, Ptr, PtrSettings};

fn main() {
    // `-- collision` solves the seed's collision variant; `interval` adds the velocity
    // bounds between the nodes; `nopeaks` leaves out the clearances' peak rows; `defaults`
    // solves the task as the arm crate states it by default (3 nodes per segment,
    // time-scaled torques) instead of the tutorial's 2 nodes per segment.
    let has = |flag: &str| std::env::args().any(|a| a == flag);
    let s = seed::build_with(seed::Variant {
        collision: has("collision"),
        interval_bounds: has("interval"),
        without_clearance_peaks: has("nopeaks"),
        task_defaults: has("defaults"),
    });
    let t0 = std::time::Instant::now();
    // `-- dp`: adaptive Dormand–Prince instead of fixed-step RK4.
    let mut settings = PtrSettings::default();
    if std::env::args().any(|a| a == "dp") {
        settings.discretization.integrator =
            armature_scvx::Integrator::DormandPrince { rtol: 1e-8, atol: 1e-10 };
    }
    // `-- qn`: the quasi-Newton model with the Lagrangian merit.
    if std::env::args().any(|a| a == "qn") {
        settings.quasi_newton = true;
        settings.merit = armature_scvx::Merit::Lagrangian { sigma: 0.5 };
    }
    // `-- ipm`: the native warm-started interior point for the subproblems.
    if std::env::args().any(|a| a == "ipm") {
        settings.subproblem.solver = armature_scvx::SubproblemSolver::InteriorPoint;
    }
    // `-- clarabel`: Clarabel for every subproblem.
    if std::env::args().any(|a| a == "clarabel") {
        settings.subproblem.solver = armature_scvx::SubproblemSolver::Clarabel;
    }
    let mut ptr = Ptr::new(s.ocp.clone(), settings).unwrap();
    let built = t0.elapsed();
    println!("subproblem: {:?}", ptr.dimensions());
    let mut out = std::io::stdout().lock();
    IterationTable::header(&mut out).expect("stdout");
    let r = ptr
        .solve_with(&s.x, &s.u, &s.s, |it, _| {
            IterationTable::row(&mut out, it).ok();
        })
        .expect("sizes match");
    let solved = t0.elapsed() - built;
    let c = seed::check(&s, &r);
    println!(
        "{:?} after {} iterations: T = {:.4} s (pattern {:.1} ms, solve {:.1} ms: discretization {:.1} ms, subproblems {:.1} ms)",
        r.status,
        r.history.len(),
        r.final_time,
        built.as_secs_f64() * 1e3,
        solved.as_secs_f64() * 1e3,
        r.timings.discretization_ms,
        r.timings.subproblem_ms
    );
    if let Some(v) = &r.max_violation {
        println!(
            "largest remaining violation: {} = {:.2e} at node {:?}",
            v.constraint, v.value, v.node
        );
    }
    println!(
        "dense ({} samples): joint {:.1e}, velocity {:.1e}, table {:.1e}; nodes: waypoint {:.4} m, orientation {:+.4}° beyond its range",
        c.samples,
        c.joint_violation,
        c.velocity_violation,
        c.table_violation,
        c.waypoint_error,
        c.orientation_excess.to_degrees()
    );
    println!(
        "smallest clearance on the dense trajectory: {:.4} m ({})",
        c.min_clearance.0, c.min_clearance.1
    );
}
