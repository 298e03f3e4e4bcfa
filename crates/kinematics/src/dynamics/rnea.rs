//! Inverse dynamics by the recursive Newton–Euler algorithm, in the base frame.

use super::spatial::Sv;
use super::{DynamicsWorkspace, RigidBodyModel};
use crate::KinematicsError;

impl RigidBodyModel {
    /// Inverse dynamics `τ = M(q)·q̈ + C(q, q̇)·q̇ + g(q)` (RNEA) into `tau`.
    ///
    /// Forward pass: `vᵢ = vᵢ₋₁ + Sᵢq̇ᵢ`, `aᵢ = aᵢ₋₁ + Sᵢq̈ᵢ + vᵢ × Sᵢq̇ᵢ` from `a₀ = [−g; 0]`,
    /// `fᵢ = Iᵢaᵢ + vᵢ ×* Iᵢvᵢ`; backward: `Fᵢ = fᵢ + Fᵢ₊₁`, `τᵢ = Sᵢ·Fᵢ`.
    ///
    /// # Errors
    /// [`KinematicsError::WrongJointCount`] or [`KinematicsError::NonFiniteJoint`] for inputs
    /// that do not fit the chain.
    pub fn rnea(
        &self,
        ws: &mut DynamicsWorkspace,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        tau: &mut [f64],
    ) -> Result<(), KinematicsError> {
        self.check(&[q, qd, qdd], &[tau.len()])?;
        self.kinematics(ws, q);
        self.rnea_passes(ws, qd, qdd, tau);
        Ok(())
    }

    /// The bias torques `C(q, q̇)·q̇ + g(q)` (RNEA with `q̈ = 0`) into `out`.
    ///
    /// # Errors
    /// As [`rnea`](Self::rnea).
    pub fn nonlinear_effects(
        &self,
        ws: &mut DynamicsWorkspace,
        q: &[f64],
        qd: &[f64],
        out: &mut [f64],
    ) -> Result<(), KinematicsError> {
        self.check(&[q, qd], &[out.len()])?;
        self.kinematics(ws, q);
        ws.scratch.fill(0.0);
        let zeros = std::mem::take(&mut ws.scratch);
        self.rnea_passes(ws, qd, &zeros, out);
        ws.scratch = zeros;
        Ok(())
    }

    /// The two RNEA passes on the kinematics already in `ws`; leaves `vᵢ`, `aᵢ`, the momenta
    /// `hᵢ = Iᵢvᵢ` and the accumulated forces `Fᵢ` in `ws` for the derivatives.
    pub(crate) fn rnea_passes(
        &self,
        ws: &mut DynamicsWorkspace,
        qd: &[f64],
        qdd: &[f64],
        tau: &mut [f64],
    ) {
        let (mut v, mut a) = (Sv::ZERO, self.a0());
        for i in 0..self.dof() {
            let s = ws.s[i];
            let sqd = s.scale(qd[i]);
            v += sqd;
            a += s.scale(qdd[i]) + v.cross_motion(&sqd);
            let inertia = &ws.inertia[i];
            let h = inertia.apply(&v);
            ws.v[i] = v;
            ws.a[i] = a;
            ws.h[i] = h;
            ws.f[i] = inertia.apply(&a) + v.cross_force(&h);
        }
        let mut f = Sv::ZERO;
        for i in (0..self.dof()).rev() {
            f += ws.f[i];
            ws.f[i] = f;
            tau[i] = ws.s[i].dot(&f);
        }
    }
}
