//! Exact first derivatives of the inverse and forward dynamics.
//!
//! Inverse dynamics, with respect to `qⱼ`: turning joint `j` moves every body from `j` on
//! rigidly about `Sⱼ`, and everything in the base frame is equivariant under that motion, so
//! the change of `τ_k` (`k ≥ j`) is the change of an RNEA whose upstream velocity and
//! acceleration turn the other way, `δv = −Sⱼ × vⱼ₋₁`, `δa = −Sⱼ × aⱼ₋₁`, with the screws and
//! inertias held; the joints before `j` also see the turned force, `δFⱼ + Sⱼ ×* Fⱼ`. With
//! respect to `q̇ⱼ`: `δv_k = Sⱼ`, `δa_j = vⱼ × Sⱼ`, `δa_k = δa_{k−1} + Sⱼ × S_k q̇_k`.
//! Each column is one sweep over the bodies after `j`: O(n²) in all.
//!
//! Forward dynamics: `∂q̈/∂(q, q̇) = −M⁻¹·∂τ/∂(q, q̇)` at `q̈ = ABA(q, q̇, τ)`, and
//! `∂q̈/∂τ = M⁻¹`.

use nalgebra::DMatrix;

use super::spatial::Sv;
use super::{DynamicsWorkspace, RigidBodyModel};
use crate::KinematicsError;

/// The three n × n partial derivatives of a dynamics map `(q, q̇, u) ↦ y`: for the inverse
/// dynamics `u = q̈` and `y = τ` (so `u_partial = M(q)`), for the forward dynamics `u = τ` and
/// `y = q̈` (so `u_partial = M(q)⁻¹`). Made once by [`DynamicsPartials::new`] and refilled.
#[derive(Debug, Clone, PartialEq)]
pub struct DynamicsPartials {
    /// `∂y/∂q`.
    pub q_partial: DMatrix<f64>,
    /// `∂y/∂q̇`.
    pub qd_partial: DMatrix<f64>,
    /// `∂y/∂u`.
    pub u_partial: DMatrix<f64>,
}

impl DynamicsPartials {
    /// Zeros for `n` joints.
    pub fn new(n: usize) -> DynamicsPartials {
        DynamicsPartials {
            q_partial: DMatrix::zeros(n, n),
            qd_partial: DMatrix::zeros(n, n),
            u_partial: DMatrix::zeros(n, n),
        }
    }
}

impl RigidBodyModel {
    /// Inverse dynamics and its exact derivatives: `τ` into `tau`; `∂τ/∂q`, `∂τ/∂q̇` and
    /// `∂τ/∂q̈ = M(q)` into `partials`.
    ///
    /// # Errors
    /// As [`rnea`](Self::rnea), and for partials that are not n × n.
    pub fn rnea_derivatives(
        &self,
        ws: &mut DynamicsWorkspace,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        tau: &mut [f64],
        partials: &mut DynamicsPartials,
    ) -> Result<(), KinematicsError> {
        self.check(&[q, qd, qdd], &[tau.len()])?;
        self.check_partials(partials)?;
        self.kinematics(ws, q);
        self.rnea_passes(ws, qd, qdd, tau);
        self.rnea_sweeps(ws, qd, &mut partials.q_partial, &mut partials.qd_partial);
        self.composite_mass_matrix(ws);
        partials.u_partial.copy_from(&ws.mass);
        Ok(())
    }

    /// Forward dynamics and its exact derivatives: `q̈` into `qdd`; `∂q̈/∂q`, `∂q̈/∂q̇` and
    /// `∂q̈/∂τ = M(q)⁻¹` into `partials`.
    ///
    /// # Errors
    /// As [`aba`](Self::aba), and for partials that are not n × n.
    pub fn aba_derivatives(
        &self,
        ws: &mut DynamicsWorkspace,
        q: &[f64],
        qd: &[f64],
        tau: &[f64],
        qdd: &mut [f64],
        partials: &mut DynamicsPartials,
    ) -> Result<(), KinematicsError> {
        self.check(&[q, qd, tau], &[qdd.len()])?;
        self.check_partials(partials)?;
        self.kinematics(ws, q);
        self.aba_passes(ws, qd, tau, qdd);
        let mut tau_back = std::mem::take(&mut ws.scratch);
        self.rnea_passes(ws, qd, qdd, &mut tau_back);
        ws.scratch = tau_back;
        let DynamicsPartials { q_partial, qd_partial, u_partial } = partials;
        self.rnea_sweeps(ws, qd, q_partial, qd_partial);
        self.composite_mass_matrix(ws);
        ws.factor_mass_matrix();
        u_partial.fill(0.0);
        for j in 0..self.dof() {
            u_partial[(j, j)] = 1.0;
            for m in [&mut *q_partial, &mut *qd_partial, &mut *u_partial] {
                let mut col = m.column_mut(j);
                ws.solve_in_place(col.as_mut_slice());
            }
        }
        q_partial.neg_mut();
        qd_partial.neg_mut();
        Ok(())
    }

    fn check_partials(&self, p: &DynamicsPartials) -> Result<(), KinematicsError> {
        for m in [&p.q_partial, &p.qd_partial, &p.u_partial] {
            self.check_square(m)?;
        }
        Ok(())
    }

    /// The derivative sweeps on an RNEA already run in `ws`.
    fn rnea_sweeps(
        &self,
        ws: &mut DynamicsWorkspace,
        qd: &[f64],
        dtau_dq: &mut DMatrix<f64>,
        dtau_dqd: &mut DMatrix<f64>,
    ) {
        let n = self.dof();
        for j in 0..n {
            let sj = ws.s[j];
            // With respect to q_j.
            let (v_up, a_up) =
                if j == 0 { (Sv::ZERO, self.a0()) } else { (ws.v[j - 1], ws.a[j - 1]) };
            let dv = -sj.cross_motion(&v_up);
            let mut da = -sj.cross_motion(&a_up);
            for k in j..n {
                da += dv.cross_motion(&ws.s[k].scale(qd[k]));
                let inertia = &ws.inertia[k];
                ws.df[k] = inertia.apply(&da)
                    + dv.cross_force(&ws.h[k])
                    + ws.v[k].cross_force(&inertia.apply(&dv));
            }
            let turned = self.accumulate(ws, j, dtau_dq) + sj.cross_force(&ws.f[j]);
            for k in 0..j {
                dtau_dq[(k, j)] = ws.s[k].dot(&turned);
            }
            // With respect to q̇_j.
            let mut da = ws.v[j].cross_motion(&sj);
            for k in j..n {
                if k > j {
                    da += sj.cross_motion(&ws.s[k].scale(qd[k]));
                }
                let inertia = &ws.inertia[k];
                ws.df[k] = inertia.apply(&da)
                    + sj.cross_force(&ws.h[k])
                    + ws.v[k].cross_force(&inertia.apply(&sj));
            }
            let df = self.accumulate(ws, j, dtau_dqd);
            for k in 0..j {
                dtau_dqd[(k, j)] = ws.s[k].dot(&df);
            }
        }
    }

    /// Sums `ws.df[k]` from the tip down to `j`, writing `S_k·δF_k` into column `j` of `out`
    /// for `k ≥ j`; returns `δFⱼ`.
    fn accumulate(&self, ws: &DynamicsWorkspace, j: usize, out: &mut DMatrix<f64>) -> Sv {
        let mut df = Sv::ZERO;
        for k in (j..self.dof()).rev() {
            df += ws.df[k];
            out[(k, j)] = ws.s[k].dot(&df);
        }
        df
    }
}
