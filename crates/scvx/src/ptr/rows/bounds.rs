//! Linear inequality rows (nonnegative cone) with constant coefficients: the box bounds of
//! every state, control and dilation at every node, the final time's bounds
//! `t_min ≤ Δτ·Σ s_k ≤ t_max`, the CTCS increments `y_{k+1} − y_k ≤ ε`, and the
//! nonnegativity of the virtual controls and buffers.

use super::{Cone, Placement, RowBuilder, RowFamily, Source, VarLayout};
use crate::Ocp;

/// Appends the box bounds, the final time's bounds and the increments.
pub(in crate::ptr) fn push(v: &VarLayout, ocp: &Ocp, rb: &mut RowBuilder) {
    for k in 0..v.nn {
        for i in 0..v.n {
            rb.bound(v.x(k, i), 1.0, ocp.x_max[i]);
            rb.bound(v.x(k, i), -1.0, ocp.x_min[i]);
        }
        for i in (0..v.m).filter(|&i| !ocp.dynamics.is_time_scaled(i)) {
            rb.bound(v.u(k, i), 1.0, ocp.u_max[i]);
            rb.bound(v.u(k, i), -1.0, ocp.u_min[i]);
        }
        rb.bound(v.s(k), 1.0, ocp.s_max);
        rb.bound(v.s(k), -1.0, ocp.s_min);
    }
    push_time_scaled(v, ocp, rb);
    let dtau = 1.0 / (v.nn - 1) as f64;
    for (sign, bound) in [(1.0, ocp.final_time.1), (-1.0, ocp.final_time.0)] {
        if bound.is_finite() && (sign > 0.0 || bound > 0.0) {
            for k in 0..v.nn - 1 {
                rb.entry(v.s(k), Source::Const(sign * dtau));
            }
            rb.end_row(sign * bound);
        }
    }
    for &crate::Increment { state: r, eps, first, last } in &ocp.increments {
        for k in first..last.min(v.nn - 1) {
            rb.entry(v.x(k + 1, r), Source::Const(1.0));
            rb.entry(v.x(k, r), Source::Const(-1.0));
            rb.end_row(eps);
        }
    }
}

/// The bounds of the time-scaled controls (`w = s·u`): `u_min·s_k ≤ w ≤ u_max·s_k` at both
/// ends of each segment k (at its start only for a zero-order hold), so the physical
/// control `w(τ)/s_k` holds its bounds all along the segment.
fn push_time_scaled(v: &VarLayout, ocp: &Ocp, rb: &mut RowBuilder) {
    let d = &ocp.dynamics;
    for i in (0..v.m).filter(|&i| d.is_time_scaled(i)) {
        for k in 0..v.nn - 1 {
            let ends: &[usize] = if d.is_foh(i) { &[k, k + 1] } else { &[k] };
            for &node in ends {
                for (sign, bound) in [(1.0, ocp.u_max[i]), (-1.0, ocp.u_min[i])] {
                    if bound.is_finite() {
                        rb.entry(v.u(node, i), Source::Const(sign));
                        rb.entry(v.s(k), Source::Const(-sign * bound));
                        rb.end_row(0.0);
                    }
                }
            }
        }
    }
}

/// Appends `z[c] ≥ 0` for every virtual control and buffer (columns `vp0..n_vars`).
pub(in crate::ptr) fn push_nonnegative(v: &VarLayout, n_vars: usize, rb: &mut RowBuilder) {
    for c in v.vp0..n_vars {
        rb.bound(c, -1.0, 0.0);
    }
}

/// The box bounds, final-time bounds and CTCS increments as a [`RowFamily`].
pub(in crate::ptr) struct Bounds;

impl RowFamily for Bounds {
    const CONE: Cone = Cone::Nonnegative;

    fn push(cx: &mut Placement<'_>) {
        push(cx.v, cx.ocp, &mut cx.rb);
    }
}

/// The nonnegativity of the virtual controls and buffers as a [`RowFamily`] (placed last
/// among the nonnegative rows, once every buffer column exists).
pub(in crate::ptr) struct Nonnegativity;

impl RowFamily for Nonnegativity {
    const CONE: Cone = Cone::Nonnegative;

    fn push(cx: &mut Placement<'_>) {
        push_nonnegative(cx.v, cx.n_vars, &mut cx.rb);
    }
}
