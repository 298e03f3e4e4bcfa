//! Verifying a retimed trajectory (`ArmTask::retime`) without the retiming's code: every
//! constraint of the task on its samples (the suite's own FK), and the samples' consistency
//! with each other and with the dynamics — the angles against the velocities integrated from
//! the first sample (trapezoidal rule), and the torques that the finite-difference
//! accelerations need (the verification's own inverse dynamics) against the limits.

use armature_arm::Retimed;

use crate::generate::SuiteTask;
use crate::run::checks;
use crate::verify::{self, Dense, Worst};

/// The largest violation of the retimed trajectory `r` of task `t`.
pub fn verify_retimed(t: &SuiteTask, r: &Retimed) -> Worst {
    let dense = Dense {
        t: r.time.clone(),
        q: r.angle.clone(),
        qd: r.velocity.clone(),
        tau: r.torque.clone(),
        segment_starts: Vec::new(),
    };
    let c = checks(t);
    let mut worst = verify::check(&c, &dense, &r.node_times);
    let mut note = |v: f64, what: String| {
        if v > worst.value {
            worst = Worst { value: v, what };
        }
    };
    let mut id = InverseDynamics::new(t);
    let n = c.qd_max.len();
    let (mut mid_q, mut mid_v, mut acc, mut tau) =
        (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut integrated = r.angle[0].clone();
    for i in 0..r.time.len() - 1 {
        let dt = r.time[i + 1] - r.time[i];
        if dt.is_nan() || dt <= 0.0 {
            note(f64::INFINITY, format!("time does not increase at sample {i}"));
            continue;
        }
        let (q0, q1, v0, v1) = (&r.angle[i], &r.angle[i + 1], &r.velocity[i], &r.velocity[i + 1]);
        for j in 0..n {
            // The angles against the velocities integrated so far (rad).
            integrated[j] += 0.5 * dt * (v0[j] + v1[j]);
            let drift = (integrated[j] - q1[j]).abs();
            note(
                drift,
                format!("joint {j} angle against the velocities at t = {:.3}", r.time[i + 1]),
            );
            mid_q[j] = 0.5 * (q0[j] + q1[j]);
            mid_v[j] = 0.5 * (v0[j] + v1[j]);
            acc[j] = (v1[j] - v0[j]) / dt;
        }
        id.torque(&mid_q, &mid_v, &acc, &mut tau);
        for j in 0..n {
            note(
                tau[j].abs() - c.tau_max[j],
                format!("joint {j} torque (finite differences) at t = {:.3}", r.time[i]),
            );
        }
    }
    worst
}

/// The verification's inverse dynamics: `I·q̈`, or the rigid-body RNEA.
enum InverseDynamics {
    Decoupled(Vec<f64>),
    RigidBody(Box<(armature_kinematics::RigidBodyModel, armature_kinematics::DynamicsWorkspace)>),
}

impl InverseDynamics {
    fn new(t: &SuiteTask) -> Self {
        match &t.task.dynamics {
            armature_arm::DynamicsModel::DecoupledInertia(i) => Self::Decoupled(i.clone()),
            armature_arm::DynamicsModel::RigidBody { gravity } => {
                let model = armature_kinematics::RigidBodyModel::new(&t.task.chain, *gravity)
                    .expect("a planned rigid-body task has a model");
                let ws = model.workspace();
                Self::RigidBody(Box::new((model, ws)))
            }
        }
    }

    fn torque(&mut self, q: &[f64], qd: &[f64], qdd: &[f64], out: &mut [f64]) {
        match self {
            Self::Decoupled(inertia) => {
                for ((o, a), i) in out.iter_mut().zip(qdd).zip(inertia.iter()) {
                    *o = a * i;
                }
            }
            Self::RigidBody(rigid) => {
                let (model, ws) = &mut **rigid;
                if model.rnea(ws, q, qd, qdd, out).is_err() {
                    out.fill(f64::INFINITY);
                }
            }
        }
    }
}
