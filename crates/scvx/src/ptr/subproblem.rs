//! Solving the convex subproblem with the native interior point or Clarabel.

use super::*;

impl Ptr {
    /// The native interior point for this subproblem pattern.
    pub(super) fn interior_point(&self) -> Result<InteriorPoint, crate::ipm::IpmError> {
        let cones = Cones { zero: self.n_zero, nonneg: self.n_nonneg, soc: self.socs.clone() };
        // Each node's states, controls and dilation are its stage; virtual controls and
        // buffers take theirs from the rows they enter (the KKT ordering's hint).
        let (n, m) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u());
        let (u0, s0, vp0, _) = self.layout();
        let stages: Vec<Option<usize>> = (0..self.n_vars)
            .map(|c| match c {
                c if c < u0 => Some(c / n),
                c if c < s0 => Some((c - u0) / m),
                c if c < vp0 => Some(c - s0),
                _ => None,
            })
            .collect();
        InteriorPoint::new(
            self.n_vars,
            (&self.p_colptr, &self.p_rowval),
            self.b.len(),
            (&self.a_colptr, &self.a_rowval),
            cones,
            self.settings.subproblem.interior_point.clone(),
        )?
        .with_stages(&stages)?
        .with_switchable_rows(
            &self
                .peaks
                .iter()
                .filter(|p| {
                    let PeakOf::Function { c, .. } = p.of else { return false };
                    self.intervals[c].activation.is_finite()
                })
                .map(|p| p.row)
                .collect::<Vec<_>>(),
        )
    }

    /// Solve the assembled subproblem into `st.sol_x`/`st.sol_z`: the native interior point
    /// when chosen, Clarabel otherwise or when the native solves fail (see [`backend`]).
    pub(super) fn solve_subproblem(
        &self,
        st: &mut Iterate,
        set: &SubproblemSettings,
        record: &mut Iteration,
    ) -> Result<(), PtrStatus> {
        let tolerance = set.inexact_tolerance(st.history.last());
        let (p, q, a, b, lam_tr) = (&st.pvals, &st.q, &st.nz, &st.b, st.lam_tr);
        let data = ConicData { p, q, a, b, lam_tr, tolerance };
        if set.solver == SubproblemSolver::InteriorPoint {
            if st.native.is_none() && !st.native_unusable {
                let ipm = self.interior_point().ok();
                st.native =
                    ipm.map(|i| NativeBackend::new(i, data.p.len(), self.n_vars, data.b.len()));
                st.native_unusable = st.native.is_none();
            }
            if let Some(native) = st.native.as_mut() {
                let r = native.solve(&data);
                record.subproblem_iterations += r.iterations;
                if r.solved() {
                    record.subproblem_status = r.status;
                    st.sol_x.copy_from_slice(native.x());
                    st.sol_z.copy_from_slice(native.z());
                    return Ok(());
                }
            }
        }
        let clarabel = st.clarabel.get_or_insert_with(|| ClarabelBackend::new(self, &set.clarabel));
        let r = clarabel.solve(&data);
        record.subproblem_iterations += r.iterations;
        record.subproblem_status = r.status;
        match r.status {
            _ if r.solved() => {
                st.sol_x.copy_from_slice(clarabel.x());
                st.sol_z.copy_from_slice(clarabel.z());
                Ok(())
            }
            SubproblemStatus::PrimalInfeasible | SubproblemStatus::AlmostPrimalInfeasible => {
                Err(PtrStatus::SubproblemInfeasible)
            }
            _ => Err(PtrStatus::NumericalFailure),
        }
    }
}
