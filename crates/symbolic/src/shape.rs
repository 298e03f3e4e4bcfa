//! Shapes of expressions.

use core::fmt;

/// The shape of an expression: a scalar, a vector of `n` entries, or an `r`×`c` matrix.
///
/// Entries are stored row-major. A vector behaves as a column where a matrix product needs
/// one (`A @ v`), and as a row on the left (`v @ A`), like numpy's 1-D arrays.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Shape {
    /// A single number.
    Scalar,
    /// A vector of `n` entries.
    Vector(usize),
    /// An `rows`×`cols` matrix.
    Matrix(usize, usize),
}

impl Shape {
    /// Number of entries.
    pub fn numel(&self) -> usize {
        match *self {
            Shape::Scalar => 1,
            Shape::Vector(n) => n,
            Shape::Matrix(r, c) => r * c,
        }
    }

    /// Rows when seen as a matrix (a vector is a column).
    pub fn rows(&self) -> usize {
        match *self {
            Shape::Scalar => 1,
            Shape::Vector(n) => n,
            Shape::Matrix(r, _) => r,
        }
    }

    /// Columns when seen as a matrix (a vector is a column).
    pub fn cols(&self) -> usize {
        match *self {
            Shape::Scalar | Shape::Vector(_) => 1,
            Shape::Matrix(_, c) => c,
        }
    }

    /// The canonical shape of a `rows`×`cols` block: scalar for 1×1, vector for a column.
    pub(crate) fn of_block(rows: usize, cols: usize) -> Shape {
        match (rows, cols) {
            (1, 1) => Shape::Scalar,
            (n, 1) => Shape::Vector(n),
            (r, c) => Shape::Matrix(r, c),
        }
    }
}

impl fmt::Display for Shape {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Shape::Scalar => write!(f, "scalar"),
            Shape::Vector(n) => write!(f, "vector({n})"),
            Shape::Matrix(r, c) => write!(f, "matrix({r}×{c})"),
        }
    }
}
