//! The task as an SCvx problem: states, controls and dynamics, then the task's constraints
//! on the forward kinematics.

use armature_lie::SO3;
use armature_scvx::{
    Ball, BetweenNodes, Control, CtcsOptions, Penalty, Problem, ProblemConstraint, Sampling, State,
};
use armature_symbolic::{Expr, Shape};

use crate::dynamics::Resolved;
use crate::guess::Guess;
use crate::{ArmTask, Clearance, waypoint_parameter};

/// The states (angles, velocities), the torques and the dynamics `q̈ = τ / I`, with their
/// bounds, boundary values and guesses.
pub(crate) fn states_and_dynamics(task: &ArmTask, dynamics: &Resolved, guess: &Guess) -> Problem {
    let (chain, nodes) = (&task.chain, task.nodes);
    let n = chain.dof();
    let (ik, spline, duration) = (&guess.ik, &guess.spline, guess.duration);
    let (velocity_limit, torque_limit) = (&task.velocity_limit, &task.torque_limit);
    let (qlo, qhi) = chain.position_limits();
    let angle = State::new("angle", n)
        .bounds(&qlo, &qhi)
        .initial_value(&ik.q[0])
        .guess(ik.q.iter().flatten().copied().collect());
    let angle = if task.angle_limit_peaks { angle.with_interval_bounds() } else { angle };
    let velocity = State::new("velocity", n)
        .bounds(&velocity_limit.iter().map(|v| -v).collect::<Vec<_>>(), velocity_limit)
        .initial_value(&vec![0.0; n])
        .final_value(&vec![0.0; n])
        .guess((0..nodes).flat_map(|k| spline.velocity(k, duration)).collect());
    let velocity =
        if task.velocity_limit_peaks { velocity.with_interval_bounds() } else { velocity };
    let qd: Vec<Vec<f64>> = (0..nodes).map(|k| spline.velocity(k, duration)).collect();
    let qdd: Vec<Vec<f64>> = (0..nodes).map(|k| spline.acceleration(k, duration)).collect();
    let tau_guess = dynamics.torques(&ik.q, &qd, &qdd);
    let torque = Control::new("torque", n)
        .bounds(&torque_limit.iter().map(|t| -t).collect::<Vec<_>>(), torque_limit)
        .guess(
            tau_guess
                .iter()
                .flat_map(|t| t.iter().zip(torque_limit).map(|(t, l)| t.clamp(-l, *l)))
                .collect(),
        );
    let torque = if task.time_scaled_torque { torque.with_time_scaling() } else { torque };
    let qdd_expr = dynamics.acceleration(&angle.expr(), &velocity.expr(), &torque.expr());
    Problem {
        dynamics: vec![velocity.expr(), qdd_expr],
        states: vec![angle, velocity],
        controls: vec![torque],
        // Velocity limits the motion rides: a row per grid point is smooth where a segment's
        // peak row hops between points from one iteration to the next.
        interval_bounds_sampling: Sampling::GridPoints,
        ..Problem::new(nodes)
    }
}

/// The task's constraints on the forward kinematics of `problem`'s angles: waypoint balls,
/// orientation ranges, the table, clearances; and the outputs (end-effector pose, frames,
/// clearances).
///
/// # Errors
/// The symbolic forward kinematics' (for the robot).
pub(crate) fn add_task_constraints(problem: &mut Problem, t: &ArmTask) -> Result<(), String> {
    let chain = &t.chain;
    let nodes = problem.nodes;
    let fk = chain.symbolic_fk(&problem.states[0].expr()).map_err(|e| e.to_string())?;
    let p_ee = fk.ee_position();
    // The limits' integral budget per segment: the angle limits, the table and, without
    // velocity rows (the rigid-body model's default), the velocity limits. Alone it must keep
    // the velocities within 1e-4 of their limits between the nodes: at 1e-6 a tenth of the
    // suite's tasks ended 1-4e-4 over, at 1e-7 those converge (BENCHMARKS.md, 2026-12-04);
    // 1e-7 left the UR5e rigid-body demo 1.001e-4 rad/s over, 3e-8 holds it at 9e-5 or less
    // and leaves every suite task's T as it was (2026-12-05, night).
    // Velocities with rows at every grid point stay out of it (`Problem::state_bounds_ctcs`):
    // its kink where the motion rides the limit kept the trajectories 5 % slower
    // (2026-12-05, night).
    let limits = CtcsOptions { penalty: Penalty::Relu, eps: 3e-8, group: 0 };
    let mut constraints: Vec<ProblemConstraint> = Vec::new();
    let mut between_nodes = Vec::new();
    if let Some(h) = t.table_height {
        constraints.push(ProblemConstraint {
            constraint: (Expr::scalar(h) - p_ee.at(2)).le(0.0).ctcs().named("table"),
            ctcs: limits,
        });
    }
    let mut balls: Vec<Ball> = t
        .waypoints
        .iter()
        .map(|p| Ball {
            name: format!("waypoint {}", p.name),
            g: &p_ee - Expr::parameter(&waypoint_parameter(&p.name), Shape::Vector(3), &p.position),
            radius: p.tolerance,
            nodes: vec![p.node],
        })
        .collect();
    for o in &t.orientation {
        let r = SO3::from_quaternion_wxyz(o.quaternion_wxyz).map_err(|e| e.to_string())?;
        let (deg, first, last, name) = (o.tolerance_deg, o.first, o.last, &o.name);
        let log = Expr::from_matrix(&r.matrix().transpose()).matmul(&fk.ee_rotation()).so3_log();
        // Held at every point of the integration grid (the parabola through each point and
        // its neighbours, with a bound on its cubic error, catching what lies between them;
        // `Sampling::GridPoints`): a CTCS integral of the angle
        // leaves it 1e-2 rad out between the nodes, and one peak row per segment zig-zags
        // (BENCHMARKS.md). The squared form is smooth where the gripper is exactly on target
        // and equals the angle's excess to first order at the bound.
        let tol = deg.to_radians();
        if last > first {
            between_nodes.push(BetweenNodes {
                name: format!("orientation {name} within {deg}°"),
                g: (log.dot(&log) - tol * tol) * (0.5 / tol),
                first,
                last,
                activation: None,
                sampling: Sampling::GridPoints,
            });
        }
        balls.push(Ball {
            name: format!("orientation {name} within {deg}° at the nodes"),
            g: log,
            radius: deg.to_radians(),
            nodes: (first..=last).collect(),
        });
    }
    let mut outputs =
        vec![("ee_position".to_string(), p_ee.clone()), ("ee_pose".to_string(), fk.t_ee.clone())];
    for (name, frame) in &fk.frames {
        outputs.push((format!("T_{name}"), frame.clone()));
    }
    if let Some(Clearance { model, margin, between_nodes_activation: activation }) = &t.collision {
        let positions: Vec<Expr> = fk.positions.iter().map(|(_, p)| p.clone()).collect();
        let distances = model.symbolic_distances(&positions);
        if !distances.is_empty() {
            // Every pair's signed distance, in the model's pair order (the 3D view's readout).
            let all: Vec<Expr> = distances.iter().map(|(_, d)| d.clone()).collect();
            outputs.push(("clearance".to_string(), Expr::concat(&all)));
        }
        if let (Some(activation), false) = (activation, distances.is_empty()) {
            between_nodes.push(BetweenNodes {
                name: "clearance".into(),
                g: Expr::concat(&distances.iter().map(|(_, d)| *margin - d).collect::<Vec<_>>()),
                first: 0,
                last: nodes - 1,
                activation: Some(*activation),
                sampling: Sampling::Peak,
            });
        }
        for (pair, d) in distances {
            constraints.push(ProblemConstraint {
                constraint: (*margin - &d).le(0.0).ctcs().named(format!("clearance {pair}")),
                // An integral of its own: summed into the limits' integral, the clearance
                // violations of single pairs are drowned and the solve stalls.
                ctcs: CtcsOptions { group: 1, ..limits },
            });
            constraints.push(
                (*margin - &d).le(0.0).named(format!("clearance {pair} at the nodes")).into(),
            );
        }
    }
    problem.constraints = constraints;
    problem.balls = balls;
    problem.between_nodes = between_nodes;
    problem.outputs = outputs;
    problem.state_bounds_ctcs = Some(limits);
    Ok(())
}
