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
//! which is quasi-definite, so one sparse LDLᵀ factorization (QDLDL with an approximate
//! minimum-degree ordering, computed once) serves the predictor and corrector of an
//! iteration, with iterative refinement against the unregularized matrix. GᵀW⁻²G is
//! accumulated from a list of products fixed by the sparsity pattern, so an iteration
//! allocates nothing.
//!
//! Clarabel solves the same problems through its homogeneous embedding and detects
//! infeasibility; this solver does not (PTR's subproblems are feasible by construction: virtual
//! controls and buffers relax every linearized row). It reports [`IpmStatus::MaxIterations`]
//! or [`IpmStatus::NumericalError`] instead, and the caller falls back to Clarabel.

use clarabel::algebra::CscMatrix;
use clarabel::qdldl::{QDLDLFactorisation, QDLDLSettings};

/// Largest second-order cone handled (scaling works on fixed-size arrays).
pub const MAX_SOC: usize = 8;

/// Settings of [`InteriorPoint`].
#[derive(Debug, Clone, PartialEq)]
pub struct IpmSettings {
    /// Duality-gap (absolute and relative) and feasibility tolerance. Default 1e-8.
    pub tolerance: f64,
    /// Iteration cap. Default 50.
    pub max_iterations: u32,
    /// Static regularization δ of the reduced KKT matrix. Default 1e-8.
    pub regularization: f64,
    /// Refinement steps of each Newton direction against the full (unreduced) system.
    /// Default 1: without it, directions lose accuracy near the cone boundaries.
    pub refinement_steps: u32,
    /// Warm start: after a first solve, start from x = 0 (the subproblem's deviation form),
    /// the previous duals and s = b, each pushed this far inside its cone; 0 starts cold every
    /// time. Default 1e-2: on the 74 quasi-Newton subproblems of the seed solve, 36 % fewer
    /// iterations than cold starts (1e-3 and 1e-1 do slightly worse).
    pub warm_start_margin: f64,
}

impl Default for IpmSettings {
    fn default() -> Self {
        IpmSettings {
            tolerance: 1e-8,
            max_iterations: 50,
            regularization: 1e-8,
            refinement_steps: 1,
            warm_start_margin: 1e-2,
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

/// A term of GᵀW⁻²G: `kkt[k] += m · a[pa] · a[pb]`, with m the weight of a nonnegative row
/// or one entry of a cone's W⁻².
#[derive(Debug, Clone, Copy)]
struct Term {
    kkt: usize,
    weight: usize,
    pa: usize,
    pb: usize,
}

/// Buffers of one Newton solve: right-hand side b, residual r, correction c, scratch.
#[derive(Debug, Default)]
struct Newton {
    b1: Vec<f64>,
    b2: Vec<f64>,
    b3: Vec<f64>,
    r1: Vec<f64>,
    r2: Vec<f64>,
    r3: Vec<f64>,
    cx: Vec<f64>,
    cz: Vec<f64>,
    cs: Vec<f64>,
    v: Vec<f64>,
    t1: Vec<f64>,
    t2: Vec<f64>,
    t3: Vec<f64>,
}

impl Newton {
    fn new(n: usize, m: usize, mc: usize) -> Newton {
        Newton {
            b1: vec![0.0; n],
            b2: vec![0.0; m],
            b3: vec![0.0; mc],
            r1: vec![0.0; n],
            r2: vec![0.0; m],
            r3: vec![0.0; mc],
            cx: vec![0.0; n],
            cz: vec![0.0; m],
            cs: vec![0.0; m],
            v: vec![0.0; mc],
            t1: vec![0.0; mc],
            t2: vec![0.0; mc],
            t3: vec![0.0; mc],
        }
    }
}

/// A reusable interior-point solver for one sparsity pattern. See the [module docs](self).
pub struct InteriorPoint {
    n: usize,
    m: usize,
    cones: Cones,
    settings: IpmSettings,
    /// KKT values (upper triangle, column-compressed), their positions P → KKT and A₀ → KKT.
    kkt: Vec<f64>,
    kkt_index: Vec<usize>,
    p_map: Vec<usize>,
    eq_map: Vec<(usize, usize)>,
    diag: Vec<usize>,
    terms: Vec<Term>,
    /// Per cone: its columns (prefix offsets into a flat list), for each column and cone row
    /// the nz index of A or `usize::MAX`, and its KKT pairs (kkt index, column a, column b).
    soc_cols: Vec<usize>,
    soc_g: Vec<usize>,
    soc_pair_ptr: Vec<usize>,
    soc_pairs: Vec<(usize, usize, usize)>,
    gt: Vec<f64>,
    p_colptr: Vec<usize>,
    p_rowval: Vec<usize>,
    a_colptr: Vec<usize>,
    a_rowval: Vec<usize>,
    /// Row structure of A: for each row, its (column, nz index) entries.
    row_ptr: Vec<usize>,
    row_entries: Vec<(usize, usize)>,
    ldl: QDLDLFactorisation<f64>,
    /// Per-row weights (nonnegative rows: z/s), then each cone's W, W⁻¹ and W⁻² (dense).
    weights: Vec<f64>,
    soc_off: Vec<usize>,
    w: Vec<f64>,
    winv: Vec<f64>,
    newton: Newton,
    x: Vec<f64>,
    z: Vec<f64>,
    s: Vec<f64>,
    lambda: Vec<f64>,
    dx: Vec<f64>,
    dz: Vec<f64>,
    ds: Vec<f64>,
    rx: Vec<f64>,
    rz: Vec<f64>,
    u: Vec<f64>,
    tmp: Vec<f64>,
    tmp2: Vec<f64>,
    rhs: Vec<f64>,
    sol: Vec<f64>,
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
            .field("kkt_nonzeros", &self.kkt.len())
            .field("l_nonzeros", &self.ldl.nnzL())
            .finish()
    }
}

impl InteriorPoint {
    /// Analyse a pattern: P (n × n, upper triangle) and A (m × n), each given as its
    /// column-compressed (column pointers, row indices).
    ///
    /// # Errors
    /// [`IpmError::Pattern`] when sizes disagree or P has an entry below its diagonal.
    pub fn new(
        n: usize,
        (p_colptr, p_rowval): (&[usize], &[usize]),
        m: usize,
        (a_colptr, a_rowval): (&[usize], &[usize]),
        cones: Cones,
        settings: IpmSettings,
    ) -> Result<InteriorPoint, IpmError> {
        if p_colptr.len() != n + 1 || a_colptr.len() != n + 1 {
            return Err(IpmError::Pattern("column pointers must have n + 1 entries"));
        }
        if cones.zero + cones.nonneg + cones.soc.iter().sum::<usize>() != m {
            return Err(IpmError::Pattern("cone sizes must add up to the rows of A"));
        }
        if cones.soc.iter().any(|&d| !(2..=MAX_SOC).contains(&d)) {
            return Err(IpmError::Pattern("second-order cones need 2 to 8 rows"));
        }
        if a_rowval.iter().any(|&r| r >= m) {
            return Err(IpmError::Pattern("row index of A out of range"));
        }
        let m0 = cones.zero;
        let dim = n + m0;
        // Rows of A (cone part only) as (column, nz index) lists.
        let mut row_ptr = vec![0usize; m + 1];
        for &r in a_rowval {
            row_ptr[r + 1] += 1;
        }
        for r in 0..m {
            row_ptr[r + 1] += row_ptr[r];
        }
        let mut fill = row_ptr.clone();
        let mut row_entries = vec![(0usize, 0usize); a_rowval.len()];
        for c in 0..n {
            for p in a_colptr[c]..a_colptr[c + 1] {
                let r = a_rowval[p];
                row_entries[fill[r]] = (c, p);
                fill[r] += 1;
            }
        }
        // Weight slots: one per nonnegative row, then d² per cone.
        let mut soc_off = Vec::with_capacity(cones.soc.len() + 1);
        let mut off = cones.nonneg;
        for &d in &cones.soc {
            soc_off.push(off);
            off += d * d;
        }
        soc_off.push(off);
        // Upper-triangle KKT entries (row, col) with their sources.
        let mut entries: Vec<(usize, usize)> = (0..dim).map(|c| (c, c)).collect();
        for c in 0..n {
            for &r in &p_rowval[p_colptr[c]..p_colptr[c + 1]] {
                if r > c {
                    return Err(IpmError::Pattern("P must be upper triangular"));
                }
                entries.push((r, c));
            }
            for p in a_colptr[c]..a_colptr[c + 1] {
                if a_rowval[p] < m0 {
                    entries.push((c, n + a_rowval[p]));
                }
            }
        }
        let mut raw_terms: Vec<(usize, usize, usize, usize, usize)> = Vec::new();
        let nonneg_rows = m0..m0 + cones.nonneg;
        for r in nonneg_rows {
            let es = &row_entries[row_ptr[r]..row_ptr[r + 1]];
            for &(ca, pa) in es {
                for &(cb, pb) in es {
                    if ca <= cb && (ca < cb || pa == pb) {
                        raw_terms.push((ca, cb, r - m0, pa, pb));
                    }
                }
            }
        }
        // Cones: GᵀW⁻²G = (W⁻¹G)ᵀ(W⁻¹G) over the columns the cone's rows touch, formed from
        // W⁻¹ (W⁻² itself loses its small eigenvalues to cancellation near the boundary).
        let mut soc_cols = Vec::with_capacity(cones.soc.len() + 1);
        let mut soc_g = Vec::new();
        let mut soc_pair_ptr = vec![0usize];
        let mut soc_pair_cols = Vec::new();
        let mut r0 = m0 + cones.nonneg;
        let mut max_gt = 0;
        soc_cols.push(0);
        for &d in &cones.soc {
            let mut cols: Vec<usize> = (r0..r0 + d)
                .flat_map(|r| row_entries[row_ptr[r]..row_ptr[r + 1]].iter().map(|e| e.0))
                .collect();
            cols.sort_unstable();
            cols.dedup();
            for &c in &cols {
                for i in 0..d {
                    let r = r0 + i;
                    let nz = row_entries[row_ptr[r]..row_ptr[r + 1]]
                        .iter()
                        .find(|e| e.0 == c)
                        .map_or(usize::MAX, |e| e.1);
                    soc_g.push(nz);
                }
            }
            for ja in 0..cols.len() {
                for jb in ja..cols.len() {
                    soc_pair_cols.push((cols[ja], cols[jb], ja, jb));
                }
            }
            soc_pair_ptr.push(soc_pair_cols.len());
            max_gt = max_gt.max(d * cols.len());
            soc_cols.push(soc_cols.last().copied().unwrap_or(0) + cols.len());
            r0 += d;
        }
        entries.extend(soc_pair_cols.iter().map(|t| (t.0, t.1)));
        entries.extend(raw_terms.iter().map(|t| (t.0, t.1)));
        entries.sort_unstable_by_key(|&(r, c)| (c, r));
        entries.dedup();
        let mut kkt_colptr = vec![0usize; dim + 1];
        for &(_, c) in &entries {
            kkt_colptr[c + 1] += 1;
        }
        for c in 0..dim {
            kkt_colptr[c + 1] += kkt_colptr[c];
        }
        let kkt_rowval: Vec<usize> = entries.iter().map(|e| e.0).collect();
        let find = |r: usize, c: usize| {
            let lo = kkt_colptr[c];
            lo + kkt_rowval[lo..kkt_colptr[c + 1]].binary_search(&r).expect("in the pattern")
        };
        let diag: Vec<usize> = (0..dim).map(|c| find(c, c)).collect();
        let mut p_map = Vec::with_capacity(p_rowval.len());
        for c in 0..n {
            for &r in &p_rowval[p_colptr[c]..p_colptr[c + 1]] {
                p_map.push(find(r, c));
            }
        }
        let mut eq_map = Vec::new();
        for c in 0..n {
            for p in a_colptr[c]..a_colptr[c + 1] {
                if a_rowval[p] < m0 {
                    eq_map.push((p, find(c, n + a_rowval[p])));
                }
            }
        }
        let soc_pairs: Vec<(usize, usize, usize)> =
            soc_pair_cols.iter().map(|&(ca, cb, ja, jb)| (find(ca, cb), ja, jb)).collect();
        let terms: Vec<Term> = raw_terms
            .iter()
            .map(|&(ca, cb, weight, pa, pb)| Term { kkt: find(ca, cb), weight, pa, pb })
            .collect();
        let nnz = kkt_rowval.len();
        let mut signs = vec![1i8; dim];
        signs[n..].fill(-1);
        let qs = QDLDLSettings {
            logical: true,
            Dsigns: Some(signs),
            regularize_enable: true,
            regularize_eps: 1e-13,
            regularize_delta: 2e-7,
            ..QDLDLSettings::default()
        };
        let pattern =
            CscMatrix::new(dim, dim, kkt_colptr.clone(), kkt_rowval.clone(), vec![1.0; nnz]);
        let ldl = QDLDLFactorisation::new(&pattern, Some(qs))
            .map_err(|_| IpmError::Pattern("the KKT pattern cannot be factored"))?;
        let cone_rows = m - m0;
        Ok(InteriorPoint {
            n,
            m,
            settings,
            kkt: vec![0.0; nnz],
            kkt_index: (0..nnz).collect(),
            p_map,
            eq_map,
            diag,
            terms,
            soc_cols,
            soc_g,
            soc_pair_ptr,
            soc_pairs,
            gt: vec![0.0; max_gt],
            p_colptr: p_colptr.to_vec(),
            p_rowval: p_rowval.to_vec(),
            a_colptr: a_colptr.to_vec(),
            a_rowval: a_rowval.to_vec(),
            row_ptr,
            row_entries,
            ldl,
            weights: vec![0.0; off],
            w: vec![0.0; off],
            winv: vec![0.0; off],
            soc_off,
            cones,
            newton: Newton::new(n, m, cone_rows),
            x: vec![0.0; n],
            z: vec![0.0; m],
            s: vec![0.0; m],
            lambda: vec![0.0; cone_rows],
            dx: vec![0.0; n],
            dz: vec![0.0; m],
            ds: vec![0.0; m],
            rx: vec![0.0; n],
            rz: vec![0.0; m],
            u: vec![0.0; cone_rows],
            tmp: vec![0.0; cone_rows],
            tmp2: vec![0.0; cone_rows],
            rhs: vec![0.0; dim],
            sol: vec![0.0; dim],
            iterations: 0,
            objective: f64::NAN,
            has_solution: false,
        })
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
        (self.kkt.len(), self.ldl.nnzL())
    }

    /// Solve with these values of P (upper triangle), q, A and b, in the pattern given at
    /// construction.
    ///
    /// # Panics
    /// If a slice length differs from the pattern's.
    pub fn solve(&mut self, p: &[f64], q: &[f64], a: &[f64], b: &[f64]) -> IpmStatus {
        assert_eq!(p.len(), self.p_map.len(), "P values");
        assert_eq!(q.len(), self.n, "q");
        assert_eq!(a.len(), self.row_entries.len(), "A values");
        assert_eq!(b.len(), self.m, "b");
        let (n, m0) = (self.n, self.cones.zero);
        let tol = self.settings.tolerance;
        self.iterations = 0;
        let theta = self.settings.warm_start_margin;
        let warm = theta > 0.0 && self.has_solution;
        self.has_solution = false;
        if warm {
            // Warm start (the subproblems of consecutive PTR iterations differ little): x = 0,
            // the previous duals, s = b, each pushed at least θ inside its cone.
            self.x.fill(0.0);
            self.s[m0..].copy_from_slice(&b[m0..]);
            self.s[..m0].fill(0.0);
            let nn = self.cones.nonneg;
            for r in m0..m0 + nn {
                self.s[r] = self.s[r].max(theta);
                self.z[r] = self.z[r].max(theta);
            }
            let mut r = m0 + nn;
            for &d in &self.cones.soc {
                for v in [&mut self.s, &mut self.z] {
                    let nrm = v[r + 1..r + d].iter().map(|x| x * x).sum::<f64>().sqrt();
                    if v[r] - nrm < theta {
                        v[r] = nrm + theta;
                    }
                }
                r += d;
            }
        } else {
            // Start: W = I, i.e. the least-squares point of the KKT system, then both s and z are
            // shifted into the cone interior.
            self.weights.fill(0.0);
            self.w.fill(0.0);
            self.winv.fill(0.0);
            self.weights[..self.cones.nonneg].fill(1.0);
            for (k, &d) in self.cones.soc.iter().enumerate() {
                let o = self.soc_off[k];
                for i in 0..d {
                    self.weights[o + i * d + i] = 1.0;
                    self.w[o + i * d + i] = 1.0;
                    self.winv[o + i * d + i] = 1.0;
                }
            }
            if !self.factor(p, a) {
                return IpmStatus::NumericalError;
            }
            self.rhs[..n].iter_mut().zip(q).for_each(|(r, qi)| *r = -qi);
            self.rhs[n..].copy_from_slice(&b[..m0]);
            // + Gᵀ b_G
            for r in m0..self.m {
                for &(c, pp) in &self.row_entries[self.row_ptr[r]..self.row_ptr[r + 1]] {
                    self.rhs[c] += a[pp] * b[r];
                }
            }
            self.kkt_solve();
            self.x.copy_from_slice(&self.sol[..n]);
            self.z[..m0].copy_from_slice(&self.sol[n..]);
            // z_G = G x − b_G, s_G = −z_G.
            self.s.fill(0.0);
            for r in m0..self.m {
                let mut g = -b[r];
                for &(c, pp) in &self.row_entries[self.row_ptr[r]..self.row_ptr[r + 1]] {
                    g += a[pp] * self.x[c];
                }
                self.z[r] = g;
                self.s[r] = -g;
            }
            shift_into_cone(&mut self.s[m0..], &self.cones);
            shift_into_cone(&mut self.z[m0..], &self.cones);
        }
        let degree = (self.cones.nonneg + self.cones.soc.len()).max(1) as f64;
        let (qn, bn) = (inf_norm(q), inf_norm(b));
        loop {
            // Residuals r_x = Px + q + Aᵀz and r_z = Ax + s − b.
            self.rx.copy_from_slice(q);
            let mut xpx = 0.0;
            for c in 0..n {
                for k in self.p_colptr[c]..self.p_colptr[c + 1] {
                    let r = self.p_rowval[k];
                    self.rx[r] += p[k] * self.x[c];
                    if r != c {
                        self.rx[c] += p[k] * self.x[r];
                        xpx += 2.0 * p[k] * self.x[r] * self.x[c];
                    } else {
                        xpx += p[k] * self.x[c] * self.x[c];
                    }
                }
            }
            self.rz.iter_mut().zip(b).zip(&self.s).for_each(|((r, bi), si)| *r = si - bi);
            for c in 0..n {
                for k in self.a_colptr[c]..self.a_colptr[c + 1] {
                    let r = self.a_rowval[k];
                    self.rx[c] += a[k] * self.z[r];
                    self.rz[r] += a[k] * self.x[c];
                }
            }
            let gap: f64 = self.s[m0..].iter().zip(&self.z[m0..]).map(|(s, z)| s * z).sum();
            let pobj = 0.5 * xpx + dot(q, &self.x);
            let dobj = -0.5 * xpx - dot(b, &self.z);
            self.objective = pobj;
            let pres = inf_norm(&self.rz);
            let dres = inf_norm(&self.rx);
            let xn = inf_norm(&self.x);
            let scale_p = 1f64.max(bn + xn + inf_norm(&self.s));
            let scale_d = 1f64.max(qn + xn);
            if !(pres.is_finite() && dres.is_finite() && gap.is_finite()) {
                return IpmStatus::NumericalError;
            }
            if pres <= tol * scale_p && dres <= tol * scale_d && {
                let g = (pobj - dobj).abs().max(gap);
                g <= tol || g <= tol * pobj.abs().min(dobj.abs())
            } {
                self.has_solution = true;
                return IpmStatus::Solved;
            }
            if self.iterations >= self.settings.max_iterations {
                return IpmStatus::MaxIterations;
            }
            self.iterations += 1;
            let mu = gap / degree;
            // Scaling and reduced KKT.
            self.scaling();
            if !self.factor(p, a) {
                return IpmStatus::NumericalError;
            }
            // Predictor: u = λ⁻¹∘(−λ∘λ) = −λ.
            for (u, l) in self.u.iter_mut().zip(&self.lambda) {
                *u = -l;
            }
            self.direction(p, a);
            let alpha_aff = self.step_length().min(1.0);
            let mut gap_aff = 0.0;
            for r in m0..self.m {
                gap_aff +=
                    (self.s[r] + alpha_aff * self.ds[r]) * (self.z[r] + alpha_aff * self.dz[r]);
            }
            let sigma = (gap_aff / gap).clamp(0.0, 1.0).powi(3);
            // Corrector: ξ = −λ∘λ + σμe − (W⁻¹Δs_a)∘(WΔz_a); u = λ⁻¹∘ξ.
            self.corrector_rhs(sigma * mu);
            self.direction(p, a);
            let alpha = (0.99 * self.step_length()).min(1.0);
            for (x, d) in self.x.iter_mut().zip(&self.dx) {
                *x += alpha * d;
            }
            for r in 0..self.m {
                self.z[r] += alpha * self.dz[r];
                self.s[r] += alpha * self.ds[r];
            }
        }
    }

    /// Assemble P + GᵀW⁻²G + δI and −δI into the KKT values and factor them.
    fn factor(&mut self, p: &[f64], a: &[f64]) -> bool {
        let delta = self.settings.regularization;
        self.kkt.fill(0.0);
        for (k, &i) in self.p_map.iter().enumerate() {
            self.kkt[i] += p[k];
        }
        for &(pa, i) in &self.eq_map {
            self.kkt[i] += a[pa];
        }
        for t in &self.terms {
            self.kkt[t.kkt] += self.weights[t.weight] * a[t.pa] * a[t.pb];
        }
        for (k, &d) in self.cones.soc.iter().enumerate() {
            let (c0, c1) = (self.soc_cols[k], self.soc_cols[k + 1]);
            let nc = c1 - c0;
            let o = self.soc_off[k];
            // G̃ = W⁻¹G_c, d × nc, column-major.
            for j in 0..nc {
                let g = &self.soc_g[(c0 + j) * d..(c0 + j + 1) * d];
                for kk in 0..d {
                    let mut acc = 0.0;
                    for (i, &nz) in g.iter().enumerate() {
                        if nz != usize::MAX {
                            acc += self.winv[o + kk * d + i] * a[nz];
                        }
                    }
                    self.gt[j * d + kk] = acc;
                }
            }
            for &(idx, ja, jb) in &self.soc_pairs[self.soc_pair_ptr[k]..self.soc_pair_ptr[k + 1]] {
                let (ga, gb) = (&self.gt[ja * d..ja * d + d], &self.gt[jb * d..jb * d + d]);
                self.kkt[idx] += dot(ga, gb);
            }
        }
        for (c, &i) in self.diag.iter().enumerate() {
            self.kkt[i] += if c < self.n { delta } else { -delta };
        }
        self.ldl.update_values(&self.kkt_index, &self.kkt);
        self.ldl.refactor().is_ok() && self.ldl.D.iter().all(|d| d.is_finite())
    }

    /// Solve the reduced KKT system for `rhs` into `sol`. (No refinement at this level: each
    /// Newton direction is refined against the full system instead, which also corrects
    /// the static regularization; refining here as well doubled the solves for the same
    /// iterates.)
    fn kkt_solve(&mut self) {
        self.sol.copy_from_slice(&self.rhs);
        self.ldl.solve(&mut self.sol);
    }

    /// Nesterov–Todd scaling of the current (s, z): W, W⁻¹, W⁻² per cone and λ = Wz.
    fn scaling(&mut self) {
        let m0 = self.cones.zero;
        for i in 0..self.cones.nonneg {
            let (s, z) = (self.s[m0 + i], self.z[m0 + i]);
            self.weights[i] = z / s;
            self.w[i] = (s / z).sqrt();
            self.winv[i] = 1.0 / self.w[i];
            self.lambda[i] = (s * z).sqrt();
        }
        let mut r = m0 + self.cones.nonneg;
        for (k, &d) in self.cones.soc.iter().enumerate() {
            let o = self.soc_off[k];
            let l0 = r - m0;
            nt_scaling(
                &self.s[r..r + d],
                &self.z[r..r + d],
                &mut self.w[o..o + d * d],
                &mut self.winv[o..o + d * d],
                &mut self.weights[o..o + d * d],
                &mut self.lambda[l0..l0 + d],
            );
            r += d;
        }
    }

    /// W⁻²v = W⁻¹(W⁻¹v) (cone part) into `out`.
    fn apply_winv2(&self, v: &[f64], out: &mut [f64], scratch: &mut [f64]) {
        self.apply(&self.winv, v, scratch);
        self.apply(&self.winv, scratch, out);
    }

    /// W·v (cone part) into `out`.
    fn apply(&self, mat: &[f64], v: &[f64], out: &mut [f64]) {
        let nn = self.cones.nonneg;
        for i in 0..nn {
            out[i] = mat[i] * v[i];
        }
        let mut r = nn;
        for (k, &d) in self.cones.soc.iter().enumerate() {
            let o = self.soc_off[k];
            for i in 0..d {
                out[r + i] = (0..d).map(|j| mat[o + i * d + j] * v[r + j]).sum();
            }
            r += d;
        }
    }

    /// Newton direction for the current residuals and the complementarity term u:
    ///
    /// ```text
    /// PΔx + AᵀΔz = −r_x,   AΔx + Δs = −r_z,   WΔz + W⁻¹Δs = u (cone rows; Δs = 0 on equality rows)
    /// ```
    ///
    /// solved through the reduced KKT matrix, then refined against this full system (the
    /// reduction amplifies errors in Δx by W⁻² in Δz as the iterates approach the boundary).
    fn direction(&mut self, p: &[f64], a: &[f64]) {
        let (n, m0, m) = (self.n, self.cones.zero, self.m);
        let mut nw = std::mem::take(&mut self.newton);
        for (r, x) in nw.b1.iter_mut().zip(&self.rx) {
            *r = -x;
        }
        for (r, x) in nw.b2.iter_mut().zip(&self.rz) {
            *r = -x;
        }
        nw.b3.copy_from_slice(&self.u);
        nw.r1.copy_from_slice(&nw.b1);
        nw.r2.copy_from_slice(&nw.b2);
        nw.r3.copy_from_slice(&nw.b3);
        self.reduced_solve(a, &mut nw);
        self.dx.copy_from_slice(&nw.cx);
        self.dz.copy_from_slice(&nw.cz);
        self.ds.copy_from_slice(&nw.cs);
        let bnorm = inf_norm(&nw.b1).max(inf_norm(&nw.b2)).max(inf_norm(&nw.b3));
        for _ in 0..self.settings.refinement_steps {
            // r = b − K(Δx, Δz, Δs)
            nw.r1.copy_from_slice(&nw.b1);
            for c in 0..n {
                for k in self.p_colptr[c]..self.p_colptr[c + 1] {
                    let r = self.p_rowval[k];
                    nw.r1[r] -= p[k] * self.dx[c];
                    if r != c {
                        nw.r1[c] -= p[k] * self.dx[r];
                    }
                }
            }
            for ((r, b), d) in nw.r2.iter_mut().zip(&nw.b2).zip(&self.ds) {
                *r = b - d;
            }
            for c in 0..n {
                for k in self.a_colptr[c]..self.a_colptr[c + 1] {
                    let r = self.a_rowval[k];
                    nw.r1[c] -= a[k] * self.dz[r];
                    nw.r2[r] -= a[k] * self.dx[c];
                }
            }
            self.apply(&self.w, &self.dz[m0..], &mut nw.t1);
            self.apply(&self.winv, &self.ds[m0..], &mut nw.t2);
            for i in 0..m - m0 {
                nw.r3[i] = nw.b3[i] - nw.t1[i] - nw.t2[i];
            }
            let err = inf_norm(&nw.r1).max(inf_norm(&nw.r2)).max(inf_norm(&nw.r3));
            if err <= 1e-13 * (1.0 + bnorm) {
                break;
            }
            self.reduced_solve(a, &mut nw);
            self.dx.iter_mut().zip(&nw.cx).for_each(|(d, c)| *d += c);
            self.dz.iter_mut().zip(&nw.cz).for_each(|(d, c)| *d += c);
            self.ds.iter_mut().zip(&nw.cs).for_each(|(d, c)| *d += c);
        }
        self.newton = nw;
    }

    /// One solve of the Newton system with right-hand side (r1, r2, r3) through the reduced
    /// KKT factorization, into (cx, cz, cs).
    fn reduced_solve(&mut self, a: &[f64], nw: &mut Newton) {
        let (n, m0, m) = (self.n, self.cones.zero, self.m);
        // v = W r3 − r2_G; Δz_G = W⁻²(GΔx + v); Δs_G = r2_G − GΔx.
        self.apply(&self.w, &nw.r3, &mut nw.t1);
        for r in m0..m {
            nw.v[r - m0] = nw.t1[r - m0] - nw.r2[r];
        }
        self.apply_winv2(&nw.v, &mut nw.t2, &mut nw.t3);
        self.rhs[..n].copy_from_slice(&nw.r1);
        for r in m0..m {
            for &(c, pp) in &self.row_entries[self.row_ptr[r]..self.row_ptr[r + 1]] {
                self.rhs[c] -= a[pp] * nw.t2[r - m0];
            }
        }
        self.rhs[n..].copy_from_slice(&nw.r2[..m0]);
        self.kkt_solve();
        nw.cx.copy_from_slice(&self.sol[..n]);
        nw.cz[..m0].copy_from_slice(&self.sol[n..]);
        for r in m0..m {
            let mut g = 0.0;
            for &(c, pp) in &self.row_entries[self.row_ptr[r]..self.row_ptr[r + 1]] {
                g += a[pp] * nw.cx[c];
            }
            nw.cs[r] = nw.r2[r] - g;
            nw.t1[r - m0] = g + nw.v[r - m0];
        }
        self.apply_winv2(&nw.t1, &mut nw.t2, &mut nw.t3);
        nw.cz[m0..].copy_from_slice(&nw.t2);
        nw.cs[..m0].fill(0.0);
    }

    /// Largest α with s + αΔs and z + αΔz in the cone.
    fn step_length(&self) -> f64 {
        let m0 = self.cones.zero;
        let mut alpha = f64::INFINITY;
        let nn = self.cones.nonneg;
        for r in m0..m0 + nn {
            if self.ds[r] < 0.0 {
                alpha = alpha.min(-self.s[r] / self.ds[r]);
            }
            if self.dz[r] < 0.0 {
                alpha = alpha.min(-self.z[r] / self.dz[r]);
            }
        }
        let mut r = m0 + nn;
        for &d in &self.cones.soc {
            alpha = alpha.min(soc_step(&self.s[r..r + d], &self.ds[r..r + d]));
            alpha = alpha.min(soc_step(&self.z[r..r + d], &self.dz[r..r + d]));
            r += d;
        }
        alpha
    }

    /// u = λ⁻¹∘(−λ∘λ + σμe − (W⁻¹Δs)∘(WΔz)) from the predictor's Δs, Δz.
    fn corrector_rhs(&mut self, sigma_mu: f64) {
        let m0 = self.cones.zero;
        let mut a = std::mem::take(&mut self.tmp);
        let mut bb = std::mem::take(&mut self.tmp2);
        self.apply(&self.winv, &self.ds[m0..], &mut a);
        self.apply(&self.w, &self.dz[m0..], &mut bb);
        let nn = self.cones.nonneg;
        for i in 0..nn {
            let xi = -self.lambda[i] * self.lambda[i] + sigma_mu - a[i] * bb[i];
            self.u[i] = xi / self.lambda[i];
        }
        let mut r = nn;
        for &d in &self.cones.soc {
            let l = &self.lambda[r..r + d];
            // ξ = −λ∘λ + σμe − a∘b, with x∘y = (xᵀy, x₀y₁ + y₀x₁).
            let mut xi = [0.0; MAX_SOC];
            let xi = &mut xi[..d];
            xi[0] = -dot(l, l) + sigma_mu - dot(&a[r..r + d], &bb[r..r + d]);
            for j in 1..d {
                xi[j] = -2.0 * l[0] * l[j] - (a[r] * bb[r + j] + bb[r] * a[r + j]);
            }
            soc_inv_prod(l, xi, &mut self.u[r..r + d]);
            r += d;
        }
        self.tmp = a;
        self.tmp2 = bb;
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn inf_norm(a: &[f64]) -> f64 {
    a.iter().fold(0.0, |m, x| m.max(x.abs()))
}

/// Shift a cone vector into the interior: v += (1 + α)e when its smallest "eigenvalue" −α is
/// not positive.
fn shift_into_cone(v: &mut [f64], cones: &Cones) {
    let nn = cones.nonneg;
    let mut alpha = v[..nn].iter().fold(f64::NEG_INFINITY, |m, x| m.max(-x));
    let mut r = nn;
    for &d in &cones.soc {
        alpha = alpha.max(-(v[r] - v[r + 1..r + d].iter().map(|x| x * x).sum::<f64>().sqrt()));
        r += d;
    }
    if alpha >= 0.0 {
        let shift = 1.0 + alpha;
        v[..nn].iter_mut().for_each(|x| *x += shift);
        let mut r = nn;
        for &d in &cones.soc {
            v[r] += shift;
            r += d;
        }
    }
}

/// Largest α ≥ 0 with x + αd in the second-order cone (x in its interior): the smallest
/// positive root of (x₀ + αd₀)² − ‖x₁ + αd₁‖².
fn soc_step(x: &[f64], d: &[f64]) -> f64 {
    let qa = d[0] * d[0] - d[1..].iter().map(|v| v * v).sum::<f64>();
    let qb = x[0] * d[0] - x[1..].iter().zip(&d[1..]).map(|(a, b)| a * b).sum::<f64>();
    let qc = (x[0] * x[0] - x[1..].iter().map(|v| v * v).sum::<f64>()).max(0.0);
    let mut best = f64::INFINITY;
    let disc = qb * qb - qa * qc;
    if qa.abs() < 1e-300 {
        if qb < 0.0 {
            best = -qc / (2.0 * qb);
        }
    } else if disc >= 0.0 {
        let qq = -(qb + qb.signum() * disc.sqrt());
        for root in [qq / qa, if qq != 0.0 { qc / qq } else { f64::INFINITY }] {
            if root > 0.0 {
                best = best.min(root);
            }
        }
    }
    best
}

/// u with λ∘u = ξ in the second-order cone's Jordan algebra.
fn soc_inv_prod(l: &[f64], xi: &[f64], u: &mut [f64]) {
    let d = l.len();
    let l1l1: f64 = l[1..].iter().map(|v| v * v).sum();
    let l1x1: f64 = l[1..].iter().zip(&xi[1..]).map(|(a, b)| a * b).sum();
    let det = l[0] * l[0] - l1l1;
    u[0] = (l[0] * xi[0] - l1x1) / det;
    for j in 1..d {
        u[j] = (xi[j] - u[0] * l[j]) / l[0];
    }
}

/// Nesterov–Todd scaling of one second-order cone: W (= Wᵀ), W⁻¹, W⁻² (dense, row-major)
/// and λ = Wz = W⁻¹s.
fn nt_scaling(
    s: &[f64],
    z: &[f64],
    w: &mut [f64],
    winv: &mut [f64],
    winv2: &mut [f64],
    lambda: &mut [f64],
) {
    let d = s.len();
    let det =
        |v: &[f64]| (v[0] * v[0] - v[1..].iter().map(|x| x * x).sum::<f64>()).max(1e-300).sqrt();
    let (sd, zd) = (det(s), det(z));
    let mut sb = [0.0; MAX_SOC];
    let mut zb = [0.0; MAX_SOC];
    for i in 0..d {
        sb[i] = s[i] / sd;
        zb[i] = z[i] / zd;
    }
    let gamma = ((1.0 + dot(&sb[..d], &zb[..d])) / 2.0).sqrt();
    let mut wb = [0.0; MAX_SOC];
    wb[0] = (sb[0] + zb[0]) / (2.0 * gamma);
    for i in 1..d {
        wb[i] = (sb[i] - zb[i]) / (2.0 * gamma);
    }
    let eta = (sd / zd).sqrt();
    // W̄ = [w₀ w₁ᵀ; w₁ I + w₁w₁ᵀ/(1 + w₀)], W = ηW̄, W⁻¹ = η⁻¹ J W̄ J.
    for i in 0..d {
        for j in 0..d {
            let v = if i == 0 && j == 0 {
                wb[0]
            } else if i == 0 {
                wb[j]
            } else if j == 0 {
                wb[i]
            } else {
                f64::from(u8::from(i == j)) + wb[i] * wb[j] / (1.0 + wb[0])
            };
            w[i * d + j] = eta * v;
            let sign = if (i == 0) != (j == 0) { -1.0 } else { 1.0 };
            winv[i * d + j] = sign * v / eta;
            // W⁻² = η⁻²(2(Jw̄)(Jw̄)ᵀ − J)
            let jwi = if i == 0 { wb[0] } else { -wb[i] };
            let jwj = if j == 0 { wb[0] } else { -wb[j] };
            let jij = if i == j { if i == 0 { 1.0 } else { -1.0 } } else { 0.0 };
            winv2[i * d + j] = (2.0 * jwi * jwj - jij) / (eta * eta);
        }
    }
    for i in 0..d {
        lambda[i] = (0..d).map(|j| w[i * d + j] * z[j]).sum();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A point strictly inside a d-dimensional second-order cone.
    fn interior(d: usize) -> impl Strategy<Value = Vec<f64>> {
        (prop::collection::vec(-1.0..1.0f64, d - 1), 1e-3..2.0f64).prop_map(|(u, margin)| {
            let n = u.iter().map(|x| x * x).sum::<f64>().sqrt();
            std::iter::once(n + margin).chain(u).collect()
        })
    }

    fn mat_vec(m: &[f64], v: &[f64]) -> Vec<f64> {
        let d = v.len();
        (0..d).map(|i| (0..d).map(|j| m[i * d + j] * v[j]).sum()).collect()
    }

    proptest! {
        /// Nesterov–Todd: Wz = W⁻¹s = λ, W·W⁻¹ = I and W⁻² = W⁻¹W⁻¹.
        #[test]
        fn nt_scaling_maps_z_and_s_to_the_same_point(
            (s, z) in (2usize..=5).prop_flat_map(|d| (interior(d), interior(d))),
        ) {
            let d = s.len();
            let (mut w, mut wi, mut wi2, mut l) =
                (vec![0.0; d * d], vec![0.0; d * d], vec![0.0; d * d], vec![0.0; d]);
            nt_scaling(&s, &z, &mut w, &mut wi, &mut wi2, &mut l);
            let wz = mat_vec(&w, &z);
            let wis = mat_vec(&wi, &s);
            for i in 0..d {
                prop_assert!((wz[i] - l[i]).abs() < 1e-9 * (1.0 + l[i].abs()));
                prop_assert!((wis[i] - l[i]).abs() < 1e-9 * (1.0 + l[i].abs()));
                for j in 0..d {
                    let id: f64 = (0..d).map(|k| w[i * d + k] * wi[k * d + j]).sum();
                    prop_assert!((id - f64::from(u8::from(i == j))).abs() < 1e-9);
                    let w2: f64 = (0..d).map(|k| wi[i * d + k] * wi[k * d + j]).sum();
                    prop_assert!((w2 - wi2[i * d + j]).abs() < 1e-7 * (1.0 + w2.abs()));
                }
            }
        }

        /// λ∘u = ξ for the returned u, with x∘y = (xᵀy, x₀y₁ + y₀x₁).
        #[test]
        fn inverse_product_solves_the_jordan_product(
            l in interior(4),
            xi in prop::collection::vec(-2.0..2.0f64, 4),
        ) {
            let mut u = [0.0; 4];
            soc_inv_prod(&l, &xi, &mut u);
            prop_assert!((dot(&l, &u) - xi[0]).abs() < 1e-8 * (1.0 + xi[0].abs()) * l[0] / (l[0] - l[1..].iter().map(|v| v * v).sum::<f64>().sqrt()));
            for j in 1..4 {
                let p = l[0] * u[j] + u[0] * l[j];
                prop_assert!((p - xi[j]).abs() < 1e-6 * (1.0 + u[0].abs() + u[j].abs()));
            }
        }

        /// The step to the cone boundary lands on it, and shorter steps stay inside.
        #[test]
        fn soc_step_stops_at_the_boundary(x in interior(4), d in prop::collection::vec(-3.0..3.0f64, 4)) {
            let a = soc_step(&x, &d);
            let gap = |t: f64| {
                let p: Vec<f64> = x.iter().zip(&d).map(|(x, d)| x + t * d).collect();
                p[0] - p[1..].iter().map(|v| v * v).sum::<f64>().sqrt()
            };
            prop_assert!(gap(0.5 * a.min(1e6)) > 0.0);
            if a.is_finite() {
                prop_assert!(gap(a).abs() < 1e-8 * (1.0 + x[0] + a * d[0].abs()));
            } else {
                prop_assert!(gap(1e6) >= 0.0);
            }
        }
    }

    #[test]
    fn shifting_puts_vectors_inside_each_cone() {
        let cones = Cones { zero: 0, nonneg: 2, soc: vec![3] };
        let mut v = vec![-1.0, 0.5, 0.0, 2.0, 0.0];
        shift_into_cone(&mut v, &cones);
        // The worst "eigenvalue" was −2 (the cone), so every block moved by 3.
        assert_eq!(v, vec![2.0, 3.5, 3.0, 2.0, 0.0]);
        assert!(v[2] > (v[3] * v[3] + v[4] * v[4]).sqrt());
    }

    #[test]
    fn inconsistent_patterns_are_errors() {
        let ok = |cones: Cones, m: usize| {
            InteriorPoint::new(
                1,
                (&[0, 1], &[0]),
                m,
                (&[0, 1], &[0]),
                cones,
                IpmSettings::default(),
            )
        };
        assert!(ok(Cones { zero: 0, nonneg: 1, soc: vec![] }, 1).is_ok());
        assert!(ok(Cones { zero: 0, nonneg: 2, soc: vec![] }, 1).is_err());
        assert!(ok(Cones { zero: 0, nonneg: 0, soc: vec![1] }, 1).is_err());
        let lower = InteriorPoint::new(
            2,
            (&[0, 1, 1], &[1]),
            1,
            (&[0, 1, 1], &[0]),
            Cones { zero: 0, nonneg: 1, soc: vec![] },
            IpmSettings::default(),
        );
        assert!(lower.is_err(), "P below its diagonal");
    }
}
