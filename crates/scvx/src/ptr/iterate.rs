//! The running solve's state: the reference, its discretization and every buffer an
//! iteration reuses (allocated once, in `Ptr::iterate`).

use super::*;

/// The state of a running solve: the reference, the weights and the subproblem's data and
/// solver (kept between solves of the same [`Ptr`]).
pub(super) struct Iterate {
    pub(super) xb: Vec<f64>,
    pub(super) ub: Vec<f64>,
    pub(super) sb: Vec<f64>,
    pub(super) dbar: Discretization,
    pub(super) dcand: Discretization,
    pub(super) ev: NodalEval,
    pub(super) lam_vc: Vec<f64>,
    pub(super) lam_vb: Vec<f64>,
    pub(super) lam_tr: f64,
    pub(super) jbar: f64,
    pub(super) tf: f64,
    pub(super) history: Vec<Iteration>,
    /// Per element: its Hessian approximation (`d×d`, row-major) and whether it has one.
    pub(super) hess: Vec<Vec<f64>>,
    pub(super) hess_ready: Vec<bool>,
    /// The exact nodal curvature and the blocks the subproblem's `P` holds.
    pub(super) curv: curvature::CurvatureScratch,
    /// The second-order correction's buffers.
    pub(super) soc: correction::CorrectionScratch,
    /// Duals of the last subproblem.
    pub(super) duals: Vec<f64>,
    /// Constraint coefficients at the candidate.
    pub(super) nz_new: Vec<f64>,
    /// Element scratch: step, gradient difference, H·step, damped difference.
    pub(super) qn_s: Vec<f64>,
    pub(super) qn_g: Vec<f64>,
    pub(super) qn_hs: Vec<f64>,
    pub(super) qn_r: Vec<f64>,
    pub(super) status: Option<PtrStatus>,
    pub(super) timings: Timings,
    pub(super) q: Vec<f64>,
    pub(super) zbar: Vec<f64>,
    pub(super) zc: Vec<f64>,
    pub(super) pvals: Vec<f64>,
    pub(super) inv_s2: Vec<f64>,
    pub(super) nz: Vec<f64>,
    pub(super) b: Vec<f64>,
    /// The subproblem's backends, built at their first solve.
    pub(super) native: Option<NativeBackend>,
    /// The native solver could not take this pattern (Clarabel is used throughout).
    pub(super) native_unusable: bool,
    pub(super) clarabel: Option<ClarabelBackend>,

    pub(super) sol_x: Vec<f64>,
    pub(super) sol_z: Vec<f64>,
    /// `nz` and `b` hold the linearization of the current reference (false once it moves):
    /// after a rejected step the next subproblem reuses them.
    pub(super) linearized: bool,
}

impl std::fmt::Debug for Iterate {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Iterate")
            .field("iteration", &self.history.len())
            .field("status", &self.status)
            .field("final_time", &self.tf)
            .field("lam_tr", &self.lam_tr)
            .finish_non_exhaustive()
    }
}

impl Ptr {
    /// Buffers and subproblem data of a solve (allocated once per `Ptr`).
    pub(super) fn iterate(&self) -> Iterate {
        let (n, m, nn) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u(), self.ocp.nodes);
        let pts = self.settings.discretization.substeps + 1;
        let (u0, s0, vp0, _) = self.layout();
        let n_primal = vp0;
        // Trust-region scale per variable: S = max(1, range/2) from its bounds (OpenSCvx's
        // affine scaling), so the region is measured in comparable units.
        let scale_of = |lo: f64, hi: f64| {
            if lo.is_finite() && hi.is_finite() { (0.5 * (hi - lo)).max(1.0) } else { 1.0 }
        };
        let inv_s2: Vec<f64> = (0..n_primal)
            .map(|i| {
                let sc = if i < u0 {
                    scale_of(self.ocp.x_min[i % n], self.ocp.x_max[i % n])
                } else if i < s0 {
                    scale_of(
                        self.ocp.u_min[(i - u0) % m.max(1)],
                        self.ocp.u_max[(i - u0) % m.max(1)],
                    )
                } else {
                    self.ocp.s_scale.unwrap_or_else(|| scale_of(self.ocp.s_min, self.ocp.s_max))
                };
                1.0 / (sc * sc)
            })
            .collect();
        let dmax = self.elements.iter().map(|e| e.cols.len()).max().unwrap_or(0);
        Iterate {
            xb: vec![0.0; nn * n],
            ub: vec![0.0; nn * m],
            sb: vec![0.0; nn],
            dbar: self.output(),
            dcand: self.output(),
            ev: NodalEval {
                lanes: (0..rayon::current_num_threads().max(1))
                    .map(|_| EvalLane {
                        ws: self.ocp.nodal.iter().map(|c| c.function.workspace()).collect(),
                        iws: self
                            .ocp
                            .interval_constraints
                            .iter()
                            .map(|c| c.function.workspace())
                            .collect(),
                        input: vec![0.0; n + m],
                    })
                    .collect(),
                values: vec![0.0; self.g_len.0],
                jac: vec![0.0; self.g_len.1],
                violation: vec![0.0; self.buffers.len() + self.peaks.len()],
                buffer_violation: vec![0.0; self.peak_buffers()],
                peak_vals: vec![0.0; self.peak_src.len()],
                peak_g: vec![0.0; self.peaks.len()],
                fgrid: vec![
                    0.0;
                    self.intervals.iter().map(|m| (m.last - m.first) * pts * m.nout).sum()
                ],
                fjac: vec![
                    0.0;
                    self.intervals.iter().map(|m| (m.last - m.first) * pts * m.nnz).sum()
                ],
                fjac_at: vec![false; self.intervals.iter().map(|m| (m.last - m.first) * pts).sum()],
                stencil_points: Vec::with_capacity(
                    self.intervals.iter().map(|m| (m.last - m.first) * pts).sum(),
                ),
                stencils: vec![(0, [0.0; evaluate::STENCIL]); self.peaks.len()],
                vertices: vec![None; self.peaks.len()],
                fgrid_reference: false,
                segment_peak: vec![0.0; self.intervals.iter().map(|m| m.last - m.first).sum()],
            },
            lam_vc: vec![0.0; n],
            lam_vb: vec![0.0; self.buffers.len() + self.peak_buffers()],
            lam_tr: 0.0,
            jbar: 0.0,
            tf: 0.0,
            history: Vec::new(),
            hess: self.elements.iter().map(|e| vec![0.0; e.cols.len() * e.cols.len()]).collect(),
            hess_ready: vec![false; self.elements.len()],
            curv: self.curvature_scratch(),
            soc: self.correction_scratch(),
            duals: vec![0.0; self.b.len()],
            nz_new: vec![0.0; self.a_rowval.len()],
            qn_s: vec![0.0; dmax],
            qn_g: vec![0.0; dmax],
            qn_hs: vec![0.0; dmax],
            qn_r: vec![0.0; dmax],
            status: None,
            timings: Timings::default(),
            q: vec![0.0; self.n_vars],
            zbar: vec![0.0; n_primal],
            zc: vec![0.0; n_primal],
            pvals: vec![0.0; self.p_rowval.len()],
            inv_s2,
            nz: vec![0.0; self.a_rowval.len()],
            b: self.b.clone(),
            native: None,
            native_unusable: false,
            clarabel: None,
            sol_x: vec![0.0; self.n_vars],
            sol_z: vec![0.0; self.b.len()],
            linearized: false,
        }
    }
}
