//! Constraints between the nodes ([`Problem::between_nodes`], [`IntervalConstraint`]): a
//! minimum-time point mass in the plane passes a disc. With the clearance only at the nodes,
//! the time-optimal segments cut through the disc between them; with the peak rows the dense
//! trajectory stays out of it.

use armature_scvx::{
    BetweenNodes, Control, IntervalConstraint, Problem, ProblemConstraint, ProblemError, Ptr,
    PtrError, PtrSettings, Solution, State, Time,
};
use armature_symbolic::{Expr, Function, Shape};

const NODES: usize = 6;
/// The disc: centre (1, −0.1), radius 0.3; the straight line from (0, 0) to (2, 0) crosses it.
const CENTRE: [f64; 2] = [1.0, -0.1];
const RADIUS: f64 = 0.3;

/// `r² − |p − c|²` (≤ 0 outside the disc), as an expression of the position state, with the
/// centre `c` a parameter.
fn inside(p: &Expr) -> Expr {
    let d = p - Expr::parameter("centre", Shape::Vector(2), &CENTRE);
    -(d.clone() * d).sum() + RADIUS * RADIUS
}

/// The deepest penetration of the disc at `centre` on a dense trajectory (m).
fn depth(s: &Solution, centre: [f64; 2]) -> f64 {
    s.trajectory["p"]
        .iter()
        .map(|p| RADIUS - ((p[0] - centre[0]).powi(2) + (p[1] - centre[1]).powi(2)).sqrt())
        .fold(f64::NEG_INFINITY, f64::max)
}

fn problem(between_nodes: bool) -> Problem {
    problem_with(between_nodes, None)
}

fn problem_with(between_nodes: bool, activation: Option<f64>) -> Problem {
    let p = State::new("p", 2).initial_value(&[0.0, 0.0]).final_value(&[2.0, 0.0]);
    let v = State::new("v", 2)
        .bounds(&[-5.0, -5.0], &[5.0, 5.0])
        .initial_value(&[0.0, 0.0])
        .final_value(&[0.0, 0.0]);
    let a = Control::new("a", 2).bounds(&[-1.0, -1.0], &[1.0, 1.0]);
    let g = inside(&p.expr());
    Problem {
        dynamics: vec![v.expr(), a.expr()],
        constraints: vec![ProblemConstraint::from(g.le(0.0).named("outside the disc"))],
        between_nodes: if between_nodes {
            vec![BetweenNodes {
                name: "outside the disc".into(),
                g,
                first: 0,
                last: NODES - 1,
                activation,
                sampling: armature_scvx::Sampling::Peak,
            }]
        } else {
            Vec::new()
        },
        states: vec![p, v],
        controls: vec![a],
        time: Time::Free { min: 0.0, max: 10.0, guess: 4.0, minimize: true },
        ..Problem::new(NODES)
    }
}

/// The solution and the deepest penetration of the disc on its dense trajectory (m).
fn solve(between_nodes: bool) -> (Solution, f64) {
    let mut compiled = problem(between_nodes).compile(PtrSettings::default()).unwrap();
    let s = compiled.solve().unwrap();
    let depth = depth(&s, CENTRE);
    eprintln!(
        "between nodes {between_nodes}: {} after {} iterations, T = {:.5} s, depth {depth:.2e} m",
        s.status, s.iterations, s.final_time
    );
    (s, depth)
}

#[test]
fn peak_rows_keep_the_path_out_of_the_disc_between_the_nodes() {
    let (nodal, depth_nodal) = solve(false);
    assert_eq!(nodal.status, armature_scvx::PtrStatus::Converged);
    // At the nodes only: a segment cuts into the disc (more than the dense check's 1e-4).
    assert!(depth_nodal > 1e-3, "deepest penetration {depth_nodal}");
    let (peaks, depth_peaks) = solve(true);
    assert_eq!(peaks.status, armature_scvx::PtrStatus::Converged);
    // Between the nodes too: the peak of each segment on the integration grid, refined by a
    // parabola, is within the integration's accuracy of the continuous one.
    assert!(depth_peaks <= 1e-5, "deepest penetration {depth_peaks}");
    // The axes' accelerations are bounded apart, so the path can dodge the disc sideways
    // without slowing down: both reach (or approach) the unconstrained optimum 2√2 s, and
    // the rows never buy time.
    let unconstrained = 2.0 * 2f64.sqrt();
    assert!(peaks.final_time >= unconstrained - 1e-6, "T = {}", peaks.final_time);
    // (Each solve stops where the model sees less than `eps_flat` of the cost left to gain.)
    let eps_flat = PtrSettings::default().eps_flat;
    assert!(peaks.final_time >= nodal.final_time * (1.0 - eps_flat));
    // The report names the constraint and finds it met.
    let v = peaks
        .violations
        .iter()
        .find(|v| v.constraint == "outside the disc between nodes")
        .expect("reported");
    assert!(v.value <= 1e-6 && v.node.is_some(), "{v:?}");
}

#[test]
fn grid_point_rows_keep_the_path_out_of_the_disc_too() {
    let mut problem = problem(true);
    problem.between_nodes[0].sampling = armature_scvx::Sampling::GridPoints;
    let mut compiled = problem.compile(PtrSettings::default()).unwrap();
    // One row per grid point of each of the 5 segments (11 points each: a node is held on
    // both of its sides) against one per segment; the rows of a segment share its buffer
    // (one column, one `ν ≥ 0` row), as its single peak row has one.
    let dims = |c: &mut armature_scvx::CompiledProblem| {
        let d = c.ptr().dimensions();
        (d.inequality_rows, d.variables)
    };
    let peak = dims(&mut problem_with(true, None).compile(PtrSettings::default()).unwrap());
    assert_eq!(dims(&mut compiled), (peak.0 + (5 * 11 - 5), peak.1));
    let s = compiled.solve().unwrap();
    assert_eq!(s.status, armature_scvx::PtrStatus::Converged, "{:?}", s.max_violation);
    let d = depth(&s, CENTRE);
    assert!(d <= 1e-5, "deepest penetration {d}");
    // The optimum: with the acceleration bounded per axis, the path can bend around the disc
    // in y while x runs its bang-bang profile, so the unobstructed minimum time 2·√(2/1)
    // (a lower bound for any path) is approached — to within `2·eps_flat`: the solve
    // polishes once its model sees less than `eps_flat` left to gain, and along the disc the
    // model sees half of what each step gains (ratios 1.8: the disc's negative curvature is
    // projected out of the subproblem), so it stops 0.39 % above the bound (measured; 61
    // iterations to within 1e-4 without polishing).
    let bound = 2.0 * 2f64.sqrt();
    let eps_flat = PtrSettings::default().eps_flat;
    let t = s.final_time;
    assert!(t <= bound * (1.0 + 2.0 * eps_flat) && t >= bound - 1e-6, "{t}");
}

#[test]
fn moving_the_disc_re_solves_without_recompiling() {
    let mut compiled = problem(true).compile(PtrSettings::default()).unwrap();
    assert_eq!(compiled.solve().unwrap().status, armature_scvx::PtrStatus::Converged);
    // The disc's centre moves to the other side of the line: the nodal and the between-nodes
    // constraint read it (the dynamics do not).
    let moved = [1.1, 0.1];
    assert_eq!(compiled.set_parameter("centre", &moved).unwrap(), 2);
    let s = compiled.solve().unwrap();
    assert_eq!(s.status, armature_scvx::PtrStatus::Converged, "{:?}", s.max_violation);
    let d = depth(&s, moved);
    assert!(d <= 1e-5, "deepest penetration of the moved disc {d}");
    // The path now passes below the disc.
    let lowest = s.trajectory["p"].iter().map(|p| p[1]).fold(f64::INFINITY, f64::min);
    assert!(lowest < -0.1, "lowest point {lowest}");
}

#[test]
fn bad_between_nodes_constraints_are_errors() {
    // Segments beyond the last node.
    let mut p = problem(true);
    p.between_nodes[0].last = NODES;
    let e = p.compile(PtrSettings::default()).unwrap_err();
    assert!(
        matches!(&e, ProblemError::Bad { what, .. } if what.contains("outside the disc")),
        "{e}"
    );
    // An empty interval.
    let mut p = problem(true);
    p.between_nodes[0].first = 3;
    p.between_nodes[0].last = 3;
    assert!(p.compile(PtrSettings::default()).is_err());
    // A control in g.
    let mut p = problem(true);
    p.between_nodes[0].g = p.controls[0].expr().sum();
    let e = p.compile(PtrSettings::default()).unwrap_err();
    assert!(e.to_string().contains("states only"), "{e}");
    // An activation distance that is not positive.
    for bad in [0.0, -0.1, f64::NAN] {
        let e = problem_with(true, Some(bad)).compile(PtrSettings::default()).unwrap_err();
        assert!(e.to_string().contains("activation"), "{e}");
    }
}

/// With an activation distance the segments far from the disc (its first and last, about
/// 0.4 m² below the bound) leave their peak rows out of the subproblem: the interior point
/// factors a smaller KKT matrix, and the solve converges to the same kind of path, out of the
/// disc. (The steps can differ: a row switched off at one reference may have bound a later
/// subproblem's step; here the final times agree to 0.1 %.)
#[test]
fn far_segments_switch_their_peak_rows_off() {
    let solve_with = |activation| {
        let mut compiled = problem_with(true, activation).compile(PtrSettings::default()).unwrap();
        let s = compiled.solve().unwrap();
        let kkt = compiled.ptr().dimensions().reduced_kkt_nonzeros.expect("interior point");
        (s, kkt)
    };
    let (all, kkt_all) = solve_with(None);
    // g = r² − |p − c|² (m²).
    let (screened, kkt_screened) = solve_with(Some(0.15));
    assert_eq!(screened.status, armature_scvx::PtrStatus::Converged);
    assert!(depth(&screened, CENTRE) <= 1e-5);
    assert!(
        (screened.final_time - all.final_time).abs() < 1e-3 * all.final_time,
        "{} against {}",
        screened.final_time,
        all.final_time
    );
    assert!(kkt_screened.1 < kkt_all.1, "factor nonzeros {kkt_screened:?} against {kkt_all:?}");
}

#[test]
fn the_solver_checks_interval_constraints_too() {
    // The same checks at the `Ocp` level, as errors of `Ptr::new`.
    let mut compiled = problem(false).compile(PtrSettings::default()).unwrap();
    let mut ocp = compiled.ptr().ocp().clone();
    let (n, m) = (ocp.dynamics.n_x(), ocp.dynamics.n_u());
    let states: Vec<Expr> = (0..n).map(|i| Expr::variable(&format!("x{i}"), 1)).collect();
    let controls: Vec<Expr> = (0..m).map(|i| Expr::variable(&format!("u{i}"), 1)).collect();
    let args = [states.as_slice(), controls.as_slice()];
    let reads_control = Function::compile(&[&states[0] + &controls[0]], &args).unwrap();
    ocp.interval_constraints = vec![IntervalConstraint {
        name: "bad".into(),
        function: reads_control,
        first: 0,
        last: NODES - 1,
        activation: None,
        sampling: armature_scvx::Sampling::Peak,
    }];
    let e = Ptr::new(ocp.clone(), PtrSettings::default()).unwrap_err();
    assert!(matches!(&e, PtrError::IntervalConstraint { name, .. } if name == "bad"), "{e}");
    let states_only = Function::compile(&[states[0].clone()], &args).unwrap();
    ocp.interval_constraints[0].function = states_only;
    ocp.interval_constraints[0].last = NODES;
    let e = Ptr::new(ocp.clone(), PtrSettings::default()).unwrap_err();
    assert!(e.to_string().contains("first < last"), "{e}");
    ocp.interval_constraints[0].last = NODES - 1;
    ocp.interval_constraints[0].activation = Some(f64::NAN);
    let e = Ptr::new(ocp, PtrSettings::default()).unwrap_err();
    assert!(e.to_string().contains("activation"), "{e}");
}
