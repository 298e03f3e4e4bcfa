//! `[robot]`'s dynamics model as the file gives it: the decoupled `q̈ = τ / I` of the seed
//! tutorial (`inertia`), or rigid-body `M(q)q̈ + C(q, q̇)q̇ + g(q) = τ` (`dynamics =
//! "rigid_body"`, `gravity`). Whether the robot has the mass properties for it is
//! [`armature_arm`]'s check, located at the `dynamics` key.

use armature_arm::DynamicsModel;
use armature_kinematics::STANDARD_GRAVITY;

use crate::task::{DynamicsKind, LocatedError, Source, TaskFile};

/// `[robot]`'s `dynamics`, `inertia` and `gravity`, checked for what the file alone tells.
///
/// # Errors
/// A missing `inertia` for the decoupled model; `inertia` given to the rigid-body model;
/// `gravity` for the decoupled model, or not three finite numbers.
pub fn dynamics_model(task: &TaskFile, src: Source<'_>) -> Result<DynamicsModel, LocatedError> {
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
            Ok(DynamicsModel::DecoupledInertia(inertia.get_ref().clone()))
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
                    _ => return Err(src.error(g, "gravity must be three finite numbers (m/s²)")),
                },
            };
            Ok(DynamicsModel::RigidBody { gravity })
        }
    }
}
