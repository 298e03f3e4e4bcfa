//! Forward dynamics by the articulated-body algorithm, in the base frame.

use nalgebra::Vector6;

use super::spatial::Sv;
use super::{DynamicsWorkspace, RigidBodyModel};
use crate::KinematicsError;

impl RigidBodyModel {
    /// Forward dynamics `q̈ = M(q)⁻¹·(τ − C(q, q̇)·q̇ − g(q))` (ABA) into `qdd`, in O(n).
    ///
    /// In the base frame the articulated inertias of a child add to its parent's without
    /// transforms: `IAᵢ₋₁ += IAᵢ − UᵢUᵢᵀ/Dᵢ` with `Uᵢ = IAᵢSᵢ`, `Dᵢ = Sᵢ·Uᵢ`.
    ///
    /// # Errors
    /// As [`rnea`](Self::rnea).
    pub fn aba(
        &self,
        ws: &mut DynamicsWorkspace,
        q: &[f64],
        qd: &[f64],
        tau: &[f64],
        qdd: &mut [f64],
    ) -> Result<(), KinematicsError> {
        self.check(&[q, qd, tau], &[qdd.len()])?;
        self.kinematics(ws, q);
        self.aba_passes(ws, qd, tau, qdd);
        Ok(())
    }

    /// The three ABA passes on the kinematics already in `ws`.
    pub(crate) fn aba_passes(
        &self,
        ws: &mut DynamicsWorkspace,
        qd: &[f64],
        tau: &[f64],
        qdd: &mut [f64],
    ) {
        let n = self.dof();
        let mut v = Sv::ZERO;
        for i in 0..n {
            let sqd = ws.s[i].scale(qd[i]);
            v += sqd;
            let inertia = &ws.inertia[i];
            ws.h[i] = v.cross_motion(&sqd);
            ws.ia[i] = inertia.to_matrix();
            ws.f[i] = v.cross_force(&inertia.apply(&v));
        }
        for i in (0..n).rev() {
            let s: Vector6<f64> = ws.s[i].to_vector();
            let u: Vector6<f64> = ws.ia[i] * s;
            let d = s.dot(&u);
            let ui = tau[i] - ws.s[i].dot(&ws.f[i]);
            ws.u[i] = Sv::from_vector(&u);
            ws.d[i] = d;
            ws.uu[i] = ui;
            if i > 0 {
                let ia = ws.ia[i] - u * (u.transpose() / d);
                let pa = ws.f[i].to_vector() + ia * ws.h[i].to_vector() + u * (ui / d);
                ws.ia[i - 1] += ia;
                ws.f[i - 1] += Sv::from_vector(&pa);
            }
        }
        let mut a = self.a0();
        for i in 0..n {
            a += ws.h[i];
            qdd[i] = (ws.uu[i] - ws.u[i].dot(&a)) / ws.d[i];
            a += ws.s[i].scale(qdd[i]);
        }
    }
}
