//! A finer grid's guess from a coarser grid's solution: the second stage of a mesh
//! refinement ([`ArmTask::refined`](crate::ArmTask::refined)).

use std::collections::{BTreeMap, HashMap};

use armature_scvx::{CompiledProblem, PricedRow, Prices, ProblemError, Solution};

use crate::node_tables::NodeTables;

type Table = Vec<Vec<f64>>;

/// Sets the guess of `fine` — the same task [`refined`](crate::ArmTask::refined) (or
/// [`subdivided`](crate::ArmTask::subdivided)) by `factor` — from `coarse`'s solution: the
/// coarse nodes keep their values; a new node between nodes `k` and `k + 1` at fraction `w`
/// of the segment takes the dense trajectory's angles and velocities at its instant (cubic
/// Hermite in the angles, linear in the velocities, between the two dense samples around
/// it) and the torques `(1 − w)·u_k + w·u_{k+1}` of the coarse first-order hold, which the
/// finer hold represents exactly; each segment's duration is split evenly. The guess is
/// then the coarse trajectory itself, up to the dense samples' interpolation. The refined
/// stage also starts from `coarse`'s exact-penalty prices, mapped to the finer grid's rows
/// ([`Solution::prices`], [`REFINED_TRUST_REGION_WEIGHT`]).
///
/// # Errors
/// [`ProblemError::Bad`] when `coarse` lacks the arm's tables (`time`, `angle`, `velocity`,
/// `torque` at the nodes and on the dense trajectory), has fewer than two nodes, or
/// `factor` is 0; the problem layer's when `fine` does not have `(N − 1)·factor + 1` nodes
/// of the same arm.
///
/// # Example
/// ```
/// let seed = armature_arm::fixtures::pick_and_place();
/// let coarse = seed.plan()?.compile()?.solve()?;
/// let mut fine = seed.refined(2).plan()?.compile()?;
/// armature_arm::set_refined_guess(&mut fine, &coarse, 2)?;
/// let solution = fine.solve()?;
/// assert!(solution.final_time < coarse.final_time);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn set_refined_guess(
    fine: &mut CompiledProblem,
    coarse: &Solution,
    factor: usize,
) -> Result<(), ProblemError> {
    let c = Coarse::new(coarse)?;
    if factor == 0 {
        return Err(bad("a factor of 0"));
    }
    let nf = (c.times.len() - 1) * factor + 1;
    let (mut angle, mut velocity, mut torque) = (Vec::new(), Vec::new(), Vec::new());
    let mut dilation = Vec::with_capacity(nf);
    for j in 0..nf {
        let k = (j / factor).min(c.times.len() - 2);
        let w = (j - k * factor) as f64 / factor as f64;
        if w == 0.0 || w == 1.0 {
            let node = if w == 0.0 { k } else { k + 1 };
            angle.extend_from_slice(&c.q[node]);
            velocity.extend_from_slice(&c.v[node]);
            torque.extend_from_slice(&c.u[node]);
        } else {
            c.dense_at(c.times[k] + w * (c.times[k + 1] - c.times[k]), &mut angle, &mut velocity);
            torque.extend(c.u[k].iter().zip(&c.u_end[k]).map(|(a, b)| (1.0 - w) * a + w * b));
        }
        dilation.push((nf - 1) as f64 * (c.times[k + 1] - c.times[k]) / factor as f64);
    }
    fine.set_guess("angle", &angle)?;
    fine.set_guess("velocity", &velocity)?;
    fine.set_guess("torque", &torque)?;
    fine.set_dilation_guess(&dilation)?;
    carry_prices(fine, &coarse.prices, factor);
    Ok(())
}

/// The trust-region weight a refined stage starts with, its prices carried from the coarse
/// stage. Its first steps are then held back by what they would buy, not by the trust
/// region: on the suite's arm7-0* tasks any weight from 0.001 to 0.015 ends within 0.2 % of
/// the same final times in the same iterations, where the carried final weight of the
/// coarse stage left two rigid-body tasks 7–10 % slower (BENCHMARKS.md).
pub const REFINED_TRUST_REGION_WEIGHT: f64 = 0.004;

/// The coarse solve's exact-penalty prices as the refined stage's starting prices: a row at
/// coarse node `k` is the fine row at node `k·factor` (a fine node between two coarse ones
/// takes the larger of theirs), a bound between the nodes on coarse segment `j` prices it
/// on each of the fine segments it was split into; the dynamics rows' carry over as they
/// are, and the trust region starts at [`REFINED_TRUST_REGION_WEIGHT`]. Without them, the
/// refined stage's first steps bought buffers at their starting price (from the converged
/// coarse path, T 6 % lower, violations 6e-2) and its next iterations paid them back
/// (BENCHMARKS.md).
/// A coarse solution without prices (built by hand, or read back from a file) leaves the
/// refined stage the settings' prices and trust region.
fn carry_prices(fine: &mut CompiledProblem, coarse: &Prices, factor: usize) {
    if coarse.rows.is_empty() && coarse.state_rows.is_empty() {
        fine.ptr().set_starting_prices(&[], |_| None, None);
        return;
    }
    let by_row: HashMap<PricedRow, f64> = coarse.rows.iter().copied().collect();
    let at = |row: PricedRow| by_row.get(&row).copied();
    let price = |row: PricedRow| match row {
        PricedRow::Nodal { constraint, node, output } => {
            let coarse_node = |k| at(PricedRow::Nodal { constraint, node: k, output });
            let here = coarse_node(node / factor);
            let next = (node % factor != 0).then(|| coarse_node(node / factor + 1)).flatten();
            match (here, next) {
                (Some(a), Some(b)) => Some(a.max(b)),
                (a, b) => a.or(b),
            }
        }
        PricedRow::BetweenNodes { bound, segment } => {
            at(PricedRow::BetweenNodes { bound, segment: segment / factor })
        }
    };
    let trust = Some(REFINED_TRUST_REGION_WEIGHT);
    fine.ptr().set_starting_prices(&coarse.state_rows, price, trust);
}

fn bad(reason: impl Into<String>) -> ProblemError {
    ProblemError::Bad { what: "refined guess".into(), reason: reason.into() }
}

/// The tables of a coarse arm solution that the refined guess reads, checked.
struct Coarse<'a> {
    times: Vec<f64>,
    q: &'a Table,
    v: &'a Table,
    u: &'a Table,
    /// The torques where each segment ends.
    u_end: Table,
    dense_t: Vec<f64>,
    dq: &'a Table,
    dv: &'a Table,
}

impl<'a> Coarse<'a> {
    fn new(s: &'a Solution) -> Result<Self, ProblemError> {
        let table = |t: &'a BTreeMap<String, Table>, name: &str| {
            t.get(name).ok_or_else(|| bad(format!("the coarse solution has no \"{name}\"")))
        };
        let column = |t: &Table| t.iter().filter_map(|r| r.first().copied()).collect::<Vec<_>>();
        let width = s.nodes.get("angle").and_then(|t| t.first()).map_or(0, Vec::len);
        let nodes = NodeTables::new(&s.nodes, Some(&s.control_ends), width).map_err(bad)?;
        let dense = &s.trajectory;
        let c = Coarse {
            times: nodes.times,
            q: nodes.q,
            v: nodes.v,
            u: nodes.u,
            u_end: nodes.u_end,
            dense_t: column(table(dense, "time")?),
            dq: table(dense, "angle")?,
            dv: table(dense, "velocity")?,
        };
        let d = c.dense_t.len();
        let rows_ok = |t: &Table| t.len() == d && t.iter().all(|r| r.len() == width);
        if d < 2 {
            return Err(bad("the coarse solution needs two dense samples or more"));
        }
        if !(rows_ok(c.dq) && rows_ok(c.dv)) {
            return Err(bad(
                "the coarse solution's dense angle and velocity tables differ in shape",
            ));
        }
        Ok(c)
    }

    /// Angles (cubic Hermite with the velocities as slopes) and velocities (linear) of the
    /// dense trajectory at `t`, appended.
    fn dense_at(&self, t: f64, angle: &mut Vec<f64>, velocity: &mut Vec<f64>) {
        let i = self.dense_t.partition_point(|&s| s <= t).clamp(1, self.dense_t.len() - 1);
        let (t0, t1) = (self.dense_t[i - 1], self.dense_t[i]);
        let h = t1 - t0;
        let s = if h > 0.0 { ((t - t0) / h).clamp(0.0, 1.0) } else { 0.0 };
        let (h00, h10) = (2.0 * s.powi(3) - 3.0 * s * s + 1.0, s.powi(3) - 2.0 * s * s + s);
        let (h01, h11) = (-2.0 * s.powi(3) + 3.0 * s * s, s.powi(3) - s * s);
        let (q0, q1, v0, v1) = (&self.dq[i - 1], &self.dq[i], &self.dv[i - 1], &self.dv[i]);
        for c in 0..q0.len() {
            angle.push(h00 * q0[c] + h10 * h * v0[c] + h01 * q1[c] + h11 * h * v1[c]);
            velocity.push((1.0 - s) * v0[c] + s * v1[c]);
        }
    }
}

/// What a mesh refinement keeps ([`keep_refined`]): the two stages joined, or the first
/// stage's result when the refined stage did not converge.
#[derive(Debug, Clone)]
pub enum Refinement {
    /// The refined stage converged: both stages as one solution ([`join_stages`]).
    Refined(Solution),
    /// The refined stage did not converge: the first stage's solution, unchanged, and the
    /// refined stage's (its status, violations and iterations say why and at what cost).
    KeptFirstStage {
        /// The first stage's solution.
        first: Solution,
        /// The refined stage's solution, not kept.
        refined: Box<Solution>,
    },
}

impl Refinement {
    /// The kept solution.
    pub fn solution(&self) -> &Solution {
        match self {
            Refinement::Refined(s) | Refinement::KeptFirstStage { first: s, .. } => s,
        }
    }

    /// The kept solution, by value.
    pub fn into_solution(self) -> Solution {
        match self {
            Refinement::Refined(s) | Refinement::KeptFirstStage { first: s, .. } => s,
        }
    }
}

/// A refinement never loses a converged result: the refined stage `fine` is kept (joined to
/// `coarse`, [`join_stages`]) when it converged, otherwise `coarse` is (a refined stage can
/// fail where the first converged: the finer grid's rows are new constraints, and its walk
/// another one; the suite saw one such task of 162, BENCHMARKS.md).
///
/// # Example
/// ```
/// use armature_arm::Refinement;
///
/// let seed = armature_arm::fixtures::pick_and_place();
/// let coarse = seed.plan()?.compile()?.solve()?;
/// let mut capped = seed.refined(2);
/// capped.settings.max_iterations = 2;
/// let mut fine = capped.plan()?.compile()?;
/// armature_arm::set_refined_guess(&mut fine, &coarse, 2)?;
/// match armature_arm::keep_refined(coarse.clone(), fine.solve()?) {
///     Refinement::KeptFirstStage { first, refined } => {
///         assert_eq!(first.final_time, coarse.final_time);
///         assert!(!refined.converged());
///     }
///     Refinement::Refined(_) => panic!("two iterations do not converge a refined stage"),
/// }
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn keep_refined(coarse: Solution, fine: Solution) -> Refinement {
    if fine.converged() {
        Refinement::Refined(join_stages(&coarse, fine))
    } else {
        Refinement::KeptFirstStage { first: coarse, refined: Box::new(fine) }
    }
}

/// The outcome of a two-stage solve as one [`Solution`]: the refined stage's trajectory,
/// status and violations, with the iterations, the history (the refined stage's records
/// numbered on from the coarse stage's) and the timings of both stages.
///
/// # Example
/// ```
/// let seed = armature_arm::fixtures::pick_and_place();
/// let coarse = seed.plan()?.compile()?.solve()?;
/// let mut fine = seed.refined(2).plan()?.compile()?;
/// armature_arm::set_refined_guess(&mut fine, &coarse, 2)?;
/// let both = armature_arm::join_stages(&coarse, fine.solve()?);
/// assert_eq!(both.history.len(), both.iterations);
/// assert!(both.final_time < coarse.final_time);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn join_stages(coarse: &Solution, mut fine: Solution) -> Solution {
    let mut history = coarse.history.clone();
    history.extend(fine.history.drain(..).map(|mut it| {
        it.iteration += coarse.iterations;
        it
    }));
    fine.history = history;
    fine.iterations += coarse.iterations;
    let (t, c) = (&mut fine.timings, &coarse.timings);
    t.discretization_ms += c.discretization_ms;
    t.subproblem_ms += c.subproblem_ms;
    t.solve_ms += c.solve_ms;
    t.post_processing_ms += c.post_processing_ms;
    fine
}
