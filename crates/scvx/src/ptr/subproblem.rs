//! Solving the convex subproblem with the native interior point or Clarabel.

use super::*;

/// Clarabel's status as a static name (no allocation per iteration).
pub(super) fn status_name(s: SolverStatus) -> SubproblemStatus {
    match s {
        SolverStatus::Solved => SubproblemStatus::Solved,
        SolverStatus::AlmostSolved => SubproblemStatus::AlmostSolved,
        SolverStatus::PrimalInfeasible => SubproblemStatus::PrimalInfeasible,
        SolverStatus::AlmostPrimalInfeasible => SubproblemStatus::AlmostPrimalInfeasible,
        SolverStatus::DualInfeasible => SubproblemStatus::DualInfeasible,
        SolverStatus::AlmostDualInfeasible => SubproblemStatus::AlmostDualInfeasible,
        SolverStatus::MaxIterations => SubproblemStatus::MaxIterations,
        SolverStatus::MaxTime => SubproblemStatus::MaxTime,
        SolverStatus::NumericalError => SubproblemStatus::NumericalError,
        SolverStatus::InsufficientProgress => SubproblemStatus::InsufficientProgress,
        _ => SubproblemStatus::Other,
    }
}

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
            self.settings.subproblem.interior_point(),
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
    /// (warm-started; retried with the objective scaled when it fails) when chosen, Clarabel
    /// otherwise or when the native solves fail.
    pub(super) fn solve_subproblem(
        &self,
        st: &mut Iterate,
        set: &SubproblemSettings,
        record: &mut Iteration,
    ) -> Result<(), PtrStatus> {
        let nv = self.n_vars;
        if set.solver == SubproblemSolver::InteriorPoint && st.ipm.is_none() && !st.ipm_unusable {
            st.ipm = self.interior_point().ok();
            st.ipm_unusable = st.ipm.is_none();
        }
        if let (SubproblemSolver::InteriorPoint, Some(ipm)) = (set.solver, st.ipm.as_mut()) {
            // The objective as given, unless a solve of this run already needed it scaled:
            // then divided by λ_tr (a safeguard for a KKT matrix a heavy trust-region weight
            // leaves badly scaled). The minimizer is the same; the duals scale back. A
            // failure at a lighter λ_tr goes to Clarabel as it is.
            let sigma = st.lam_tr.max(1.0);
            let mut scaled = st.scale_objective;
            loop {
                let s = if scaled { sigma } else { 1.0 };
                // The same accuracy in the original units: the gap tolerance scales too.
                ipm.set_objective_scale(s);
                let status = if scaled {
                    for (d, v) in st.p_scaled.iter_mut().zip(&st.pvals) {
                        *d = v / s;
                    }
                    for (d, v) in st.q_scaled.iter_mut().zip(&st.q) {
                        *d = v / s;
                    }
                    ipm.solve(&st.p_scaled, &st.q_scaled, &st.nz, &st.b)
                } else {
                    ipm.solve(&st.pvals, &st.q, &st.nz, &st.b)
                };
                record.subproblem_iterations += ipm.iterations();
                if status == IpmStatus::Solved {
                    record.subproblem_status = SubproblemStatus::Solved;
                    st.sol_x.copy_from_slice(ipm.x());
                    for (d, z) in st.sol_z.iter_mut().zip(ipm.z()) {
                        *d = z * s;
                    }
                    st.scale_objective |= scaled;
                    return Ok(());
                }
                if scaled || sigma <= HEAVY_TRUST_REGION {
                    break;
                }
                scaled = true;
                ipm.reset();
            }
        }
        // Clarabel: in-place update when the solver exists (same pattern); rebuild if that
        // fails.
        if let Some(sv) = st.solver.as_mut() {
            let updated = sv.update_P(&st.pvals).is_ok()
                && sv.update_q(&st.q).is_ok()
                && sv.update_A(&st.nz).is_ok()
                && sv.update_b(&st.b).is_ok();
            if !updated {
                st.solver = None;
            }
        }
        if st.solver.is_none() {
            let pm = CscMatrix::new(
                nv,
                nv,
                self.p_colptr.clone(),
                self.p_rowval.clone(),
                st.pvals.clone(),
            );
            let am = CscMatrix::new(
                st.b.len(),
                nv,
                self.a_colptr.clone(),
                self.a_rowval.clone(),
                st.nz.clone(),
            );
            st.solver = DefaultSolver::new(&pm, &st.q, &am, &st.b, &st.cones, set.clarabel()).ok();
        }
        let Some(sv) = st.solver.as_mut() else {
            return Err(PtrStatus::NumericalFailure);
        };
        sv.solve();
        record.subproblem_iterations += sv.solution.iterations;
        record.subproblem_status = status_name(sv.solution.status);
        match sv.solution.status {
            SolverStatus::Solved | SolverStatus::AlmostSolved => {
                st.sol_x.copy_from_slice(&sv.solution.x);
                st.sol_z.copy_from_slice(&sv.solution.z);
                Ok(())
            }
            SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => {
                Err(PtrStatus::SubproblemInfeasible)
            }
            _ => Err(PtrStatus::NumericalFailure),
        }
    }
}
