//! Boundary rows (zero cone): the fixed initial and final state components, and
//! `s_{N−1} = s_{N−2}` (the last node's dilation is not a segment's).

use super::{Cone, Placement, RowBuilder, RowFamily, Source, VarLayout};
use crate::Ocp;

/// Appends the boundary rows.
pub(in crate::ptr) fn push(v: &VarLayout, ocp: &Ocp, rb: &mut RowBuilder) {
    let last = v.nn - 1;
    for (k, values) in [(0, &ocp.x_initial), (last, &ocp.x_final)] {
        for (i, value) in values.iter().enumerate() {
            if let Some(value) = value {
                rb.entry(v.x(k, i), Source::Const(1.0));
                rb.end_row(*value);
            }
        }
    }
    rb.entry(v.s(last), Source::Const(1.0));
    rb.entry(v.s(last - 1), Source::Const(-1.0));
    rb.end_row(0.0);
}

/// The boundary rows as a [`RowFamily`].
pub(in crate::ptr) struct Boundary;

impl RowFamily for Boundary {
    const CONE: Cone = Cone::Zero;

    fn push(cx: &mut Placement<'_>) {
        push(cx.v, cx.ocp, &mut cx.rb);
    }
}
