//! The forward dynamics as one node of an expression graph, with its exact Jacobian.

use std::sync::{Arc, Mutex};

use armature_symbolic::{Expr, ExternalFunction};

use super::{DynamicsPartials, DynamicsWorkspace, RigidBodyModel};

/// `q̈ = ABA(q, q̇, τ)` for the graph: inputs `[q; q̇; τ]` (3n), outputs `q̈` (n), Jacobian
/// `[∂q̈/∂q, ∂q̈/∂q̇, M⁻¹]`. Workspaces are pooled so that parallel evaluations (one per
/// discretization lane) neither share nor allocate once warm.
#[derive(Debug)]
struct ForwardDynamicsNode {
    model: RigidBodyModel,
    pool: Mutex<Vec<(DynamicsWorkspace, DynamicsPartials)>>,
}

/// Workspaces kept ready (more are made, and kept, if more threads evaluate at once).
const POOLED: usize = 4;

impl ExternalFunction for ForwardDynamicsNode {
    fn name(&self) -> &str {
        "forward_dynamics"
    }

    fn n_outputs(&self) -> usize {
        self.model.dof()
    }

    fn eval(&self, inputs: &[f64], values: &mut [f64], jacobian: &mut [f64]) {
        let n = self.model.dof();
        let taken = self.pool.lock().map(|mut p| p.pop()).unwrap_or(None);
        let (mut ws, mut d) =
            taken.unwrap_or_else(|| (self.model.workspace(), DynamicsPartials::new(n)));
        let (q, rest) = inputs.split_at(n);
        let (qd, tau) = rest.split_at(n);
        match self.model.aba_derivatives(&mut ws, q, qd, tau, values, &mut d) {
            Ok(()) => {
                for i in 0..n {
                    let row = &mut jacobian[i * 3 * n..(i + 1) * 3 * n];
                    for j in 0..n {
                        row[j] = d.q_partial[(i, j)];
                        row[n + j] = d.qd_partial[(i, j)];
                        row[2 * n + j] = d.u_partial[(i, j)];
                    }
                }
            }
            // Non-finite inputs: the values say so, and the caller's checks name the node.
            Err(_) => {
                values.fill(f64::NAN);
                jacobian.fill(f64::NAN);
            }
        }
        if let Ok(mut p) = self.pool.lock() {
            p.push((ws, d));
        }
    }
}

impl RigidBodyModel {
    /// The forward dynamics `q̈ = M(q)⁻¹·(τ − C(q, q̇)·q̇ − g(q))` as an expression of the
    /// vectors `q`, `q̇` and `τ` (n entries each): one external node evaluated by the ABA,
    /// with the exact Jacobian of [`aba_derivatives`](Self::aba_derivatives).
    ///
    /// # Example
    /// ```
    /// use armature_kinematics::{RigidBodyModel, chain_from_urdf_str};
    /// use armature_symbolic::{Expr, Function};
    /// # let xml = include_str!("../../tests/fixtures/dynamics/prismatic.urdf");
    /// let chain = chain_from_urdf_str(xml, "base", "tool", None).unwrap();
    /// let model = RigidBodyModel::new(&chain, [0.0, 0.0, -9.81]).unwrap();
    /// let (q, qd, tau) = (Expr::variable("q", 3), Expr::variable("qd", 3), Expr::variable("tau", 3));
    /// let qdd = model.forward_dynamics_expr(&q, &qd, &tau);
    /// let f = Function::compile(&[qdd], &[&[q, qd, tau]]).unwrap();
    /// let x = [0.1, 0.05, -0.3, 0.2, 0.0, 0.1, 1.0, 5.0, -0.5];
    /// let (mut ws, mut out) = (f.workspace(), [0.0; 3]);
    /// f.eval(&x, &mut ws, &mut out, None).unwrap();
    /// let (mut dws, mut direct) = (model.workspace(), [0.0; 3]);
    /// model.aba(&mut dws, &x[..3], &x[3..6], &x[6..], &mut direct).unwrap();
    /// assert_eq!(out, direct);
    /// ```
    pub fn forward_dynamics_expr(&self, q: &Expr, qd: &Expr, tau: &Expr) -> Expr {
        let n = self.dof();
        let pool = (0..POOLED).map(|_| (self.workspace(), DynamicsPartials::new(n))).collect();
        let node = ForwardDynamicsNode { model: self.clone(), pool: Mutex::new(pool) };
        Expr::external(Arc::new(node), &[q.clone(), qd.clone(), tau.clone()])
    }
}
