//! Acceptance: the seed tutorial's 7-DOF pick-and-place converges, hits every waypoint within
//! 1 cm, keeps the gripper orientation within 5° / 0.1° at every node of its ranges, meets
//! the joint, velocity and table limits on the dense trajectory (dt = 0.01) within 1e-4, and
//! finishes in at most 4 s.

mod seed;

use armature_scvx::{
    CorrectionSolve, Merit, Ptr, PtrError, PtrResult, PtrSettings, PtrStatus, SubproblemSolver,
};

#[test]
fn seed_pick_and_place_converges_and_meets_the_task() {
    let s = seed::build();
    let mut ptr = Ptr::new(s.ocp.clone(), PtrSettings::default()).unwrap();
    let r = ptr.solve(&s.x, &s.u, &s.s).unwrap();
    assert_meets_the_task(&s, &r);
}

/// The defaults with Clarabel for every subproblem.
/// First-order subproblems: no exact curvature, no second-order correction.
fn first_order() -> PtrSettings {
    let mut s = PtrSettings::default();
    s.exact_hessian = false;
    s.second_order_correction = false;
    s
}

/// Clarabel for every subproblem, the second-order correction solved again (Clarabel has no
/// factorization to move a solution on).
fn only_clarabel() -> PtrSettings {
    let mut s = resolving();
    s.subproblem.solver = SubproblemSolver::Clarabel;
    s
}

/// The defaults with the second-order correction solved again
/// ([`CorrectionSolve::Resolve`]): the tests that compare two ways of solving the same
/// subproblems compare their solutions; the default correction's step comes from the native
/// solver's factorization, whose rounding depends on its pattern.
fn resolving() -> PtrSettings {
    let mut s = PtrSettings::default();
    s.correction_solve = CorrectionSolve::Resolve;
    s
}

/// The native warm-started interior point (the default; Clarabel only as a fallback) and
/// Clarabel for every subproblem both meet the task, at final times within 3 %, the native
/// one in fewer interior-point iterations per subproblem. (Their paths part where a step sits
/// at the acceptance threshold — the two solvers' last digits differ — and each then stops
/// polishing where its model sees less than `eps_flat` left to gain.)
#[test]
fn native_interior_point_matches_clarabel_in_fewer_subproblem_iterations() {
    let s = seed::build();
    let default =
        Ptr::new(s.ocp.clone(), PtrSettings::default()).unwrap().solve(&s.x, &s.u, &s.s).unwrap();
    assert_meets_the_task(&s, &default);
    let r = Ptr::new(s.ocp.clone(), resolving()).unwrap().solve(&s.x, &s.u, &s.s).unwrap();
    assert_meets_the_task(&s, &r);
    let clarabel =
        Ptr::new(s.ocp.clone(), only_clarabel()).unwrap().solve(&s.x, &s.u, &s.s).unwrap();
    assert_meets_the_task(&s, &clarabel);
    assert!(
        (r.final_time - clarabel.final_time).abs() < 0.03 * r.final_time,
        "{} vs {}",
        r.final_time,
        clarabel.final_time
    );
    let its = |r: &PtrResult| -> u32 { r.history.iter().map(|h| h.subproblem_iterations).sum() };
    let per = |r: &PtrResult| its(r) as f64 / r.history.len() as f64;
    assert!(per(&r) < 0.85 * per(&clarabel), "{} vs {} per subproblem", per(&r), per(&clarabel));
}

/// When the native interior point stops short (here: a cap of one iteration), and so does
/// its retry with the objective scaled, Clarabel solves the subproblem instead, and the solve
/// is the same as with Clarabel alone.
#[test]
fn clarabel_takes_over_when_the_native_solver_stops_short() {
    let s = seed::build();
    // One subproblem solve per iteration (no second-order correction re-solve), so that each
    // record counts one subproblem's iterations.
    let capped = {
        let mut s = PtrSettings::default();
        s.subproblem.interior_point.max_iterations = 1;
        s.second_order_correction = false;
        s
    };
    let r = Ptr::new(s.ocp.clone(), capped).unwrap().solve(&s.x, &s.u, &s.s).unwrap();
    let mut plain = only_clarabel();
    plain.second_order_correction = false;
    let c = Ptr::new(s.ocp.clone(), plain).unwrap().solve(&s.x, &s.u, &s.s).unwrap();
    assert_eq!(r.status, PtrStatus::Converged);
    assert_eq!(r.x, c.x);
    assert_eq!(r.final_time, c.final_time);
    // Each subproblem counts the native solver's one iteration, its scaled retry's one
    // (at a heavy λ_tr), and then Clarabel's.
    for (a, b) in r.history.iter().zip(&c.history) {
        let extra = a.subproblem_iterations - b.subproblem_iterations;
        let heavy = a.lam_tr > 1e3;
        assert!(extra == 1 || (heavy && extra == 2), "{extra} at λ_tr = {}", a.lam_tr);
    }
}

/// The quasi-Newton model with the Lagrangian merit meets the same task and goes further
/// down the final time than first-order subproblems, whose trust region stops them early
/// (a short step held back by a heavy λ_tr, not a stationary point).
#[test]
fn quasi_newton_reaches_a_lower_final_time() {
    let s = seed::build();
    // The quasi-Newton path takes more iterations than the first-order one, and how many
    // moves with the subproblem solutions' last digits (its BFGS pairs use the duals): it
    // converged in 65 to 101 across solver revisions; in the arm crate's formulation it
    // needs about 240 (T ≈ 1.28 s against the first-order 1.56 s).
    let settings = {
        let mut s = first_order();
        s.quasi_newton = true;
        s.merit = Merit::Lagrangian { sigma: 0.5 };
        s.max_iterations = 600;
        s
    };
    let r = Ptr::new(s.ocp.clone(), settings).unwrap().solve(&s.x, &s.u, &s.s).unwrap();
    assert_meets_the_task(&s, &r);
    let first_order =
        Ptr::new(s.ocp.clone(), first_order()).unwrap().solve(&s.x, &s.u, &s.s).unwrap();
    assert!(
        r.final_time < first_order.final_time - 0.1,
        "quasi-Newton T = {} vs first-order T = {}",
        r.final_time,
        first_order.final_time
    );
    // The first-order stop is held back by its trust region: its weight's gradient at the
    // last step is above the quasi-Newton one's (0.075 against 0.015 with the native
    // subproblem solver, 0.026 with Clarabel's duals: the quasi-Newton path depends on them).
    let (g_fo, g_qn) =
        (first_order.history.last().unwrap().tr_gradient, r.history.last().unwrap().tr_gradient);
    assert!(g_fo > g_qn, "trust-region gradient {g_fo} vs {g_qn}");
}

fn assert_meets_the_task(s: &seed::Seed, r: &PtrResult) {
    let c = seed::check(s, r);
    eprintln!(
        "{:?} after {} iterations, T = {:.4} s; {c:?}",
        r.status,
        r.history.len(),
        r.final_time
    );
    assert_eq!(r.status, PtrStatus::Converged);
    assert!(r.final_time <= 4.0 + 1e-9, "T = {}", r.final_time);
    assert!((c.dense_final_time - r.final_time).abs() < 1e-9);
    // Waypoints within 1 cm, orientations within 5° / 0.1°, joint, velocity and table limits
    // within 1e-4 on the dense trajectory (the criteria `seed_neighbourhood` reports too).
    assert_eq!(c.missed(false), None);
    // Dynamically consistent: the nodes are where the dynamics take them.
    assert!(r.history.last().unwrap().max_defect < 1e-6);
}

/// Moving the place waypoint is a parameter change: the same `Ptr` (same compiled functions,
/// same subproblem pattern and solver) re-solves from the previous solution and converges to a
/// trajectory through the new waypoint.
#[test]
fn re_solve_after_moving_a_waypoint_needs_no_recompilation() {
    let mut s = seed::build();
    let mut ptr = Ptr::new(s.ocp.clone(), PtrSettings::default()).unwrap();
    let first = ptr.solve(&s.x, &s.u, &s.s).unwrap();
    assert_eq!(first.status, PtrStatus::Converged);
    let moved = [0.30, 0.28, 0.05];
    assert_eq!(ptr.set_parameter(&seed::waypoint_parameter(5), &moved), Ok(1));
    assert!(matches!(
        ptr.set_parameter("no_such_parameter", &[0.0]),
        Err(PtrError::UnknownParameter(_))
    ));
    assert!(matches!(
        ptr.set_parameter(&seed::waypoint_parameter(5), &[0.3]),
        Err(PtrError::Parameter(_))
    ));
    let second = ptr.solve(&first.x, &first.u, &first.s).unwrap();
    s.ocp = ptr.ocp().clone();
    let c = seed::check(&s, &second);
    eprintln!(
        "re-solve: {:?} after {} iterations, T = {:.4} s; {c:?}",
        second.status,
        second.history.len(),
        second.final_time
    );
    assert_eq!(second.status, PtrStatus::Converged);
    assert_eq!(seed::waypoint(&s.ocp, 5), nalgebra::Vector3::from(moved));
    assert!(c.waypoint_error <= 0.01 + 1e-6, "waypoint error {} m", c.waypoint_error);
    assert!(c.joint_violation <= 1e-4 && c.velocity_violation <= 1e-4 && c.table_violation <= 1e-4);
    assert!(c.orientation_excess <= 1e-6, "orientation off by {}", c.orientation_excess);
    // The final position moved with the waypoint.
    assert!(second.final_time <= 4.0 + 1e-9);
}

/// The seed's collision variant: capsule links, non-adjacent self-collision and the ball at
/// (0.35, 0, 0.25), with exact distances from `armature-collision`. The plain solution passes
/// through the ball; this one converges with every task constraint met and no pair
/// penetrating anywhere on the dense trajectory (dt = 0.01).
#[test]
fn seed_collision_variant_converges_without_penetration() {
    let s = seed::build_collision();
    let r =
        Ptr::new(s.ocp.clone(), PtrSettings::default()).unwrap().solve(&s.x, &s.u, &s.s).unwrap();
    let c = seed::check(&s, &r);
    eprintln!(
        "collision: {:?} after {} iterations, T = {:.4} s; {c:?}",
        r.status,
        r.history.len(),
        r.final_time
    );
    assert_eq!(r.status, PtrStatus::Converged);
    assert!(r.final_time <= 4.0 + 1e-9);
    assert!(
        c.min_clearance.0 > 0.0,
        "{} penetrates by {} m",
        c.min_clearance.1,
        -c.min_clearance.0
    );
    assert!(c.waypoint_error <= 0.01 + 1e-6, "waypoint error {} m", c.waypoint_error);
    assert!(c.orientation_excess <= 1e-6, "orientation off by {}", c.orientation_excess);
    assert!(c.joint_violation <= 1e-4 && c.velocity_violation <= 1e-4 && c.table_violation <= 1e-4);
    // The plain problem's solution does hit the ball: the variant is not vacuous.
    let plain = seed::build();
    let rp = Ptr::new(plain.ocp.clone(), PtrSettings::default())
        .unwrap()
        .solve(&plain.x, &plain.u, &plain.s)
        .unwrap();
    assert!(seed::check(&plain, &rp).min_clearance.0 < 0.0);
}

/// The clearances' peak rows of segments where every pair keeps more than 2 cm beyond its
/// margin sit out of the subproblem (`IntervalConstraint::activation`): the interior point
/// factors a smaller KKT matrix, and the solve takes the same steps as with every row in
/// while the rows it leaves out stay slack — on the tutorial's collision variant the first
/// six; from the seventh the two walks part (by 1e-3 s of final time there) and converge
/// 1.1 % apart.
#[test]
fn switching_far_peak_rows_off_keeps_the_collision_iterates() {
    let s = seed::build_collision();
    let clearance = |ocp: &armature_scvx::Ocp| {
        ocp.interval_constraints.iter().position(|c| c.name == "clearance").unwrap()
    };
    let k = clearance(&s.ocp);
    assert_eq!(s.ocp.interval_constraints[k].activation, Some(0.02));
    let mut all_in = s.ocp.clone();
    all_in.interval_constraints[k].activation = None;
    // Every subproblem solved to the interior point's tolerance: inexact solves (to 1e-5
    // far from the optimum) would let the two take different paths from the start.
    let mut settings = resolving();
    settings.subproblem.inexact = 0.0;
    let solve = |ocp: &armature_scvx::Ocp| {
        let mut ptr = Ptr::new(ocp.clone(), settings.clone()).unwrap();
        let r = ptr.solve(&s.x, &s.u, &s.s).unwrap();
        (r, ptr.dimensions().reduced_kkt_nonzeros.expect("interior point"))
    };
    let ((screened, kkt_screened), (full, kkt_full)) = (solve(&s.ocp), solve(&all_in));
    eprintln!(
        "screened {:?} {} it T {}, all in {:?} {} it T {}",
        screened.status,
        screened.history.len(),
        screened.final_time,
        full.status,
        full.history.len(),
        full.final_time
    );
    assert_eq!((screened.status, full.status), (PtrStatus::Converged, PtrStatus::Converged));
    // The far rows' duals are zero only to the subproblems' tolerance, and the exact
    // curvature weighs them: the same steps, to a microsecond of final time.
    for (a, b) in screened.history.iter().zip(&full.history).take(6) {
        assert_eq!(a.accepted, b.accepted, "iteration {}", a.iteration);
        assert!((a.final_time - b.final_time).abs() < 1e-6, "iteration {}", a.iteration);
    }
    assert!((screened.final_time - full.final_time).abs() < 0.02 * full.final_time);
    assert_eq!(seed::check(&s, &screened).missed(true), None);
    // At the end only the segment that passes the ball keeps its clearance rows: L is 11 %
    // smaller (the orientation ranges' rows at every grid point stay in).
    assert!(
        (kkt_screened.1 as f64) < 0.93 * kkt_full.1 as f64,
        "{kkt_screened:?} against {kkt_full:?}"
    );
}

/// The native interior point stops on the complementarity gap `sᵀz`. With the objectives'
/// difference as its gap, two subproblems of this collision solve (λ_tr = 0.5, 12 RK4
/// substeps) ran to its 50-iteration cap and went to Clarabel: `sᵀz` fell below the tolerance
/// while `|pobj − dobj|` stayed near 1e-6, the primal residual (about 1e-9) weighted by duals
/// at the penalty weights. At a heavy trust-region weight (λ_tr > 1e3) a subproblem that
/// reaches the cap is solved again with the objective divided by λ_tr (see
/// [`SubproblemSolver::InteriorPoint`]); every subproblem of this run is solved.
#[test]
fn no_light_subproblem_runs_the_interior_point_to_its_cap() {
    let s = seed::build_collision();
    // One subproblem solve per iteration (no second-order correction re-solve), so that each
    // record counts one subproblem's iterations.
    let settings = {
        let mut s = PtrSettings::default();
        s.second_order_correction = false;
        s.lam_tr = 0.5;
        s.discretization.substeps = 12;
        s
    };
    let cap = settings.subproblem.interior_point.max_iterations;
    let r = Ptr::new(s.ocp.clone(), settings).unwrap().solve(&s.x, &s.u, &s.s).unwrap();
    assert_eq!(r.status, PtrStatus::Converged);
    assert_eq!(seed::check(&s, &r).missed(true), None);
    let light = r.history.iter().filter(|h| h.lam_tr <= 1e3);
    let worst = light.map(|h| h.subproblem_iterations).max().unwrap();
    assert!(worst < cap, "a subproblem took {worst} interior-point iterations (cap {cap})");
    assert!(
        r.history.iter().all(|h| h.subproblem_status == armature_scvx::SubproblemStatus::Solved)
    );
}

/// With the velocity bounds also enforced between the nodes ([`armature_scvx::Ocp::interval_bounds`]),
/// first-order PTR no longer creeps along the blind linearization of the velocity limits'
/// CTCS integral: it meets the same task at a final time well below the default's (plain;
/// with the collision extension, where the clearance shapes the motion, about where the
/// default ends). Its steps do not shrink below the step-length test within the iteration
/// cap (a stopping test on stationarity is issue 28's), so the run may end there: every
/// constraint still holds on the dense trajectory.
#[test]
fn interval_bounds_meet_the_task_at_a_lower_final_time() {
    for collision in [false, true] {
        let variant = seed::Variant { collision, ..seed::Variant::default() };
        let s = seed::build_with(variant);
        let default = Ptr::new(s.ocp.clone(), PtrSettings::default())
            .unwrap()
            .solve(&s.x, &s.u, &s.s)
            .unwrap();
        let s = seed::build_with(seed::Variant { interval_bounds: true, ..variant });
        let r = Ptr::new(s.ocp.clone(), PtrSettings::default())
            .unwrap()
            .solve(&s.x, &s.u, &s.s)
            .unwrap();
        assert_meets_the_task_by_the_cap(&s, &r, collision);
        assert!(
            collision || r.final_time < default.final_time - 0.05,
            "collision {collision}: T = {} against {}",
            r.final_time,
            default.final_time
        );
        // The peak rows are reported, and met.
        let v = r.violations.iter().find(|v| v.constraint == "bounds of velocity[0] between nodes");
        assert!(v.is_some_and(|v| v.value <= 1e-6), "{v:?}");
    }
}

/// Converged, or stopped at the iteration cap, with every task constraint met on the dense
/// trajectory and no defect left.
fn assert_meets_the_task_by_the_cap(s: &seed::Seed, r: &PtrResult, collision: bool) {
    let c = seed::check(s, r);
    eprintln!(
        "{:?} after {} iterations, T = {:.4} s; {c:?}",
        r.status,
        r.history.len(),
        r.final_time
    );
    assert!(matches!(r.status, PtrStatus::Converged | PtrStatus::MaxIterations), "{:?}", r.status);
    assert_eq!(c.missed(collision), None);
    assert!(r.history.last().unwrap().max_defect < 1e-6);
}

/// The Lagrangian merit prices every defect nonnegatively (its duals are clipped to the
/// price it keeps). With the raw duals, the collision variant's first-order solve with that
/// merit (in the formulation without the clearances' peak rows, whose path shows it)
/// accepted steps that grew the collision row's defect (its dual, about 2000, exceeds half
/// its price) until λ_tr reached its cap, and ended at the iteration cap, penetrating.
#[test]
fn the_lagrangian_merit_does_not_reward_defects() {
    let s = seed::build_with(seed::Variant {
        collision: true,
        without_clearance_peaks: true,
        ..seed::Variant::default()
    });
    let settings = {
        let mut s = PtrSettings::default();
        s.merit = Merit::Lagrangian { sigma: 0.5 };
        s
    };
    let r = Ptr::new(s.ocp.clone(), settings).unwrap().solve(&s.x, &s.u, &s.s).unwrap();
    assert_meets_the_task(&s, &r);
    let c = seed::check(&s, &r);
    assert!(c.min_clearance.0 > 0.0, "{} penetrates by {}", c.min_clearance.1, -c.min_clearance.0);
}
