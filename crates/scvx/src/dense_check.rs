//! The honest report: every constraint the problem holds in continuous time, evaluated on
//! the dense trajectory after the solve — the path constraints (`.ctcs()`, over their node
//! ranges), the between-nodes constraints, the state bounds when they are held between
//! the nodes ([`Problem::state_bounds_ctcs`](crate::Problem::state_bounds_ctcs)), and how
//! far the re-integrated states land from the node states ([`node_drift`]). The PTR
//! loop sees these only through integrals and peak rows; a solve whose dense trajectory
//! breaks one by more than [`PtrSettings::dense_tolerance`](crate::PtrSettings) is not
//! reported converged.

use armature_symbolic::Function;

use crate::{ConstraintRef, DenseTrajectory, ProblemError, Violation};

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

/// How far the dense re-integration (from the initial state, through the controls and
/// dilations alone) lands from the solution's own node states: for each of the first `rows`
/// state rows (the problem's states, not the CTCS integrals), the largest
/// `|x_dense(t_k) − x_k|` over the nodes k ≥ 1, named `re-integration of NAME`, at the node's
/// instant (its segment: the one that ends there). The solver holds its dynamics on its own
/// integration grid; this is that grid's error as the dense trajectory sees it — at the last
/// node, how far from its final condition the re-integrated motion ends.
pub(crate) fn node_drift(
    dense: &DenseTrajectory,
    x_nodes: &[f64],
    (n, rows): (usize, usize),
    name: impl Fn(usize) -> String,
) -> Vec<Violation> {
    // A segment's last sample is its end node (the steps divide each segment evenly).
    let ends: Vec<(usize, usize)> = (1..dense.segment.len())
        .filter(|&j| dense.segment.get(j + 1).is_none_or(|&next| next != dense.segment[j]))
        .map(|j| (j, dense.segment[j] + 1))
        .filter(|&(_, k)| (k + 1) * n <= x_nodes.len())
        .collect();
    (0..rows)
        .map(|row| {
            let drift = ends.iter().map(|&(j, k)| {
                let d = (dense.x[j * n + row] - x_nodes[k * n + row]).abs();
                (if d.is_nan() { f64::INFINITY } else { d }, j)
            });
            let name = format!("re-integration of {}", name(row));
            violation(ConstraintRef::Dense { name }, worst(drift), dense)
        })
        .collect()
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
