//! The conic backends that solve each subproblem
//! `min ½ zᵀPz + qᵀz  s.t.  Az + s = b, s ∈ K` in the pattern fixed by `Ptr::new`: the native
//! interior point ([`NativeBackend`], warm-started) and Clarabel ([`ClarabelBackend`], the
//! fallback or the chosen solver). A new solver is one more implementation of
//! [`ConicBackend`] and one more [`SubproblemSolver`] variant.

use super::*;

/// The numeric data of one subproblem, in the fixed pattern (`P`'s upper triangle and `A`'s
/// nonzeros in column order; vectors, as Clarabel's in-place updates take them).
pub(super) struct ConicData<'a> {
    pub(super) p: &'a Vec<f64>,
    pub(super) q: &'a Vec<f64>,
    pub(super) a: &'a Vec<f64>,
    pub(super) b: &'a Vec<f64>,
    /// The trust-region weight (the native solver scales a heavy objective by it).
    pub(super) lam_tr: f64,
    /// The accuracy this solve needs (the native solver's tolerance, never tighter than its
    /// own setting; see [`SubproblemSettings::inexact`]). Clarabel keeps its own.
    pub(super) tolerance: f64,
}

/// How one backend solve ended.
#[derive(Debug, Clone, Copy)]
pub(super) struct BackendSolve {
    pub(super) status: SubproblemStatus,
    pub(super) iterations: u32,
}

impl BackendSolve {
    /// Whether its solution may be used.
    pub(super) fn solved(&self) -> bool {
        matches!(self.status, SubproblemStatus::Solved | SubproblemStatus::AlmostSolved)
    }
}

/// A solver of the subproblem in a fixed pattern; after a solved [`solve`](Self::solve),
/// [`x`](Self::x) and [`z`](Self::z) hold its primal solution and the duals of its rows.
pub(super) trait ConicBackend {
    /// Solves with the given values (warm-started where the backend can).
    fn solve(&mut self, data: &ConicData<'_>) -> BackendSolve;
    /// The primal solution of the last solve.
    fn x(&self) -> &[f64];
    /// The duals of the last solve.
    fn z(&self) -> &[f64];
    /// Forgets warm-start information (the next solve starts cold).
    fn reset(&mut self);
}

/// The native interior point, warm-started from the previous subproblem. A solve that does
/// not reach the tolerance at a heavy trust-region weight (λ_tr > 1e3) is retried cold with
/// the objective divided by λ_tr (and its gap tolerance alike), and the rest of the run then
/// solves scaled: the minimizer is the same, the duals scale back.
pub(super) struct NativeBackend {
    pub(super) ipm: InteriorPoint,
    p_scaled: Vec<f64>,
    q_scaled: Vec<f64>,
    z: Vec<f64>,
    /// A solve of this run needed the objective scaled.
    scale_objective: bool,
}

impl NativeBackend {
    pub(super) fn new(ipm: InteriorPoint, p_len: usize, n: usize, rows: usize) -> NativeBackend {
        NativeBackend {
            ipm,
            p_scaled: vec![0.0; p_len],
            q_scaled: vec![0.0; n],
            z: vec![0.0; rows],
            scale_objective: false,
        }
    }

    /// The last solution moved from right-hand side `b` to `b_new` (P, q and A as last
    /// solved; see [`InteriorPoint::moved_solution`]), in the units of the last solve.
    pub(super) fn moved_solution(&mut self, p: &[f64], b: &[f64], b_new: &[f64]) -> Option<&[f64]> {
        let p = if self.scale_objective { &self.p_scaled[..] } else { p };
        self.ipm.moved_solution(p, b, b_new)
    }

    /// A new run: cold, and with the objective as given.
    pub(super) fn restart(&mut self) {
        self.ipm.reset();
        self.scale_objective = false;
    }
}

impl ConicBackend for NativeBackend {
    fn solve(&mut self, d: &ConicData<'_>) -> BackendSolve {
        let sigma = d.lam_tr.max(1.0);
        let mut scaled = self.scale_objective;
        let mut iterations = 0;
        self.ipm.set_tolerance(d.tolerance);
        loop {
            let s = if scaled { sigma } else { 1.0 };
            // The same accuracy in the original units: the gap tolerance scales too.
            self.ipm.set_objective_scale(s);
            let status = if scaled {
                for (o, v) in self.p_scaled.iter_mut().zip(d.p) {
                    *o = v / s;
                }
                for (o, v) in self.q_scaled.iter_mut().zip(d.q) {
                    *o = v / s;
                }
                self.ipm.solve(&self.p_scaled, &self.q_scaled, d.a, d.b)
            } else {
                self.ipm.solve(d.p, d.q, d.a, d.b)
            };
            iterations += self.ipm.iterations();
            if status == IpmStatus::Solved {
                for (o, z) in self.z.iter_mut().zip(self.ipm.z()) {
                    *o = z * s;
                }
                self.scale_objective |= scaled;
                return BackendSolve { status: SubproblemStatus::Solved, iterations };
            }
            if scaled || sigma <= HEAVY_TRUST_REGION {
                let status = match status {
                    IpmStatus::MaxIterations => SubproblemStatus::MaxIterations,
                    _ => SubproblemStatus::NumericalError,
                };
                return BackendSolve { status, iterations };
            }
            scaled = true;
            self.ipm.reset();
        }
    }

    fn x(&self) -> &[f64] {
        self.ipm.x()
    }

    fn z(&self) -> &[f64] {
        &self.z
    }

    fn reset(&mut self) {
        self.ipm.reset();
    }
}

/// Clarabel (cold starts: it has no warm start). The solver is built at its first solve and
/// then updated in place (presolve off keeps the pattern); rebuilt if an update fails.
pub(super) struct ClarabelBackend {
    solver: Option<DefaultSolver<f64>>,
    n: usize,
    p_pattern: (Vec<usize>, Vec<usize>),
    a_pattern: (Vec<usize>, Vec<usize>),
    cones: Vec<SupportedConeT<f64>>,
    settings: DefaultSettings<f64>,
}

impl ClarabelBackend {
    pub(super) fn new(ptr: &Ptr, settings: &ClarabelSettings) -> ClarabelBackend {
        let mut cones: Vec<SupportedConeT<f64>> =
            vec![ZeroConeT(ptr.n_zero), NonnegativeConeT(ptr.n_nonneg)];
        cones.extend(ptr.socs.iter().map(|&d| SecondOrderConeT(d)));
        ClarabelBackend {
            solver: None,
            n: ptr.n_vars,
            p_pattern: (ptr.p_colptr.clone(), ptr.p_rowval.clone()),
            a_pattern: (ptr.a_colptr.clone(), ptr.a_rowval.clone()),
            cones,
            settings: settings.to_clarabel(),
        }
    }

    fn build(&mut self, d: &ConicData<'_>) {
        let (pc, pr) = &self.p_pattern;
        let pm = CscMatrix::new(self.n, self.n, pc.clone(), pr.clone(), d.p.to_vec());
        let (ac, ar) = &self.a_pattern;
        let am = CscMatrix::new(d.b.len(), self.n, ac.clone(), ar.clone(), d.a.to_vec());
        self.solver =
            DefaultSolver::new(&pm, d.q, &am, d.b, &self.cones, self.settings.clone()).ok();
    }
}

impl ConicBackend for ClarabelBackend {
    fn solve(&mut self, d: &ConicData<'_>) -> BackendSolve {
        if let Some(sv) = self.solver.as_mut() {
            let updated = sv.update_P(d.p).is_ok()
                && sv.update_q(d.q).is_ok()
                && sv.update_A(d.a).is_ok()
                && sv.update_b(d.b).is_ok();
            if !updated {
                self.solver = None;
            }
        }
        if self.solver.is_none() {
            self.build(d);
        }
        let Some(sv) = self.solver.as_mut() else {
            return BackendSolve { status: SubproblemStatus::SetupFailed, iterations: 0 };
        };
        sv.solve();
        BackendSolve { status: status_of(sv.solution.status), iterations: sv.solution.iterations }
    }

    fn x(&self) -> &[f64] {
        self.solver.as_ref().map_or(&[], |s| &s.solution.x)
    }

    fn z(&self) -> &[f64] {
        self.solver.as_ref().map_or(&[], |s| &s.solution.z)
    }

    fn reset(&mut self) {}
}

/// Clarabel's status as the typed subproblem status.
fn status_of(s: SolverStatus) -> SubproblemStatus {
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
