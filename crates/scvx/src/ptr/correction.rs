//! The second-order correction of a step: the subproblem solved once more with its
//! constant terms moved by the nonlinear error its step left.
//!
//! A row linearized at the reference models a nonlinear value `h` (a defect, `−g` of an
//! inequality, `g` of a cone row, `−g` of a peak): `b − A·Δz ≈ h(z̄ + Δz)`, `b = h(z̄)`. After
//! the step `Δz` the error of that model is `e = h(z̄ + Δz) − (b − A·Δz)`, of second order in
//! the step. The corrected subproblem keeps `P`, `q` and `A` and shifts `b` by `e`,
//! `b′ = h(z̄ + Δz) + A·Δz`, so its step `Δz′` satisfies the rows up to the error's change
//! between `Δz` and `Δz′` — of third order when the two are close. A step whose ratio the
//! second-order defects spoil (the Maratos effect: the exact-penalty merit prices them at
//! full price, and the trust region then stays tight although the model is good) is
//! replaced by its corrected one when that one's ratio against the same prediction is
//! better.

use super::*;

/// The buffers of the correction (allocated once).
#[derive(Debug)]
pub(super) struct CorrectionScratch {
    /// The corrected right-hand sides, and (swapped in) the original ones while solving.
    b: Vec<f64>,
    /// `A·Δz` over the primal columns.
    az: Vec<f64>,
    /// The corrected step (swapped with `sol_x` around its solve).
    pub(super) step: Vec<f64>,
    /// The original candidate, restored when the correction loses.
    zc: Vec<f64>,
}

impl Iterate {
    /// The corrected right-hand sides of the last [`Ptr::corrected_rhs`].
    #[cfg(test)]
    pub(super) fn soc_rhs(&self) -> &[f64] {
        &self.soc.b
    }
}

impl Ptr {
    /// The correction's buffers for this problem.
    pub(super) fn correction_scratch(&self) -> CorrectionScratch {
        let rows = self.b.len();
        CorrectionScratch {
            b: vec![0.0; rows],
            az: vec![0.0; rows],
            step: vec![0.0; self.n_vars],
            zc: vec![0.0; self.layout().2],
        }
    }

    /// The corrected right-hand sides `h(z̄ + Δz) + A·Δz` of every row linearized at the
    /// reference into `st.soc.b` (the others keep theirs), from the candidate's defects,
    /// nodal values and peaks as its merit left them in `st.dcand` and `st.ev`. False when a
    /// value is not finite (no correction then).
    pub(super) fn corrected_rhs(&self, st: &mut Iterate, z: &[f64]) -> bool {
        let (n, nn) = (self.ocp.dynamics.n_x(), self.ocp.nodes);
        let vp0 = self.layout().2;
        let sc = &mut st.soc;
        sc.az.fill(0.0);
        for (c, zc) in z.iter().enumerate().take(vp0) {
            for p in self.a_colptr[c]..self.a_colptr[c + 1] {
                sc.az[self.a_rowval[p]] += st.nz[p] * zc;
            }
        }
        sc.b.copy_from_slice(&st.b);
        for (r, d) in st.dcand.defect.iter().enumerate().take((nn - 1) * n) {
            sc.b[r] = d + sc.az[r];
        }
        for nr in &self.nodal_rows {
            let g = st.ev.values[self.g_offsets[nr.eval].0 + nr.output];
            sc.b[nr.row] = if nr.cone { g } else { -g } + sc.az[nr.row];
        }
        for p in &self.peaks {
            // A switched-off row has no coefficients: it stays as linearized.
            if self.row_active(&st.ev, p) {
                sc.b[p.row] = -self.peak(&st.dcand, &st.ev, p).0 + sc.az[p.row];
            }
        }
        sc.b.iter().all(|b| b.is_finite())
    }

    /// The corrected step by a solve of the corrected subproblem into `st.soc.step` (the
    /// subproblem's status in `record` stays the step's).
    fn solve_corrected(&self, st: &mut Iterate, set: &PtrSettings, record: &mut Iteration) -> bool {
        std::mem::swap(&mut st.b, &mut st.soc.b);
        std::mem::swap(&mut st.sol_x, &mut st.soc.step);
        let status = record.subproblem_status;
        let solved = self.solve_subproblem(st, &set.subproblem, record).is_ok();
        record.subproblem_status = status;
        std::mem::swap(&mut st.sol_x, &mut st.soc.step);
        std::mem::swap(&mut st.b, &mut st.soc.b);
        solved
    }

    /// The corrected step as the step's solution moved to the corrected right-hand sides on
    /// the native interior point's last factorization, into `st.soc.step` (false without a
    /// native solution to move).
    fn moved_step(st: &mut Iterate) -> bool {
        let Some(native) = st.native.as_mut() else { return false };
        match native.moved_solution(&st.pvals, &st.b, &st.soc.b) {
            Some(x) => {
                st.soc.step.copy_from_slice(x);
                true
            }
            None => false,
        }
    }

    /// Tries the second-order correction of the step `z` whose candidate (in `st.zc`,
    /// `st.dcand`, `st.ev`) reached the ratio `rho` against `predicted`, its corrected step
    /// computed as [`PtrSettings::correction_solve`] says. When a corrected candidate's ratio
    /// beats `rho` and `least`, it stays in `st.zc`/`st.dcand` (the step in `st.soc.step`)
    /// and its merit values, ratio and `‖Δz′‖²_S` are returned; otherwise the original
    /// candidate is restored.
    pub(super) fn correct(
        &mut self,
        st: &mut Iterate,
        set: &PtrSettings,
        z: &[f64],
        (phibar, predicted, rho, least): (f64, f64, f64, f64),
        record: &mut Iteration,
    ) -> Result<Option<(MeritValues, f64, f64)>, PtrError> {
        if !self.corrected_rhs(st, z) {
            return Ok(None);
        }
        st.soc.zc.copy_from_slice(&st.zc);
        let beats = |r: f64| r > rho && r >= least;
        let mode = set.correction_solve;
        if mode != CorrectionSolve::Resolve {
            if timed(st, record, |st, _| Self::moved_step(st)) {
                let c = self.corrected_candidate(st, set, (phibar, predicted), record)?;
                if beats(c.1) {
                    return Ok(Some(c));
                }
            }
            // The plain step stands, or (no resolve) is rejected without a correction.
            if mode == CorrectionSolve::Factorization || rho >= least {
                self.restore_candidate(st, record)?;
                return Ok(None);
            }
        }
        if timed(st, record, |st, record| self.solve_corrected(st, set, record)) {
            let c = self.corrected_candidate(st, set, (phibar, predicted), record)?;
            if beats(c.1) {
                return Ok(Some(c));
            }
        }
        self.restore_candidate(st, record)?;
        Ok(None)
    }

    /// The candidate of the corrected step in `st.soc.step`, evaluated into `st.zc`,
    /// `st.dcand` and `st.ev`: its merit values, ratio and `‖Δz′‖²_S`.
    fn corrected_candidate(
        &mut self,
        st: &mut Iterate,
        set: &PtrSettings,
        (phibar, predicted): (f64, f64),
        record: &mut Iteration,
    ) -> Result<(MeritValues, f64, f64), PtrError> {
        let vp0 = self.layout().2;
        let step = &st.soc.step;
        for i in 0..vp0 {
            st.zc[i] = st.zbar[i] + step[i];
        }
        let j_tr = (0..vp0).map(|i| step[i] * step[i] * st.inv_s2[i]).sum();
        let prices = (&st.lam_vc[..], &st.lam_vb[..]);
        let (m, ms) = self.evaluate(&st.zc, &mut st.dcand, &mut st.ev, prices)?;
        record.discretization_ms += ms;
        st.timings.discretization_ms += ms;
        let phi = m.0 + merit_shift(set.merit, &st.dcand.defect, &st.duals, &st.lam_vc);
        Ok((m, (phibar - phi) / predicted, j_tr))
    }

    /// The original candidate again, with its evaluation (the caller may still take it).
    fn restore_candidate(
        &mut self,
        st: &mut Iterate,
        record: &mut Iteration,
    ) -> Result<(), PtrError> {
        st.zc.copy_from_slice(&st.soc.zc);
        let prices = (&st.lam_vc[..], &st.lam_vb[..]);
        let (_, ms) = self.evaluate(&st.zc, &mut st.dcand, &mut st.ev, prices)?;
        record.discretization_ms += ms;
        st.timings.discretization_ms += ms;
        Ok(())
    }
}

/// Runs `f` (a way to the corrected step) with its time added to the subproblem's.
fn timed(
    st: &mut Iterate,
    record: &mut Iteration,
    f: impl FnOnce(&mut Iterate, &mut Iteration) -> bool,
) -> bool {
    let t = Instant::now();
    let ok = f(st, record);
    let ms = t.elapsed().as_secs_f64() * 1e3;
    record.subproblem_ms += ms;
    st.timings.subproblem_ms += ms;
    ok
}
