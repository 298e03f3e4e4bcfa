//! The dynamics rows (zero cone), one per segment and state:
//! `A_k x_k − x_{k+1} + B⁻_k [u_k; s_k] + B⁺_k u_{k+1} + ν⁺_k − ν⁻_k = −c_k`, with only the
//! structurally nonzero entries of `A` and `B±` (the transition pattern). Their values are
//! the discretization's, refilled each iteration.

use armature_symbolic::SparsityPattern;

use super::{Cone, Placement, RowBuilder, RowFamily, Source, VarLayout};

/// Appends the dynamics rows.
pub(in crate::ptr) fn push(v: &VarLayout, tp: &SparsityPattern, rb: &mut RowBuilder) {
    let (n, m, mc) = (v.n, v.m, v.mc);
    for k in 0..v.nn - 1 {
        for r in 0..n {
            for j in (0..n).filter(|&j| tp.contains(r, j)) {
                rb.entry(v.x(k, j), Source::A(k * n * n + r * n + j));
            }
            rb.entry(v.x(k + 1, r), Source::Const(-1.0));
            for i in (0..m).filter(|&i| tp.contains(r, n + i)) {
                rb.entry(v.u(k, i), Source::Bm(k * n * mc + r * mc + i));
                rb.entry(v.u(k + 1, i), Source::Bp(k * n * mc + r * mc + i));
            }
            rb.entry(v.s(k), Source::Bm(k * n * mc + r * mc + m));
            rb.entry(v.vp0 + k * n + r, Source::Const(1.0));
            rb.entry(v.vm0 + k * n + r, Source::Const(-1.0));
            rb.end_row(0.0);
        }
    }
}

/// The dynamics rows as a [`RowFamily`].
pub(in crate::ptr) struct Dynamics;

impl RowFamily for Dynamics {
    const CONE: Cone = Cone::Zero;

    fn push(cx: &mut Placement<'_>) {
        push(cx.v, cx.tp, &mut cx.rb);
    }
}
