//! Compressed sparse column (CSC) sparsity patterns.

use core::fmt;

/// The structure of a sparse matrix in compressed sparse column form, without values.
///
/// Row indices are sorted within each column. A compiled [`Function`](crate::Function)
/// fixes its Jacobian pattern at compile time; evaluation writes the values of these
/// nonzeros in this order, so downstream code (e.g. a convex-subproblem assembler) can
/// compute its own index maps once.
///
/// `Display` draws a text picture, `*` for a structural nonzero and `.` otherwise:
/// ```
/// use armature_symbolic::SparsityPattern;
/// let p = SparsityPattern::from_entries(2, 3, &[(0, 0), (1, 1), (1, 2)]);
/// assert_eq!(p.to_string(), "*..\n.**\n");
/// assert_eq!(p.nnz(), 3);
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SparsityPattern {
    nrows: usize,
    ncols: usize,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
}

impl SparsityPattern {
    /// A pattern from `(row, col)` entries (any order; duplicates merged). Entries outside
    /// `nrows × ncols` are dropped.
    pub fn from_entries(nrows: usize, ncols: usize, entries: &[(usize, usize)]) -> Self {
        let mut cols: Vec<Vec<usize>> = vec![Vec::new(); ncols];
        for &(r, c) in entries {
            if r < nrows && c < ncols {
                cols[c].push(r);
            }
        }
        let mut col_ptr = Vec::with_capacity(ncols + 1);
        let mut row_idx = Vec::new();
        col_ptr.push(0);
        for mut c in cols {
            c.sort_unstable();
            c.dedup();
            row_idx.extend(c);
            col_ptr.push(row_idx.len());
        }
        Self { nrows, ncols, col_ptr, row_idx }
    }

    /// Number of rows.
    pub fn nrows(&self) -> usize {
        self.nrows
    }

    /// Number of columns.
    pub fn ncols(&self) -> usize {
        self.ncols
    }

    /// Number of structural nonzeros.
    pub fn nnz(&self) -> usize {
        self.row_idx.len()
    }

    /// Column pointers (`ncols + 1` entries).
    pub fn col_ptr(&self) -> &[usize] {
        &self.col_ptr
    }

    /// Row index of each nonzero, column by column.
    pub fn row_idx(&self) -> &[usize] {
        &self.row_idx
    }

    /// Position of entry `(row, col)` among the nonzeros, if it is one.
    pub fn position(&self, row: usize, col: usize) -> Option<usize> {
        if col >= self.ncols {
            return None;
        }
        let (s, e) = (self.col_ptr[col], self.col_ptr[col + 1]);
        self.row_idx[s..e].binary_search(&row).ok().map(|k| s + k)
    }

    /// Whether `(row, col)` is a structural nonzero.
    pub fn contains(&self, row: usize, col: usize) -> bool {
        self.position(row, col).is_some()
    }

    /// All nonzeros as `(row, col)`, in storage order.
    pub fn entries(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        (0..self.ncols).flat_map(move |c| {
            self.row_idx[self.col_ptr[c]..self.col_ptr[c + 1]].iter().map(move |&r| (r, c))
        })
    }

    /// The sub-pattern of columns `start..end` (nonzeros `col_ptr[start]..col_ptr[end]` of
    /// this pattern, in the same order).
    pub fn columns(&self, start: usize, end: usize) -> SparsityPattern {
        let end = end.min(self.ncols);
        let start = start.min(end);
        let base = self.col_ptr[start];
        Self {
            nrows: self.nrows,
            ncols: end - start,
            col_ptr: self.col_ptr[start..=end].iter().map(|p| p - base).collect(),
            row_idx: self.row_idx[base..self.col_ptr[end]].to_vec(),
        }
    }

    /// Expands nonzero values in this pattern's order into a dense row-major matrix.
    pub fn to_dense(&self, values: &[f64]) -> Vec<f64> {
        let mut d = vec![0.0; self.nrows * self.ncols];
        for ((r, c), v) in self.entries().zip(values) {
            d[r * self.ncols + c] = *v;
        }
        d
    }
}

impl fmt::Display for SparsityPattern {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut grid = vec![b'.'; self.nrows * self.ncols];
        for (r, c) in self.entries() {
            grid[r * self.ncols + c] = b'*';
        }
        for r in 0..self.nrows {
            let row = &grid[r * self.ncols..(r + 1) * self.ncols];
            writeln!(f, "{}", String::from_utf8_lossy(row))?;
        }
        Ok(())
    }
}
