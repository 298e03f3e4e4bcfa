//! The honest report: every constraint the problem holds in continuous time, evaluated on
//! the dense trajectory after the solve — the path constraints (`.ctcs()`, over their node
//! ranges), the between-nodes constraints, the state bounds when they are held between
//! the nodes ([`Problem::state_bounds_ctcs`](crate::Problem::state_bounds_ctcs)), and the
//! nodes' own conditions on the re-integrated motion ([`nodes_on_dense`]). The PTR
//! loop sees these only through integrals and peak rows; a solve whose dense trajectory
//! breaks one by more than [`PtrSettings::dense_tolerance`](crate::PtrSettings) is not
//! reported converged.

use armature_symbolic::Function;

use crate::{ConstraintRef, DenseTrajectory, Ocp, ProblemError, Violation};

/// A vector function `g(x, u) ≤ 0` held from node `first` to node `last`.
#[derive(Debug, Clone)]
pub(crate) struct PathCheck {
    pub(crate) name: String,
    pub(crate) function: Function,
    pub(crate) first: usize,
    pub(crate) last: usize,
}

/// A state row's bounds, held at every instant.
#[derive(Debug, Clone)]
pub(crate) struct BoundCheck {
    /// `name[i]` (or the state's name when it is a scalar).
    pub(crate) name: String,
    pub(crate) row: usize,
    pub(crate) min: f64,
    pub(crate) max: f64,
}

/// Everything checked on the dense trajectory.
#[derive(Debug, Clone, Default)]
pub(crate) struct DenseChecks {
    pub(crate) paths: Vec<PathCheck>,
    pub(crate) bounds: Vec<BoundCheck>,
}

/// The worst value over the samples: (value, sample).
fn worst(values: impl Iterator<Item = (f64, usize)>) -> Option<(f64, usize)> {
    values.fold(None, |best, (v, j)| match best {
        Some((b, _)) if b >= v => best,
        _ => Some((v, j)),
    })
}

impl DenseChecks {
    /// The largest violation of each check on `dense` (n states, m controls per sample),
    /// with the time of the worst sample; `node_times` maps node ranges to times. Values are
    /// the positive part of `g` (or the distance outside the bounds), 0 when the check holds.
    ///
    /// # Errors
    /// A check's evaluation failure, naming it.
    pub(crate) fn violations(
        &self,
        dense: &DenseTrajectory,
        (n, m): (usize, usize),
        node_times: &[f64],
    ) -> Result<Vec<Violation>, ProblemError> {
        let samples = dense.time.len();
        let x = |j: usize| &dense.x[j * n..(j + 1) * n];
        let mut out = Vec::with_capacity(self.paths.len() + self.bounds.len());
        for b in &self.bounds {
            let excess = (0..samples).map(|j| {
                let v = x(j)[b.row];
                (if v.is_nan() { f64::INFINITY } else { (v - b.max).max(b.min - v).max(0.0) }, j)
            });
            let name = format!("bounds of {}", b.name);
            out.push(violation(ConstraintRef::Dense { name }, worst(excess), dense));
        }
        let mut input = vec![0.0; n + m];
        for c in &self.paths {
            let mut ws = c.function.workspace();
            let mut values = vec![0.0; c.function.n_outputs()];
            // The samples within the node range (a small slack for the rounding of times).
            let (t0, t1) = (node_times[c.first], node_times[c.last]);
            let slack = 1e-12 * (1.0 + t1.abs());
            let mut best: Option<(f64, usize)> = None;
            for j in
                (0..samples).filter(|&j| dense.time[j] >= t0 - slack && dense.time[j] <= t1 + slack)
            {
                input[..n].copy_from_slice(x(j));
                input[n..].copy_from_slice(&dense.u[j * m..(j + 1) * m]);
                c.function.eval(&input, &mut ws, &mut values, None).map_err(|source| {
                    ProblemError::Symbolic {
                        what: format!("constraint \"{}\" on the dense trajectory", c.name),
                        source,
                    }
                })?;
                // NaN is a violation (f64::max would drop it).
                let v = if values.iter().any(|v| v.is_nan()) {
                    f64::INFINITY
                } else {
                    values.iter().copied().fold(0.0, f64::max)
                };
                best = worst(best.into_iter().chain(std::iter::once((v, j))));
            }
            out.push(violation(ConstraintRef::Dense { name: c.name.clone() }, best, dense));
        }
        Ok(out)
    }
}

/// The nodes' own conditions on the dense re-integration (from the initial state, through
/// the controls and dilations alone): each nodal constraint of `ocp` evaluated at its nodes
/// with the re-integrated states at those instants (and the nodes' controls), and each fixed
/// final value against the re-integrated final state. The solver holds its dynamics on its
/// own integration grid, and these conditions at its node values; this is what they are on
/// the motion the controls produce. Reported as `NAME, re-integrated` and
/// `final value of STATE, re-integrated`, at the node's instant (its segment: the one that
/// ends there); values as in [`DenseChecks::violations`].
///
/// # Errors
/// A constraint's evaluation failure, naming it.
pub(crate) fn nodes_on_dense(
    ocp: &Ocp,
    dense: &DenseTrajectory,
    u_nodes: &[f64],
) -> Result<Vec<Violation>, ProblemError> {
    let (n, m) = (ocp.dynamics.n_x(), ocp.dynamics.n_u());
    // Each node's sample: the first, then each segment's last (the steps divide each segment
    // evenly, so it is the segment's end node).
    let mut at_node = vec![0];
    at_node.extend(
        (1..dense.segment.len())
            .filter(|&j| dense.segment.get(j + 1).is_none_or(|&next| next != dense.segment[j])),
    );
    let x = |j: usize| &dense.x[j * n..(j + 1) * n];
    let mut out = Vec::with_capacity(ocp.nodal.len() + n);
    let mut input = vec![0.0; n + m];
    for c in &ocp.nodal {
        let mut ws = c.function.workspace();
        let mut values = vec![0.0; c.function.n_outputs()];
        let mut best: Option<(f64, usize)> = None;
        for &k in c.nodes.iter().filter(|&&k| k < at_node.len() && (k + 1) * m <= u_nodes.len()) {
            let j = at_node[k];
            input[..n].copy_from_slice(x(j));
            input[n..].copy_from_slice(&u_nodes[k * m..(k + 1) * m]);
            c.function.eval(&input, &mut ws, &mut values, None).map_err(|source| {
                ProblemError::Symbolic {
                    what: format!("constraint \"{}\" on the re-integrated nodes", c.name),
                    source,
                }
            })?;
            let excess = c.kind.excess(&values).max(0.0);
            let v = if values.iter().any(|v| v.is_nan()) { f64::INFINITY } else { excess };
            best = worst(best.into_iter().chain(std::iter::once((v, j))));
        }
        let name = format!("{}, re-integrated", c.name);
        out.push(violation(ConstraintRef::Dense { name }, best, dense));
    }
    let last = *at_node.last().unwrap_or(&0);
    for (row, fixed) in ocp.x_final.iter().enumerate() {
        let Some(value) = fixed else { continue };
        let d = (x(last)[row] - value).abs();
        let w = Some((if d.is_nan() { f64::INFINITY } else { d }, last));
        let state = ocp.dynamics.state_name(row).unwrap_or("state");
        let name = format!("final value of {state}, re-integrated");
        out.push(violation(ConstraintRef::Dense { name }, w, dense));
    }
    Ok(out)
}

fn violation(
    constraint: ConstraintRef,
    w: Option<(f64, usize)>,
    dense: &DenseTrajectory,
) -> Violation {
    let (value, j) = w.unwrap_or((0.0, 0));
    Violation {
        constraint,
        value,
        node: dense.segment.get(j).copied(),
        time: w.map(|_| dense.time[j]),
    }
}
