//! Sparsity patterns shared by the subproblem assembly and the interior point: a
//! column-compressed pattern built from (row, column) entries, and the row view of one.

/// A column-compressed pattern (no values): column pointers and row indices, rows ascending
/// within each column.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct CscPattern {
    pub(crate) colptr: Vec<usize>,
    pub(crate) rowval: Vec<usize>,
}

impl CscPattern {
    /// The pattern of `ncols` columns holding `entries` (row, column); duplicates are merged.
    pub(crate) fn from_entries(ncols: usize, mut entries: Vec<(usize, usize)>) -> CscPattern {
        entries.sort_unstable_by_key(|&(r, c)| (c, r));
        entries.dedup();
        let mut colptr = vec![0; ncols + 1];
        for &(_, c) in &entries {
            colptr[c + 1] += 1;
        }
        for c in 0..ncols {
            colptr[c + 1] += colptr[c];
        }
        CscPattern { colptr, rowval: entries.iter().map(|e| e.0).collect() }
    }

    /// Index of entry (r, c) in `rowval`.
    ///
    /// # Panics
    /// If the entry is not in the pattern (a bug in the caller's bookkeeping).
    pub(crate) fn position(&self, r: usize, c: usize) -> usize {
        let lo = self.colptr[c];
        lo + self.rowval[lo..self.colptr[c + 1]].binary_search(&r).expect("in the pattern")
    }

    /// Stored entries.
    pub(crate) fn nnz(&self) -> usize {
        self.rowval.len()
    }
}

/// Row view of a column-compressed pattern: for each row, its (column, index into the
/// pattern's entries), columns ascending.
#[derive(Debug, Clone)]
pub(crate) struct Rows {
    ptr: Vec<usize>,
    entries: Vec<(usize, usize)>,
}

impl Rows {
    /// The rows of an `m`-row pattern given by `colptr` (n + 1 entries) and `rowval`.
    pub(crate) fn new(m: usize, colptr: &[usize], rowval: &[usize]) -> Rows {
        let mut ptr = vec![0usize; m + 1];
        for &r in rowval {
            ptr[r + 1] += 1;
        }
        for r in 0..m {
            ptr[r + 1] += ptr[r];
        }
        let mut fill = ptr.clone();
        let mut entries = vec![(0usize, 0usize); rowval.len()];
        for c in 0..colptr.len() - 1 {
            for p in colptr[c]..colptr[c + 1] {
                let r = rowval[p];
                entries[fill[r]] = (c, p);
                fill[r] += 1;
            }
        }
        Rows { ptr, entries }
    }

    /// Rebuilds this view in place for another pattern of `m` rows with at most as many
    /// entries as the first (no allocation); `fill` is scratch of length `m + 1`.
    pub(crate) fn rebuild(
        &mut self,
        m: usize,
        (colptr, rowval): (&[usize], &[usize]),
        fill: &mut [usize],
    ) {
        self.ptr.clear();
        self.ptr.resize(m + 1, 0);
        for &r in rowval {
            self.ptr[r + 1] += 1;
        }
        for r in 0..m {
            self.ptr[r + 1] += self.ptr[r];
        }
        fill.copy_from_slice(&self.ptr);
        self.entries.clear();
        self.entries.resize(rowval.len(), (0, 0));
        for c in 0..colptr.len() - 1 {
            for p in colptr[c]..colptr[c + 1] {
                let r = rowval[p];
                self.entries[fill[r]] = (c, p);
                fill[r] += 1;
            }
        }
    }

    /// Row r's (column, entry index) pairs.
    pub(crate) fn row(&self, r: usize) -> &[(usize, usize)] {
        &self.entries[self.ptr[r]..self.ptr[r + 1]]
    }

    /// Stored entries.
    pub(crate) fn nnz(&self) -> usize {
        self.entries.len()
    }

    /// `a_r · x` for row r with values `a` (indexed like the pattern's entries).
    pub(crate) fn dot(&self, r: usize, a: &[f64], x: &[f64]) -> f64 {
        self.dot_from(0.0, r, a, x)
    }

    /// `init + a_r · x`, summed from `init`.
    pub(crate) fn dot_from(&self, init: f64, r: usize, a: &[f64], x: &[f64]) -> f64 {
        self.row(r).iter().fold(init, |acc, &(c, p)| acc + a[p] * x[c])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn patterns_merge_duplicates_and_rows_transpose_them() {
        let p = CscPattern::from_entries(3, vec![(2, 0), (0, 0), (1, 2), (0, 0), (0, 2)]);
        assert_eq!(p.colptr, vec![0, 2, 2, 4]);
        assert_eq!(p.rowval, vec![0, 2, 0, 1]);
        assert_eq!(p.position(1, 2), 3);
        let rows = Rows::new(3, &p.colptr, &p.rowval);
        assert_eq!(rows.row(0), &[(0, 0), (2, 2)]);
        assert_eq!(rows.row(1), &[(2, 3)]);
        assert_eq!(rows.row(2), &[(0, 1)]);
        assert_eq!(rows.dot(0, &[1.0, 2.0, 3.0, 4.0], &[10.0, 0.0, 100.0]), 310.0);
        // Rebuilt in place for a sub-pattern (entry (0, 0) and (1, 2) dropped).
        let mut again = rows.clone();
        let mut fill = vec![0; 4];
        again.rebuild(3, (&[0, 1, 1, 2], &[2, 0]), &mut fill);
        assert_eq!(again.row(0), &[(2, 1)]);
        assert!(again.row(1).is_empty());
        assert_eq!(again.row(2), &[(0, 0)]);
        assert_eq!(again.nnz(), 2);
    }
}
