//! Numeric LDLᵀ factorization of a quasi-definite matrix on a pattern analysed once.
//!
//! The symbolic analysis — the ordering and the pattern of L — is QDLDL's (Clarabel's), run
//! once in logical mode, in its approximate-minimum-degree ordering or in a cheaper one the
//! caller offers (the staged orderings of `ipm/ordering.rs`). QDLDL's numeric factorization
//! then walks the elimination tree again for every row of every factorization to find that
//! row's pattern; here the row patterns of L, and where each entry lands in its column, are
//! computed once, so a factorization is only the up-looking arithmetic:
//!
//! ```text
//! for each row k:  y = A(0:k, k);  for j in pattern(L(k, :)) ascending:
//!                      y_i −= L(i, j)·y_j  for the rows i < k of column j
//!                      L(k, j) = y_j / D_j;   D_k −= y_j·L(k, j)
//! ```
//!
//! with QDLDL's sign-aware dynamic regularization: a pivot whose sign disagrees with the
//! expected one (or is within ε of zero) is replaced by ±δ.

use clarabel::algebra::CscMatrix;
use clarabel::qdldl::{QDLDLFactorisation, QDLDLSettings};

use super::ordering::factor_work;
use crate::sparse::Rows;

/// The factorization of `P Kₚ Pᵀ = L D Lᵀ` for one pattern of K (upper triangle).
#[derive(Debug, Clone)]
pub(super) struct Ldl {
    /// `perm[new] = old`.
    perm: Vec<usize>,
    /// Permuted upper triangle of K by column: (row, index into the caller's values).
    a_colptr: Vec<usize>,
    a_entries: Vec<(usize, usize)>,
    /// Strictly lower L, column-compressed, rows ascending in each column (as `u32`: the
    /// factorization streams them, and half the bytes is a measurable share of its time).
    l_colptr: Vec<usize>,
    l_row: Vec<u32>,
    lx: Vec<f64>,
    /// Row pattern of L: for row k, (column j, position of L(k, j) in `lx`), j ascending.
    l_rows: Rows,
    d: Vec<f64>,
    dinv: Vec<f64>,
    signs: Vec<f64>,
    eps: f64,
    delta: f64,
    y: Vec<f64>,
    work: Vec<f64>,
}

impl Ldl {
    /// Analyse the upper-triangular pattern `(colptr, rowval)` of an n × n matrix whose
    /// pivots should have the given signs (+1 / −1), in QDLDL's AMD ordering. `None` if
    /// QDLDL rejects the pattern.
    pub(super) fn analyse(
        colptr: &[usize],
        rowval: &[usize],
        signs: &[i8],
        regularization: (f64, f64),
    ) -> Option<Ldl> {
        let symbolic = symbolic(colptr, rowval, None)?;
        Ldl::from_symbolic(colptr, rowval, signs, regularization, &symbolic)
    }

    /// The same pattern analysed in the cheapest of the `candidates` orderings
    /// (`perm[new] = old`, by [`factor_work`]), if that needs less arithmetic than `than`.
    pub(super) fn cheaper(
        colptr: &[usize],
        rowval: &[usize],
        signs: &[i8],
        regularization: (f64, f64),
        candidates: &[Vec<usize>],
        than: usize,
    ) -> Option<Ldl> {
        let best = candidates
            .iter()
            .filter_map(|perm| symbolic(colptr, rowval, Some(perm.clone())))
            .min_by_key(|s| factor_work(&s.L.colptr))?;
        (factor_work(&best.L.colptr) < than)
            .then(|| Ldl::from_symbolic(colptr, rowval, signs, regularization, &best))
            .flatten()
    }

    /// Arithmetic of one factorization ([`factor_work`]).
    pub(super) fn work(&self) -> usize {
        factor_work(&self.l_colptr)
    }

    fn from_symbolic(
        colptr: &[usize],
        rowval: &[usize],
        signs: &[i8],
        (eps, delta): (f64, f64),
        symbolic: &QDLDLFactorisation<f64>,
    ) -> Option<Ldl> {
        let n = colptr.len() - 1;
        let nnz = rowval.len();
        let perm = symbolic.perm.clone();
        let mut iperm = vec![0; n];
        for (new, &old) in perm.iter().enumerate() {
            iperm[old] = new;
        }
        // K's entries in the permuted upper triangle.
        let mut entries: Vec<(usize, usize, usize)> = Vec::with_capacity(nnz);
        for c in 0..n {
            for (k, &r) in rowval.iter().enumerate().take(colptr[c + 1]).skip(colptr[c]) {
                let (a, b) = (iperm[r], iperm[c]);
                entries.push((a.min(b), a.max(b), k));
            }
        }
        entries.sort_unstable_by_key(|&(r, c, _)| (c, r));
        let mut a_colptr = vec![0; n + 1];
        for &(_, c, _) in &entries {
            a_colptr[c + 1] += 1;
        }
        for c in 0..n {
            a_colptr[c + 1] += a_colptr[c];
        }
        let a_entries = entries.iter().map(|&(r, _, k)| (r, k)).collect();
        // L's pattern, and its transpose with positions.
        let l_colptr = symbolic.L.colptr.clone();
        let l_rows = Rows::new(n, &l_colptr, &symbolic.L.rowval);
        let l_row =
            symbolic.L.rowval.iter().map(|&r| u32::try_from(r).ok()).collect::<Option<Vec<_>>>()?;
        Some(Ldl {
            perm,
            a_colptr,
            a_entries,
            lx: vec![0.0; l_row.len()],
            l_colptr,
            l_row,
            l_rows,
            d: vec![0.0; n],
            dinv: vec![0.0; n],
            signs: perm_signs(signs, &symbolic.perm),
            eps,
            delta,
            y: vec![0.0; n],
            work: vec![0.0; n],
        })
    }

    /// Nonzeros of L (strictly lower).
    pub(super) fn nnz_l(&self) -> usize {
        self.l_row.len()
    }

    /// Factor the matrix with these values (indexed like the pattern given to
    /// [`analyse`](Self::analyse)); false if a pivot is not finite.
    pub(super) fn factor(&mut self, values: &[f64]) -> bool {
        let n = self.d.len();
        for k in 0..n {
            let mut dk = 0.0;
            for &(i, src) in &self.a_entries[self.a_colptr[k]..self.a_colptr[k + 1]] {
                if i == k {
                    dk += values[src];
                } else {
                    self.y[i] += values[src];
                }
            }
            for &(j, pos) in self.l_rows.row(k) {
                let yj = self.y[j];
                self.y[j] = 0.0;
                let start = self.l_colptr[j];
                for (&i, &lij) in self.l_row[start..pos].iter().zip(&self.lx[start..pos]) {
                    self.y[i as usize] -= lij * yj;
                }
                let lkj = yj * self.dinv[j];
                self.lx[pos] = lkj;
                dk -= yj * lkj;
            }
            let sign = self.signs[k];
            if dk * sign <= self.eps {
                dk = sign * self.delta;
            }
            if !dk.is_finite() {
                return false;
            }
            self.d[k] = dk;
            self.dinv[k] = 1.0 / dk;
        }
        true
    }

    /// `b ← K⁻¹ b` with the last factorization.
    pub(super) fn solve(&mut self, b: &mut [f64]) {
        let n = self.d.len();
        for (w, &p) in self.work.iter_mut().zip(&self.perm) {
            *w = b[p];
        }
        for j in 0..n {
            let wj = self.work[j];
            let range = self.l_colptr[j]..self.l_colptr[j + 1];
            for (&i, &l) in self.l_row[range.clone()].iter().zip(&self.lx[range]) {
                self.work[i as usize] -= l * wj;
            }
        }
        for (w, di) in self.work.iter_mut().zip(&self.dinv) {
            *w *= di;
        }
        for j in (0..n).rev() {
            let range = self.l_colptr[j]..self.l_colptr[j + 1];
            let mut acc = self.work[j];
            for (&i, &l) in self.l_row[range.clone()].iter().zip(&self.lx[range]) {
                acc -= l * self.work[i as usize];
            }
            self.work[j] = acc;
        }
        for (w, &p) in self.work.iter().zip(&self.perm) {
            b[p] = *w;
        }
    }
}

/// QDLDL's symbolic analysis (logical mode) of the pattern in the ordering `perm`
/// (`None`: its AMD).
fn symbolic(
    colptr: &[usize],
    rowval: &[usize],
    perm: Option<Vec<usize>>,
) -> Option<QDLDLFactorisation<f64>> {
    let n = colptr.len() - 1;
    let pattern = CscMatrix::new(n, n, colptr.to_vec(), rowval.to_vec(), vec![1.0; rowval.len()]);
    let settings = QDLDLSettings { logical: true, perm, ..QDLDLSettings::default() };
    QDLDLFactorisation::new(&pattern, Some(settings)).ok()
}

/// The pivot signs in the permuted order.
fn perm_signs(signs: &[i8], perm: &[usize]) -> Vec<f64> {
    perm.iter().map(|&old| f64::from(signs[old])).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A quasi-definite 5 × 5 matrix: the solve inverts it, and agrees with QDLDL's.
    #[test]
    fn solves_a_quasi_definite_system_like_qdldl() {
        // Upper triangle of [4 1 0 1 0; 1 3 1 0 1; 0 1 −2 0 0; 1 0 0 −3 1; 0 1 0 1 5].
        let dense = [
            [4.0, 1.0, 0.0, 1.0, 0.0],
            [1.0, 3.0, 1.0, 0.0, 1.0],
            [0.0, 1.0, -2.0, 0.0, 0.0],
            [1.0, 0.0, 0.0, -3.0, 1.0],
            [0.0, 1.0, 0.0, 1.0, 5.0],
        ];
        let (mut colptr, mut rowval, mut vals) = (vec![0], Vec::new(), Vec::new());
        for c in 0..5 {
            for (r, row) in dense.iter().enumerate().take(c + 1) {
                if row[c] != 0.0 {
                    rowval.push(r);
                    vals.push(row[c]);
                }
            }
            colptr.push(rowval.len());
        }
        let signs = [1, 1, -1, -1, 1];
        let mut ldl = Ldl::analyse(&colptr, &rowval, &signs, (1e-13, 2e-7)).unwrap();
        assert!(ldl.factor(&vals));
        let b = [1.0, -2.0, 0.5, 3.0, -1.0];
        let mut x = b;
        ldl.solve(&mut x);
        for (r, row) in dense.iter().enumerate() {
            let kx: f64 = row.iter().zip(&x).map(|(a, v)| a * v).sum();
            assert!((kx - b[r]).abs() < 1e-12, "row {r}: {kx} vs {}", b[r]);
        }
        let settings = QDLDLSettings { Dsigns: Some(signs.to_vec()), ..QDLDLSettings::default() };
        let mut q =
            QDLDLFactorisation::new(&CscMatrix::new(5, 5, colptr, rowval, vals), Some(settings))
                .unwrap();
        let mut xq = b;
        q.solve(&mut xq);
        for (a, b) in x.iter().zip(&xq) {
            assert!((a - b).abs() < 1e-13);
        }
        assert_eq!(ldl.nnz_l(), q.nnzL());
    }

    /// A pivot of the wrong sign is regularized to ±δ instead of breaking the factorization.
    #[test]
    fn a_wrong_signed_pivot_is_regularized() {
        // [1 0; 0 1] with the second pivot expected negative.
        let mut ldl = Ldl::analyse(&[0, 1, 2], &[0, 1], &[1, -1], (1e-13, 1e-7)).unwrap();
        assert!(ldl.factor(&[1.0, 1.0]));
        let mut x = [1.0, 1.0];
        ldl.solve(&mut x);
        assert!((x[0] - 1.0).abs() < 1e-15);
        assert!((x[1] + 1e7).abs() < 1e-3, "{x:?}");
    }
}
