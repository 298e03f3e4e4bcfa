//! The partitioned damped-BFGS model of the Lagrangian's Hessian.

use super::*;

/// Powell's damped BFGS update of the symmetric positive-definite `h` (`d×d`, row-major)
/// with the step `s` and the gradient difference `y`: `y` is replaced by
/// `r = θy + (1 − θ)Hs` with θ < 1 only when `sᵀy < 0.2·sᵀHs`, so `sᵀr ≥ 0.2·sᵀHs > 0` and
/// `H⁺ = H − HssᵀH/sᵀHs + rrᵀ/sᵀr` stays positive definite and satisfies `H⁺s = r` (the
/// secant equation when undamped). `hs` and `r` are scratch of length `d`. Returns false
/// (and leaves `h`) when `sᵀHs` is zero.
pub(super) fn damped_bfgs(
    h: &mut [f64],
    s: &[f64],
    y: &[f64],
    hs: &mut [f64],
    r: &mut [f64],
) -> bool {
    let d = s.len();
    for a in 0..d {
        hs[a] = (0..d).map(|b| h[a * d + b] * s[b]).sum();
    }
    let shs: f64 = s.iter().zip(hs.iter()).map(|(a, b)| a * b).sum();
    if shs <= 1e-300 {
        return false;
    }
    let sy: f64 = s.iter().zip(y).map(|(a, b)| a * b).sum();
    let theta = if sy >= 0.2 * shs { 1.0 } else { 0.8 * shs / (shs - sy) };
    for a in 0..d {
        r[a] = theta * y[a] + (1.0 - theta) * hs[a];
    }
    let sr: f64 = s.iter().zip(r.iter()).map(|(a, b)| a * b).sum();
    for a in 0..d {
        for b in 0..d {
            h[a * d + b] += r[a] * r[b] / sr - hs[a] * hs[b] / shs;
        }
    }
    true
}

impl Ptr {
    /// A row whose curvature the subproblem has exactly (left out of the BFGS pairs).
    fn exact_row(&self, row: usize) -> bool {
        self.exact.exact_rows.get(row).copied().unwrap_or(false)
    }

    pub(super) fn update_hessian(&self, st: &mut Iterate) {
        // The constraint Jacobians at the candidate (its merit needed their values only).
        let (u0, s0, _, _) = self.layout();
        self.eval_nodal(&st.zc[..u0], &st.zc[u0..s0], &mut st.ev, &st.lam_vb, true);
        self.fill_peaks(&st.dcand, &mut st.ev, GridAt::Other);
        fill_values(&self.sources, &st.dcand, &st.ev, &st.ev.peak_vals, &mut st.nz_new);
        for (e, el) in self.elements.iter().enumerate() {
            let d = el.cols.len();
            if d == 0 {
                continue;
            }
            let (sv, gv) = (&mut st.qn_s[..d], &mut st.qn_g[..d]);
            for (a, &c) in el.cols.iter().enumerate() {
                sv[a] = st.zc[c] - st.zbar[c];
                gv[a] = (self.a_colptr[c]..self.a_colptr[c + 1])
                    .filter(|&p| {
                        self.row_elem[self.a_rowval[p]] == e && !self.exact_row(self.a_rowval[p])
                    })
                    .map(|p| (st.nz_new[p] - st.nz[p]) * st.duals[self.a_rowval[p]])
                    .sum();
            }
            let ss: f64 = sv.iter().zip(&el.cols).map(|(x, &c)| x * x * st.inv_s2[c]).sum();
            let sy: f64 = sv.iter().zip(gv.iter()).map(|(a, b)| a * b).sum();
            if ss < 1e-20 {
                continue;
            }
            let h = &mut st.hess[e];
            if !st.hess_ready[e] {
                // Initial scaled identity γ·S⁻² with γ = ‖ŷ‖²/ŷᵀŝ (Nocedal–Wright 6.20) in the
                // trust-region scaling.
                let yy: f64 = gv.iter().zip(&el.cols).map(|(g, &c)| g * g / st.inv_s2[c]).sum();
                if sy <= 1e-12 * (yy * ss).sqrt() {
                    continue;
                }
                let gamma = QN_INITIAL_SCALE * yy / sy;
                h.fill(0.0);
                for (a, &c) in el.cols.iter().enumerate() {
                    h[a * d + a] = gamma * st.inv_s2[c];
                }
                st.hess_ready[e] = true;
            }
            damped_bfgs(h, sv, gv, &mut st.qn_hs[..d], &mut st.qn_r[..d]);
        }
    }
}
