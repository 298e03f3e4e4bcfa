//! The joint-space mass matrix by the composite rigid-body algorithm, in the base frame.

use nalgebra::DMatrix;

use super::spatial::SpatialInertia;
use super::{DynamicsWorkspace, RigidBodyModel};
use crate::KinematicsError;

impl RigidBodyModel {
    /// The mass matrix `M(q)` (CRBA) into `m` (n × n, symmetric positive definite).
    ///
    /// With the composite inertias `Iᶜᵢ = Σ_{k ≥ i} I_k` (all in the base frame, so they add
    /// without transforms), `M_ij = Sⱼ·(Iᶜᵢ Sᵢ)` for `j ≤ i`.
    ///
    /// # Errors
    /// [`KinematicsError::WrongJointCount`] / [`KinematicsError::NonFiniteJoint`] for a `q`
    /// that does not fit, or an `m` of the wrong size.
    pub fn crba(
        &self,
        ws: &mut DynamicsWorkspace,
        q: &[f64],
        m: &mut DMatrix<f64>,
    ) -> Result<(), KinematicsError> {
        self.check(&[q], &[])?;
        self.check_square(m)?;
        self.kinematics(ws, q);
        self.composite_mass_matrix(ws);
        m.copy_from(&ws.mass);
        Ok(())
    }

    /// `M(q)` into `ws.mass` from the kinematics already in `ws`.
    pub(crate) fn composite_mass_matrix(&self, ws: &mut DynamicsWorkspace) {
        let mut ic = SpatialInertia::ZERO;
        for i in (0..self.dof()).rev() {
            ic.add(&ws.inertia[i]);
            ws.composite[i] = ic;
            let fi = ic.apply(&ws.s[i]);
            for j in 0..=i {
                let mij = ws.s[j].dot(&fi);
                ws.mass[(i, j)] = mij;
                ws.mass[(j, i)] = mij;
            }
        }
    }
}
