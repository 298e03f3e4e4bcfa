//! The seed tutorial's 7-DOF pick-and-place, built from `kinematics` symbolic FK with the
//! seed's numbers and the IK initial guess (shared by the test and the example).
//!
//! Modeling choices (each checked by the acceptance test):
//! - The state box, velocity box and table constraints form one CTCS group integrating
//!   `max(0, g)` with ε = 1e-6 per segment: the linear penalty keeps its gradient as the
//!   violation shrinks, so a small ε stays well conditioned, and the dense trajectory meets
//!   the limits.
//! - The orientation constraints are CTCS groups as in the seed (squared ReLU, ε = 1e-4) and,
//!   as OpenSCvx's `check_nodally`, nodal second-order-cone constraints at the nodes of
//!   their ranges.
//! - [`Variant::interval_bounds`] adds the velocity bounds between the nodes (see
//!   [`Ocp::interval_bounds`]): at the optimum the velocities touch their bounds inside
//!   segments, where the CTCS integral's linearization has no gradient; without the peak
//!   rows first-order PTR stops on a short step far from the optimum (T ≈ 1.55 s against
//!   ≈ 1.28 s), at an iteration count that swings with any setting.
//! - Waypoints are nodal balls `‖p_ee − w‖ ≤ 1 cm` (second-order cones in the subproblem).
//! - The guess is the IK path, time-parameterized by a clamped cubic spline whose interval
//!   lengths follow the joint moves: dynamically consistent (zero defects) from the start.

#![allow(dead_code, unreachable_pub)]

use armature_ik::{IkSettings, JointSpline, Keyframe, Mode, ik_interpolation};
use armature_kinematics::{Chain, robots};
use armature_lie::SO3;
use armature_scvx::{
    CtcsGroup, Dynamics, NodalConstraint, NodalKind, Ocp, Penalty, PtrResult, ctcs_states,
};
use armature_symbolic::{Expr, Function, Shape};
use std::f64::consts::FRAC_1_SQRT_2;

/// Nodes (2 per segment).
pub const NODES: usize = 11;
/// Joint inertias.
pub const INERTIA: [f64; 7] = [0.08, 0.06, 0.05, 0.04, 0.02, 0.01, 0.005];
/// Torque limits.
pub const TORQUE: [f64; 7] = [8.0, 8.0, 4.0, 4.0, 2.0, 1.0, 0.5];
/// Velocity limit.
pub const VELOCITY: f64 = 3.0;
/// Gripper down: Ry(90°).
pub const Q_DOWN: [f64; 4] = [FRAC_1_SQRT_2, 0.0, FRAC_1_SQRT_2, 0.0];
/// Waypoints (position, orientation) at nodes 0, 2, …, 10.
pub const WAYPOINTS: [([f64; 3], [f64; 4]); 6] = [
    ([0.69, 0.0, 0.34], [1.0, 0.0, 0.0, 0.0]),
    ([0.35, -0.25, 0.2], Q_DOWN),
    ([0.35, -0.25, 0.05], Q_DOWN),
    ([0.35, -0.25, 0.2], Q_DOWN),
    ([0.35, 0.25, 0.2], Q_DOWN),
    ([0.35, 0.25, 0.05], Q_DOWN),
];
/// Orientation bounds: (degrees, nodes).
pub fn orientation_ranges() -> [(f64, Vec<usize>); 2] {
    [(5.0, (2..=10).collect()), (0.1, (2..=6).chain(8..=10).collect())]
}

/// Clearance the collision variant asks of every pair (m): the CTCS integral with ε = 1e-6
/// lets the trajectory dip ~0.3 mm below its bound between nodes, so the bound keeps 2 mm.
pub const CLEARANCE_MARGIN: f64 = 0.002;

/// Activation distance of the clearances' peak rows (m): a segment's rows are in the
/// subproblem only while some pair there comes within 2 cm of its margin.
pub const CLEARANCE_ACTIVATION: f64 = 0.02;

/// Name of the parameter holding waypoint `w`'s position.
pub fn waypoint_parameter(w: usize) -> String {
    format!("waypoint_{w}")
}

/// The problem and its guess.
#[derive(Debug)]
pub struct Seed {
    pub arm: Chain,
    pub ocp: Ocp,
    pub x: Vec<f64>,
    pub u: Vec<f64>,
    pub s: Vec<f64>,
}

/// Builds the seed problem and its guess.
pub fn build() -> Seed {
    build_with(Variant::default())
}

/// The seed's collision variant: capsules base–shoulder 0.06, shoulder–elbow 0.05,
/// elbow–wrist 0.04, wrist–ee 0.035, non-adjacent self-collision and the ball at
/// (0.35, 0, 0.25) r = 0.06, as exact pair distances from `armature-collision`, kept ≥ 0 in
/// continuous time (a CTCS group) and at every node.
pub fn build_collision() -> Seed {
    build_with(Variant { collision: true, ..Variant::default() })
}

/// Which version of the seed problem to build.
#[derive(Debug, Clone, Copy, Default)]
pub struct Variant {
    /// The collision extension ([`build_collision`]).
    pub collision: bool,
    /// The velocity bounds also enforced between the nodes at each segment's peak
    /// ([`Ocp::interval_bounds`]), with the box group's CTCS budget at ε = 1e-5: the peak
    /// rows hold the bound, so the integral only has to catch what lies between the
    /// integration grid's points.
    pub interval_bounds: bool,
    /// With `collision`: the clearances only as their CTCS integral and at the nodes, without
    /// their peak rows between the nodes ([`Ocp::interval_constraints`]) — the formulation
    /// before those rows, kept for the regression tests whose cases it produced.
    pub without_clearance_peaks: bool,
}

/// The seed problem in the given variant.
pub fn build_with(variant: Variant) -> Seed {
    let Variant { collision, interval_bounds, without_clearance_peaks } = variant;
    let arm = robots::arm7();
    let nodes = NODES;
    let angle = Expr::variable("angle", 7);
    let velocity = Expr::variable("velocity", 7);
    let torque = Expr::variable("torque", 7);
    let i_inv = Expr::constant_vector(&INERTIA.map(|i| 1.0 / i));
    let fk = arm.symbolic_fk(&angle).unwrap();
    let p_ee = fk.ee_position();
    let (qlo, qhi) = arm.position_limits();
    let vmax = Expr::constant_vector(&[VELOCITY; 7]);
    let down = SO3::from_quaternion_wxyz(Q_DOWN).unwrap();
    let r_des_t = Expr::from_matrix(&down.matrix().transpose());
    let log = r_des_t.matmul(&fk.ee_rotation()).so3_log();
    let ori = log.norm2();
    let [(loose, loose_nodes), (tight, _)] = orientation_ranges();
    let ori_group = |deg: f64, first: usize, last: usize| CtcsGroup {
        constraints: vec![&ori - deg.to_radians()],
        first,
        last,
        penalty: Penalty::SquaredRelu,
    };
    let mut groups = vec![
        CtcsGroup {
            constraints: vec![
                &angle - Expr::constant_vector(&qhi),
                Expr::constant_vector(&qlo) - &angle,
                &velocity - &vmax,
                -&vmax - &velocity,
                -p_ee.at(2),
            ],
            first: 0,
            last: nodes - 1,
            penalty: Penalty::Relu,
        },
        ori_group(loose, 2, 10),
        ori_group(tight, 2, 6),
        ori_group(tight, 8, 10),
    ];
    let mut eps = vec![if interval_bounds { 1e-5 } else { 1e-6 }, 1e-4, 1e-4, 1e-4];
    let distances = if collision {
        let model = armature_collision::CollisionModel::seed_arm7(&arm).unwrap();
        let positions: Vec<Expr> = fk.positions.iter().map(|(_, p)| p.clone()).collect();
        model.symbolic_distances(&positions)
    } else {
        Vec::new()
    };
    if collision {
        groups.push(CtcsGroup {
            constraints: distances.iter().map(|(_, d)| CLEARANCE_MARGIN - d).collect(),
            first: 0,
            last: nodes - 1,
            penalty: Penalty::Relu,
        });
        eps.push(1e-6);
    }
    let mut states = vec![angle.clone(), velocity.clone()];
    let mut rhs = vec![velocity.clone(), &i_inv * &torque];
    for (y, f) in ctcs_states(&groups) {
        states.push(y);
        rhs.push(f);
    }
    let mut dynamics = Dynamics::new(&states, &[torque.clone()], &rhs, &[true; 7]).unwrap();
    for (i, g) in groups.iter().enumerate() {
        dynamics = dynamics.gate(14 + i, g.first, g.last).unwrap();
    }
    let n = 14 + groups.len();
    let n_groups = groups.len();
    let args = [states.as_slice(), &[torque.clone()]];
    let mut nodal = Vec::new();
    for (w, (p, _)) in WAYPOINTS.iter().enumerate() {
        nodal.push(NodalConstraint {
            name: format!("waypoint {w}"),
            // A parameter: moving a waypoint re-solves without recompiling.
            function: Function::compile(
                &[&p_ee - Expr::parameter(&waypoint_parameter(w), Shape::Vector(3), p)],
                &args,
            )
            .unwrap(),
            nodes: vec![2 * w],
            kind: NodalKind::Ball { radius: 0.01 },
            output_names: Vec::new(),
        });
    }
    // Every pair's `margin − d ≤ 0` in one function: the pairs share the forward kinematics.
    let clearance = (!distances.is_empty()).then(|| {
        let g: Vec<Expr> = distances.iter().map(|(_, d)| CLEARANCE_MARGIN - d).collect();
        Function::compile(&[Expr::concat(&g)], &args).unwrap()
    });
    if let Some(function) = &clearance {
        nodal.push(NodalConstraint {
            name: "clearance".into(),
            function: function.clone(),
            nodes: (0..nodes).collect(),
            kind: NodalKind::Inequality,
            output_names: distances.iter().map(|(pair, _)| format!("clearance {pair}")).collect(),
        });
    }
    let log_f = Function::compile(&[log], &args).unwrap();
    for (deg, nodes) in orientation_ranges() {
        nodal.push(NodalConstraint {
            name: format!("orientation {deg}°"),
            function: log_f.clone(),
            nodes,
            kind: NodalKind::Ball { radius: deg.to_radians() },
            output_names: Vec::new(),
        });
    }
    debug_assert_eq!(loose_nodes.len(), 9);
    // The IK path through the keyframes, time-parameterized by a spline.
    let keyframes: Vec<Keyframe> = WAYPOINTS
        .iter()
        .enumerate()
        .map(|(w, (p, q))| Keyframe { node: 2 * w, position: *p, quaternion_wxyz: Some(*q) })
        .collect();
    let ik = ik_interpolation(
        &arm,
        &keyframes,
        &[0.0; 7],
        &IkSettings { restarts: 8, ..IkSettings::default() },
        Mode::Sequential,
    )
    .unwrap();
    let knots = JointSpline::time_optimal_knots(&ik.q, &[VELOCITY; 7]).unwrap();
    let spline = JointSpline::through_timed(&ik.q, &knots).unwrap();
    let amax: Vec<f64> = (0..7).map(|j| TORQUE[j] / INERTIA[j]).collect();
    let duration = spline.min_duration(&[VELOCITY; 7], &amax).clamp(0.5, 4.0);
    let mut x = vec![0.0; nodes * n];
    let mut u = vec![0.0; nodes * 7];
    for k in 0..nodes {
        x[k * n..k * n + 7].copy_from_slice(&ik.q[k]);
        x[k * n + 7..k * n + 14].copy_from_slice(&spline.velocity(k, duration));
        for (j, a) in spline.acceleration(k, duration).iter().enumerate() {
            u[k * 7 + j] = a * INERTIA[j];
        }
    }
    // Dilation per segment: its share of the duration (Δτ = 1/(N − 1)).
    let mut s: Vec<f64> = knots.iter().map(|h| h * duration * (nodes - 1) as f64).collect();
    s.push(s[nodes - 2]);
    let mut x_min = qlo.clone();
    x_min.extend([-VELOCITY; 7]);
    x_min.extend(vec![0.0; n_groups]);
    let mut x_max = qhi.clone();
    x_max.extend([VELOCITY; 7]);
    x_max.extend(vec![1e-3; n_groups]);
    let mut x_initial: Vec<Option<f64>> = ik.q[0].iter().map(|&v| Some(v)).collect();
    x_initial.extend(vec![Some(0.0); 7 + n_groups]);
    let mut x_final: Vec<Option<f64>> = vec![None; 7];
    x_final.extend([Some(0.0); 7]);
    x_final.extend(vec![None; n_groups]);
    let ocp = Ocp {
        dynamics,
        nodes,
        x_min,
        x_max,
        u_min: TORQUE.iter().map(|t| -t).collect(),
        u_max: TORQUE.to_vec(),
        x_initial,
        x_final,
        s_min: 0.1,
        s_max: 20.0,
        final_time: (0.0, 4.0),
        time_weight: 1.0,
        final_cost: vec![],
        increments: (0..n_groups)
            .map(|i| armature_scvx::Increment {
                state: 14 + i,
                eps: eps[i],
                first: groups[i].first,
                last: groups[i].last,
            })
            .collect(),
        nodal,
        // The velocities: the bounds the time-optimal motion rides (the joint limits are far
        // from this motion; the dense check verifies both).
        interval_bounds: if interval_bounds { (7..14).collect() } else { vec![] },
        interval_bounds_sampling: armature_scvx::Sampling::Peak,
        // The clearances also at each segment's peak (the CTCS integral alone switches its
        // gradient on and off where the motion grazes an obstacle between the nodes).
        interval_constraints: match clearance {
            Some(function) if !without_clearance_peaks => vec![armature_scvx::IntervalConstraint {
                name: "clearance".into(),
                function,
                first: 0,
                last: nodes - 1,
                activation: Some(CLEARANCE_ACTIVATION),
                sampling: armature_scvx::Sampling::Peak,
            }],
            _ => Vec::new(),
        },
    };
    // CTCS integrals along the guess, so it has no defects in those rows either.
    let mut ws = ocp.dynamics.workspace();
    let mut out = ocp.dynamics.output(nodes);
    ocp.dynamics.discretize(&x, &u, &s, &Default::default(), &mut ws, &mut out).unwrap();
    for k in 0..nodes - 1 {
        for r in 14..n {
            x[(k + 1) * n + r] = out.x_prop[k * n + r];
        }
    }
    Seed { arm, ocp, x, u, s }
}

/// What the acceptance test checks.
#[derive(Debug)]
pub struct Checks {
    pub samples: usize,
    pub dense_final_time: f64,
    pub joint_violation: f64,
    pub velocity_violation: f64,
    pub table_violation: f64,
    pub waypoint_error: f64,
    /// Largest orientation error (rad) over the nodes of each range of `orientation_ranges`.
    pub orientation_error: [f64; 2],
    /// Smallest signed distance of any collision pair of the seed's collision model on the
    /// dense trajectory, and the pair (negative: penetration).
    pub min_clearance: (f64, String),
}

impl Checks {
    /// The acceptance test's task criteria (waypoints within 1 cm, orientation within 5° /
    /// 0.1°, joint, velocity and table limits within 1e-4 on the dense trajectory and, with
    /// `collision`, no penetration): the first one missed, if any.
    pub fn missed(&self, collision: bool) -> Option<String> {
        let deg = |d: f64| d.to_radians() + 1e-6;
        if self.waypoint_error > 0.01 + 1e-6 {
            Some(format!("waypoint off by {:.4} m", self.waypoint_error))
        } else if self.orientation_error[0] > deg(5.0) || self.orientation_error[1] > deg(0.1) {
            Some(format!("orientation off by {:.3?} rad", self.orientation_error))
        } else if self.joint_violation > 1e-4 || self.velocity_violation > 1e-4 {
            Some(format!(
                "limits violated by {:.1e} / {:.1e}",
                self.joint_violation, self.velocity_violation
            ))
        } else if self.table_violation > 1e-4 {
            Some(format!("table violated by {:.1e}", self.table_violation))
        } else if collision && self.min_clearance.0 <= 0.0 {
            Some(format!("{} penetrates by {:.4} m", self.min_clearance.1, -self.min_clearance.0))
        } else {
            None
        }
    }
}

/// Waypoint `w`'s current position (its parameter's value in the problem).
pub fn waypoint(ocp: &Ocp, w: usize) -> nalgebra::Vector3<f64> {
    let name = waypoint_parameter(w);
    let c = ocp.nodal.iter().find(|c| c.function.parameter(&name).is_some()).unwrap();
    nalgebra::Vector3::from_column_slice(c.function.parameter(&name).unwrap())
}

/// Dense (dt = 0.01, single shooting from x₀) and nodal checks of a result.
pub fn check(seed: &Seed, r: &PtrResult) -> Checks {
    let n = seed.ocp.dynamics.n_x();
    let (times, dense) = seed.ocp.dynamics.propagate(&r.x[..n], &r.u, &r.s, 0.01).unwrap();
    let (qlo, qhi) = seed.arm.position_limits();
    let mut fw = seed.arm.fk_workspace();
    let (mut jv, mut vv, mut tv) = (0.0f64, 0.0f64, 0.0f64);
    let model = armature_collision::CollisionModel::seed_arm7(&seed.arm).unwrap();
    let mut cws = model.workspace(&seed.arm);
    let mut clearance = (f64::INFINITY, String::new());
    for row in dense.chunks(n) {
        for (k, pr) in
            model.evaluate(&seed.arm, &row[..7], &mut cws, false).unwrap().iter().enumerate()
        {
            if pr.distance < clearance.0 {
                let p = &model.pairs()[k];
                clearance = (pr.distance, format!("{}|{}", p.a, p.b));
            }
        }
        for j in 0..7 {
            jv = jv.max(row[j] - qhi[j]).max(qlo[j] - row[j]);
            vv = vv.max(row[7 + j].abs() - VELOCITY);
        }
        seed.arm.forward_ee(&row[..7], &mut fw).unwrap();
        tv = tv.max(-fw.ee_matrix().1.z);
    }
    let down = SO3::from_quaternion_wxyz(Q_DOWN).unwrap().matrix();
    let mut wp = 0.0f64;
    let mut ori = [0.0f64; 2];
    for k in 0..NODES {
        seed.arm.forward_ee(&r.x[k * n..k * n + 7], &mut fw).unwrap();
        let (rot, p) = fw.ee_matrix();
        if k % 2 == 0 {
            wp = wp.max((p - waypoint(&seed.ocp, k / 2)).norm());
        }
        let e = SO3::from_matrix(&(down.transpose() * rot)).unwrap().log().norm();
        for (i, (_, nodes)) in orientation_ranges().iter().enumerate() {
            if nodes.contains(&k) {
                ori[i] = ori[i].max(e);
            }
        }
    }
    Checks {
        samples: times.len(),
        dense_final_time: *times.last().unwrap(),
        joint_violation: jv.max(0.0),
        velocity_violation: vv.max(0.0),
        table_violation: tv.max(0.0),
        waypoint_error: wp,
        orientation_error: ori,
        min_clearance: clearance,
    }
}
