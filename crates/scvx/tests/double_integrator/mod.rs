//! The minimum-time double integrator shared by the tests: 1 m from rest to rest with
//! |a| ≤ 1 m/s² (bang–bang, T* = 2 s), and its poor initial guess.

use armature_scvx::{Dynamics, NodalConstraint, Ocp};
use armature_symbolic::Expr;

/// The problem on `nodes` nodes, with the nodal constraints `nodal(p, v, a)` builds from the
/// states p, v and the control a.
pub(crate) fn problem(
    nodes: usize,
    nodal: impl FnOnce(&Expr, &Expr, &Expr) -> Vec<NodalConstraint>,
) -> Ocp {
    let p = Expr::variable("p", 1);
    let v = Expr::variable("v", 1);
    let a = Expr::variable("a", 1);
    let nodal = nodal(&p, &v, &a);
    let dynamics =
        Dynamics::new(&[p, v.clone()], &[a.clone()], &[v, a], &[true]).expect("valid dynamics");
    Ocp {
        dynamics,
        nodes,
        x_min: vec![-10.0, -10.0],
        x_max: vec![10.0, 10.0],
        u_min: vec![-1.0],
        u_max: vec![1.0],
        x_initial: vec![Some(0.0), Some(0.0)],
        x_final: vec![Some(1.0), Some(0.0)],
        s_min: 0.1,
        s_max: 10.0,
        s_scale: None,
        final_time: (0.0, f64::INFINITY),
        time_weight: 1.0,
        final_cost: vec![],
        increments: vec![],
        nodal,
        interval_bounds: vec![],
        interval_bounds_sampling: armature_scvx::Sampling::Peak,
        interval_constraints: Vec::new(),
    }
}

/// A poor guess `(x, u, s)`: straight line in position, zero velocity and acceleration, 3 s.
pub(crate) fn poor_guess(nodes: usize) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let x = (0..nodes).flat_map(|k| [k as f64 / (nodes - 1) as f64, 0.0]).collect();
    (x, vec![0.0; nodes], vec![3.0; nodes])
}
