//! The subproblem's rows, one file per [`RowFamily`], and the bookkeeping `Ptr::new` builds
//! once: where each nonzero's value comes from, the interval (peak) rows, the quasi-Newton
//! elements and the nodal rows.
//!
//! # Adding a family
//! A family is a type implementing [`RowFamily`] in its own file: its cone and a `push` that
//! appends its rows (entries with their value [`Source`]s, right-hand sides) through the
//! [`Placement`]. Register it with one line in [`row_families!`] below; `Ptr::new` places
//! every family cone by cone (zero, nonnegative, second-order), in the order listed. A
//! family with constant coefficients needs nothing else (the subproblem enforces its rows
//! exactly); one whose coefficients vary adds a [`Source`] variant, refilled each iteration.
//! `control_rate.rs` (a test) is such a family: a rate limit on the controls.

pub(super) mod boundary;
pub(super) mod bounds;
#[cfg(test)]
mod control_rate;
pub(super) mod dynamics;
pub(super) mod nodal;
pub(super) mod peaks;

use armature_symbolic::SparsityPattern;

use crate::Ocp;

/// The cone of a family's rows; the subproblem's rows are ordered by cone in this order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(super) enum Cone {
    /// Equalities `Az = b`.
    Zero,
    /// Inequalities `Az ≤ b`.
    Nonnegative,
    /// Second-order cones `b − Az ∈ SOC`.
    SecondOrder,
}

/// What a row family reads while `Ptr::new` places it, and where it records its rows.
pub(super) struct Placement<'a> {
    pub(super) v: &'a VarLayout,
    pub(super) ocp: &'a Ocp,
    /// The dynamics' transition pattern (which `A`, `B±` entries are structurally nonzero).
    pub(super) tp: &'a SparsityPattern,
    /// Integration grid points per segment.
    pub(super) pts: usize,
    /// Per (nodal constraint, node) evaluation block: its value and Jacobian offsets.
    pub(super) g_offsets: &'a [(usize, usize)],
    /// The state rows whose bounds hold between the nodes.
    pub(super) interval_rows: &'a [usize],
    /// Subproblem columns (every buffer included).
    pub(super) n_vars: usize,
    pub(super) rb: RowBuilder,
    pub(super) nodal: nodal::NodalPlacement,
    pub(super) peaks: peaks::PeakPlacement,
    /// Sizes of the second-order cones, in row order.
    pub(super) socs: Vec<usize>,
}

/// One family of subproblem rows: its cone and how it appends its rows.
pub(super) trait RowFamily {
    /// The cone of its rows.
    const CONE: Cone;
    /// Appends its rows to `cx.rb` (and records what later stages need in `cx`).
    fn push(cx: &mut Placement<'_>);
}

/// Declares [`Family`], one variant per row family, in placement order within each cone.
macro_rules! row_families {
    ($($(#[$attr:meta])* $variant:ident => $ty:ty),* $(,)?) => {
        /// Every row family of the subproblem.
        #[derive(Debug, Clone, Copy, PartialEq, Eq)]
        pub(super) enum Family {
            $($(#[$attr])* #[doc = stringify!($ty)] $variant),*
        }

        impl Family {
            /// All families, in placement order within each cone.
            pub(super) const ALL: &'static [Family] = &[$($(#[$attr])* Family::$variant),*];

            /// Its cone.
            pub(super) fn cone(self) -> Cone {
                match self {
                    $($(#[$attr])* Family::$variant => <$ty as RowFamily>::CONE),*
                }
            }

            /// Appends its rows.
            pub(super) fn push(self, cx: &mut Placement<'_>) {
                match self {
                    $($(#[$attr])* Family::$variant => <$ty as RowFamily>::push(cx)),*
                }
            }
        }
    };
}

row_families! {
    Dynamics => dynamics::Dynamics,
    Boundary => boundary::Boundary,
    Bounds => bounds::Bounds,
    NodalInequalities => nodal::Inequalities,
    StatePeaks => peaks::StatePeaks,
    FunctionPeaks => peaks::FunctionPeaks,
    #[cfg(test)]
    ControlRate => control_rate::ControlRate,
    Nonnegativity => bounds::Nonnegativity,
    Balls => nodal::Balls,
}

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
    /// A fixed grid point of the segment ([`crate::Sampling::GridPoints`]), or `None` for
    /// the peak.
    pub(super) at: Option<usize>,
    /// Its buffer, numbered among the peak rows' buffers: the rows of one bound (a state
    /// row's side, or an interval constraint's output) on one segment share one, at every
    /// grid point (see `rows/peaks.rs`).
    pub(super) buffer: usize,
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
