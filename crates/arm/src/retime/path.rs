//! The path of a solved trajectory on a fine grid: its angles and their first and second
//! derivatives in the solution's own time, by re-integrating the arm's dynamics under the
//! solution's first-order-hold torques from its initial state (single shooting, RK4).

use armature_kinematics::DynamicsWorkspace;

use crate::dynamics::Resolved;
use crate::node_tables::NodeTables;

type Table = Vec<Vec<f64>>;

/// Grid points of the path over the whole solution (at least [`MIN_STEPS`] per segment).
pub(crate) const POINTS: usize = 2000;
/// RK4 steps per segment at least.
const MIN_STEPS: usize = 4;

/// The path on its grid: the parameter `σ` (the solution's time), `q(σ)`, `q′(σ)`, `q″(σ)`,
/// and the grid index of each node.
#[derive(Debug, Clone)]
pub(crate) struct PathSamples {
    pub(crate) sigma: Vec<f64>,
    pub(crate) q: Table,
    pub(crate) dq: Table,
    pub(crate) ddq: Table,
    pub(crate) nodes: Vec<usize>,
}

/// `q̈` of the model, with its workspace.
pub(crate) struct Model<'a> {
    pub(crate) resolved: &'a Resolved,
    pub(crate) ws: Option<DynamicsWorkspace>,
}

impl<'a> Model<'a> {
    pub(crate) fn new(resolved: &'a Resolved) -> Self {
        let ws = match resolved {
            Resolved::Decoupled(_) => None,
            Resolved::RigidBody(m) => Some(m.workspace()),
        };
        Model { resolved, ws }
    }

    /// `q̈ = f(q, q̇, τ)` into `out` (NaN where the model fails).
    fn qdd(&mut self, q: &[f64], qd: &[f64], tau: &[f64], out: &mut [f64]) {
        match (self.resolved, self.ws.as_mut()) {
            (Resolved::RigidBody(m), Some(ws)) => {
                if m.aba(ws, q, qd, tau, out).is_err() {
                    out.fill(f64::NAN);
                }
            }
            (Resolved::Decoupled(inertia), _) => {
                for (j, o) in out.iter_mut().enumerate() {
                    *o = tau[j] / inertia[j];
                }
            }
            (Resolved::RigidBody(_), None) => out.fill(f64::NAN),
        }
    }
}

/// The path of `nodes`' trajectory under `model` on a grid of about [`POINTS`] points.
pub(crate) fn sample(model: &mut Model<'_>, nodes: &NodeTables<'_>) -> PathSamples {
    let n = nodes.q[0].len();
    let total = nodes.times[nodes.times.len() - 1] - nodes.times[0];
    let (mut q, mut qd) = (nodes.q[0].clone(), nodes.v[0].clone());
    let mut out = PathSamples {
        sigma: Vec::with_capacity(POINTS + 1),
        q: Vec::with_capacity(POINTS + 1),
        dq: Vec::with_capacity(POINTS + 1),
        ddq: Vec::with_capacity(POINTS + 1),
        nodes: vec![0],
    };
    let mut acc = vec![0.0; n];
    let mut tau = vec![0.0; n];
    let mut push = |out: &mut PathSamples, model: &mut Model<'_>, s, q: &[f64], qd: &[f64]| {
        let k = nodes.times.partition_point(|&t| t <= s).clamp(1, nodes.times.len() - 1) - 1;
        torque_at(nodes, k, s, &mut tau);
        model.qdd(q, qd, &tau, &mut acc);
        out.sigma.push(s);
        out.q.push(q.to_vec());
        out.dq.push(qd.to_vec());
        out.ddq.push(acc.clone());
    };
    push(&mut out, model, nodes.times[0], &q, &qd);
    let (mut k1, mut k2, mut k3, mut k4) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let (mut qs, mut vs, mut ts) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let zero = vec![0.0; n];
    for k in 0..nodes.times.len() - 1 {
        let (t0, h) = (nodes.times[k], nodes.times[k + 1] - nodes.times[k]);
        let steps = ((h / total * POINTS as f64).ceil() as usize).max(MIN_STEPS);
        let dt = h / steps as f64;
        for i in 0..steps {
            let s = t0 + i as f64 * dt;
            // RK4 on (q, q̇), its position stages written out:
            // k2 at (q + ½h·q̇, q̇ + ½h·k1), k3 at (q + ½h·q̇ + ¼h²·k1, q̇ + ½h·k2),
            // k4 at (q + h·q̇ + ½h²·k2, q̇ + h·k3).
            let mut stage = |qa: f64, qc: f64, qk: &[f64], va: f64, vk: &[f64], kv: &mut [f64]| {
                for j in 0..n {
                    qs[j] = q[j] + qa * qd[j] + qc * qk[j];
                    vs[j] = qd[j] + va * vk[j];
                }
                torque_at(nodes, k, s + qa, &mut ts);
                model.qdd(&qs, &vs, &ts, kv);
            };
            let (half, sq) = (dt / 2.0, dt * dt);
            stage(0.0, 0.0, &zero, 0.0, &zero, &mut k1);
            stage(half, 0.0, &zero, half, &k1, &mut k2);
            stage(half, sq / 4.0, &k1, half, &k2, &mut k3);
            stage(dt, sq / 2.0, &k2, dt, &k3, &mut k4);
            for j in 0..n {
                q[j] += dt * qd[j] + dt * dt / 6.0 * (k1[j] + k2[j] + k3[j]);
                qd[j] += dt / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
            }
            let end = if i + 1 == steps { nodes.times[k + 1] } else { s + dt };
            push(&mut out, model, end, &q, &qd);
        }
        out.nodes.push(out.sigma.len() - 1);
    }
    out
}

/// The first-order-hold torques of segment `k` at time `s` into `out`.
fn torque_at(nodes: &NodeTables<'_>, k: usize, s: f64, out: &mut [f64]) {
    let (t0, t1) = (nodes.times[k], nodes.times[k + 1]);
    let w = ((s - t0) / (t1 - t0)).clamp(0.0, 1.0);
    for (j, o) in out.iter_mut().enumerate() {
        *o = (1.0 - w) * nodes.u[k][j] + w * nodes.u[k + 1][j];
    }
}
