//! Nodal constraint rows, with values refilled each iteration from the constraint's
//! Jacobian at the reference:
//! - an inequality `g(x_k, u_k) ≤ 0`, one row per output (nonnegative cone):
//!   `∇g·z − ν_b ≤ ∇g·z̄ − g(z̄)`, with a buffer `ν_b ≥ 0` each;
//! - a ball `‖g‖ ≤ r`, one second-order cone per node with a buffer on its radius:
//!   `[r + ν_b; g(z̄) + ∇g·(z − z̄)] ∈ SOC`.

use super::{Cone, NodalRow, Placement, RowBuilder, RowFamily, Source, VarLayout};
use crate::{NodalConstraint, NodalKind, Ocp};

/// The nodal rows as placed: the rows, each buffer's owner and the balls still to place.
#[derive(Debug, Default)]
pub(in crate::ptr) struct NodalPlacement {
    /// Every nodal row (inequalities, then the balls' cone rows).
    pub(in crate::ptr) rows: Vec<NodalRow>,
    /// Per buffer: its evaluation block, constraint and output (`None` for a ball's norm).
    pub(in crate::ptr) buffers: Vec<(usize, usize, Option<usize>)>,
    /// Per ball: (constraint, node, evaluation block, buffer column).
    balls: Vec<(usize, usize, usize, usize)>,
}

/// The subproblem columns and Jacobian-buffer indices of output `out` of a (constraint,
/// node) block whose Jacobian nonzeros start at `goff`.
fn jacobian_row(
    v: &VarLayout,
    c: &NodalConstraint,
    k: usize,
    goff: usize,
    out: usize,
) -> Vec<(usize, usize)> {
    let p = c.function.jacobian_pattern();
    let mut entries = Vec::new();
    for col in 0..p.ncols() {
        for nzi in p.col_ptr()[col]..p.col_ptr()[col + 1] {
            if p.row_idx()[nzi] == out {
                let var = if col < v.n { v.x(k, col) } else { v.u(k, col - v.n) };
                entries.push((var, goff + nzi));
            }
        }
    }
    entries
}

/// Appends the inequality rows and reserves the balls' buffers (evaluation blocks are
/// numbered (constraint, node) in order; `g_offsets` holds each block's offsets).
pub(in crate::ptr) fn push_inequalities(
    v: &VarLayout,
    ocp: &Ocp,
    g_offsets: &[(usize, usize)],
    rb: &mut RowBuilder,
) -> NodalPlacement {
    let mut placed = NodalPlacement::default();
    let mut eval = 0;
    for (ci, c) in ocp.nodal.iter().enumerate() {
        for &k in &c.nodes {
            let (_, goff) = g_offsets[eval];
            match c.kind {
                NodalKind::Inequality => {
                    for out in 0..c.function.n_outputs() {
                        for (var, i) in jacobian_row(v, c, k, goff, out) {
                            rb.entry(var, Source::G(i));
                        }
                        rb.entry(v.vb0 + placed.buffers.len(), Source::Const(-1.0));
                        placed.rows.push(NodalRow { output: out, row: rb.row, eval, cone: false });
                        placed.buffers.push((eval, ci, Some(out)));
                        rb.end_row(0.0);
                    }
                }
                NodalKind::Ball { .. } => {
                    placed.balls.push((ci, k, eval, v.vb0 + placed.buffers.len()));
                    placed.buffers.push((eval, ci, None));
                }
            }
            eval += 1;
        }
    }
    placed
}

/// Appends the balls' cone rows (after every nonnegative row); returns the cone sizes.
pub(in crate::ptr) fn push_balls(
    v: &VarLayout,
    ocp: &Ocp,
    g_offsets: &[(usize, usize)],
    placed: &mut NodalPlacement,
    rb: &mut RowBuilder,
) -> Vec<usize> {
    let mut socs = Vec::new();
    for &(ci, k, ev, buffer) in &placed.balls {
        let c = &ocp.nodal[ci];
        let NodalKind::Ball { radius } = c.kind else { continue };
        rb.entry(buffer, Source::Const(-1.0));
        rb.end_row(radius);
        let (_, goff) = g_offsets[ev];
        for out in 0..c.function.n_outputs() {
            for (var, i) in jacobian_row(v, c, k, goff, out) {
                rb.entry(var, Source::NegG(i));
            }
            placed.rows.push(NodalRow { output: out, row: rb.row, eval: ev, cone: true });
            rb.end_row(0.0);
        }
        socs.push(1 + c.function.n_outputs());
    }
    socs
}

/// The nodal inequalities (and the balls' buffers) as a [`RowFamily`].
pub(in crate::ptr) struct Inequalities;

impl RowFamily for Inequalities {
    const CONE: Cone = Cone::Nonnegative;

    fn push(cx: &mut Placement<'_>) {
        cx.nodal = push_inequalities(cx.v, cx.ocp, cx.g_offsets, &mut cx.rb);
    }
}

/// The balls' second-order cones as a [`RowFamily`].
pub(in crate::ptr) struct Balls;

impl RowFamily for Balls {
    const CONE: Cone = Cone::SecondOrder;

    fn push(cx: &mut Placement<'_>) {
        let socs = push_balls(cx.v, cx.ocp, cx.g_offsets, &mut cx.nodal, &mut cx.rb);
        cx.socs.extend(socs);
    }
}
