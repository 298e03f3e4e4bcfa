//! A solve's result by name: [`Solution`], and the [`SolutionLayout`] that names flat
//! trajectories (and evaluates the outputs) independently of the solver.

use super::*;

/// How flat state, control and output vectors map to names; evaluates the algebraic outputs.
/// Cloned from [`CompiledProblem::layout`], it names trajectories independently of the
/// solver (e.g. in an observer while the solve runs).
#[derive(Debug, Clone)]
pub struct SolutionLayout {
    pub(super) states: Vec<Block>,
    pub(super) controls: Vec<Block>,
    pub(super) outputs: Vec<Block>,
    pub(super) output_fn: Option<Function>,
    pub(super) n: usize,
    pub(super) m: usize,
    pub(super) holds: ControlHolds,
}

/// A solve's result by name, with stable top-level keys (scripts depend on them).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Solution {
    /// `"converged"` or why it stopped (`"max_iterations"`, `"stalled"`,
    /// `"subproblem_infeasible"`, `"numerical_failure"`).
    pub status: PtrStatus,
    /// Final time (s).
    pub final_time: f64,
    /// SCvx iterations.
    pub iterations: usize,
    /// At the nodes: `time`, every state, control and algebraic output by name, each as
    /// rows (one per node; matrix outputs row-major).
    pub nodes: BTreeMap<String, Vec<Vec<f64>>>,
    /// Every control by name at the end of each segment (N − 1 rows): on segment k a
    /// first-order-hold control runs linearly from `nodes[name][k]` to
    /// `control_ends[name][k]`. That is the next node's value, except for a time-scaled
    /// control ([`Control::time_scaled`](crate::Control#structfield.time_scaled)), which
    /// jumps at a node where the segments' durations change (its node table holds the value
    /// where each segment starts), and a zero-order-hold one (its value at the start).
    pub control_ends: BTreeMap<String, Vec<Vec<f64>>>,
    /// The same on the dense trajectory (single shooting from the initial state at
    /// `dense_dt`, first-order-hold controls).
    pub trajectory: BTreeMap<String, Vec<Vec<f64>>>,
    /// Per-iteration records.
    pub history: Vec<Iteration>,
    /// Wall-clock totals (ms), with the post-processing.
    pub timings: SolutionTimings,
    /// Largest violation of every constraint: at the nodes (dynamics per state component,
    /// nodal constraints, balls, the CTCS integrals), then on the dense trajectory (each
    /// constraint held in continuous time, named `… (dense)`, with the instant in `time`).
    pub violations: Vec<Violation>,
    /// The largest positive violation, if any.
    pub max_violation: Option<Violation>,
    /// The exact-penalty prices and the trust-region weight the solve ended with: what the
    /// same task on another grid can start from ([`Ptr::set_starting_prices`](crate::Ptr::set_starting_prices)).
    /// Not serialized.
    #[serde(skip)]
    pub prices: crate::Prices,
}

/// Wall-clock totals of a solve (ms).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct SolutionTimings {
    /// Discretizations.
    pub discretization_ms: f64,
    /// Convex subproblems.
    pub subproblem_ms: f64,
    /// The whole SCvx loop.
    pub solve_ms: f64,
    /// Dense propagation and output evaluation.
    pub post_processing_ms: f64,
}

impl SolutionLayout {
    /// Name → rows for the samples `times` with states `x` (rows of n, the CTCS integrals
    /// included) and controls `u` (rows of m): `time`, every state and control, every output.
    ///
    /// # Errors
    /// Buffers that do not match the layout; an output evaluation failure.
    pub fn tables(
        &self,
        times: &[f64],
        x: &[f64],
        u: &[f64],
    ) -> Result<BTreeMap<String, Vec<Vec<f64>>>, ProblemError> {
        let mut t = self.series(times, x, u)?;
        let (n, m) = (self.n, self.m);
        if let Some(f) = &self.output_fn {
            let mut ws = f.workspace();
            let mut input = vec![0.0; n + m];
            let mut values = vec![0.0; f.n_outputs()];
            let mut cols: Vec<Vec<Vec<f64>>> =
                vec![Vec::with_capacity(times.len()); self.outputs.len()];
            for (xr, ur) in x.chunks(n).zip(u.chunks(m.max(1))) {
                input[..n].copy_from_slice(xr);
                input[n..].copy_from_slice(&ur[..m]);
                f.eval(&input, &mut ws, &mut values, None).map_err(sym("outputs"))?;
                for (col, b) in cols.iter_mut().zip(&self.outputs) {
                    col.push(values[b.offset..b.offset + b.size].to_vec());
                }
            }
            for (col, b) in cols.into_iter().zip(&self.outputs) {
                t.insert(b.name.clone(), col);
            }
        }
        Ok(t)
    }

    /// As [`tables`](Self::tables) without the outputs: `time`, every state and control.
    ///
    /// # Errors
    /// Buffers that do not match the layout.
    pub fn series(
        &self,
        times: &[f64],
        x: &[f64],
        u: &[f64],
    ) -> Result<BTreeMap<String, Vec<Vec<f64>>>, ProblemError> {
        let (n, m) = (self.n, self.m);
        if x.len() != times.len() * n || u.len() != times.len() * m {
            return Err(bad(
                "trajectory",
                format!(
                    "{} samples need {} state and {} control values, got {} and {}",
                    times.len(),
                    times.len() * n,
                    times.len() * m,
                    x.len(),
                    u.len()
                ),
            ));
        }
        let mut t = BTreeMap::new();
        t.insert("time".to_string(), times.iter().map(|&v| vec![v]).collect());
        let rows = |data: &[f64], width: usize, b: &Block| -> Vec<Vec<f64>> {
            data.chunks(width).map(|r| r[b.offset..b.offset + b.size].to_vec()).collect()
        };
        for b in &self.states {
            t.insert(b.name.clone(), rows(x, n, b));
        }
        for b in &self.controls {
            t.insert(b.name.clone(), rows(u, m, b));
        }
        Ok(t)
    }

    /// Name → rows of every control for flat control rows `u` (rows of m).
    pub(crate) fn control_series(&self, u: &[f64]) -> BTreeMap<String, Vec<Vec<f64>>> {
        let m = self.m.max(1);
        self.controls
            .iter()
            .map(|b| {
                let rows = u.chunks(m).map(|r| r[b.offset..b.offset + b.size].to_vec());
                (b.name.clone(), rows.collect())
            })
            .collect()
    }

    /// Name → rows for samples given by name (e.g. a trajectory retimed outside the solver):
    /// every state and control of the layout is read from `series` (one row of its width
    /// per sample), the CTCS integrals are zero, and every output is evaluated, as
    /// [`tables`](Self::tables) does. Series of `series` the layout does not name are left
    /// out.
    ///
    /// # Errors
    /// A state or control missing from `series`, or with a row count or width that does not
    /// fit; an output evaluation failure.
    pub fn tables_named(
        &self,
        times: &[f64],
        series: &BTreeMap<String, Vec<Vec<f64>>>,
    ) -> Result<BTreeMap<String, Vec<Vec<f64>>>, ProblemError> {
        let fill = |blocks: &[Block], width: usize| -> Result<Vec<f64>, ProblemError> {
            let mut flat = vec![0.0; times.len() * width];
            for b in blocks {
                let rows = series
                    .get(&b.name)
                    .ok_or_else(|| bad("trajectory", format!("no series `{}`", b.name)))?;
                if rows.len() != times.len() || rows.iter().any(|r| r.len() != b.size) {
                    return Err(bad(
                        "trajectory",
                        format!("`{}` needs {} rows of {}", b.name, times.len(), b.size),
                    ));
                }
                for (row, r) in flat.chunks_mut(width.max(1)).zip(rows) {
                    row[b.offset..b.offset + b.size].copy_from_slice(r);
                }
            }
            Ok(flat)
        };
        let x = fill(&self.states, self.n)?;
        let u = fill(&self.controls, self.m)?;
        self.tables(times, &x, &u)
    }

    /// Named tables of a nodal trajectory (e.g. the current iterate in an observer).
    ///
    /// # Errors
    /// As [`tables`](Self::tables).
    pub fn nodal_tables(
        &self,
        t: &Trajectory<'_>,
    ) -> Result<BTreeMap<String, Vec<Vec<f64>>>, ProblemError> {
        self.tables(&node_times(t), t.x, &self.holds.profile(t.u, t.s).starts)
    }

    /// As [`nodal_tables`](Self::nodal_tables) without the outputs (`time`, every state and
    /// control): what a monitor reads from each iterate, without evaluating the outputs.
    ///
    /// # Errors
    /// As [`series`](Self::series).
    pub fn nodal_series(
        &self,
        t: &Trajectory<'_>,
    ) -> Result<BTreeMap<String, Vec<Vec<f64>>>, ProblemError> {
        self.series(&node_times(t), t.x, &self.holds.profile(t.u, t.s).starts)
    }

    /// Every control of a nodal trajectory by name at the end of each segment, as
    /// [`Solution::control_ends`].
    pub fn nodal_control_ends(&self, t: &Trajectory<'_>) -> BTreeMap<String, Vec<Vec<f64>>> {
        self.control_series(&self.holds.profile(t.u, t.s).ends)
    }
}

/// The node times of a nodal trajectory, from its dilations.
fn node_times(t: &Trajectory<'_>) -> Vec<f64> {
    let dtau = 1.0 / (t.nodes.max(2) - 1) as f64;
    let mut times = vec![0.0; t.nodes];
    for k in 1..t.nodes {
        times[k] = times[k - 1] + t.s[k - 1] * dtau;
    }
    times
}

impl Solution {
    /// Rows of `name` at the nodes (`None` if there is no such series).
    pub fn at_nodes(&self, name: &str) -> Option<&[Vec<f64>]> {
        self.nodes.get(name).map(Vec::as_slice)
    }

    /// Rows of `name` on the dense trajectory.
    pub fn dense(&self, name: &str) -> Option<&[Vec<f64>]> {
        self.trajectory.get(name).map(Vec::as_slice)
    }

    /// Whether the solve converged.
    pub fn converged(&self) -> bool {
        self.status == PtrStatus::Converged
    }
}
