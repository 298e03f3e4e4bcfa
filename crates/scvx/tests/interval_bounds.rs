//! Interval bounds ([`Ocp::interval_bounds`]): a state bound enforced between the nodes at
//! each segment's peak. On the minimum-time double integrator with a velocity limit, the
//! nodal bound alone lets the velocity overshoot inside segments; the peak rows keep it.

mod double_integrator;

use armature_scvx::{Ocp, Ptr, PtrError, PtrResult, PtrSettings, PtrStatus};
use double_integrator::{poor_guess, problem};

/// Velocity limit (m/s): bang–coast–bang, T* = 2·v/a + (1 − v²/a)/v.
const VMAX: f64 = 0.6;

fn limited(nodes: usize, interval: bool) -> Ocp {
    let mut ocp = problem(nodes, |_, _, _| vec![]);
    ocp.x_max[1] = VMAX;
    ocp.x_min[1] = -VMAX;
    if interval {
        ocp.interval_bounds = vec![1];
    }
    ocp
}

fn solve(ocp: Ocp) -> (PtrResult, f64) {
    let nodes = ocp.nodes;
    let dynamics = ocp.dynamics.clone();
    let (x, u, s) = poor_guess(nodes);
    let r = Ptr::new(ocp, PtrSettings::default()).unwrap().solve(&x, &u, &s).unwrap();
    // The largest velocity on a fine single-shooting propagation.
    let (_, dense) = dynamics.propagate(&r.x[..2], &r.u, &r.s, 1e-3).unwrap();
    let vmax = dense.chunks(2).map(|x| x[1].abs()).fold(0.0, f64::max);
    eprintln!(
        "{:?} after {} iterations, T = {:.5} s, largest velocity {vmax:.6}",
        r.status,
        r.history.len(),
        r.final_time
    );
    (r, vmax)
}

#[test]
fn peak_rows_keep_a_velocity_limit_between_the_nodes() {
    let nodes = 6;
    let t_star = 2.0 * VMAX + (1.0 - VMAX * VMAX) / VMAX;
    let (nodal, v_nodal) = solve(limited(nodes, false));
    assert_eq!(nodal.status, PtrStatus::Converged);
    // Nodal bounds alone: the velocity overshoots inside a segment, which buys time.
    assert!(v_nodal > VMAX + 1e-2, "largest velocity {v_nodal}");
    let (peak, v_peak) = solve(limited(nodes, true));
    assert_eq!(peak.status, PtrStatus::Converged);
    // FOH acceleration makes the velocity quadratic in time: the parabola through the grid
    // points is exact, and so is the peak, held to the convergence tolerance `eps_vb`.
    let eps_vb = PtrSettings::default().eps_vb;
    assert!(v_peak <= VMAX + eps_vb, "largest velocity {v_peak}");
    // The limit costs time, and no discretization beats the continuous optimum; the exact
    // curvature brings 6 nodes within 2 % of it.
    assert!(peak.final_time > nodal.final_time + 1e-3);
    assert!(peak.final_time >= t_star - 1e-6, "T = {} < T* = {t_star}", peak.final_time);
    assert!(peak.final_time <= 1.02 * t_star, "T = {} vs T* = {t_star}", peak.final_time);
    // The report names the bound and finds it met.
    let v = peak.violations.iter().find(|v| v.constraint == "bounds of v between nodes").unwrap();
    assert!(v.value <= 1e-6 && v.node.is_some(), "{v:?}");
}

#[test]
fn an_interval_bound_on_a_missing_row_is_an_error() {
    let mut ocp = limited(4, true);
    ocp.interval_bounds = vec![1, 5];
    let e = Ptr::new(ocp, PtrSettings::default()).unwrap_err();
    assert!(matches!(e, PtrError::IntervalBoundRow { row: 5, states: 2 }), "{e}");
}

/// A state whose bounds have a row at every grid point leaves the state bounds' CTCS
/// integral (no integral state is added for it), and its bounds are still checked on the
/// dense trajectory.
#[test]
fn bounds_held_at_every_grid_point_need_no_integral() {
    use armature_scvx::{Control, Problem, Sampling, State, Time};
    let problem = |sampling: Sampling| {
        let p = State::new("p", 1).initial_value(&[0.0]).final_value(&[1.0]);
        let v = State::new("v", 1)
            .bounds(&[-VMAX], &[VMAX])
            .initial_value(&[0.0])
            .final_value(&[0.0])
            .with_interval_bounds();
        let a = Control::new("a", 1).bounds(&[-1.0], &[1.0]);
        Problem {
            dynamics: vec![v.expr(), a.expr()],
            states: vec![p, v],
            controls: vec![a],
            time: Time::Free { min: 0.0, max: 10.0, guess: 3.0, minimize: true },
            interval_bounds_sampling: sampling,
            ..Problem::new(11)
        }
    };
    let n_x = |s: Sampling| {
        problem(s).compile(PtrSettings::default()).unwrap().ptr().ocp().dynamics.n_x()
    };
    assert_eq!(n_x(Sampling::Peak), 3, "p, v and the integral");
    assert_eq!(n_x(Sampling::GridPoints), 2, "p and v only");
    let s = problem(Sampling::GridPoints).compile(PtrSettings::default()).unwrap().solve().unwrap();
    assert_eq!(s.status, PtrStatus::Converged);
    let fastest = s.trajectory["v"].iter().map(|r| r[0].abs()).fold(0.0, f64::max);
    assert!(fastest <= VMAX + 1e-6, "largest velocity {fastest}");
    let dense = s.violations.iter().find(|v| v.constraint == "bounds of v (dense)").unwrap();
    assert!(dense.value <= 1e-6 && dense.time.is_some(), "{dense:?}");
}

/// Polishing ([`PtrSettings::eps_flat`]): after an accepted, nearly feasible step whose
/// predicted decrease is below `eps_flat·max(1, |cost|)` — and that bought no buffer or
/// virtual control (whose prices then double instead) — λ_tr quadruples (up to its cap);
/// the solve ends within `eps_flat` (relative) of where it ends without polishing, having
/// stopped trading defects for gains smaller than that.
#[test]
fn flat_steps_tighten_the_trust_region() {
    let set = PtrSettings::default();
    let (r, _) = solve(limited(6, true));
    assert_eq!(r.status, PtrStatus::Converged);
    let mut flat = 0;
    for w in r.history.windows(2) {
        let (h, next) = (&w[0], &w[1]);
        let nearly_feasible =
            h.max_defect < 1e3 * set.eps_defect && h.max_violation < 1e3 * set.eps_vb;
        // (Bought: some buffer or virtual control above the tolerances; below them in sum,
        // none is.)
        let bought_none = h.j_vb <= set.eps_vb && h.j_vc <= set.eps_defect;
        let small = h.predicted.abs() < set.eps_flat * h.cost.max(1.0);
        if h.accepted && nearly_feasible && small && bought_none {
            flat += 1;
            assert_eq!(next.lam_tr, (4.0 * h.lam_tr).min(set.lam_tr_max), "after {h:?}");
        }
    }
    assert!(flat >= 1, "no flat step in {} iterations", r.history.len());
    let mut off = PtrSettings::default();
    off.eps_flat = 0.0;
    let nodes = 6;
    let (x, u, s) = double_integrator::poor_guess(nodes);
    let r0 = Ptr::new(limited(nodes, true), off).unwrap().solve(&x, &u, &s).unwrap();
    assert_eq!(r0.status, PtrStatus::Converged);
    let gap = (r.final_time - r0.final_time) / r0.final_time;
    assert!(gap.abs() <= set.eps_flat, "{} vs {} without", r.final_time, r0.final_time);
}
