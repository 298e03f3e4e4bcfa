//! The reduced KKT matrix of the interior point: its pattern (computed once from P's and
//! A's), the list of products that fill it for a given scaling, and its LDLᵀ factorization.
//!
//! ```text
//! K = [P + GᵀW⁻²G + δI    A₀ᵀ ]      (upper triangle stored, n + m₀ square)
//!     [      A₀          −δI ]
//! ```
//!
//! with A₀ the equality rows of A and G its cone rows. A nonnegative row i adds
//! `(z_i/s_i)·a_iᵀa_i`; a second-order cone adds `(W⁻¹G_c)ᵀ(W⁻¹G_c)` over the columns its
//! rows touch. A *dense* nonnegative row (more than [`IpmSettings::dense_row`](super::IpmSettings::dense_row) entries, such as a
//! free-final-time row `Σ_k s_k ≤ t_max` over every segment's dilation) is not folded in —
//! its product would join all its columns into one clique, so K's entries would grow with the
//! square of the horizon and its ordering with the cube. It keeps a row and a column of its
//! own instead, `[a_i; −s_i/z_i]`, whose unknown is its Δz_i (eliminating it gives back the
//! folded product), and the orderings leave it to the end. K is factored as LDLᵀ ([`Ldl`]: QDLDL's symbolic analysis, done once, in
//! AMD's ordering or, for a multistage problem, the cheapest staged one) with sign-aware
//! dynamic regularization (+ for the primal block, − for the dual block), so K only has to
//! be quasi-definite.

use super::ldl::Ldl;
use super::ordering::staged_orderings;
use super::scaling::Scaling;
use super::{Cones, IpmError, dot};
use crate::sparse::{CscPattern, Rows};

/// A product `kkt[kkt] += weight_i · a[pa] · a[pb]` of a nonnegative row i: its K entry and
/// row here (what every factorization reads, 8 bytes), its A positions in `term_a`.
#[derive(Debug, Clone, Copy)]
struct Term {
    kkt: u32,
    row: u32,
}

/// The LDLᵀ factor's dynamic regularization (ε, δ): a pivot of the wrong sign, or within ε
/// of zero, becomes ±δ.
const LDL_REGULARIZATION: (f64, f64) = (1e-13, 2e-7);

/// The reduced KKT matrix, its fill plan and its factorization. `rhs` in, `sol` out.
pub(super) struct ReducedKkt {
    n: usize,
    values: Vec<f64>,
    p_map: Vec<usize>,
    eq_map: Vec<(usize, usize)>,
    /// The dense nonnegative rows kept in K (numbered from A's first row; their K rows
    /// follow the equality rows, in this order), their entries' (value in A, K entry) and
    /// K's diagonal entry of each.
    dense: Vec<usize>,
    dense_map: Vec<(usize, usize)>,
    dense_diag: Vec<usize>,
    diag: Vec<usize>,
    terms: Vec<Term>,
    /// Per term: its A positions (pa, pb), and `a[pa]·a[pb]` for the A of this solve
    /// ([`load_a`](Self::load_a)): A is fixed while the interior point iterates, only the
    /// weights change, so each factorization reads one product instead of two values of A.
    term_a: Vec<(u32, u32)>,
    term_products: Vec<f64>,
    /// Per cone: its columns (`cone_cols[k]..cone_cols[k + 1]` in a flat list), for each of
    /// those columns and each cone row the value index in A or `usize::MAX`, and the KKT
    /// entries (index, column a, column b) of each column pair.
    cone_cols: Vec<usize>,
    cone_g: Vec<usize>,
    pair_ptr: Vec<usize>,
    pairs: Vec<(usize, usize, usize)>,
    /// W⁻¹G_c of the cone being assembled (d × columns, column-major).
    gt: Vec<f64>,
    /// K's pattern and pivot signs, kept for [`reorder`](Self::reorder).
    pattern: CscPattern,
    signs: Vec<i8>,
    ldl: Ldl,
    pub(super) rhs: Vec<f64>,
    pub(super) sol: Vec<f64>,
    /// Scratch of [`load_rhs`](Self::load_rhs), one entry per row of A.
    masked: Vec<f64>,
}

impl ReducedKkt {
    /// The pattern of K for P's pattern (upper triangle) and A's rows, factored in AMD's
    /// ordering. Nonnegative rows with more than `dense_row` entries keep their own rows. A
    /// nonnegative row `r` (numbered from the first row of A) for which `off(r)`
    /// holds has at most one nonzero value in the solves this analysis serves: it only adds
    /// to K's diagonal, so its products off the diagonal are left out of the pattern.
    pub(super) fn analyse(
        n: usize,
        (p_colptr, p_rowval): (&[usize], &[usize]),
        rows: &Rows,
        cones: &Cones,
        dense_row: usize,
        off: impl Fn(usize) -> bool,
    ) -> Result<ReducedKkt, IpmError> {
        let m0 = cones.zero;
        let dense: Vec<usize> =
            (m0..m0 + cones.nonneg).filter(|&r| !off(r) && rows.row(r).len() > dense_row).collect();
        let dim = n + m0 + dense.len();
        let mut entries: Vec<(usize, usize)> = (0..dim).map(|c| (c, c)).collect();
        for c in 0..n {
            for &r in &p_rowval[p_colptr[c]..p_colptr[c + 1]] {
                if r > c {
                    return Err(IpmError::Pattern("P must be upper triangular"));
                }
                entries.push((r, c));
            }
        }
        for r in 0..m0 {
            entries.extend(rows.row(r).iter().map(|&(c, _)| (c, n + r)));
        }
        for (j, &r) in dense.iter().enumerate() {
            entries.extend(rows.row(r).iter().map(|&(c, _)| (c, n + m0 + j)));
        }
        // Nonnegative rows: every pair of a row's entries.
        let mut raw_terms = Vec::new();
        for r in m0..m0 + cones.nonneg {
            if dense.binary_search(&r).is_ok() {
                continue;
            }
            let diagonal_only = off(r);
            for &(ca, pa) in rows.row(r) {
                for &(cb, pb) in rows.row(r) {
                    if (ca < cb && !diagonal_only) || pa == pb {
                        raw_terms.push((ca, cb, r - m0, pa, pb));
                    }
                }
            }
        }
        // Cones: every pair of the columns their rows touch.
        let (mut cone_cols, mut cone_g, mut pair_ptr) = (vec![0], Vec::new(), vec![0]);
        let (mut pair_cols, mut max_gt) = (Vec::new(), 0);
        let mut r0 = m0 + cones.nonneg;
        for &d in &cones.soc {
            let mut cols: Vec<usize> =
                (r0..r0 + d).flat_map(|r| rows.row(r).iter().map(|e| e.0)).collect();
            cols.sort_unstable();
            cols.dedup();
            for &c in &cols {
                for r in r0..r0 + d {
                    let nz = rows.row(r).iter().find(|e| e.0 == c).map_or(usize::MAX, |e| e.1);
                    cone_g.push(nz);
                }
            }
            for ja in 0..cols.len() {
                for jb in ja..cols.len() {
                    pair_cols.push((cols[ja], cols[jb], ja, jb));
                }
            }
            pair_ptr.push(pair_cols.len());
            max_gt = max_gt.max(d * cols.len());
            cone_cols.push(cone_cols.last().copied().unwrap_or(0) + cols.len());
            r0 += d;
        }
        entries.extend(raw_terms.iter().map(|t| (t.0, t.1)));
        entries.extend(pair_cols.iter().map(|t| (t.0, t.1)));
        let pattern = CscPattern::from_entries(dim, entries);
        let find = |r: usize, c: usize| pattern.position(r, c);
        let diag = (0..dim).map(|c| find(c, c)).collect();
        let mut p_map = Vec::with_capacity(p_rowval.len());
        for c in 0..n {
            p_map.extend(p_rowval[p_colptr[c]..p_colptr[c + 1]].iter().map(|&r| find(r, c)));
        }
        let mut eq_map = Vec::new();
        for r in 0..m0 {
            eq_map.extend(rows.row(r).iter().map(|&(c, p)| (p, find(c, n + r))));
        }
        let mut dense_map = Vec::new();
        for (j, &r) in dense.iter().enumerate() {
            dense_map.extend(rows.row(r).iter().map(|&(c, p)| (p, find(c, n + m0 + j))));
        }
        let dense_diag = (0..dense.len()).map(|j| find(n + m0 + j, n + m0 + j)).collect();
        let narrow = |i: usize| u32::try_from(i).map_err(|_| IpmError::Pattern("K too large"));
        // Kept row by row, as made: sorted by K entry, consecutive terms would update the
        // same entry and wait on each other (measured: the assembly twice as slow).
        let terms = raw_terms
            .iter()
            .map(|&(ca, cb, row, _, _)| Ok(Term { kkt: narrow(find(ca, cb))?, row: narrow(row)? }))
            .collect::<Result<Vec<_>, IpmError>>()?;
        let term_a = raw_terms
            .iter()
            .map(|&(_, _, _, pa, pb)| Ok((narrow(pa)?, narrow(pb)?)))
            .collect::<Result<Vec<_>, IpmError>>()?;
        let pairs = pair_cols.iter().map(|&(ca, cb, ja, jb)| (find(ca, cb), ja, jb)).collect();
        let nnz = pattern.nnz();
        let mut signs = vec![1i8; dim];
        signs[n..].fill(-1);
        let ldl = Ldl::analyse(&pattern.colptr, &pattern.rowval, &signs, LDL_REGULARIZATION)
            .ok_or(IpmError::Pattern("the KKT pattern cannot be factored"))?;
        Ok(ReducedKkt {
            n,
            values: vec![0.0; nnz],
            p_map,
            eq_map,
            dense,
            dense_map,
            dense_diag,
            diag,
            term_products: vec![0.0; terms.len()],
            terms,
            term_a,
            cone_cols,
            cone_g,
            pair_ptr,
            pairs,
            gt: vec![0.0; max_gt],
            pattern,
            signs,
            ldl,
            rhs: vec![0.0; dim],
            sol: vec![0.0; dim],
            masked: vec![0.0; m0 + cones.nonneg + cones.soc.iter().sum::<usize>()],
        })
    }

    /// Re-orders the factorization for a multistage problem whose variables have these
    /// `stages`: the cheapest of the staged orderings ([`staged_orderings`]) replaces AMD's
    /// if it needs less arithmetic.
    pub(super) fn reorder(&mut self, stages: &[Option<usize>]) {
        let (colptr, rowval) = (&self.pattern.colptr, &self.pattern.rowval);
        let last = self.diag.len() - self.dense.len();
        let than = self.ldl.work();
        let candidates = staged_orderings(colptr, rowval, stages, last, than);
        let regularization = LDL_REGULARIZATION;
        if let Some(ldl) =
            Ldl::cheaper(colptr, rowval, &self.signs, regularization, &candidates, than)
        {
            self.ldl = ldl;
        }
    }

    /// Nonzeros of K (upper triangle) and of its factor L.
    pub(super) fn nonzeros(&self) -> (usize, usize) {
        (self.values.len(), self.ldl.nnz_l())
    }

    /// Takes the values of A for the factorizations that follow (the products of its
    /// nonnegative rows' entries).
    pub(super) fn load_a(&mut self, a: &[f64]) {
        for (x, &(pa, pb)) in self.term_products.iter_mut().zip(&self.term_a) {
            *x = a[pa as usize] * a[pb as usize];
        }
    }

    /// Values of P (upper), A and the scaling into K, then its factorization; false if that
    /// fails or is not finite. A must be the one last given to [`load_a`](Self::load_a).
    pub(super) fn factor(
        &mut self,
        p: &[f64],
        a: &[f64],
        scaling: &Scaling,
        cones: &Cones,
        delta: f64,
    ) -> bool {
        let kkt = &mut self.values;
        kkt.fill(0.0);
        for (k, &i) in self.p_map.iter().enumerate() {
            kkt[i] += p[k];
        }
        for &(pa, i) in self.eq_map.iter().chain(&self.dense_map) {
            kkt[i] += a[pa];
        }
        for (&r, &i) in self.dense.iter().zip(&self.dense_diag) {
            kkt[i] -= 1.0 / scaling.weights[r - cones.zero];
        }
        for (t, &product) in self.terms.iter().zip(&self.term_products) {
            kkt[t.kkt as usize] += scaling.weights[t.row as usize] * product;
        }
        for (k, &d) in cones.soc.iter().enumerate() {
            let (c0, c1) = (self.cone_cols[k], self.cone_cols[k + 1]);
            let winv = scaling.winv_block(k);
            for j in 0..c1 - c0 {
                let g = &self.cone_g[(c0 + j) * d..(c0 + j + 1) * d];
                for kk in 0..d {
                    let mut acc = 0.0;
                    for (i, &nz) in g.iter().enumerate() {
                        if nz != usize::MAX {
                            acc += winv[kk * d + i] * a[nz];
                        }
                    }
                    self.gt[j * d + kk] = acc;
                }
            }
            for &(idx, ja, jb) in &self.pairs[self.pair_ptr[k]..self.pair_ptr[k + 1]] {
                kkt[idx] += dot(&self.gt[ja * d..ja * d + d], &self.gt[jb * d..jb * d + d]);
            }
        }
        // The static regularization: not on the dense rows, whose diagonal −s_i/z_i < 0
        // already makes K quasi-definite (an active row's s_i/z_i is far below δ, which would
        // then swamp it).
        let regularized = self.diag.len() - self.dense.len();
        for (c, &i) in self.diag[..regularized].iter().enumerate() {
            kkt[i] += if c < self.n { delta } else { -delta };
        }
        self.ldl.factor(kkt)
    }

    /// The right-hand side for the reduced system of the Newton step
    /// `(P + GᵀW⁻²G)Δx + A₀ᵀΔz₀ = r₁ − GᵀW⁻²v`, `A₀Δx = r₂,₀` with `wv = W⁻²v` (cone rows):
    /// a dense row's term moves to its own row, `a_iᵀΔx − Δz_i·s_i/z_i = −v_i`. A is given
    /// by columns (`colptr`, `rowval`, values), so that `Gᵀ(W⁻²v)` is one gathered sum per
    /// column.
    pub(super) fn load_rhs(
        &mut self,
        (r1, r2_eq): (&[f64], &[f64]),
        (colptr, rowval, a): (&[usize], &[usize], &[f64]),
        (wv, v): (&[f64], &[f64]),
    ) {
        let (n, m0) = (self.n, r2_eq.len());
        // W⁻²v on the cone rows that fold into K, zero elsewhere.
        self.masked[..m0].fill(0.0);
        self.masked[m0..].copy_from_slice(wv);
        for &r in &self.dense {
            self.masked[r] = 0.0;
        }
        for c in 0..n {
            let range = colptr[c]..colptr[c + 1];
            let gathered: f64 =
                rowval[range.clone()].iter().zip(&a[range]).map(|(&r, x)| x * self.masked[r]).sum();
            self.rhs[c] = r1[c] - gathered;
        }
        self.rhs[n..n + m0].copy_from_slice(r2_eq);
        for (j, &r) in self.dense.iter().enumerate() {
            self.rhs[n + m0 + j] = -v[r - m0];
        }
    }

    /// `sol = K⁻¹ rhs` with the last factorization.
    pub(super) fn solve(&mut self) {
        self.sol.copy_from_slice(&self.rhs);
        self.ldl.solve(&mut self.sol);
    }
}
