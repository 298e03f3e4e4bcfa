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
    /// pass of the largest path accelerations), from rest to rest.
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
        self.retime_tables(&solution.nodes, path::POINTS)
    }

    /// The final time of the trajectory whose node tables are `nodes` (`time`, `angle`,
    /// `velocity`, `torque`: a solution's, or an iterate's from
    /// [`SolutionLayout::nodal_series`](armature_scvx::SolutionLayout::nodal_series)) retimed
    /// along its path as [`retime`](Self::retime) does, on a grid of about `points` points
    /// (at least 4 per segment; `retime` samples about 2000): a coarser grid estimates the
    /// same time at a fraction of the cost, to follow a solve's progress.
    ///
    /// # Errors
    /// As [`retime`](Self::retime).
    pub fn retimed_final_time(
        &self,
        nodes: &BTreeMap<String, Vec<Vec<f64>>>,
        points: usize,
    ) -> Result<f64, ArmError> {
        self.retime_tables(nodes, points).map(|r| r.final_time)
    }

    /// [`retime`](Self::retime) of the node tables `nodes` on about `points` points.
    fn retime_tables(
        &self,
        nodes: &BTreeMap<String, Vec<Vec<f64>>>,
        points: usize,
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
        let nodes = NodeTables::new(nodes, n).map_err(bad)?;
        if !nodes.at_rest() {
            return Err(bad("retiming needs a trajectory from rest to rest".into()));
        }
        let mut model = Model::new(&resolved);
        let path = path::sample(&mut model, &nodes, points);
        let delta: Vec<f64> = path.sigma.windows(2).map(|w| w[1] - w[0]).collect();
        let coef = rows::torque_coefficients(&mut model, &path);
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
        out.torque.push(coef[i].iter().map(|[a, b, c]| a * u + b * x + c).collect());
    }
    out
}
