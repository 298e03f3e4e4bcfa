//! Retiming a solved trajectory: the same path in space, at the fastest speed along it that
//! the velocity and torque limits allow ([`ArmTask::retime`]).

mod path;
mod rows;
mod stall;
mod topp;

use std::collections::BTreeMap;

use armature_scvx::Solution;
use serde::Serialize;

use self::path::Model;
pub use self::stall::RetimeStall;
use self::topp::ToppFailure;
use crate::dynamics::Resolved;
use crate::node_tables::NodeTables;
use crate::{ArmError, ArmTask, TaskItem};

/// Series by name, one row per node (or per segment end), as a solution's tables hold them.
type Tables = BTreeMap<String, Vec<Vec<f64>>>;

/// A trajectory retimed along its path: samples at the points of the retiming grid (about
/// 2000, closer in time where the arm moves slowly), each with its time, angles, velocities,
/// accelerations and torques.
///
/// Every sample lies on the solved path (the angles are the path's, only their times
/// change), so what the path satisfies — waypoints, orientation ranges, the table, clearances,
/// angle limits — still holds; the velocities and torques hold their limits at every sample,
/// the torques on both sides of it (the path acceleration `s̈` is constant between samples
/// and the torque jumps there).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Retimed {
    /// The final time (s).
    pub final_time: f64,
    /// When the path passes each node of the solution (s).
    pub node_times: Vec<f64>,
    /// Sample times (s), from 0.
    pub time: Vec<f64>,
    /// Joint angles per sample (rad).
    pub angle: Vec<Vec<f64>>,
    /// Joint velocities per sample (rad/s).
    pub velocity: Vec<Vec<f64>>,
    /// Joint accelerations at each sample, with the path acceleration of the interval that
    /// starts there (rad/s²). The path acceleration is constant over each interval; the
    /// joints' accelerations vary within it with the path's shape (`q″ṡ² + q′s̈`).
    pub acceleration: Vec<Vec<f64>>,
    /// Joint torques at each sample, as its acceleration needs them (N·m); within the limits
    /// there and, by the rows at both ends of every interval, in between.
    pub torque: Vec<Vec<f64>>,
}

impl ArmTask {
    /// The solved trajectory `solution` of this task retimed: its path, re-integrated from
    /// its initial state under its torques, followed time-optimally within the task's
    /// velocity and torque limits (TOPP-RA: a backward pass of controllable speeds, a forward
    /// pass of the largest path accelerations), from rest to rest. The limits hold at the
    /// samples (about 2000); where the torque between two of them, as the motion there asks
    /// it, would leave a limit, the grid is doubled (twice at most).
    ///
    /// A solve's final time is that of its control parametrization (first-order-hold
    /// torques on the task's nodes); along the same path the limits usually allow a faster
    /// timing, which this finds in about a millisecond.
    ///
    /// # Errors
    /// [`TaskItem::Solution`] when `solution` lacks the arm's node tables (`time`, `angle`,
    /// `velocity`, `torque`) or they do not fit the arm, when it does not start and end at
    /// rest, or when its path cannot be followed within the limits; the task's own errors
    /// for a dynamics model or limits that do not fit the chain.
    ///
    /// # Example
    /// ```
    /// let seed = armature_arm::fixtures::pick_and_place();
    /// let solution = seed.plan()?.compile()?.solve()?;
    /// let retimed = seed.retime(&solution)?;
    /// assert!(retimed.final_time < solution.final_time);
    /// assert_eq!(retimed.node_times.len(), seed.nodes);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn retime(&self, solution: &Solution) -> Result<Retimed, ArmError> {
        let ends = Some(&solution.control_ends);
        self.retime_tables((&solution.nodes, ends), path::POINTS, MIDPOINT_REFINEMENTS)
    }

    /// The final time of the trajectory whose node tables are `nodes` (`time`, `angle`,
    /// `velocity`, `torque`: a solution's, or an iterate's from
    /// [`SolutionLayout::nodal_series`](armature_scvx::SolutionLayout::nodal_series)), with
    /// its torques where each segment ends in `control_ends` (a solution's, or
    /// [`SolutionLayout::nodal_control_ends`](armature_scvx::SolutionLayout::nodal_control_ends);
    /// `None`: each next node's), retimed
    /// along its path as [`retime`](Self::retime) does, on a grid of about `points` points
    /// (at least 4 per segment; `retime` samples about 2000): a coarser grid estimates the
    /// same time at a fraction of the cost, to follow a solve's progress.
    ///
    /// # Errors
    /// As [`retime`](Self::retime).
    pub fn retimed_final_time(
        &self,
        nodes: &Tables,
        control_ends: Option<&Tables>,
        points: usize,
    ) -> Result<f64, ArmError> {
        self.retime_tables((nodes, control_ends), points, 0).map(|r| r.final_time)
    }

    /// [`retime`](Self::retime) of the node tables `nodes` on about `points` points, the grid
    /// doubled up to `refinements` times while the torque between two samples leaves a limit
    /// ([`midpoint_torque_excess`]).
    fn retime_tables(
        &self,
        (nodes, ends): (&Tables, Option<&Tables>),
        points: usize,
        refinements: usize,
    ) -> Result<Retimed, ArmError> {
        let n = self.chain.dof();
        let resolved = Resolved::new(&self.dynamics, &self.chain)?;
        let limits_fit = |l: &[f64]| l.len() == n && l.iter().all(|v| v.is_finite() && *v > 0.0);
        if !limits_fit(&self.velocity_limit) {
            return Err(ArmError::new(TaskItem::VelocityLimit, format!("{n} limits > 0 needed")));
        }
        if !limits_fit(&self.torque_limit) {
            return Err(ArmError::new(TaskItem::TorqueLimit, format!("{n} limits > 0 needed")));
        }
        let bad = |m: String| ArmError::new(TaskItem::Solution, m);
        let nodes = NodeTables::new(nodes, ends, n).map_err(bad)?;
        if !nodes.at_rest() {
            return Err(bad("retiming needs a trajectory from rest to rest".into()));
        }
        let mut model = Model::new(&resolved);
        let mut points = points;
        for round in 0..=refinements {
            let retimed = self.retime_on(&mut model, &nodes, points)?;
            if round == refinements
                || midpoint_torque_excess(&mut model, &retimed, &self.torque_limit) <= 0.0
            {
                return Ok(retimed);
            }
            points *= 2;
        }
        unreachable!("the last round returns")
    }

    /// The retiming of `nodes`' path on a grid of about `points` points.
    fn retime_on(
        &self,
        model: &mut Model<'_>,
        nodes: &NodeTables<'_>,
        points: usize,
    ) -> Result<Retimed, ArmError> {
        let bad = |m: String| ArmError::new(TaskItem::Solution, m);
        let path = path::sample(model, nodes, points);
        let delta: Vec<f64> = path.sigma.windows(2).map(|w| w[1] - w[0]).collect();
        let coef = rows::torque_coefficients(model, &path);
        let finite = |t: &[Vec<f64>]| t.iter().flatten().all(|x| x.is_finite());
        if !(finite(&path.q) && finite(&path.dq) && finite(&path.ddq))
            || coef.iter().flatten().flatten().any(|x| !x.is_finite())
        {
            return Err(bad("the re-integrated path is not finite".into()));
        }
        let stages = rows::stages(&path, &coef, &delta, &self.velocity_limit, &self.torque_limit);
        let profile = topp::time_optimal(&stages, &delta).map_err(|f| {
            let at = |i: usize| path.sigma[i.min(path.sigma.len() - 1)];
            bad(match f {
                ToppFailure::Uncontrollable(i) => format!(
                    "the path cannot be followed within the torque limits at t = {:.3} s",
                    at(i)
                ),
                ToppFailure::StartNotAtRest => "the path cannot start from rest".into(),
                ToppFailure::Stalls(i) => format!("the retimed path stops at t = {:.3} s", at(i)),
            })
        })?;
        Ok(samples(&path, &coef, &profile))
    }
}

/// How often [`ArmTask::retime`] doubles its grid at most when the torque between two samples
/// leaves a limit: the rows hold it at the samples, and between them it follows the path's
/// curvature, which on a fine mesh (a refined solve's 13 to 41 nodes) took an iiwa7 task
/// 6e-3 N·m over a limit at 2000 points and not at 2400 (BENCHMARKS.md, 2026-12-07).
const MIDPOINT_REFINEMENTS: usize = 2;

/// The largest excess over its limit of a joint torque between two samples of `r`, as the
/// motion there asks it: at each interval's midpoint, the mean of its ends' angles and
/// velocities with the velocities' difference quotient as the acceleration (≤ 0: within).
fn midpoint_torque_excess(model: &mut Model<'_>, r: &Retimed, limits: &[f64]) -> f64 {
    let n = limits.len();
    let (mut q, mut v, mut a, mut tau) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut worst = f64::NEG_INFINITY;
    for i in 0..r.time.len() - 1 {
        let dt = r.time[i + 1] - r.time[i];
        for j in 0..n {
            q[j] = 0.5 * (r.angle[i][j] + r.angle[i + 1][j]);
            v[j] = 0.5 * (r.velocity[i][j] + r.velocity[i + 1][j]);
            a[j] = (r.velocity[i + 1][j] - r.velocity[i][j]) / dt;
        }
        model.torque(&q, &v, &a, &mut tau);
        worst = tau.iter().zip(limits).map(|(t, l)| t.abs() - l).fold(worst, f64::max);
    }
    // A non-finite torque counts as an excess.
    if worst.is_nan() { f64::INFINITY } else { worst }
}

/// The retimed samples of `path` under `profile`.
fn samples(
    path: &path::PathSamples,
    coef: &rows::Coefficients,
    profile: &topp::Profile,
) -> Retimed {
    let points = path.q.len();
    let mut out = Retimed {
        final_time: profile.t[points - 1],
        node_times: path.nodes.iter().map(|&i| profile.t[i]).collect(),
        time: profile.t.clone(),
        angle: path.q.clone(),
        velocity: Vec::with_capacity(points),
        acceleration: Vec::with_capacity(points),
        torque: Vec::with_capacity(points),
    };
    for i in 0..points {
        let (x, u) = (profile.x[i].max(0.0), profile.u[i.min(points - 2)]);
        let speed = x.sqrt();
        let (dq, ddq) = (&path.dq[i], &path.ddq[i]);
        out.velocity.push(dq.iter().map(|d| d * speed).collect());
        out.acceleration.push(dq.iter().zip(ddq).map(|(d, dd)| dd * x + d * u).collect());
        out.torque.push(coef[i].iter().map(|[a, b, c, _]| a * u + b * x + c).collect());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_grid_whose_torque_leaves_a_limit_between_samples_is_refined() {
        let seed = crate::fixtures::pick_and_place();
        let solution = seed.plan().unwrap().compile().unwrap().solve().unwrap();
        let resolved = Resolved::new(&seed.dynamics, &seed.chain).unwrap();
        let excess =
            |r: &Retimed| midpoint_torque_excess(&mut Model::new(&resolved), r, &seed.torque_limit);
        // On 200 points the seed's torque passes a limit between two samples (by 1e-2 N·m,
        // 6e-3 on 300): a doubling holds it.
        let tables = (&solution.nodes, Some(&solution.control_ends));
        let coarse = seed.retime_tables(tables, 200, 0).unwrap();
        assert!(excess(&coarse) > 0.0);
        let refined = seed.retime_tables(tables, 200, 3).unwrap();
        assert!(excess(&refined) <= 0.0);
        assert!(refined.time.len() > coarse.time.len());
        assert!((refined.final_time - coarse.final_time).abs() < 1e-2 * coarse.final_time);
        // A grid that holds it stays as it is.
        let fine = seed.retime_tables(tables, 1600, 0).unwrap();
        assert!(excess(&fine) <= 0.0);
        assert_eq!(seed.retime_tables(tables, 1600, 3).unwrap(), fine);
        assert!(excess(&seed.retime(&solution).unwrap()) <= 0.0);
    }
}
