//! A primal–dual interior-point method for the convex subproblems of PTR, built around a
//! *reduced* KKT system whose pattern is computed once.
//!
//! # Problem
//!
//! ```text
//! minimize    ½ xᵀPx + qᵀx
//! subject to  Ax + s = b,   s ∈ K = {0}^{m₀} × ℝ₊^{m₁} × 𝒬^{d₁} × … × 𝒬^{d_k}
//! ```
//!
//! the same data and cone order as Clarabel's (P given by its upper triangle). Rows are
//! equality rows first, then nonnegative rows, then second-order cones
//! 𝒬^d = {(t, u) : ‖u‖ ≤ t}.
//!
//! # Method
//!
//! Mehrotra's predictor–corrector on the nonhomogeneous central path with Nesterov–Todd
//! scaling W (Vandenberghe, *The CVXOPT linear and quadratic cone program solvers*, 2010).
//! Each Newton system is reduced by eliminating the cone rows: with G the cone rows of A,
//!
//! ```text
//! [P + GᵀW⁻²G + δI    A₀ᵀ ] [Δx ]   [r_x]
//! [      A₀          −δI ] [Δy₀] = [r_0]
//! ```
//!
//! which is quasi-definite, so one sparse LDLᵀ factorization (a fill-reducing ordering —
//! QDLDL's approximate minimum degree, or for a multistage problem the cheapest of it and
//! the stage-sweeping orderings of [`InteriorPoint::with_stages`] — and QDLDL's symbolic
//! analysis, computed once, then arithmetic only; see `ipm/ordering.rs`, `ipm/kkt.rs` and
//! `ipm/ldl.rs`) serves the
//! predictor and corrector of an iteration. The corrector's direction (the step taken) is then
//! refined against the full, unreduced Newton system: the reduction amplifies errors in Δx by
//! W⁻² in Δz as the iterates approach the cone boundaries. The predictor's is not: it only
//! sets the centring, through its step to the boundary and the gap there (refining it too
//! cost 5–12 % more subproblem time on the seed arm, for the same first-order PTR iterates).
//! GᵀW⁻²G is accumulated from a list of products fixed by the sparsity pattern (for a cone,
//! from W⁻¹G: W⁻² itself loses its small eigenvalue to cancellation near the boundary), so a
//! solve allocates nothing.
//!
//! A nonnegative row with many entries (more than [`IpmSettings::dense_row`]; PTR's
//! final-time bounds `Σ_k s_k`, over every segment's dilation) is not folded into
//! GᵀW⁻²G: it keeps a row `[a_iᵀ, −s_i/z_i]` of its own (unknown Δz_i), and the orderings
//! eliminate it last, so K and its factor stay linear in the horizon.
//!
//! Rows that a caller switches off between solves (all but at most one of their values
//! zero; declared with [`InteriorPoint::with_switchable_rows`]) only add to K's diagonal, so
//! each solve factors K without their products: the pattern for each set of switched-off rows
//! is analysed once and cached. PTR switches off the peak rows of segments far from their
//! bound; on the seed's collision variant that takes the factor from 202 to 146 thousand
//! multiply-adds. Each solve also compacts A to the entries whose values are nonzero (those
//! rows' zeros, an inactive penalty's): the products with A — residuals, right-hand sides,
//! refinement — skip the rest, while K's assembly keeps the analysed pattern.
//!
//! After a first solve, the next one starts warm (see [`IpmSettings::warm_start_margin`]):
//! consecutive PTR subproblems differ little, and their duals carry over. A warm start that
//! jams (three steps in a row shorter than 1 % of the way to the boundary) restarts cold.
//!
//! Clarabel solves the same problems through its homogeneous embedding and detects
//! infeasibility; this solver does not (PTR's subproblems are feasible by construction: virtual
//! controls and buffers relax every linearized row). It reports [`IpmStatus::MaxIterations`]
//! or [`IpmStatus::NumericalError`] instead, and the caller falls back to Clarabel.

mod kkt;
mod ldl;
mod ordering;
mod scaling;

use crate::sparse::Rows;
use kkt::ReducedKkt;
use scaling::{Scaling, push_inside, push_inside_socs, shift_into_cone, step_length};

mod newton;
mod sensitivity;
mod start;

use newton::*;

/// Largest second-order cone handled (scaling works on fixed-size arrays).
pub const MAX_SOC: usize = 8;

/// Analyses kept for other sets of switched-off rows (see `InteriorPoint::select_kkt`).
const KKT_CACHE: usize = 4;

/// Settings of [`InteriorPoint`], deserializable from data (every field optional).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
#[non_exhaustive]
pub struct IpmSettings {
    /// Feasibility (relative) and complementarity-gap `sᵀz` (absolute, or relative to the
    /// objectives) tolerance. Default 1e-8.
    pub tolerance: f64,
    /// Iteration cap. Default 50.
    pub max_iterations: u32,
    /// Static regularization δ of the reduced KKT matrix. Default 1e-9 (wrong-signed pivots
    /// are still regularized dynamically).
    pub regularization: f64,
    /// Most refinement steps of each corrector direction against the full (unreduced) system;
    /// refinement stops once the direction's residual is below 1e-2 × `tolerance` (relative).
    /// Default 1: without refinement, directions lose accuracy near the cone boundaries;
    /// tolerances below 1e-8 want 2.
    pub refinement_steps: u32,
    /// Warm start: after a first solve, start from x = 0 (the subproblem's deviation form),
    /// the previous duals and s = b, each pushed this far inside its cone (for nonnegative
    /// rows, see [`warm_start_centring`](Self::warm_start_centring)); 0 starts cold every
    /// time. Default 1e-2.
    pub warm_start_margin: f64,
    /// Warm start of a nonnegative row: its complementarity product `s·z` is raised to at
    /// least μ₀ by raising its dual (z ≥ μ₀/s), and the slack of a row the previous solve
    /// held active (dual above the slack, product above μ₀, b ≥ 0) is placed at
    /// `max(b, μ₀/z)` instead of the margin: every row starts near the same point of the
    /// central path, and active rows close to their true slack. Default 3e-3; 0 (or less)
    /// pushes the duals by the margin like the slacks.
    pub warm_start_centring: f64,
    /// A nonnegative row with more entries than this keeps a row and a column of its own in
    /// the reduced KKT matrix (unknown: its Δz) instead of adding its outer product
    /// `(z/s)·aaᵀ`, which would join all its columns into one clique: a free final time's
    /// `Σ_k s_k ≤ t_max` over N segments would make K's entries grow as N² and its ordering
    /// as N³. Default 64.
    pub dense_row: usize,
}

impl Default for IpmSettings {
    fn default() -> Self {
        IpmSettings {
            tolerance: 1e-8,
            max_iterations: 50,
            regularization: 1e-9,
            refinement_steps: 1,
            warm_start_margin: 1e-2,
            warm_start_centring: 3e-3,
            dense_row: 64,
        }
    }
}

/// How a solve ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IpmStatus {
    /// Gap and residuals within tolerance.
    Solved,
    /// Iteration cap reached.
    MaxIterations,
    /// A factorization failed or the iterates stopped being finite.
    NumericalError,
}

/// Cone sizes in row order: equality rows, nonnegative rows, then second-order cones.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Cones {
    /// Number of equality (zero-cone) rows.
    pub zero: usize,
    /// Number of nonnegative rows.
    pub nonneg: usize,
    /// Dimension of each second-order cone.
    pub soc: Vec<usize>,
}

/// Why an [`InteriorPoint`] could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum IpmError {
    /// The pattern's sizes do not agree.
    #[error("inconsistent subproblem pattern: {0}")]
    Pattern(&'static str),
}

/// A reusable interior-point solver for one sparsity pattern. See the [module docs](self).
///
/// # Example
///
/// ```
/// use armature_scvx::ipm::{Cones, InteriorPoint, IpmSettings, IpmStatus};
/// // minimize ½x² − x  subject to  x ≤ 0.5 (one nonnegative row: 0.5 − x ≥ 0)
/// let mut ipm = InteriorPoint::new(
///     1,
///     (&[0, 1], &[0]),
///     1,
///     (&[0, 1], &[0]),
///     Cones { zero: 0, nonneg: 1, soc: vec![] },
///     IpmSettings::default(),
/// )
/// .unwrap();
/// assert_eq!(ipm.solve(&[1.0], &[-1.0], &[1.0], &[0.5]), IpmStatus::Solved);
/// assert!((ipm.x()[0] - 0.5).abs() < 1e-7);
/// assert!((ipm.z()[0] - 0.5).abs() < 1e-6); // the bound's multiplier: 1 − x
/// ```
pub struct InteriorPoint {
    n: usize,
    m: usize,
    cones: Cones,
    settings: IpmSettings,
    /// Divisor of the absolute gap tolerance (see [`InteriorPoint::set_objective_scale`]).
    objective_scale: f64,
    /// This solve's tolerance (see [`InteriorPoint::set_tolerance`]).
    tolerance: f64,
    p_colptr: Vec<usize>,
    p_rowval: Vec<usize>,
    a_colptr: Vec<usize>,
    a_rowval: Vec<usize>,
    rows: Rows,
    /// This solve's nonzero entries of A (values, column pointers, row indices, row view):
    /// the zeros of switched-off rows and of inactive linearized constraints add nothing to
    /// the products with A, which skip them. The KKT assembly keeps A's whole pattern.
    live_a: Vec<f64>,
    live_colptr: Vec<usize>,
    live_rowval: Vec<usize>,
    live_rows: Rows,
    live_fill: Vec<usize>,
    kkt: ReducedKkt,
    /// The rows declared switchable ([`with_switchable_rows`](Self::with_switchable_rows)),
    /// ascending, and for each whether it is off — at most one nonzero value — in the current
    /// solve, and in the solves `kkt` was analysed for.
    switchable: Vec<usize>,
    off: Vec<bool>,
    kkt_off: Vec<bool>,
    /// Analyses for other sets of switched-off rows met so far, least recently used first.
    kkt_cache: Vec<(Vec<bool>, ReducedKkt)>,
    /// The variables' stages given to [`with_stages`](Self::with_stages), for the orderings
    /// of later analyses.
    stages: Option<Vec<Option<usize>>>,
    scaling: Scaling,
    newton: Newton,
    x: Vec<f64>,
    z: Vec<f64>,
    s: Vec<f64>,
    dx: Vec<f64>,
    /// The last solution moved to another right-hand side (`moved_solution`).
    x_moved: Vec<f64>,
    dz: Vec<f64>,
    ds: Vec<f64>,
    rx: Vec<f64>,
    rz: Vec<f64>,
    u: Vec<f64>,
    tmp: Vec<f64>,
    tmp2: Vec<f64>,
    iterations: u32,
    objective: f64,
    has_solution: bool,
}

impl std::fmt::Debug for InteriorPoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("InteriorPoint")
            .field("n", &self.n)
            .field("m", &self.m)
            .field("cones", &self.cones)
            .field("kkt_nonzeros", &self.kkt.nonzeros())
            .finish()
    }
}

impl InteriorPoint {
    /// Analyse a pattern: P (n × n, upper triangle) and A (m × n), each given as its
    /// column-compressed (column pointers, row indices).
    ///
    /// # Errors
    /// [`IpmError::Pattern`] when sizes disagree, an index is out of range, P has an entry
    /// below its diagonal, or a cone has fewer than 2 or more than [`MAX_SOC`] rows.
    pub fn new(
        n: usize,
        (p_colptr, p_rowval): (&[usize], &[usize]),
        m: usize,
        (a_colptr, a_rowval): (&[usize], &[usize]),
        cones: Cones,
        settings: IpmSettings,
    ) -> Result<InteriorPoint, IpmError> {
        let bad = |what| Err(IpmError::Pattern(what));
        if p_colptr.len() != n + 1 || a_colptr.len() != n + 1 {
            return bad("column pointers must have n + 1 entries");
        }
        if p_colptr.last() != Some(&p_rowval.len()) || a_colptr.last() != Some(&a_rowval.len()) {
            return bad("the last column pointer must be the number of entries");
        }
        if p_colptr.windows(2).any(|w| w[0] > w[1]) || a_colptr.windows(2).any(|w| w[0] > w[1]) {
            return bad("column pointers must not decrease");
        }
        if cones.zero + cones.nonneg + cones.soc.iter().sum::<usize>() != m {
            return bad("cone sizes must add up to the rows of A");
        }
        if cones.soc.iter().any(|&d| !(2..=MAX_SOC).contains(&d)) {
            return bad("second-order cones need 2 to 8 rows");
        }
        if a_rowval.iter().any(|&r| r >= m) {
            return bad("row index of A out of range");
        }
        let rows = Rows::new(m, a_colptr, a_rowval);
        let pattern = (p_colptr, p_rowval);
        let kkt = ReducedKkt::analyse(n, pattern, &rows, &cones, settings.dense_row, |_| false)?;
        let cone_rows = m - cones.zero;
        Ok(InteriorPoint {
            n,
            m,
            p_colptr: p_colptr.to_vec(),
            p_rowval: p_rowval.to_vec(),
            a_colptr: a_colptr.to_vec(),
            a_rowval: a_rowval.to_vec(),
            live_a: Vec::with_capacity(a_rowval.len()),
            live_colptr: Vec::with_capacity(n + 1),
            live_rowval: Vec::with_capacity(a_rowval.len()),
            live_rows: rows.clone(),
            live_fill: vec![0; m + 1],
            rows,
            kkt,
            off: Vec::new(),
            kkt_off: Vec::new(),
            kkt_cache: Vec::with_capacity(KKT_CACHE),
            switchable: Vec::new(),
            stages: None,
            scaling: Scaling::new(&cones),
            newton: Newton::new(n, m, cone_rows),
            cones,
            x: vec![0.0; n],
            z: vec![0.0; m],
            s: vec![0.0; m],
            dx: vec![0.0; n],
            x_moved: vec![0.0; n],
            dz: vec![0.0; m],
            ds: vec![0.0; m],
            rx: vec![0.0; n],
            rz: vec![0.0; m],
            u: vec![0.0; cone_rows],
            tmp: vec![0.0; cone_rows],
            tmp2: vec![0.0; cone_rows],
            iterations: 0,
            objective: f64::NAN,
            has_solution: false,
            objective_scale: 1.0,
            tolerance: settings.tolerance,
            settings,
        })
    }

    /// For a multistage problem (a trajectory's nodes): re-orders the KKT factorization for
    /// `stages`, each variable's stage (node) or `None` for a variable that belongs to no
    /// node in particular (a slack, a virtual control). The matrix is then factored in the
    /// ordering that needs the least arithmetic among AMD and two minimum-degree orderings
    /// that sweep the stages from the last (unstaged variables and equality rows take the
    /// least, or the greatest, stage of the staged variables they touch). On the seed arm's
    /// subproblems the factor does 25–31 % less work than in AMD's ordering.
    ///
    /// # Errors
    /// [`IpmError::Pattern`] if `stages` does not have one entry per variable.
    ///
    /// # Example
    ///
    /// ```
    /// use armature_scvx::ipm::{Cones, InteriorPoint, IpmSettings, IpmStatus};
    /// // A chain x₀ → x₁ → x₂ (x_{k+1} = x_k + u_k), x₀ = 1, minimizing ½Σ(x_k² + u_k²):
    /// // variables [x₀, x₁, x₂, u₀, u₁], stages [0, 1, 2, 0, 1].
    /// let p = (&[0, 1, 2, 3, 4, 5][..], &[0, 1, 2, 3, 4][..]);
    /// // Rows: x₀ = 1; x₁ − x₀ − u₀ = 0; x₂ − x₁ − u₁ = 0.
    /// let a = (&[0, 2, 4, 5, 6, 7][..], &[0, 1, 1, 2, 2, 1, 2][..]);
    /// let a_values = [1.0, -1.0, 1.0, -1.0, 1.0, -1.0, -1.0];
    /// let cones = Cones { zero: 3, nonneg: 0, soc: vec![] };
    /// let mut ipm = InteriorPoint::new(5, p, 3, a, cones, IpmSettings::default())
    ///     .and_then(|ipm| ipm.with_stages(&[Some(0), Some(1), Some(2), Some(0), Some(1)]))
    ///     .unwrap();
    /// let status = ipm.solve(&[1.0; 5], &[0.0; 5], &a_values, &[1.0, 0.0, 0.0]);
    /// assert_eq!(status, IpmStatus::Solved);
    /// let x = ipm.x();
    /// assert!((x[0] - 1.0).abs() < 1e-7);
    /// assert!((x[1] - (x[0] + x[3])).abs() < 1e-7 && (x[2] - (x[1] + x[4])).abs() < 1e-7);
    /// ```
    pub fn with_stages(mut self, stages: &[Option<usize>]) -> Result<InteriorPoint, IpmError> {
        if stages.len() != self.n {
            return Err(IpmError::Pattern("stages must have one entry per variable"));
        }
        self.kkt.reorder(stages);
        self.stages = Some(stages.to_vec());
        Ok(self)
    }

    /// Declares nonnegative `rows` (indices into A's rows) that the caller may switch off
    /// between solves by zeroing all but at most one of their values — for PTR, the peak rows
    /// of segments far from their bound, which then keep only their buffer. An off row only
    /// adds to K's diagonal, so each solve factors K without the off rows' products: the
    /// pattern for each set of off rows is analysed once (allocating; the four most recently
    /// left ones are kept, as is the full pattern's) and reused whenever that set recurs.
    ///
    /// # Errors
    /// [`IpmError::Pattern`] if a row is not a nonnegative row.
    pub fn with_switchable_rows(mut self, rows: &[usize]) -> Result<InteriorPoint, IpmError> {
        let nonneg = self.cones.zero..self.cones.zero + self.cones.nonneg;
        if rows.iter().any(|r| !nonneg.contains(r)) {
            return Err(IpmError::Pattern("switchable rows must be nonnegative rows"));
        }
        self.switchable = rows.to_vec();
        self.switchable.sort_unstable();
        self.switchable.dedup();
        self.off = vec![false; self.switchable.len()];
        self.kkt_off = vec![false; self.switchable.len()];
        Ok(self)
    }

    /// The primal solution x of the last solve.
    pub fn x(&self) -> &[f64] {
        &self.x
    }

    /// The dual solution z of the last solve (sign convention Px + q + Aᵀz = 0, as Clarabel).
    pub fn z(&self) -> &[f64] {
        &self.z
    }

    /// The slacks s = b − Ax of the last solve.
    pub fn s(&self) -> &[f64] {
        &self.s
    }

    /// Primal objective ½xᵀPx + qᵀx at the last iterate.
    pub fn objective(&self) -> f64 {
        self.objective
    }

    /// Sets the tolerance of the next solves to `tolerance`, or to
    /// [`IpmSettings::tolerance`] if that is tighter (or `tolerance` is not a finite
    /// number): a caller that needs a rough solution (PTR far from its optimum, where the
    /// step only has to decrease the merit) saves the last few iterations.
    pub fn set_tolerance(&mut self, tolerance: f64) {
        let floor = self.settings.tolerance;
        self.tolerance = if tolerance.is_finite() { tolerance.max(floor) } else { floor };
    }

    /// Declares that the objectives of the next solves are the original one divided by
    /// `scale` (default 1; anything not finite and positive means 1). The absolute gap
    /// tolerance becomes `tolerance / scale`, so a solution is as accurate in the original
    /// objective's units as an unscaled solve would be.
    ///
    /// Dividing a heavy objective (PTR's trust-region weight λ_tr ≥ 1e3) keeps the KKT
    /// system well conditioned, but it divides the linear prices too. With the tolerance
    /// unchanged, a variable priced at `c` in the original units ends at about
    /// `gap · scale / c` instead of 0: on the seed arm, virtual controls of about 2e-6 at
    /// λ_tr ≈ 1e5, which kept PTR from meeting its defect tolerance until λ_tr reached its cap.
    pub fn set_objective_scale(&mut self, scale: f64) {
        self.objective_scale = if scale.is_finite() && scale > 0.0 { scale } else { 1.0 };
    }

    /// Forget the last solution: the next solve starts cold.
    pub fn reset(&mut self) {
        self.has_solution = false;
    }

    /// Iterations of the last solve.
    pub fn iterations(&self) -> u32 {
        self.iterations
    }

    /// Nonzeros of the reduced KKT matrix (upper triangle) and of its LDLᵀ factor L.
    pub fn kkt_nonzeros(&self) -> (usize, usize) {
        self.kkt.nonzeros()
    }

    /// Solve with these values of P (upper triangle), q, A and b, in the pattern given at
    /// construction. Warm-starts from the last solve if it succeeded (and
    /// [`IpmSettings::warm_start_margin`] is positive).
    ///
    /// # Panics
    /// If a slice length differs from the pattern's.
    pub fn solve(&mut self, p: &[f64], q: &[f64], a: &[f64], b: &[f64]) -> IpmStatus {
        assert_eq!(p.len(), self.p_rowval.len(), "P values");
        assert_eq!(q.len(), self.n, "q");
        assert_eq!(a.len(), self.rows.nnz(), "A values");
        assert_eq!(b.len(), self.m, "b");
        let (m0, tol) = (self.cones.zero, self.tolerance);
        self.compact(a);
        self.select_kkt();
        self.kkt.load_a(a);
        self.iterations = 0;
        let mut warm = self.settings.warm_start_margin > 0.0 && self.has_solution;
        self.has_solution = false;
        // Consecutive short steps of a warm start (see below).
        let mut jammed = 0;
        if warm {
            self.start_warm(b);
        } else if !self.start_cold(p, q, a, b) {
            return IpmStatus::NumericalError;
        }
        let degree = (self.cones.nonneg + self.cones.soc.len()).max(1) as f64;
        let (qn, bn) = (inf_norm(q), inf_norm(b));
        loop {
            let res = self.residuals(p, q, b);
            self.objective = res.pobj;
            if !(res.primal.is_finite() && res.dual.is_finite() && res.gap.is_finite()) {
                return IpmStatus::NumericalError;
            }
            let xn = inf_norm(&self.x);
            // Optimal when feasible within the tolerance and the complementarity gap sᵀz is
            // small (CVXOPT's test). Not the objectives' difference: that is sᵀz plus the
            // residuals weighted by x and z, and PTR's duals reach the penalty weights
            // (10³–10⁶), so a primal residual of 1e-9 can hold |pobj − dobj| near 1e-6 while
            // sᵀz goes to zero — a few seed subproblems spent 120–170 iterations there.
            let gap = res.gap;
            if res.primal <= tol * 1f64.max(bn + xn + inf_norm(&self.s))
                && res.dual <= tol * 1f64.max(qn + xn)
                && (gap <= tol / self.objective_scale
                    || gap <= tol * res.pobj.abs().min(res.dobj.abs()))
            {
                self.has_solution = true;
                return IpmStatus::Solved;
            }
            if self.iterations >= self.settings.max_iterations {
                return IpmStatus::MaxIterations;
            }
            self.iterations += 1;
            self.scaling.compute(&self.s[m0..], &self.z[m0..]);
            if !self.kkt.factor(p, a, &self.scaling, &self.cones, self.settings.regularization) {
                return IpmStatus::NumericalError;
            }
            // Predictor: u = λ⁻¹∘(−λ∘λ) = −λ.
            for (u, l) in self.u.iter_mut().zip(&self.scaling.lambda) {
                *u = -l;
            }
            // The affine direction only sets the centring (through its step to the boundary
            // and the gap there): it is not refined.
            self.direction(p, false);
            let alpha_aff = self.step_to_boundary().min(1.0);
            let gap_aff = self.gap_after(alpha_aff);
            // (No cone rows: no gap and no centring.)
            let sigma =
                if res.gap > 0.0 { (gap_aff / res.gap).clamp(0.0, 1.0).powi(3) } else { 0.0 };
            // Corrector: u = λ⁻¹∘(−λ∘λ + σμe − (W⁻¹Δs_a)∘(WΔz_a)).
            self.scaling.apply_winv(&self.ds[m0..], &mut self.tmp);
            self.scaling.apply_w(&self.dz[m0..], &mut self.tmp2);
            let mu = res.gap / degree;
            self.scaling.corrector(sigma * mu, &self.tmp, &self.tmp2, &mut self.u);
            self.direction(p, true);
            let mut alpha = (0.99 * self.step_to_boundary()).min(1.0);
            if self.gap_after(alpha) > res.gap {
                // Mehrotra's second-order term, taken from a poor affine step, can make the
                // combined step raise the gap (and cycle); centre without it instead.
                self.tmp.fill(0.0);
                self.scaling.corrector(sigma * mu, &self.tmp, &self.tmp, &mut self.u);
                self.direction(p, true);
                alpha = (0.99 * self.step_to_boundary()).min(1.0);
                // A long centring step can still raise the gap through its second-order
                // term α²·ΔsᵀΔz, and the iterates then cycle between the cone boundaries
                // (one random problem in about 10⁵ did, forever). Shorten it until the gap
                // does not grow: the first-order decrease α(1 − σ)·gap wins for small α.
                let mut halvings = 0;
                while self.gap_after(alpha) > res.gap && halvings < 30 {
                    alpha *= 0.5;
                    halvings += 1;
                }
            }
            // A warm start far from the new problem's central path can jam: the step to the
            // boundary collapses and the iterates stop moving (2 of 40 000 warm re-solves of
            // slightly moved random problems did, to the iteration cap). After three such
            // steps in a row, start again cold.
            jammed = if warm && alpha < 1e-2 { jammed + 1 } else { 0 };
            if jammed >= 3 {
                warm = false;
                if !self.start_cold(p, q, a, b) {
                    return IpmStatus::NumericalError;
                }
                continue;
            }
            for (x, d) in self.x.iter_mut().zip(&self.dx) {
                *x += alpha * d;
            }
            for r in 0..self.m {
                self.z[r] += alpha * self.dz[r];
                self.s[r] += alpha * self.ds[r];
            }
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn inf_norm(a: &[f64]) -> f64 {
    a.iter().fold(0.0, |m, x| m.max(x.abs()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inconsistent_patterns_are_errors() {
        let one = |cones: Cones, m: usize| {
            InteriorPoint::new(
                1,
                (&[0, 1], &[0]),
                m,
                (&[0, 1], &[0]),
                cones,
                IpmSettings::default(),
            )
        };
        assert!(one(Cones { zero: 0, nonneg: 1, soc: vec![] }, 1).is_ok());
        assert!(one(Cones { zero: 0, nonneg: 2, soc: vec![] }, 1).is_err(), "cone sizes");
        assert!(one(Cones { zero: 0, nonneg: 0, soc: vec![1] }, 1).is_err(), "cone of 1");
        let cones = || Cones { zero: 0, nonneg: 1, soc: vec![] };
        let settings = IpmSettings::default;
        let lower =
            InteriorPoint::new(2, (&[0, 1, 1], &[1]), 1, (&[0, 1, 1], &[0]), cones(), settings());
        assert!(lower.is_err(), "P below its diagonal");
        let short = InteriorPoint::new(1, (&[0, 2], &[0]), 1, (&[0, 1], &[0]), cones(), settings());
        assert!(short.is_err(), "last pointer past the entries");
        let row = InteriorPoint::new(1, (&[0, 1], &[0]), 1, (&[0, 1], &[3]), cones(), settings());
        assert!(row.is_err(), "row out of range");
    }
}
