//! The native interior point against Clarabel on random strictly convex problems with
//! equality, nonnegative and second-order-cone rows (unique minimizers, so x must agree),
//! and its warm start on a re-solve.

use armature_scvx::ipm::{Cones, InteriorPoint, IpmSettings, IpmStatus};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSolver, IPSolver, NonnegativeConeT, SecondOrderConeT, SolverStatus,
    ZeroConeT,
};
use proptest::prelude::*;
use proptest::strategy::ValueTree;

/// Dense column-major data → CSC (all entries kept, so the pattern is dense).
fn csc(rows: usize, cols: usize, dense: &[f64], upper: bool) -> (Vec<usize>, Vec<usize>, Vec<f64>) {
    csc_where(rows, cols, dense, upper, |_| true)
}

/// Dense column-major data → CSC of its nonzero entries.
fn sparse_csc(
    rows: usize,
    cols: usize,
    dense: &[f64],
    upper: bool,
) -> (Vec<usize>, Vec<usize>, Vec<f64>) {
    csc_where(rows, cols, dense, upper, |v| v != 0.0)
}

fn csc_where(
    rows: usize,
    cols: usize,
    dense: &[f64],
    upper: bool,
    keep: impl Fn(f64) -> bool,
) -> (Vec<usize>, Vec<usize>, Vec<f64>) {
    let (mut cp, mut rv, mut v) = (vec![0], Vec::new(), Vec::new());
    for c in 0..cols {
        for r in 0..rows {
            if (!upper || r <= c) && keep(dense[c * rows + r]) {
                rv.push(r);
                v.push(dense[c * rows + r]);
            }
        }
        cp.push(rv.len());
    }
    (cp, rv, v)
}

#[derive(Debug, Clone)]
struct Problem {
    n: usize,
    m: usize,
    p: Vec<f64>,
    q: Vec<f64>,
    a: Vec<f64>,
    b: Vec<f64>,
    cones: Cones,
    /// The strictly feasible point the problem was built around (empty where unknown).
    x0: Vec<f64>,
}

/// P = MᵀM + I; A random; b = A x₀ + s₀ with s₀ inside the cones (strictly feasible).
fn problem() -> impl Strategy<Value = Problem> {
    (2usize..6, 0usize..2, 1usize..6, 0usize..3).prop_flat_map(|(n, m0, m1, k)| {
        let m = m0 + m1 + 3 * k;
        (
            prop::collection::vec(-1.0..1.0f64, n * n),
            prop::collection::vec(-1.0..1.0f64, n),
            prop::collection::vec(-1.0..1.0f64, m * n),
            prop::collection::vec(-1.0..1.0f64, n),
            prop::collection::vec(0.1..1.0f64, m),
        )
            .prop_map(move |(mm, q, a, x0, s0)| {
                let mut p = vec![0.0; n * n];
                for i in 0..n {
                    for j in 0..n {
                        p[j * n + i] = (0..n).map(|k| mm[i * n + k] * mm[j * n + k]).sum::<f64>()
                            + f64::from(u8::from(i == j));
                    }
                }
                let mut s = s0.clone();
                s[..m0].fill(0.0);
                for c in 0..k {
                    let r = m0 + m1 + 3 * c;
                    s[r] = 0.1 + (s[r + 1] * s[r + 1] + s[r + 2] * s[r + 2]).sqrt();
                }
                let b = (0..m)
                    .map(|r| (0..n).map(|c| a[c * m + r] * x0[c]).sum::<f64>() + s[r])
                    .collect();
                let cones = Cones { zero: m0, nonneg: m1, soc: vec![3; k] };
                Problem { n, m, p, q, a, b, cones, x0 }
            })
    })
}

/// Clarabel's solution (x, objective) of the dense problem at tolerance `tol`, if it
/// solves it (at 1e-9, Clarabel reaches its iteration cap on about one random problem in a
/// few thousand that ours solves).
fn clarabel(pr: &Problem, tol: f64) -> Option<(Vec<f64>, f64)> {
    let (pc, prw, pv) = csc(pr.n, pr.n, &pr.p, true);
    let (ac, ar, av) = csc(pr.m, pr.n, &pr.a, false);
    let mut cones = vec![ZeroConeT(pr.cones.zero), NonnegativeConeT(pr.cones.nonneg)];
    cones.extend(pr.cones.soc.iter().map(|&d| SecondOrderConeT(d)));
    let settings = DefaultSettings {
        verbose: false,
        tol_gap_abs: tol,
        tol_gap_rel: tol,
        tol_feas: tol,
        ..DefaultSettings::default()
    };
    let mut cl = DefaultSolver::new(
        &CscMatrix::new(pr.n, pr.n, pc, prw, pv),
        &pr.q,
        &CscMatrix::new(pr.m, pr.n, ac, ar, av),
        &pr.b,
        &cones,
        settings,
    )
    .unwrap();
    cl.solve();
    matches!(cl.solution.status, SolverStatus::Solved | SolverStatus::AlmostSolved)
        .then(|| (cl.solution.x.clone(), cl.solution.obj_val))
}

/// The optimality certificate of `ipm`'s last solution, computed here from the dense data:
/// primal residual `‖Ax + s − b‖∞`, dual residual `‖Px + q + Aᵀz‖∞`, gap `sᵀz` (relative
/// to `max(1, |objective|)`), and
/// whether s and z lie in the cones (zero rows: s = 0; nonnegative rows: s, z ≥ 0;
/// second-order cones: t ≥ ‖v‖ for both). For a convex problem, all of them small is a
/// proof of optimality without any reference solver.
fn certificate(pr: &Problem, ipm: &InteriorPoint) -> (f64, f64, f64, bool) {
    let (x, s, z) = (ipm.x(), ipm.s(), ipm.z());
    let (n, m) = (pr.n, pr.m);
    let primal = (0..m)
        .map(|r| ((0..n).map(|c| pr.a[c * m + r] * x[c]).sum::<f64>() + s[r] - pr.b[r]).abs())
        .fold(0.0, f64::max);
    let dual = (0..n)
        .map(|i| {
            let px: f64 = (0..n).map(|j| pr.p[j * n + i] * x[j]).sum();
            let az: f64 = (0..m).map(|r| pr.a[i * m + r] * z[r]).sum();
            (px + pr.q[i] + az).abs()
        })
        .fold(0.0, f64::max);
    let (m0, m1) = (pr.cones.zero, pr.cones.nonneg);
    // sᵀz relative to the objective, as the solver's stopping test measures it (it stops
    // at sᵀz ≤ tol·|objective| when the objective is large).
    let pobj: f64 = (0..n)
        .map(|i| x[i] * (0.5 * (0..n).map(|j| pr.p[j * n + i] * x[j]).sum::<f64>() + pr.q[i]))
        .sum();
    let gap: f64 =
        s[m0..].iter().zip(&z[m0..]).map(|(a, b)| a * b).sum::<f64>() / pobj.abs().max(1.0);
    let mut inside = s[..m0].iter().all(|v| *v == 0.0)
        && s[m0..m0 + m1].iter().chain(&z[m0..m0 + m1]).all(|v| *v >= 0.0);
    let mut r = m0 + m1;
    for &d in &pr.cones.soc {
        for v in [&s[r..r + d], &z[r..r + d]] {
            inside &= v[0] >= v[1..].iter().map(|w| w * w).sum::<f64>().sqrt();
        }
        r += d;
    }
    (primal, dual, gap, inside)
}

/// Ours and Clarabel's solve at tolerance `tol` (ours with two refinement steps, which
/// tolerances below 1e-8 want).
/// The settings of these tests: a tolerance, two refinement steps.
fn settings(tolerance: f64) -> IpmSettings {
    let mut s = IpmSettings::default();
    s.tolerance = tolerance;
    s.refinement_steps = 2;
    s
}

fn solve_both(
    pr: &Problem,
    settings: IpmSettings,
) -> (InteriorPoint, IpmStatus, Option<(Vec<f64>, f64)>) {
    let (pc, prw, pv) = csc(pr.n, pr.n, &pr.p, true);
    let (ac, ar, av) = csc(pr.m, pr.n, &pr.a, false);
    let mut ipm =
        InteriorPoint::new(pr.n, (&pc, &prw), pr.m, (&ac, &ar), pr.cones.clone(), settings.clone())
            .unwrap();
    let status = ipm.solve(&pv, &pr.q, &av, &pr.b);
    let reference = clarabel(pr, settings.tolerance);
    (ipm, status, reference)
}

/// `ipm`'s solution carries its own certificate, recomputed from the data (feasible,
/// stationary, complementary), and agrees with Clarabel's where Clarabel solves the problem
/// (where it reaches its iteration cap, the certificate stands alone).
fn certified_and_agreeing(
    pr: &Problem,
    ipm: &InteriorPoint,
    reference: Option<(Vec<f64>, f64)>,
) -> Result<(), TestCaseError> {
    let (primal, dual, gap, inside) = certificate(pr, ipm);
    let xn = ipm.x().iter().fold(1.0f64, |a, v| a.max(v.abs()));
    prop_assert!(primal < 1e-8 * xn && dual < 1e-8 * xn, "residuals {primal:e} {dual:e}");
    prop_assert!(gap.abs() < 1e-6 && inside, "gap {gap:e}, in the cones: {inside}");
    if let Some((x, obj)) = reference {
        for (a, b) in ipm.x().iter().zip(&x) {
            prop_assert!((a - b).abs() < 1e-4 * (1.0 + b.abs()), "{:?} vs {:?}", ipm.x(), x);
        }
        prop_assert!((ipm.objective() - obj).abs() < 1e-6 * (1.0 + obj.abs()));
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn agrees_with_clarabel(pr in problem()) {
        // Both at 1e-9: the minimizer is then pinned to about 1e-4 (|Δx|² ≲ 2·gap, P ⪰ I).
        let (ipm, status, reference) = solve_both(&pr, settings(1e-9));
        prop_assert_eq!(status, IpmStatus::Solved);
        certified_and_agreeing(&pr, &ipm, reference)?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// Nonnegative rows kept in K with rows of their own (`dense_row = 0`: every one),
    /// with and without a staged ordering: the same certified solution as Clarabel's.
    #[test]
    fn rows_kept_in_k_give_the_same_solution(
        pr in problem(),
        stages in prop::collection::vec(prop::option::of(0usize..4), 6),
        staged in any::<bool>(),
    ) {
        let mut kept = settings(1e-9);
        kept.dense_row = 0;
        let (ipm, _, reference) = solve_both(&pr, kept.clone());
        let (pc, prw, pv) = csc(pr.n, pr.n, &pr.p, true);
        let (ac, ar, av) = csc(pr.m, pr.n, &pr.a, false);
        let mut ipm = if staged {
            InteriorPoint::new(pr.n, (&pc, &prw), pr.m, (&ac, &ar), pr.cones.clone(), kept)
                .and_then(|ipm| ipm.with_stages(&stages[..pr.n]))
                .unwrap()
        } else {
            ipm
        };
        prop_assert_eq!(ipm.solve(&pv, &pr.q, &av, &pr.b), IpmStatus::Solved);
        certified_and_agreeing(&pr, &ipm, reference)?;
        // K has one more row per nonnegative row.
        let folded = solve_both(&pr, settings(1e-9)).0;
        prop_assert!(ipm.kkt_nonzeros().0 <= folded.kkt_nonzeros().0 + pr.cones.nonneg * (pr.n + 1));
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// A staged ordering of the KKT factorization (any stages, some variables unstaged) is
    /// only a permutation: the same certified solution as in AMD's ordering.
    #[test]
    fn a_staged_ordering_gives_the_same_solution(
        pr in problem(),
        stages in prop::collection::vec(prop::option::of(0usize..4), 6),
    ) {
        let (amd, status, _) = solve_both(&pr, settings(1e-9));
        prop_assert_eq!(status, IpmStatus::Solved);
        let (pc, prw, pv) = csc(pr.n, pr.n, &pr.p, true);
        let (ac, ar, av) = csc(pr.m, pr.n, &pr.a, false);
        let mut staged =
            InteriorPoint::new(pr.n, (&pc, &prw), pr.m, (&ac, &ar), pr.cones.clone(), settings(1e-9))
                .and_then(|ipm| ipm.with_stages(&stages[..pr.n]))
                .unwrap();
        prop_assert_eq!(staged.solve(&pv, &pr.q, &av, &pr.b), IpmStatus::Solved);
        let (primal, dual, gap, inside) = certificate(&pr, &staged);
        let xn = staged.x().iter().fold(1.0f64, |a, v| a.max(v.abs()));
        prop_assert!(primal < 1e-8 * xn && dual < 1e-8 * xn, "residuals {primal:e} {dual:e}");
        prop_assert!(gap.abs() < 1e-6 && inside, "gap {gap:e}, in the cones: {inside}");
        for (a, b) in staged.x().iter().zip(amd.x()) {
            prop_assert!((a - b).abs() < 1e-4 * (1.0 + b.abs()), "{:?} vs {:?}", staged.x(), amd.x());
        }
        prop_assert!(staged.kkt_nonzeros().1 <= amd.kkt_nonzeros().1 + pr.n * pr.n);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// Switchable rows: nonnegative rows whose values a caller zeroes (all but at most one)
    /// between solves. One solver, declared with all its nonnegative rows switchable, solves
    /// the problem with some rows off, the original (all on: back to the full pattern), then
    /// the first again (a cached analysis), each from a cold start: each time the same
    /// certified solution as a fresh solver that knows nothing of switchable rows.
    #[test]
    fn switched_off_rows_give_the_same_solution(
        pr in problem(),
        off in prop::collection::vec(prop::option::of(0usize..6), 6),
    ) {
        let m0 = pr.cones.zero;
        let nonneg: Vec<usize> = (m0..m0 + pr.cones.nonneg).collect();
        // Rows off: all entries zero but, for `Some(c)`, column c's; a loose right-hand side
        // keeps the problem's interior point x₀ ∈ (−1, 1)ⁿ strictly feasible.
        let mut switched = pr.clone();
        for (&r, keep) in nonneg.iter().zip(&off) {
            if let Some(keep) = keep {
                for c in 0..pr.n {
                    if *keep >= pr.n || c != *keep {
                        switched.a[c * pr.m + r] = 0.0;
                    }
                }
                switched.b[r] = 2.0;
            }
        }
        let (pc, prw, pv) = csc(pr.n, pr.n, &pr.p, true);
        let (ac, ar, _) = csc(pr.m, pr.n, &pr.a, false);
        let values = |pr: &Problem| csc(pr.m, pr.n, &pr.a, false).2;
        let fresh_solver = || {
            InteriorPoint::new(pr.n, (&pc, &prw), pr.m, (&ac, &ar), pr.cones.clone(), settings(1e-9))
        };
        let mut switchable =
            fresh_solver().and_then(|ipm| ipm.with_switchable_rows(&nonneg)).unwrap();
        for case in [&switched, &pr, &switched] {
            let (fresh, status, _) = solve_both(case, settings(1e-9));
            prop_assert_eq!(status, IpmStatus::Solved);
            // Cold, as the fresh solver (a warm start from another problem is not the point).
            switchable.reset();
            let status = switchable.solve(&pv, &case.q, &values(case), &case.b);
            prop_assert_eq!(status, IpmStatus::Solved);
            let (primal, dual, gap, inside) = certificate(case, &switchable);
            let xn = switchable.x().iter().fold(1.0f64, |a, v| a.max(v.abs()));
            prop_assert!(primal < 1e-8 * xn && dual < 1e-8 * xn, "residuals {primal:e} {dual:e}");
            prop_assert!(gap.abs() < 1e-6 && inside, "gap {gap:e}, in the cones: {inside}");
            for (a, b) in switchable.x().iter().zip(fresh.x()) {
                let (xs, xf) = (switchable.x(), fresh.x());
                prop_assert!((a - b).abs() < 1e-4 * (1.0 + b.abs()), "{:?} vs {:?}", xs, xf);
            }
        }
        // Rows off leave K's pattern smaller (or equal), never larger.
        prop_assert!(switchable.kkt_nonzeros().0 <= fresh_solver().unwrap().kkt_nonzeros().0);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// Entries of A's pattern whose values are zero (a linearized constraint that does not
    /// depend on a variable at this point) add nothing: a solver whose pattern holds them
    /// (its products with A skip them) reaches the same certified solution as one whose
    /// pattern leaves them out.
    #[test]
    fn zero_values_in_the_pattern_change_nothing(
        pr in problem(),
        zeros in prop::collection::vec(any::<bool>(), 60),
    ) {
        // Zeroed entries, with b moved so that x₀ stays strictly feasible: the problem's
        // pattern changes, not its conditioning (keeping b can leave a nearly infeasible
        // problem whose only solutions lie far out, x ≈ 70 at a vertex; both patterns then
        // take the same steps up to rounding, and one of them reached the iteration cap).
        let mut zeroed = pr.clone();
        for (i, (v, z)) in zeroed.a.iter_mut().zip(&zeros).enumerate() {
            if *z {
                let (r, c) = (i % pr.m, i / pr.m);
                zeroed.b[r] -= *v * pr.x0[c];
                *v = 0.0;
            }
        }
        let (pc, prw, pv) = csc(pr.n, pr.n, &pr.p, true);
        let solve = |(ac, ar, av): (Vec<usize>, Vec<usize>, Vec<f64>)| {
            let mut ipm = InteriorPoint::new(
                pr.n, (&pc, &prw), pr.m, (&ac, &ar), pr.cones.clone(), settings(1e-9),
            )
            .unwrap();
            let status = ipm.solve(&pv, &zeroed.q, &av, &zeroed.b);
            (status, ipm)
        };
        let (full_status, full) = solve(csc(pr.m, pr.n, &zeroed.a, false));
        let (sparse_status, sparse) = solve(sparse_csc(pr.m, pr.n, &zeroed.a, false));
        prop_assert_eq!(full_status, IpmStatus::Solved);
        prop_assert_eq!(sparse_status, IpmStatus::Solved);
        for ipm in [&full, &sparse] {
            let (primal, dual, gap, inside) = certificate(&zeroed, ipm);
            let xn = ipm.x().iter().fold(1.0f64, |a, v| a.max(v.abs()));
            prop_assert!(primal < 1e-8 * xn && dual < 1e-8 * xn, "residuals {primal:e} {dual:e}");
            prop_assert!(gap.abs() < 1e-6 && inside, "gap {gap:e}, in the cones: {inside}");
        }
        for (a, b) in full.x().iter().zip(sparse.x()) {
            prop_assert!((a - b).abs() < 1e-5 * (1.0 + b.abs()), "{:?} vs {:?}", full.x(), sparse.x());
        }
    }
}

/// Declaring a row that is not a nonnegative row switchable is an error.
#[test]
fn only_nonnegative_rows_are_switchable() {
    // One equality row and one nonnegative row on x ∈ ℝ².
    let ipm = || {
        InteriorPoint::new(
            2,
            (&[0, 1, 2], &[0, 1]),
            2,
            (&[0, 2, 4], &[0, 1, 0, 1]),
            Cones { zero: 1, nonneg: 1, soc: vec![] },
            IpmSettings::default(),
        )
        .unwrap()
    };
    assert!(ipm().with_switchable_rows(&[1]).is_ok());
    assert!(ipm().with_switchable_rows(&[0]).is_err());
    assert!(ipm().with_switchable_rows(&[2]).is_err());
}

/// A multistage problem (a discrete double integrator driven to rest from x₀ over N steps,
/// minimizing the control effort under a box on the controls that binds): with each node's variables
/// staged, the factor is no larger than in AMD's ordering, and the solution is the same.
#[test]
fn stages_never_cost_more_than_amd_on_a_horizon() {
    let nodes = 30;
    let (nx, nu) = (2, 1);
    let n = nodes * nx + (nodes - 1) * nu;
    let u0 = nodes * nx;
    // Equality rows: x₀ = (1, 0); x_{k+1} = A x_k + B u_k; x_{N−1} = 0. Then |u_k| ≤ 0.6.
    let (dt, mut rows) = (0.1, Vec::new());
    rows.push(vec![(0, 1.0)]);
    rows.push(vec![(1, 1.0)]);
    for k in 0..nodes - 1 {
        let (x, y) = (k * nx, (k + 1) * nx);
        rows.push(vec![(y, 1.0), (x, -1.0), (x + 1, -dt)]);
        rows.push(vec![(y + 1, 1.0), (x + 1, -1.0), (u0 + k, -dt)]);
    }
    rows.push(vec![((nodes - 1) * nx, 1.0)]);
    rows.push(vec![((nodes - 1) * nx + 1, 1.0)]);
    let m0 = rows.len();
    let mut b = vec![0.0; m0];
    b[0] = 1.0;
    for k in 0..nodes - 1 {
        rows.push(vec![(u0 + k, 1.0)]);
        rows.push(vec![(u0 + k, -1.0)]);
        b.extend([0.6, 0.6]);
    }
    let m = rows.len();
    let mut dense = vec![0.0; m * n];
    for (r, row) in rows.iter().enumerate() {
        for &(c, v) in row {
            dense[c * m + r] = v;
        }
    }
    let (ac, ar, av) = sparse_csc(m, n, &dense, false);
    let mut p = vec![0.0; n * n];
    for c in 0..n {
        p[c * n + c] = if c >= u0 { 1.0 } else { 1e-3 };
    }
    let (pc, prw, pv) = sparse_csc(n, n, &p, true);
    let cones = Cones { zero: m0, nonneg: m - m0, soc: vec![] };
    let stages: Vec<Option<usize>> =
        (0..n).map(|c| Some(if c < u0 { c / nx } else { c - u0 })).collect();
    let mut amd =
        InteriorPoint::new(n, (&pc, &prw), m, (&ac, &ar), cones.clone(), IpmSettings::default())
            .unwrap();
    let mut staged =
        InteriorPoint::new(n, (&pc, &prw), m, (&ac, &ar), cones, IpmSettings::default())
            .and_then(|ipm| ipm.with_stages(&stages))
            .unwrap();
    let q = vec![0.0; n];
    assert_eq!(amd.solve(&pv, &q, &av, &b), IpmStatus::Solved);
    assert_eq!(staged.solve(&pv, &q, &av, &b), IpmStatus::Solved);
    assert!(staged.kkt_nonzeros().1 <= amd.kkt_nonzeros().1);
    for (a, s) in amd.x().iter().zip(staged.x()) {
        assert!((a - s).abs() < 1e-6, "{a} vs {s}");
    }
    // The box holds, and binds (the unconstrained effort-optimal control peaks at 6/T² ≈
    // 0.71), and the rest state is reached.
    let peak = staged.x()[u0..].iter().fold(0.0f64, |a, u| a.max(u.abs()));
    assert!(peak <= 0.6 + 1e-7 && peak > 0.6 - 1e-6, "{peak}");
    assert!(staged.x()[(nodes - 1) * nx].abs() < 1e-7);
    // Stages of the wrong length are refused.
    let cones = Cones { zero: m0, nonneg: m - m0, soc: vec![] };
    let short = InteriorPoint::new(n, (&pc, &prw), m, (&ac, &ar), cones, IpmSettings::default())
        .and_then(|ipm| ipm.with_stages(&stages[1..]));
    assert!(short.is_err());
}

/// Re-solving the same data warm-starts from the last duals: the same answer, in fewer
/// iterations. After `reset`, the solve is cold again.
#[test]
fn warm_start_saves_iterations_and_reset_forgets_it() {
    // The default warm start (nonnegative rows centred) and the plain margin push.
    for centring in [IpmSettings::default().warm_start_centring, 0.0] {
        let mut runner = proptest::test_runner::TestRunner::deterministic();
        let mut saved = 0;
        for _ in 0..20 {
            let pr = problem().new_tree(&mut runner).unwrap().current();
            let mut set = settings(1e-8);
            set.warm_start_centring = centring;
            let (mut ipm, status, reference) = solve_both(&pr, set);
            assert_eq!(status, IpmStatus::Solved);
            let (x, _) = reference.expect("Clarabel solves these 20 problems");
            let cold = ipm.iterations();
            let (_, _, pv) = csc(pr.n, pr.n, &pr.p, true);
            let (_, _, av) = csc(pr.m, pr.n, &pr.a, false);
            // The deviation form a PTR re-solve sees: x = 0 is a sensible start.
            assert_eq!(ipm.solve(&pv, &pr.q, &av, &pr.b), IpmStatus::Solved);
            for (a, b) in ipm.x().iter().zip(&x) {
                assert!((a - b).abs() < 1e-3 * (1.0 + b.abs()), "{a} vs {b}");
            }
            saved += i64::from(cold) - i64::from(ipm.iterations());
            ipm.reset();
            assert_eq!(ipm.solve(&pv, &pr.q, &av, &pr.b), IpmStatus::Solved);
            assert_eq!(ipm.iterations(), cold, "reset makes the next solve cold");
        }
        assert!(saved > 0, "centring {centring}: warm starts saved {saved} iterations over 20");
    }
}

/// `set_tolerance` loosens the next solves: each loose solve meets its own certificate at
/// the looser tolerance, costs no more iterations than the tight one, and saves some over
/// 20 problems; a tolerance tighter than the setting (or not a number) keeps the setting.
#[test]
fn a_looser_tolerance_stops_earlier_and_still_certifies() {
    let mut runner = proptest::test_runner::TestRunner::deterministic();
    let mut saved = 0;
    for _ in 0..20 {
        let pr = problem().new_tree(&mut runner).unwrap().current();
        let (mut ipm, status, _) = solve_both(&pr, settings(1e-9));
        assert_eq!(status, IpmStatus::Solved);
        let (tight, x) = (ipm.iterations(), ipm.x().to_vec());
        let (_, _, pv) = csc(pr.n, pr.n, &pr.p, true);
        let (_, _, av) = csc(pr.m, pr.n, &pr.a, false);
        let solve = |ipm: &mut InteriorPoint, tolerance: f64| {
            ipm.reset();
            ipm.set_tolerance(tolerance);
            assert_eq!(ipm.solve(&pv, &pr.q, &av, &pr.b), IpmStatus::Solved);
            ipm.iterations()
        };
        for floor in [1e-12, f64::NAN] {
            assert_eq!(solve(&mut ipm, floor), tight, "{floor}: the setting's 1e-9 holds");
        }
        let loose = solve(&mut ipm, 1e-4);
        assert!(loose <= tight, "{loose} > {tight}");
        saved += tight - loose;
        let (primal, dual, gap, inside) = certificate(&pr, &ipm);
        let xn = ipm.x().iter().fold(1.0f64, |a, v| a.max(v.abs()));
        assert!(primal < 1e-4 * xn && dual < 1e-4 * xn && inside, "{primal:e} {dual:e}");
        assert!(gap.abs() < 1e-3, "gap {gap:e}");
        for (a, b) in ipm.x().iter().zip(&x) {
            assert!((a - b).abs() < 1e-1 * (1.0 + b.abs()), "{a} vs {b}");
        }
    }
    assert!(saved > 0, "a 1e-4 tolerance saved {saved} iterations over 20 problems");
}

fn solve_dense(
    n: usize,
    p: &[f64],
    q: &[f64],
    a: &[f64],
    b: &[f64],
    cones: Cones,
) -> (IpmStatus, Vec<f64>, Vec<f64>) {
    let m = b.len();
    let (pc, prw, pv) = csc(n, n, p, true);
    let (ac, ar, av) = csc(m, n, a, false);
    let mut ipm =
        InteriorPoint::new(n, (&pc, &prw), m, (&ac, &ar), cones, IpmSettings::default()).unwrap();
    let status = ipm.solve(&pv, q, &av, b);
    (status, ipm.x().to_vec(), ipm.z().to_vec())
}

/// Equality rows only (no cone rows at all): one Newton step on the KKT system.
#[test]
fn an_equality_constrained_qp_is_solved() {
    // minimize ½(x₀² + x₁²)  subject to  x₀ + x₁ = 1  →  x = (½, ½), z = −½.
    let (status, x, z) = solve_dense(
        2,
        &[1.0, 0.0, 0.0, 1.0],
        &[0.0, 0.0],
        &[1.0, 1.0],
        &[1.0],
        Cones { zero: 1, nonneg: 0, soc: vec![] },
    );
    assert_eq!(status, IpmStatus::Solved);
    assert!((x[0] - 0.5).abs() < 1e-8 && (x[1] - 0.5).abs() < 1e-8, "{x:?}");
    assert!((z[0] + 0.5).abs() < 1e-8, "{z:?}");
}

/// A linear program (P = 0) with its optimum at a vertex.
#[test]
fn a_linear_program_reaches_its_vertex() {
    // minimize −x₀ − x₁  subject to  x₀ + 2x₁ ≤ 4,  3x₀ + x₁ ≤ 6,  x ≥ 0  →  x = (1.6, 1.2).
    let (status, x, _) = solve_dense(
        2,
        &[0.0; 4],
        &[-1.0, -1.0],
        // column-major 4×2: rows [1 2; 3 1; −1 0; 0 −1]
        &[1.0, 3.0, -1.0, 0.0, 2.0, 1.0, 0.0, -1.0],
        &[4.0, 6.0, 0.0, 0.0],
        Cones { zero: 0, nonneg: 4, soc: vec![] },
    );
    assert_eq!(status, IpmStatus::Solved);
    assert!((x[0] - 1.6).abs() < 1e-6 && (x[1] - 1.2).abs() < 1e-6, "{x:?}");
}

/// The smallest point of a second-order cone's slice: minimize t subject to ‖(1, 2)‖ ≤ t,
/// written as s = (t, 1, 2) ∈ 𝒬³ → t = √5.
#[test]
fn a_second_order_cone_program_reaches_the_norm() {
    // s = b − Ax with x = t: A = (−1, 0, 0)ᵀ, b = (0, 1, 2).
    let (status, x, _) = solve_dense(
        1,
        &[0.0],
        &[1.0],
        &[-1.0, 0.0, 0.0],
        &[0.0, 1.0, 2.0],
        Cones { zero: 0, nonneg: 0, soc: vec![3] },
    );
    assert_eq!(status, IpmStatus::Solved);
    assert!((x[0] - 5f64.sqrt()).abs() < 1e-7, "{x:?}");
}

/// An infeasible problem is not one this solver is built for (PTR's subproblems are
/// feasible by construction); it must stop with a status, not loop or panic.
#[test]
fn an_infeasible_problem_ends_with_a_status() {
    // x ≤ −1 and x ≥ 1.
    let (status, _, _) = solve_dense(
        1,
        &[1.0],
        &[0.0],
        &[1.0, -1.0],
        &[-1.0, -1.0],
        Cones { zero: 0, nonneg: 2, soc: vec![] },
    );
    assert_ne!(status, IpmStatus::Solved);
}

/// A strictly convex QP (1 equality row, 4 nonnegative rows, one 3-cone) on which Mehrotra's
/// combined step, built on a poor affine step, raised the gap every other iteration and
/// cycled to the iteration cap (found by a 3000-problem stress run). The solver now re-centres
/// without the second-order term when the combined step would raise the gap.
#[test]
fn a_cycling_mehrotra_step_is_caught() {
    let p = [
        2.824429626585226,
        -0.529872704217862,
        -0.9390593550920611,
        0.5993731830980077,
        -0.13420426384829898,
        -0.529872704217862,
        2.425755962730325,
        -0.48000605264836943,
        -0.23354778797458853,
        -0.4903600394752062,
        -0.9390593550920611,
        -0.48000605264836943,
        4.062657313356532,
        0.2848322257047237,
        0.758376286641357,
        0.5993731830980077,
        -0.23354778797458853,
        0.2848322257047237,
        3.0116698229436154,
        1.7765985636907988,
        -0.13420426384829898,
        -0.4903600394752062,
        0.758376286641357,
        1.7765985636907988,
        3.0825888201482954,
    ];
    let q = [
        0.6445425145904911,
        0.9667259608938297,
        -0.5816719071100573,
        -0.2361098912456312,
        0.7010921842036157,
    ];
    let a = [
        0.6510369554351667,
        0.15270029505862937,
        -0.4210639970651333,
        -0.7404775105364307,
        -0.016164069083117738,
        -0.7253786665061621,
        -0.17032889778254656,
        -0.5413868333821841,
        -0.6413679427202026,
        -0.030323521375593687,
        0.9573775308159622,
        -0.025754492713605304,
        0.7352062248145699,
        0.3273425968646113,
        0.2213686689684693,
        0.2803409655393909,
        0.8471562641560981,
        -0.3229682498810367,
        0.5070308329755706,
        0.16978202144395937,
        -0.7977493269407998,
        0.6148170370826809,
        -0.8975847756658686,
        0.12176740208263803,
        0.050529549579864774,
        -0.5653907639536448,
        0.48430017165055417,
        -0.8547918627281303,
        0.6748978276104911,
        0.4927684597493256,
        -0.29331641624843563,
        0.9943560821927626,
        -0.7646677734577418,
        0.5213142965401854,
        0.6009000446071033,
        -0.5809310399464664,
        -0.21098627979641327,
        -0.11170311465664207,
        -0.008184042669822311,
        -0.4843190678387097,
    ];
    let b = [
        -0.14218492007219785,
        -0.03192925948842662,
        2.18693433160655,
        0.28515966930787107,
        0.6930031955491085,
        2.5348313488673746,
        -0.5423324287556686,
        2.1023102638583615,
    ];
    let cones = Cones { zero: 1, nonneg: 4, soc: vec![3] };
    let (status, x, _) = solve_dense(5, &p, &q, &a, &b, cones.clone());
    assert_eq!(status, IpmStatus::Solved);
    // The same answer as Clarabel's.
    let (p, q, a, b) = (p.to_vec(), q.to_vec(), a.to_vec(), b.to_vec());
    let (clarabel, _) = clarabel(&Problem { n: 5, m: 8, p, q, a, b, cones, x0: vec![] }, 1e-8)
        .expect("Clarabel solves it");
    for (u, v) in x.iter().zip(&clarabel) {
        assert!((u - v).abs() < 1e-4, "{x:?} vs {clarabel:?}");
    }
}

/// A strictly convex QP (1 equality row, 1 nonnegative row, one 3-cone) on which even the
/// re-centred step raised the gap (through its second-order term): the iterates cycled
/// with period 4, the nonnegative row's slack and dual taking turns at 1 % of the boundary,
/// and the gap never fell below 0.12 (found by a 150 000-problem stress run). The solver now
/// shortens such a step until the gap does not grow; this one then solves in 7 iterations.
#[test]
fn a_cycling_centring_step_is_shortened() {
    let p = [1.6601057593832294, 0.6234734521184002, 0.6234734521184002, 1.9289543431123017];
    let q = [-0.8575799037053529, -0.7961574255607357];
    let a = [
        -0.6761856937589978,
        0.5411244986616188,
        -0.5161635518639356,
        0.39998274567692055,
        -0.17591795685498965,
        -0.5332952127918866,
        -0.6368094048403069,
        0.5034378516822591,
        -0.55980669966868,
        0.7520599679495528,
    ];
    let b = [
        0.7199993298007474,
        -0.05418194691533548,
        1.144933860458985,
        0.09531442439885485,
        0.6487897207058219,
    ];
    let cones = Cones { zero: 1, nonneg: 1, soc: vec![3] };
    let pr = Problem {
        n: 2,
        m: 5,
        p: p.to_vec(),
        q: q.to_vec(),
        a: a.to_vec(),
        b: b.to_vec(),
        cones,
        x0: vec![],
    };
    let (ipm, status, reference) = solve_both(&pr, settings(1e-9));
    assert_eq!(status, IpmStatus::Solved);
    assert!(ipm.iterations() <= 15, "{} iterations", ipm.iterations());
    let (primal, dual, gap, inside) = certificate(&pr, &ipm);
    assert!(primal < 1e-8 && dual < 1e-8 && gap < 1e-8 && inside, "{primal} {dual} {gap} {inside}");
    let (x, obj) = reference.expect("Clarabel solves it");
    for (u, v) in ipm.x().iter().zip(&x) {
        assert!((u - v).abs() < 1e-4, "{:?} vs {x:?}", ipm.x());
    }
    assert!((ipm.objective() - obj).abs() < 1e-6);
}

/// A warm start far from the new problem's central path: after solving this QP, the same
/// one with q and b moved a little (as consecutive PTR subproblems move) jammed from its
/// warm start: the steps to the boundary collapsed and it reached the iteration cap (found by
/// re-solving 40 000 perturbed random problems warm: 2 of those a cold solve solves jammed).
/// After three short steps in a row the solver now restarts cold, and solves it like a cold
/// solve does.
#[test]
fn a_jammed_warm_start_restarts_cold() {
    let pr = Problem {
        n: 2,
        m: 6,
        p: vec![1.9734621756263968, -0.15577979671139744, -0.15577979671139744, 1.121268730616585],
        q: vec![-0.6438576255074477, 0.6679702074920006],
        a: vec![
            -0.08164652097018182,
            0.6470949490533179,
            -0.49687726822160594,
            -0.2654058287038733,
            0.24895679106016316,
            0.6976097203141562,
            -0.042997681058347594,
            0.7402212785041307,
            -0.4577444755685366,
            0.3312066035842014,
            -0.3153428851701424,
            0.7616336280507783,
        ],
        b: vec![
            -0.046174339897147997,
            0.5667834718929422,
            0.8232402998875663,
            0.3436623091888693,
            0.7243285940101464,
            0.7705170987588408,
        ],
        cones: Cones { zero: 1, nonneg: 2, soc: vec![3] },
        x0: vec![],
    };
    let (pc, prw, pv) = csc(pr.n, pr.n, &pr.p, true);
    let (ac, ar, av) = csc(pr.m, pr.n, &pr.a, false);
    let new = || {
        InteriorPoint::new(2, (&pc, &prw), 6, (&ac, &ar), pr.cones.clone(), IpmSettings::default())
            .unwrap()
    };
    let mut ipm = new();
    assert_eq!(ipm.solve(&pv, &pr.q, &av, &pr.b), IpmStatus::Solved);
    // The moved problem (a cold solve solves it).
    let q: Vec<f64> =
        pr.q.iter().enumerate().map(|(i, v)| v + 0.05 * (i as f64 * 1.7).sin()).collect();
    let b: Vec<f64> =
        pr.b.iter().enumerate().map(|(i, v)| v + 0.02 * (i as f64 * 2.3).cos().abs()).collect();
    assert_eq!(ipm.solve(&pv, &q, &av, &b), IpmStatus::Solved, "warm");
    let mut cold = new();
    assert_eq!(cold.solve(&pv, &q, &av, &b), IpmStatus::Solved, "cold");
    for (u, v) in ipm.x().iter().zip(cold.x()) {
        assert!((u - v).abs() < 1e-6, "{:?} vs {:?}", ipm.x(), cold.x());
    }
    let moved = Problem { q, b, ..pr };
    let (primal, dual, gap, inside) = certificate(&moved, &ipm);
    assert!(primal < 1e-8 && dual < 1e-8 && gap < 1e-7 && inside, "{primal} {dual} {gap} {inside}");
}

/// An objective divided by a large factor (PTR's scaled solves at a heavy trust-region
/// weight) keeps its accuracy in the original units when the solver is told the factor:
/// the duality gap, measured in the original objective, meets the tolerance, and ℓ1 slacks
/// the optimum does not buy end at zero. (Without the declaration, the gap here ends at up
/// to 1e-7 and the slacks at 6e-8: the tolerance applied to the divided objective.)
#[test]
fn a_declared_objective_scale_keeps_the_solution_accurate() {
    // k copies of: minimize σx² + c·t  subject to  t ≥ a − x,  t ≥ 0, with 2σa < c, so
    // x = a and t = 0; the objective is passed divided by σ.
    let (k, c, tol) = (40, 0.3, IpmSettings::default().tolerance);
    let n = 2 * k;
    let mut pd = vec![0.0; n * n];
    let mut ad = vec![0.0; 2 * k * n];
    for i in 0..k {
        pd[i * n + i] = 2.0;
        // Rows 2i: s = x + t − a; rows 2i + 1: s = t (column-major (2k)×n).
        ad[i * 2 * k + 2 * i] = -1.0;
        ad[(k + i) * 2 * k + 2 * i] = -1.0;
        ad[(k + i) * 2 * k + 2 * i + 1] = -1.0;
    }
    let (pc, prw, pv) = csc(n, n, &pd, true);
    let (ac, ar, av) = csc(2 * k, n, &ad, false);
    let cones = Cones { zero: 0, nonneg: 2 * k, soc: vec![] };
    for sigma in [1e2, 1e4, 1e6] {
        let a: Vec<f64> = (0..k).map(|i| (0.02 + 0.1 * i as f64 / k as f64) / sigma).collect();
        let mut b = vec![0.0; 2 * k];
        for i in 0..k {
            b[2 * i] = -a[i];
        }
        let mut q = vec![0.0; n];
        q[k..].fill(c / sigma);
        let settings = IpmSettings::default();
        let mut ipm =
            InteriorPoint::new(n, (&pc, &prw), 2 * k, (&ac, &ar), cones.clone(), settings).unwrap();
        ipm.set_objective_scale(sigma);
        assert_eq!(ipm.solve(&pv, &q, &av, &b), IpmStatus::Solved, "σ = {sigma}");
        let x = ipm.x();
        let gap = sigma * ipm.s().iter().zip(ipm.z()).map(|(s, z)| s * z).sum::<f64>();
        assert!(gap <= tol, "σ = {sigma}: gap {gap:e} in the original units");
        let t_max = x[k..].iter().fold(0.0f64, |m, t| m.max(t.abs()));
        assert!(t_max <= tol, "σ = {sigma}: slack {t_max:e}");
        let x_err = (0..k).map(|i| (x[i] - a[i]).abs()).fold(0.0f64, f64::max);
        assert!(x_err <= 10.0 * tol, "σ = {sigma}: x off by {x_err:e}");
    }
}

/// `moved_solution` is the derivative of the solution with respect to b: moving b by a
/// small δ, the moved point matches a fresh solve of the moved problem to second order where
/// the rows are equalities and nonnegative rows (within a millionth of how far the solution
/// moved), and comes closer to it than the unmoved solution with second-order cones among
/// the rows (the documented approximation: within half the move; 5–30 % on these problems).
/// b itself gives back the solution, and the solver's own iterate is left as it was. Before
/// any solve there is nothing to move. 20 random problems.
#[test]
fn a_moved_right_hand_side_moves_the_solution_to_second_order() {
    let mut runner = proptest::test_runner::TestRunner::deterministic();
    let (mut exact, mut with_cones) = (0, 0);
    for case in 0..20 {
        let pr = problem().new_tree(&mut runner).unwrap().current();
        let (pc, prw, pv) = csc(pr.n, pr.n, &pr.p, true);
        let (ac, ar, av) = csc(pr.m, pr.n, &pr.a, false);
        let new = || {
            let cones = pr.cones.clone();
            InteriorPoint::new(pr.n, (&pc, &prw), pr.m, (&ac, &ar), cones, settings(1e-11)).unwrap()
        };
        let mut ipm = new();
        assert!(ipm.moved_solution(&pv, &pr.b, &pr.b).is_none(), "nothing solved yet");
        assert_eq!(ipm.solve(&pv, &pr.q, &av, &pr.b), IpmStatus::Solved);
        let x = ipm.x().to_vec();
        let same = ipm.moved_solution(&pv, &pr.b, &pr.b).unwrap().to_vec();
        for (a, b) in same.iter().zip(&x) {
            assert!((a - b).abs() < 1e-12 * (1.0 + b.abs()), "case {case}: {a} vs {b}");
        }
        let b2: Vec<f64> =
            pr.b.iter().enumerate().map(|(r, b)| b + 1e-5 * (1.7 * r as f64 + 0.3).sin()).collect();
        let moved = ipm.moved_solution(&pv, &pr.b, &b2).unwrap().to_vec();
        assert_eq!(ipm.x(), &x[..], "case {case}: the iterate stays");
        let mut fresh = new();
        assert_eq!(fresh.solve(&pv, &pr.q, &av, &b2), IpmStatus::Solved);
        let dist =
            |u: &[f64]| u.iter().zip(fresh.x()).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        let (unmoved, left) = (dist(&x), dist(&moved));
        if unmoved < 1e-9 {
            continue; // the rows pin x: nothing moves
        }
        if pr.cones.soc.is_empty() {
            assert!(left < 1e-6 * unmoved, "case {case}: moved {left:e} from {unmoved:e}");
            exact += 1;
        } else {
            assert!(left < 0.5 * unmoved, "case {case}: moved {left:e} from {unmoved:e}");
            with_cones += 1;
        }
    }
    assert!(exact >= 4 && with_cones >= 8, "cases checked: {exact} + {with_cones}");
}
