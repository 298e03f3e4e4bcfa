//! The violations of every constraint at the nodes, as the result reports them.

use super::*;

impl Ptr {
    /// Largest violation of each constraint at the reference: the dynamics defect of each
    /// state row (over its segments) and each nodal constraint (over its nodes).
    pub(super) fn violations(&self, st: &mut Iterate) -> Vec<Violation> {
        let (n, nn) = (self.ocp.dynamics.n_x(), self.ocp.nodes);
        let mut out = Vec::new();
        for r in 0..n {
            let (k, d) = (0..nn - 1)
                .map(|k| (k, st.dbar.defect[k * n + r].abs()))
                .fold((0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
            let name = self.ocp.dynamics.state_name(r).unwrap_or("state").to_string();
            out.push(Violation {
                constraint: ConstraintRef::Dynamics { state: r, name },
                value: d,
                node: Some(k),
                time: None,
            });
        }
        let zeros = vec![0.0; st.lam_vb.len()];
        self.eval_nodal(&st.xb, &st.ub, &mut st.ev, &zeros, false);
        let mut i = 0;
        for (ci, c) in self.ocp.nodal.iter().enumerate() {
            let per_node = match c.kind {
                NodalKind::Inequality => c.function.n_outputs(),
                NodalKind::Ball { .. } => 1,
            };
            // One report per distinct entry name, else one for the whole constraint: each
            // entry's report.
            let first = out.len();
            let mut slot = Vec::with_capacity(per_node);
            for o in 0..per_node {
                let name = c.output_names.get(o).unwrap_or(&c.name);
                match out[first..].iter().position(|v| v.constraint.name() == name) {
                    Some(i) => slot.push(first + i),
                    None => {
                        slot.push(out.len());
                        out.push(Violation {
                            constraint: ConstraintRef::Nodal { constraint: ci, name: name.clone() },
                            value: 0.0,
                            node: None,
                            time: None,
                        });
                    }
                }
            }
            if slot.is_empty() {
                out.push(Violation {
                    constraint: ConstraintRef::Nodal { constraint: ci, name: c.name.clone() },
                    value: 0.0,
                    node: None,
                    time: None,
                });
            }
            for &k in &c.nodes {
                for &o in &slot {
                    let worst = &mut out[o];
                    if st.ev.violation[i] > worst.value || worst.node.is_none() {
                        worst.value = worst.value.max(st.ev.violation[i]);
                        worst.node = Some(k);
                    }
                    i += 1;
                }
            }
        }
        // Interval bounds: the worst peak of each state row over the segments (the node is
        // the segment's first).
        self.eval_peaks(&st.dbar, &mut st.ev, &zeros, GridAt::Reference);
        let nb = self.buffers.len();
        // The worst peak of each interval constraint likewise.
        // (One entry per state row or interval constraint, whichever output.)
        let key = |of: PeakOf| match of {
            PeakOf::State(r) => (0, r),
            PeakOf::Function { c, .. } => (1, c),
        };
        let mut keys: Vec<(u8, usize)> = self.peaks.iter().map(|p| key(p.of)).collect();
        keys.sort_unstable();
        keys.dedup();
        for k in keys {
            let constraint = match k {
                (0, state) => ConstraintRef::StateBoundsBetweenNodes {
                    state,
                    name: self.ocp.dynamics.state_name(state).unwrap_or("state").to_string(),
                },
                (_, c) => ConstraintRef::BetweenNodes {
                    constraint: c,
                    name: self.ocp.interval_constraints[c].name.clone(),
                },
            };
            let mut worst = Violation { constraint, value: 0.0, node: None, time: None };
            for (i, p) in self.peaks.iter().enumerate().filter(|(_, p)| key(p.of) == k) {
                let v = st.ev.violation[nb + i];
                if v > worst.value || worst.node.is_none() {
                    (worst.value, worst.node) = (v, Some(p.seg));
                }
            }
            out.push(worst);
        }
        out
    }
}
