//! `[robot]`'s dynamics model, checked: the decoupled `q̈ = τ / I` of the seed tutorial or the
//! rigid-body `M(q)q̈ + C(q, q̇)q̇ + g(q) = τ`, and what the plan needs of it (the expression
//! of `q̈`, the torques along the guess).

use armature_kinematics::{Chain, RigidBodyModel, STANDARD_GRAVITY};
use armature_symbolic::Expr;

use crate::task::{DynamicsKind, LocatedError, Source, TaskFile};

/// The robot's dynamics.
#[derive(Debug, Clone)]
pub enum RobotDynamics {
    /// `q̈ = τ / I` with these inertias.
    Decoupled(Vec<f64>),
    /// The rigid-body model (ABA).
    RigidBody(RigidBodyModel),
}

impl RobotDynamics {
    /// `[robot]`'s `dynamics`, `inertia` and `gravity`, checked against the chain.
    ///
    /// # Errors
    /// A missing or wrong-sized `inertia` for the decoupled model; `inertia` given to the
    /// rigid-body model; a robot without mass properties (naming the joint and its link); a
    /// gravity that is not three finite numbers.
    pub fn from_task(
        task: &TaskFile,
        chain: &Chain,
        src: Source<'_>,
    ) -> Result<RobotDynamics, LocatedError> {
        let robot = &task.robot;
        let kind = robot.dynamics.as_ref().map_or(DynamicsKind::DecoupledInertia, |d| *d.get_ref());
        match kind {
            DynamicsKind::DecoupledInertia => {
                if let Some(g) = &robot.gravity {
                    return Err(src.error(g, "gravity applies to dynamics = \"rigid_body\" only"));
                }
                let Some(inertia) = &robot.inertia else {
                    return Err(src.error(
                        &robot.name,
                        "give `inertia = [...]` (one per joint) in [robot], or `dynamics = \"rigid_body\"`",
                    ));
                };
                let (values, n) = (inertia.get_ref(), chain.dof());
                if values.len() != n {
                    return Err(
                        src.error(inertia, format!("{} inertias for {n} joints", values.len()))
                    );
                }
                if let Some(i) = values.iter().position(|v| !(v.is_finite() && *v > 0.0)) {
                    return Err(src.error(
                        inertia,
                        format!("inertia {} of joint {i} must be > 0", values[i]),
                    ));
                }
                Ok(RobotDynamics::Decoupled(values.clone()))
            }
            DynamicsKind::RigidBody => {
                let at = robot.dynamics.as_ref().expect("rigid_body is never the default");
                if robot.inertia.is_some() {
                    return Err(src.error(
                        at,
                        "dynamics = \"rigid_body\" takes the robot's mass properties: remove `inertia` (the decoupled model's)",
                    ));
                }
                let gravity = match &robot.gravity {
                    None => STANDARD_GRAVITY,
                    Some(g) => match g.get_ref().as_slice() {
                        &[x, y, z] if [x, y, z].iter().all(|v| v.is_finite()) => [x, y, z],
                        _ => {
                            return Err(src.error(g, "gravity must be three finite numbers (m/s²)"));
                        }
                    },
                };
                RigidBodyModel::new(chain, gravity)
                    .map(RobotDynamics::RigidBody)
                    .map_err(|e| src.error(at, e.to_string()))
            }
        }
    }

    /// `q̈` as an expression of the angles, velocities and torques.
    pub fn acceleration(&self, q: &Expr, qd: &Expr, tau: &Expr) -> Expr {
        match self {
            RobotDynamics::Decoupled(inertia) => {
                let inv: Vec<f64> = inertia.iter().map(|i| 1.0 / i).collect();
                let _ = (q, qd);
                &Expr::constant_vector(&inv) * tau
            }
            RobotDynamics::RigidBody(model) => model.forward_dynamics_expr(q, qd, tau),
        }
    }

    /// The torques that move the arm through `q`, `q̇`, `q̈` (one row per node).
    pub fn torques(&self, q: &[Vec<f64>], qd: &[Vec<f64>], qdd: &[Vec<f64>]) -> Vec<Vec<f64>> {
        match self {
            RobotDynamics::Decoupled(inertia) => {
                qdd.iter().map(|a| a.iter().zip(inertia).map(|(a, i)| a * i).collect()).collect()
            }
            RobotDynamics::RigidBody(model) => {
                let mut ws = model.workspace();
                let n = model.dof();
                (0..q.len())
                    .map(|k| {
                        let mut tau = vec![0.0; n];
                        // The guess's rows are finite and of the chain's size.
                        match model.rnea(&mut ws, &q[k], &qd[k], &qdd[k], &mut tau) {
                            Ok(()) => tau,
                            Err(_) => vec![0.0; n],
                        }
                    })
                    .collect()
            }
        }
    }
}
