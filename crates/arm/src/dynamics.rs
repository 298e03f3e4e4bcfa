//! The task's dynamics model made concrete: the expression of `q̈` for the problem and the
//! torques along the initial guess.

use armature_kinematics::{Chain, RigidBodyModel};
use armature_symbolic::Expr;

use crate::{ArmError, DynamicsModel, TaskItem};

/// A [`DynamicsModel`] checked against its chain.
#[derive(Debug, Clone)]
pub(crate) enum Resolved {
    Decoupled(Vec<f64>),
    RigidBody(RigidBodyModel),
}

impl Resolved {
    /// # Errors
    /// Inertias that do not fit the chain; a chain without mass properties (naming the joint
    /// and its link); a non-finite gravity.
    pub(crate) fn new(model: &DynamicsModel, chain: &Chain) -> Result<Resolved, ArmError> {
        let bad = |m: String| ArmError::new(TaskItem::Dynamics, m);
        match model {
            DynamicsModel::DecoupledInertia(inertia) => {
                let n = chain.dof();
                if inertia.len() != n {
                    return Err(bad(format!("{} inertias for {n} joints", inertia.len())));
                }
                if let Some(i) = inertia.iter().position(|v| !(v.is_finite() && *v > 0.0)) {
                    return Err(bad(format!("inertia {} of joint {i} must be > 0", inertia[i])));
                }
                Ok(Resolved::Decoupled(inertia.clone()))
            }
            DynamicsModel::RigidBody { gravity } => RigidBodyModel::new(chain, *gravity)
                .map(Resolved::RigidBody)
                .map_err(|e| bad(e.to_string())),
        }
    }

    /// `q̈` as an expression of the angles, velocities and torques.
    pub(crate) fn acceleration(&self, q: &Expr, qd: &Expr, tau: &Expr) -> Expr {
        match self {
            Resolved::Decoupled(inertia) => {
                let inv: Vec<f64> = inertia.iter().map(|i| 1.0 / i).collect();
                &Expr::constant_vector(&inv) * tau
            }
            Resolved::RigidBody(model) => model.forward_dynamics_expr(q, qd, tau),
        }
    }

    /// The torques that move the arm through `q`, `q̇`, `q̈` (one row per node).
    pub(crate) fn torques(
        &self,
        q: &[Vec<f64>],
        qd: &[Vec<f64>],
        qdd: &[Vec<f64>],
    ) -> Vec<Vec<f64>> {
        match self {
            Resolved::Decoupled(inertia) => {
                qdd.iter().map(|a| a.iter().zip(inertia).map(|(a, i)| a * i).collect()).collect()
            }
            Resolved::RigidBody(model) => {
                let (mut ws, n) = (model.workspace(), model.dof());
                (0..q.len())
                    .map(|k| {
                        let mut tau = vec![0.0; n];
                        // A guess row that does not fit (never, for a checked task) gives zeros.
                        match model.rnea(&mut ws, &q[k], &qd[k], &qdd[k], &mut tau) {
                            Ok(()) => tau,
                            Err(_) => vec![0.0; n],
                        }
                    })
                    .collect()
            }
        }
    }

    /// The accelerations the torque limits allow each joint alone at `q` (`τ_max / M_jj`).
    pub(crate) fn accelerations_allowed(&self, q: &[f64], torque_limit: &[f64]) -> Vec<f64> {
        let n = torque_limit.len();
        match self {
            Resolved::Decoupled(inertia) => (0..n).map(|j| torque_limit[j] / inertia[j]).collect(),
            Resolved::RigidBody(model) => {
                let (mut ws, mut m) = (model.workspace(), nalgebra::DMatrix::zeros(n, n));
                match model.crba(&mut ws, q, &mut m) {
                    Ok(()) => (0..n).map(|j| torque_limit[j] / m[(j, j)]).collect(),
                    Err(_) => torque_limit.to_vec(),
                }
            }
        }
    }
}
