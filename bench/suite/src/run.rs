//! Solving the suite with default settings, verifying each result, and the table.

use std::collections::BTreeMap;
use std::time::Instant;

use armature_arm::{ArmError, KeptStage, Pipeline, Retimed, Solved};
use armature_scvx::PtrStatus;
use nalgebra::Matrix3;
use serde::Serialize;

use crate::generate::SuiteTask;
use crate::verify::{self, Accelerations, Checks, Robot, TOLERANCE};

/// One task's outcome.
#[derive(Debug, Clone, Serialize)]
pub struct Outcome {
    /// Group.
    pub group: String,
    /// Task name.
    pub name: String,
    /// The solver's status word, or the planning error.
    pub status: String,
    /// SCvx iterations.
    pub iterations: usize,
    /// Final time (s).
    pub final_time: f64,
    /// Wall time of planning and solving (ms).
    pub solve_ms: f64,
    /// The verification's largest violation and what it is.
    pub worst: f64,
    /// Which constraint.
    pub worst_what: String,
    /// Converged by the solver's word and verified independently.
    pub verified: bool,
    /// Built infeasible, and why.
    pub infeasible: Option<String>,
    /// The solution at the nodes (kept for the reference's export).
    #[serde(skip)]
    pub solution: Option<NodeSolution>,
    /// The solver's iteration records (both stages' with `--refine`).
    #[serde(skip)]
    pub history: Vec<armature_scvx::Iteration>,
}

/// A solution at its nodes.
#[derive(Debug, Clone)]
pub struct NodeSolution {
    /// Node times (s).
    pub times: Vec<f64>,
    /// Joint angles per node.
    pub angles: Vec<Vec<f64>>,
    /// Torques per node.
    pub torques: Vec<Vec<f64>>,
}

/// What the verification checks for a task.
pub fn checks(t: &SuiteTask) -> Checks {
    let task = &t.task;
    let (q_lo, q_hi) = task.chain.position_limits();
    let quat = |q: [f64; 4]| {
        *nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            q[0], q[1], q[2], q[3],
        ))
        .to_rotation_matrix()
        .matrix()
    };
    Checks {
        robot: t.robot,
        q_lo,
        q_hi,
        qd_max: task.velocity_limit.clone(),
        tau_max: task.torque_limit.clone(),
        waypoints: task
            .waypoints
            .iter()
            .map(|w| (w.node, nalgebra::Vector3::from(w.position), w.tolerance))
            .collect(),
        orientation: task
            .orientation
            .iter()
            .map(|o| -> (Matrix3<f64>, f64, usize, usize) {
                (quat(o.quaternion_wxyz), o.tolerance_deg.to_radians(), o.first, o.last)
            })
            .collect(),
        table: task.table_height,
        balls: t.balls.clone(),
        link_pairs: task.collision.as_ref().map_or_else(Vec::new, |c| {
            let links = |p: &armature_collision::Pair| match p.kind {
                armature_collision::PairKind::Links(a, b) => Some((a, b)),
                armature_collision::PairKind::LinkObstacle(..) => None,
            };
            c.model.pairs().iter().filter_map(links).collect()
        }),
        margin: task.collision.as_ref().map_or(0.0, |c| c.margin),
    }
}

/// The verification's dynamics for a task.
pub fn accelerations(t: &SuiteTask) -> Box<dyn Accelerations> {
    match &t.task.dynamics {
        armature_arm::DynamicsModel::DecoupledInertia(i) => Box::new(verify::Decoupled(i.clone())),
        armature_arm::DynamicsModel::RigidBody { gravity } => {
            let model = armature_kinematics::RigidBodyModel::new(&t.task.chain, *gravity)
                .expect("a planned rigid-body task has a model");
            let ws = model.workspace();
            Box::new(verify::RigidBody(model, ws))
        }
    }
}

/// Plans, solves and verifies one task.
pub fn run_one(t: &SuiteTask) -> Outcome {
    let mut out = Outcome {
        group: t.group.into(),
        name: t.name.clone(),
        status: String::new(),
        iterations: 0,
        final_time: f64::NAN,
        solve_ms: 0.0,
        worst: f64::INFINITY,
        worst_what: String::new(),
        verified: false,
        infeasible: t.infeasible.map(String::from),
        solution: None,
        history: Vec::new(),
    };
    let start = Instant::now();
    // The pipeline as the CLI runs it (starts, fallbacks, refinement, retiming).
    let pipeline = Pipeline { refine: Some(t.refine), retime: t.retime };
    let solved = match t.task.solve(pipeline) {
        Ok(s) => s,
        Err(e) => {
            out.status = format!("error: {e}");
            out.solve_ms = start.elapsed().as_secs_f64() * 1e3;
            return out;
        }
    };
    out.solve_ms = start.elapsed().as_secs_f64() * 1e3;
    out.iterations = iterations(&solved);
    let Solved { solution, task, retimed, refinement, .. } = solved;
    // A refined solve is verified on its own grid (waypoints and ranges at its nodes).
    let refined;
    let t = match refinement.map(|r| r.kept) {
        Some(KeptStage::Refined) => {
            refined = SuiteTask { task, ..t.clone() };
            &refined
        }
        _ => t,
    };
    out.status = format!("{:?}", solution.status);
    out.history = solution.history.clone();
    out.final_time = solution.final_time;
    let nodes = &solution.nodes;
    let times: Vec<f64> = nodes["time"].iter().map(|r| r[0]).collect();
    let mut acc = accelerations(t);
    let dense = verify::reintegrate(
        acc.as_mut(),
        &times,
        (&nodes["torque"], solution.control_ends.get("torque").map(Vec::as_slice)),
        &nodes["angle"][0],
        &nodes["velocity"][0],
    );
    let worst = verify::check(&checks(t), &dense, &times);
    out.worst = worst.value;
    out.worst_what = worst.what;
    out.verified = solution.status == PtrStatus::Converged && worst.value <= TOLERANCE;
    if let (true, Some(retimed)) = (out.verified, retimed) {
        verify_retimed(t, retimed, &mut out);
    }
    out.solution = Some(NodeSolution {
        times,
        angles: nodes["angle"].clone(),
        torques: nodes["torque"].clone(),
    });
    out
}

/// The outcome of the solution retimed along its path (`ArmTask::retime`, by the pipeline),
/// verified as such: its final time and its largest violation.
fn verify_retimed(t: &SuiteTask, retimed: Result<Retimed, ArmError>, out: &mut Outcome) {
    match retimed {
        Ok(r) => {
            let worst = crate::retimed::verify_retimed(t, &r);
            out.final_time = r.final_time;
            out.worst = worst.value;
            out.worst_what = format!("{} (retimed)", worst.what);
            out.verified = worst.value <= TOLERANCE;
        }
        Err(e) => {
            out.status = format!("retiming failed: {e}");
            out.verified = false;
        }
    }
}

/// The iterations a result took: every solve's (fallbacks, both stages of a refinement,
/// kept or not) but the starts not kept of a multi-start solve, which ran beside the kept one.
fn iterations(solved: &Solved) -> usize {
    let beside = solved.starts.as_ref().map_or(0, |r| {
        r.each.iter().enumerate().filter(|(i, _)| *i != r.kept).map(|(_, s)| s.iterations).sum()
    });
    solved.total_iterations - beside
}

fn percentile(v: &mut [f64], p: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * p).round() as usize]
}

/// The table: per group and over all feasible tasks. `t_ref` holds the verified reference
/// final time of the tasks that have one; T / T_ref is over the tasks verified on both sides.
pub fn table(outcomes: &[Outcome], t_ref: &BTreeMap<String, f64>) -> String {
    let mut s = String::from(
        "| group | tasks | converged + verified | iterations median / p90 / max | T median (s) | T / T_ref median / max (tasks) | solve median / p90 (ms) |\n|---|---|---|---|---|---|---|\n",
    );
    let mut groups: Vec<&str> = outcomes.iter().map(|o| o.group.as_str()).collect();
    groups.dedup();
    let feasible: Vec<&Outcome> = outcomes.iter().filter(|o| o.infeasible.is_none()).collect();
    let mut rows: Vec<(String, Vec<&Outcome>)> = groups
        .iter()
        .filter(|g| **g != "infeasible")
        .map(|g| (g.to_string(), feasible.iter().copied().filter(|o| o.group == *g).collect()))
        .collect();
    rows.push(("all feasible".into(), feasible.clone()));
    for (name, os) in rows {
        let n = os.len();
        let ok = os.iter().filter(|o| o.verified).count();
        let mut it: Vec<f64> = os.iter().map(|o| o.iterations as f64).collect();
        let mut tf: Vec<f64> =
            os.iter().filter(|o| o.final_time.is_finite()).map(|o| o.final_time).collect();
        let mut ms: Vec<f64> = os.iter().map(|o| o.solve_ms).collect();
        let mut ratio: Vec<f64> = os
            .iter()
            .filter(|o| o.verified)
            .filter_map(|o| t_ref.get(&o.name).map(|r| o.final_time / r))
            .collect();
        let ratio_cell = if ratio.is_empty() {
            "–".to_string()
        } else {
            let median = percentile(&mut ratio, 0.5);
            format!("{median:.3} / {:.3} ({})", percentile(&mut ratio, 1.0), ratio.len())
        };
        s += &format!(
            "| {name} | {n} | {ok} ({:.0} %) | {:.0} / {:.0} / {:.0} | {:.3} | {ratio_cell} | {:.0} / {:.0} |\n",
            100.0 * ok as f64 / n.max(1) as f64,
            percentile(&mut it.clone(), 0.5),
            percentile(&mut it, 0.9),
            os.iter().map(|o| o.iterations).max().unwrap_or(0),
            percentile(&mut tf, 0.5),
            percentile(&mut ms.clone(), 0.5),
            percentile(&mut ms, 0.9),
        );
    }
    let infeasible: Vec<&Outcome> = outcomes.iter().filter(|o| o.infeasible.is_some()).collect();
    if !infeasible.is_empty() {
        s += "\n| infeasible task | built so because | outcome |\n|---|---|---|\n";
        for o in infeasible {
            s += &format!(
                "| {} | {} | {} |\n",
                o.name,
                o.infeasible.as_deref().unwrap_or(""),
                o.status
            );
        }
    }
    s
}

/// The robot of a group, for the README.
pub fn robot_name(r: Robot) -> &'static str {
    match r {
        Robot::Arm7 => "arm7",
        Robot::Ur5e => "ur5e",
        Robot::Iiwa7 => "iiwa7",
    }
}
