//! The subproblem's row bookkeeping built once by `Ptr::new`: where each nonzero's value comes
//! from, the interval (peak) rows, the quasi-Newton elements and the nodal rows; and one file
//! per row family, each appending its rows to the pattern in cone order (see `Ptr::new`).

pub(super) mod boundary;
pub(super) mod bounds;
pub(super) mod dynamics;
pub(super) mod nodal;
pub(super) mod peaks;

#[derive(Debug, Clone, Copy)]
pub(super) enum Source {
    Const(f64),
    A(usize),
    Bm(usize),
    Bp(usize),
    /// A nodal-constraint Jacobian nonzero (index into the per-iteration buffer).
    G(usize),
    /// Its negative (cone rows: `s = b − A z`).
    NegG(usize),
    /// A coefficient of an interval-bound peak row (index into the per-iteration buffer).
    Peak(usize),
}

/// One interval row: the peak on segment `seg` of state `r` against its upper (`sign` +1)
/// or lower (−1) bound, or of an interval constraint's output (`sign` +1, bound 0).
#[derive(Debug, Clone)]
pub(super) struct PeakRow {
    pub(super) seg: usize,
    pub(super) of: PeakOf,
    pub(super) sign: f64,
    pub(super) bound: f64,
    pub(super) row: usize,
    /// Its coefficients: offsets into a grid block (`[x, Φ, B⁻, B⁺]`), in `peak_src` — of
    /// the state row's entry, or (function rows) of row 0's entry in the column, with the
    /// column's row stride in `peak_stride`.
    pub(super) src: std::ops::Range<usize>,
}

/// What a [`PeakRow`] bounds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum PeakOf {
    /// A state row ([`Ocp::interval_bounds`]).
    State(usize),
    /// Output `out` of interval constraint `c` ([`Ocp::interval_constraints`]).
    Function { c: usize, out: usize },
}

/// Per interval constraint: where its grid values and Jacobians sit in [`NodalEval`], and
/// for each output the state rows it reads with their Jacobian nonzero index.
#[derive(Debug, Clone)]
pub(super) struct IntervalMeta {
    pub(super) first: usize,
    pub(super) last: usize,
    pub(super) nout: usize,
    pub(super) nnz: usize,
    /// Offset of `(segment first, point 0)` in `NodalEval::fgrid` (values, `nout` per point)
    /// and `NodalEval::fjac` (`nnz` per point).
    pub(super) val0: usize,
    pub(super) jac0: usize,
    /// Offset of its first grid point in `NodalEval::fjac_at`, and its number of points.
    pub(super) pt0: usize,
    pub(super) points: usize,
    /// [`IntervalConstraint::activation`] (∞ for none), and the index of its first segment in
    /// `NodalEval::segment_peak`.
    pub(super) activation: f64,
    pub(super) seg0: usize,
    pub(super) deps: Vec<Vec<(usize, usize)>>,
}

/// One element of the partitioned quasi-Newton Hessian: the columns through which the rows
/// of one segment (its dynamics and the nodal constraints at its first node) are nonlinear.
#[derive(Debug, Clone)]
pub(super) struct Element {
    /// Subproblem columns (primal variables).
    pub(super) cols: Vec<usize>,
    /// For `a ≤ b`, the index in `P`'s values of entry `(cols[a], cols[b])`, row-major `d×d`.
    pub(super) pidx: Vec<usize>,
}

/// Where one nodal constraint row sits: its evaluation block and its subproblem row.
#[derive(Debug, Clone, Copy)]
pub(super) struct NodalRow {
    pub(super) output: usize,
    pub(super) row: usize,
    /// Index of its (constraint, node) evaluation block in `g_offsets`.
    pub(super) eval: usize,
    /// A cone row (`b = g(z̄) − ∇g·z̄`) rather than an inequality (`b = ∇g·z̄ − g(z̄)`).
    pub(super) cone: bool,
}

/// Where each block of the subproblem's variables starts:
/// `z = [X (N·n) | U (N·m) | S (N) | ν⁺ ((N−1)·n) | ν⁻ ((N−1)·n) | buffers | peak buffers]`.
#[derive(Debug, Clone, Copy)]
pub(super) struct VarLayout {
    /// States, controls and nodes.
    pub(super) n: usize,
    pub(super) m: usize,
    pub(super) nn: usize,
    /// Columns of `[B⁻ | B⁺]`'s blocks: the controls and the dilation.
    pub(super) mc: usize,
    pub(super) x0: usize,
    pub(super) u0: usize,
    pub(super) s0: usize,
    pub(super) vp0: usize,
    pub(super) vm0: usize,
    /// First buffer of the nodal rows.
    pub(super) vb0: usize,
}

impl VarLayout {
    pub(super) fn new(n: usize, m: usize, nn: usize) -> VarLayout {
        let (x0, u0) = (0, nn * n);
        let s0 = u0 + nn * m;
        let vp0 = s0 + nn;
        let vm0 = vp0 + (nn - 1) * n;
        VarLayout { n, m, nn, mc: m + 1, x0, u0, s0, vp0, vm0, vb0: vm0 + (nn - 1) * n }
    }

    /// Column of state `i` at node `k`.
    pub(super) fn x(&self, k: usize, i: usize) -> usize {
        self.x0 + k * self.n + i
    }

    /// Column of control `i` at node `k`.
    pub(super) fn u(&self, k: usize, i: usize) -> usize {
        self.u0 + k * self.m + i
    }

    /// Column of the dilation at node `k`.
    pub(super) fn s(&self, k: usize) -> usize {
        self.s0 + k
    }
}

/// The constraint matrix being assembled: `(row, column, value source)` triplets, the
/// right-hand side and the next row.
#[derive(Debug, Default)]
pub(super) struct RowBuilder {
    pub(super) trip: Vec<(usize, usize, Source)>,
    pub(super) b: Vec<f64>,
    pub(super) row: usize,
}

impl RowBuilder {
    /// An entry of the current row.
    pub(super) fn entry(&mut self, col: usize, src: Source) {
        self.trip.push((self.row, col, src));
    }

    /// Ends the current row with right-hand side `b`.
    pub(super) fn end_row(&mut self, b: f64) {
        self.b.push(b);
        self.row += 1;
    }

    /// The inequality `sign·z[col] ≤ sign·bound`, if the bound is finite.
    pub(super) fn bound(&mut self, col: usize, sign: f64, bound: f64) {
        if bound.is_finite() {
            self.entry(col, Source::Const(sign));
            self.end_row(sign * bound);
        }
    }
}
