//! Peak rows (nonnegative cone), one per segment (or one per grid point of it), with a
//! buffer per bound and segment: the largest value on the segment's integration grid,
//! refined by a parabola (or each grid point's half-step cell), of
//! - a state row with interval bounds, against its upper or lower bound:
//!   `sign·∇x̂_r·Δz − ν_b ≤ bound − sign·x̂_r`;
//! - an output of an interval constraint `g(x) ≤ 0`:
//!   `Σ_i w_i ∇g_o(x(t_i))·∂x(t_i)/∂z·Δz − ν_b ≤ −ĝ_o`, over the columns some state row read
//!   by `g_o` depends on.
//!
//! The coefficients are offsets into a grid block `[x, Φ, B⁻, B⁺]`, filled each iteration.
//!
//! The rows of one bound on one segment — a grid point's each, with
//! [`Sampling::GridPoints`] — share their buffer `ν_b ≥ 0`: the subproblem then pays
//! `λ·max` of the segment's violations of that bound (an ℓ∞ penalty, exact while `λ` exceeds
//! the sum of the rows' multipliers; the merit prices it alike), with one column and one
//! `ν_b ≥ 0` row per segment where a buffer per row added one per grid point (the seed's
//! subproblem: 1 079 columns instead of 2 696; BENCHMARKS.md, 2026-12-07).

use armature_symbolic::SparsityPattern;

use super::{Cone, Placement, RowFamily};
use super::{IntervalMeta, PeakOf, PeakRow, RowBuilder, Source, VarLayout};
use crate::{IntervalConstraint, Ocp, Sampling};

/// The peak rows as placed.
#[derive(Debug, Default)]
pub(in crate::ptr) struct PeakPlacement {
    pub(in crate::ptr) peaks: Vec<PeakRow>,
    /// Per coefficient: its offset in a grid block.
    pub(in crate::ptr) src: Vec<usize>,
    /// Per coefficient of a function row: its column's row stride in a grid block (0 for
    /// state rows).
    pub(in crate::ptr) stride: Vec<usize>,
    pub(in crate::ptr) intervals: Vec<IntervalMeta>,
    /// The next peak buffer's column.
    pub(in crate::ptr) buffer: usize,
    /// The first peak buffer's column.
    pub(in crate::ptr) first_buffer: usize,
}

/// The segments an interval constraint covers (clamped to the grid; checked in `start`).
pub(in crate::ptr) fn segments(c: &IntervalConstraint, nn: usize) -> std::ops::Range<usize> {
    let first = c.first.min(nn - 1);
    first..c.last.clamp(first, nn - 1)
}

/// Offsets of `Φ`, `B⁻` and `B⁺` in a grid block.
fn block_offsets(v: &VarLayout) -> (usize, usize, usize) {
    let n = v.n;
    (n, n + n * n, n + n * n + n * v.mc)
}

impl PeakPlacement {
    /// The coefficients of a peak row on segment `k` over the columns `reads` selects, with
    /// `off(block, index)` the grid offset and `stride` its column stride.
    fn coefficients(
        &mut self,
        v: &VarLayout,
        k: usize,
        reads: impl Fn(usize) -> bool,
        off: impl Fn(usize, usize) -> usize,
        stride: Option<(usize, usize)>,
        rb: &mut RowBuilder,
    ) {
        let (phi0, bm0, bp0) = block_offsets(v);
        let mut push = |col: usize, offset: usize, s: usize, rb: &mut RowBuilder| {
            rb.entry(col, Source::Peak(self.src.len()));
            self.src.push(offset);
            if stride.is_some() {
                self.stride.push(s);
            }
        };
        let (sx, su) = stride.unwrap_or((0, 0));
        for j in (0..v.n).filter(|&j| reads(j)) {
            push(v.x(k, j), phi0 + off(0, j), sx, rb);
        }
        for i in (0..v.m).filter(|&i| reads(v.n + i)) {
            push(v.u(k, i), bm0 + off(1, i), su, rb);
            push(v.u(k + 1, i), bp0 + off(1, i), su, rb);
        }
        push(v.s(k), bm0 + off(1, v.m), su, rb);
    }

    /// The first of `count` new buffer columns.
    fn new_buffers(&mut self, count: usize) -> usize {
        self.buffer += count;
        self.buffer - count
    }

    /// Ends a row of `of` on segment `seg` (at its peak, or at grid point `at`) whose
    /// coefficients start at `start`, with buffer column `buffer`.
    fn finish_row(
        &mut self,
        (seg, at): (usize, Option<usize>),
        (of, sign, bound): (PeakOf, f64, f64),
        (start, buffer): (usize, usize),
        rb: &mut RowBuilder,
    ) {
        rb.entry(buffer, Source::Const(-1.0));
        let src = start..self.src.len();
        let buffer = buffer - self.first_buffer;
        self.peaks.push(PeakRow { seg, of, sign, bound, row: rb.row, src, at, buffer });
        rb.end_row(0.0);
    }
}

/// The finite bounds of the state rows with interval bounds, `(row, sign, bound)` in the
/// order their rows are placed: a row's upper bound, then its lower.
fn state_bounds(ocp: &Ocp, rows: &[usize]) -> Vec<(usize, f64, f64)> {
    rows.iter()
        .flat_map(|&r| [(r, 1.0, ocp.x_max[r]), (r, -1.0, -ocp.x_min[r])])
        .filter(|(_, _, bound)| bound.is_finite())
        .collect()
}

/// Appends the state rows' peak rows (segment-major), their buffers from `placed.buffer`.
pub(in crate::ptr) fn push_state_peaks(
    v: &VarLayout,
    ocp: &Ocp,
    tp: &SparsityPattern,
    rows: &[usize],
    placed: &mut PeakPlacement,
    pts: usize,
    rb: &mut RowBuilder,
) {
    let bounds = state_bounds(ocp, rows);
    for k in 0..v.nn - 1 {
        let first = placed.new_buffers(bounds.len());
        for at in sample_points(ocp.interval_bounds_sampling, pts) {
            for (b, &(r, sign, bound)) in bounds.iter().enumerate() {
                let start = placed.src.len();
                let off =
                    |block: usize, i: usize| if block == 0 { r * v.n + i } else { r * v.mc + i };
                placed.coefficients(v, k, |col| tp.contains(r, col), off, None, rb);
                let of = (PeakOf::State(r), sign, bound);
                placed.finish_row((k, at), of, (start, first + b), rb);
            }
        }
    }
    placed.stride = vec![0; placed.src.len()];
}

/// The rows' places on each segment under `sampling`: the peak (`None`), or every grid point
/// of the segment. A node is both a segment's last point and the next one's first: each row
/// bounds the half step on its own segment's side (`local_peak`), so both are needed.
fn sample_points(sampling: Sampling, pts: usize) -> Vec<Option<usize>> {
    match sampling {
        Sampling::Peak => vec![None],
        Sampling::GridPoints => (0..pts).map(Some).collect(),
    }
}

/// The number of buffers of the state rows' peak rows on `nn` nodes (one per finite bound
/// and segment).
pub(in crate::ptr) fn state_buffers(ocp: &Ocp, rows: &[usize], nn: usize) -> usize {
    (nn - 1) * state_bounds(ocp, rows).len()
}

/// The number of buffers of interval constraint `c`'s peak rows on `nn` nodes (one per
/// output and segment).
pub(in crate::ptr) fn function_buffers(c: &IntervalConstraint, nn: usize) -> usize {
    segments(c, nn).len() * c.function.n_outputs()
}

/// Appends the interval constraints' peak rows (constraint, segment, output) with their
/// grid bookkeeping; `pts` is the number of grid points per segment.
pub(in crate::ptr) fn push_function_peaks(
    v: &VarLayout,
    ocp: &Ocp,
    tp: &SparsityPattern,
    pts: usize,
    placed: &mut PeakPlacement,
    rb: &mut RowBuilder,
) {
    let (mut val0, mut jac0, mut pt0) = (0, 0, 0);
    for (ci, c) in ocp.interval_constraints.iter().enumerate() {
        let jp = c.function.jacobian_pattern();
        let (nout, nnz) = (c.function.n_outputs(), jp.nnz());
        let mut deps = vec![Vec::new(); nout];
        for col in 0..jp.ncols().min(v.n) {
            for q in jp.col_ptr()[col]..jp.col_ptr()[col + 1] {
                deps[jp.row_idx()[q]].push((col, q));
            }
        }
        let segs = segments(c, v.nn);
        for k in segs.clone() {
            let first = placed.new_buffers(nout);
            for at in sample_points(c.sampling, pts) {
                for (out, dep) in deps.iter().enumerate() {
                    let start = placed.src.len();
                    let reads = |col: usize| dep.iter().any(|&(r, _)| tp.contains(r, col));
                    let stride = Some((v.n, v.mc));
                    placed.coefficients(v, k, reads, |_, i| i, stride, rb);
                    let of = (PeakOf::Function { c: ci, out }, 1.0, 0.0);
                    placed.finish_row((k, at), of, (start, first + out), rb);
                }
            }
        }
        placed.intervals.push(IntervalMeta {
            first: segs.start,
            last: segs.end,
            nout,
            nnz,
            val0,
            jac0,
            pt0,
            points: segs.len() * pts,
            activation: c.activation.unwrap_or(f64::INFINITY),
            seg0: pt0 / pts,
            deps,
        });
        pt0 += segs.len() * pts;
        val0 += segs.len() * pts * nout;
        jac0 += segs.len() * pts * nnz;
    }
}

/// The state bounds at their peaks between the nodes as a [`RowFamily`].
pub(in crate::ptr) struct StatePeaks;

impl RowFamily for StatePeaks {
    const CONE: Cone = Cone::Nonnegative;

    fn push(cx: &mut Placement<'_>) {
        push_state_peaks(cx.v, cx.ocp, cx.tp, cx.interval_rows, &mut cx.peaks, cx.pts, &mut cx.rb);
    }
}

/// The interval constraints at their peaks between the nodes as a [`RowFamily`].
pub(in crate::ptr) struct FunctionPeaks;

impl RowFamily for FunctionPeaks {
    const CONE: Cone = Cone::Nonnegative;

    fn push(cx: &mut Placement<'_>) {
        push_function_peaks(cx.v, cx.ocp, cx.tp, cx.pts, &mut cx.peaks, &mut cx.rb);
    }
}
