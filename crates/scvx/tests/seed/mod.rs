//! The seed tutorial's 7-DOF pick-and-place as the solver sees it: the task is
//! `armature_arm::fixtures::pick_and_place` (the one formulation of the repo, also behind
//! `armature demo`) stated as the tutorial states it — 2 nodes per segment, 10 RK4 steps
//! each, the torques themselves as the controls ([`tutorial`]; the task's own defaults are
//! 3 nodes per segment and time-scaled torques) — planned and compiled there; this module
//! hands its [`Ocp`] and guess to the solver-level tests, benches and examples, and checks a
//! result independently (the chain's own FK on a dense re-integration, the seed's collision
//! model).

#![allow(dead_code, unreachable_pub)]

use armature_arm::{ArmTask, fixtures, waypoint_parameter as arm_parameter};
use armature_kinematics::Chain;
use armature_lie::SO3;
use armature_scvx::{Ocp, PtrResult};

/// Nodes (2 per segment).
pub const NODES: usize = 11;
/// Velocity limit (rad/s).
pub const VELOCITY: f64 = 3.0;

/// The problem and its guess.
#[derive(Debug)]
pub struct Seed {
    /// The task it was planned from.
    pub task: ArmTask,
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

/// The seed's collision variant (`fixtures::pick_and_place_collision`).
pub fn build_collision() -> Seed {
    build_with(Variant { collision: true, ..Variant::default() })
}

/// Which version of the seed problem to build.
#[derive(Debug, Clone, Copy, Default)]
pub struct Variant {
    /// The collision extension ([`build_collision`]).
    pub collision: bool,
    /// The velocity bounds also enforced between the nodes (the task's
    /// `velocity_limit_peaks`).
    pub interval_bounds: bool,
    /// With `collision`: the clearances only as their CTCS integral and at the nodes, without
    /// their peak rows between the nodes.
    pub without_clearance_peaks: bool,
    /// The task's own defaults (3 nodes per segment, time-scaled torques) instead of the
    /// tutorial's statement.
    pub task_defaults: bool,
}

/// The seed problem in the given variant.
pub fn build_with(variant: Variant) -> Seed {
    let task = if variant.collision {
        fixtures::pick_and_place_collision()
    } else {
        fixtures::pick_and_place()
    };
    let mut task = if variant.task_defaults { task } else { tutorial(task) };
    task.velocity_limit_peaks = variant.interval_bounds;
    if let (Some(c), true) = (&mut task.collision, variant.without_clearance_peaks) {
        c.between_nodes_activation = None;
    }
    let mut compiled = task.plan().expect("the seed plans").compile().expect("the seed compiles");
    let (x, u, s) = compiled.guess();
    let (x, u, s) = (x.to_vec(), u.to_vec(), s.to_vec());
    let ocp = compiled.ptr().ocp().clone();
    Seed { arm: task.chain.clone(), task, ocp, x, u, s }
}

/// `task` as the tutorial states it: 2 nodes per segment ([`NODES`]), 10 RK4 steps each,
/// plain torques.
pub fn tutorial(task: ArmTask) -> ArmTask {
    let mut task = task.resegmented(2).expect("the seed's waypoints are evenly spaced");
    task.settings.discretization.substeps = 10;
    task.time_scaled_torque = false;
    task
}

/// Name of the parameter holding waypoint `w`'s position.
pub fn waypoint_parameter(w: usize) -> String {
    let names = ["home", "pre_grasp", "grasp", "lift", "pre_place", "place"];
    arm_parameter(names[w])
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
    /// Largest excess of the orientation error (rad) over its range's tolerance, at the nodes
    /// of each of the task's ranges (≤ 0: every range holds).
    pub orientation_excess: f64,
    /// Smallest signed distance of any collision pair of the seed's collision model on the
    /// dense trajectory, and the pair (negative: penetration).
    pub min_clearance: (f64, String),
}

impl Checks {
    /// The acceptance test's task criteria (waypoints within 1 cm, orientation ranges at
    /// their nodes, joint, velocity and table limits within 1e-4 on the dense trajectory
    /// and, with `collision`, no penetration): the first one missed, if any.
    pub fn missed(&self, collision: bool) -> Option<String> {
        if self.waypoint_error > 0.01 + 1e-6 {
            Some(format!("waypoint off by {:.4} m", self.waypoint_error))
        } else if self.orientation_excess > 1e-6 {
            Some(format!("orientation off by {:.3e} rad", self.orientation_excess))
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
    let mut wp = 0.0f64;
    let mut ori = f64::NEG_INFINITY;
    for k in 0..NODES {
        seed.arm.forward_ee(&r.x[k * n..k * n + 7], &mut fw).unwrap();
        let (rot, p) = fw.ee_matrix();
        if k % 2 == 0 {
            wp = wp.max((p - waypoint(&seed.ocp, k / 2)).norm());
        }
        for range in seed.task.orientation.iter().filter(|o| (o.first..=o.last).contains(&k)) {
            let want = SO3::from_quaternion_wxyz(range.quaternion_wxyz).unwrap().matrix();
            let e = SO3::from_matrix(&(want.transpose() * rot)).unwrap().log().norm();
            ori = ori.max(e - range.tolerance_deg.to_radians());
        }
    }
    Checks {
        samples: times.len(),
        dense_final_time: *times.last().unwrap(),
        joint_violation: jv.max(0.0),
        velocity_violation: vv.max(0.0),
        table_violation: tv.max(0.0),
        waypoint_error: wp,
        orientation_excess: ori,
        min_clearance: clearance,
    }
}
