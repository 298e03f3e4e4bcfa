//! The path of a solved trajectory on a fine grid: its angles and their first and second
//! derivatives in the solution's own time, by re-integrating the arm's dynamics under the
//! solution's first-order-hold torques from its initial state (single shooting, RK4).

use armature_kinematics::DynamicsWorkspace;

use crate::dynamics::Resolved;
use crate::node_tables::NodeTables;

type Table = Vec<Vec<f64>>;

/// Grid points of the path over the whole solution (at least [`MIN_STEPS`] per segment),
/// before the ends at rest are refined ([`REST_REFINEMENT`]).
pub(crate) const POINTS: usize = 2000;
/// RK4 steps per segment at least.
const MIN_STEPS: usize = 4;
/// How much finer the quarter of the first and last segments next to the rest is sampled:
/// where the path starts and ends at rest its tangent vanishes, the retimed motion spends long
/// between samples there, and the torque between two samples strays further from its values
/// at them (sampled as the other segments, one refined suite task needed 1.3e-3 N·m over a
/// limit between two samples 6 ms before the end; BENCHMARKS.md).
const REST_REFINEMENT: usize = 4;

/// The path on its grid: the parameter `σ` (the solution's time), `q(σ)`, `q′(σ)`, `q″(σ)`,
/// and the grid index of each node.
#[derive(Debug, Clone)]
pub(crate) struct PathSamples {
    pub(crate) sigma: Vec<f64>,
    pub(crate) q: Table,
    pub(crate) dq: Table,
    pub(crate) ddq: Table,
    /// `q″(σ)` where the interval before each point ends: `ddq` except at a node where the
    /// torque jumps (a time-scaled solution's segments change duration there).
    pub(crate) ddq_before: Table,
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

    /// `τ = M(q)q̈ + C(q, q̇)q̇ + g(q)` into `out` (NaN where the model fails).
    pub(crate) fn torque(&mut self, q: &[f64], qd: &[f64], qdd: &[f64], out: &mut [f64]) {
        match (self.resolved, self.ws.as_mut()) {
            (Resolved::RigidBody(m), Some(ws)) => {
                if m.rnea(ws, q, qd, qdd, out).is_err() {
                    out.fill(f64::NAN);
                }
            }
            (Resolved::Decoupled(inertia), _) => {
                for (j, o) in out.iter_mut().enumerate() {
                    *o = qdd[j] * inertia[j];
                }
            }
            (Resolved::RigidBody(_), None) => out.fill(f64::NAN),
        }
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

/// The path of `nodes`' trajectory under `model` on a grid of about `points` points
/// ([`POINTS`] for a result).
pub(crate) fn sample(model: &mut Model<'_>, nodes: &NodeTables<'_>, points: usize) -> PathSamples {
    let n = nodes.q[0].len();
    let total = nodes.times[nodes.times.len() - 1] - nodes.times[0];
    let (mut q, mut qd) = (nodes.q[0].clone(), nodes.v[0].clone());
    let mut out = PathSamples {
        sigma: Vec::with_capacity(points + 1),
        q: Vec::with_capacity(points + 1),
        dq: Vec::with_capacity(points + 1),
        ddq: Vec::with_capacity(points + 1),
        ddq_before: Vec::with_capacity(points + 1),
        nodes: vec![0],
    };
    let mut acc = vec![0.0; n];
    let mut tau = vec![0.0; n];
    // A point at `s` on segment `before` (its end, at a node): q″ there on both sides.
    let mut push =
        |out: &mut PathSamples, model: &mut Model<'_>, s, before, q: &[f64], qd: &[f64]| {
            let k = nodes.times.partition_point(|&t| t <= s).clamp(1, nodes.times.len() - 1) - 1;
            torque_at(nodes, before, s, &mut tau);
            model.qdd(q, qd, &tau, &mut acc);
            out.ddq_before.push(acc.clone());
            if k != before {
                torque_at(nodes, k, s, &mut tau);
                model.qdd(q, qd, &tau, &mut acc);
            }
            out.sigma.push(s);
            out.q.push(q.to_vec());
            out.dq.push(qd.to_vec());
            out.ddq.push(acc.clone());
        };
    push(&mut out, model, nodes.times[0], 0, &q, &qd);
    let (mut k1, mut k2, mut k3, mut k4) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let (mut qs, mut vs, mut ts) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let zero = vec![0.0; n];
    for k in 0..nodes.times.len() - 1 {
        let (t0, h) = (nodes.times[k], nodes.times[k + 1] - nodes.times[k]);
        let steps = ((h / total * points as f64).ceil() as usize).max(MIN_STEPS);
        let rest = (k == 0, k + 2 == nodes.times.len());
        let cuts = segment_grid(t0, h, steps, rest);
        for (i, w) in cuts.windows(2).enumerate() {
            let (s, dt) = (w[0], w[1] - w[0]);
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
            let end = if i + 2 == cuts.len() { nodes.times[k + 1] } else { w[1] };
            push(&mut out, model, end, k, &q, &qd);
        }
        out.nodes.push(out.sigma.len() - 1);
    }
    out
}

/// The grid of a segment from `t0` lasting `h`: `steps` equal steps, except that the quarter
/// next to an end at rest (`rest`: at the segment's start, at its end) is [`REST_REFINEMENT`]
/// times finer. Its points, both ends included.
fn segment_grid(t0: f64, h: f64, steps: usize, rest: (bool, bool)) -> Vec<f64> {
    let quarter = steps.div_ceil(4);
    // (length, steps) of the three parts: the quarter at the start, the middle, the quarter
    // at the end.
    let part =
        |at_rest: bool| if at_rest { (0.25 * h, quarter * REST_REFINEMENT) } else { (0.0, 0) };
    let (first, last) = (part(rest.0), part(rest.1));
    let middle = (
        h - first.0 - last.0,
        steps - if rest.0 { quarter } else { 0 } - if rest.1 { quarter } else { 0 },
    );
    let mut cuts = vec![t0];
    let mut at = t0;
    for (len, n) in [first, middle, last] {
        for i in 1..=n {
            cuts.push(at + len * i as f64 / n as f64);
        }
        at += len;
    }
    cuts
}

/// The first-order-hold torques of segment `k` at time `s` into `out`.
fn torque_at(nodes: &NodeTables<'_>, k: usize, s: f64, out: &mut [f64]) {
    let (t0, t1) = (nodes.times[k], nodes.times[k + 1]);
    let w = ((s - t0) / (t1 - t0)).clamp(0.0, 1.0);
    for (j, o) in out.iter_mut().enumerate() {
        *o = (1.0 - w) * nodes.u[k][j] + w * nodes.u_end[k][j];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segments_at_rest_are_sampled_finer_in_their_quarter_next_to_the_rest() {
        for (steps, rest) in
            [(4, (true, true)), (5, (true, false)), (40, (false, true)), (9, (false, false))]
        {
            let cuts = segment_grid(2.0, 0.5, steps, rest);
            assert_eq!(cuts[0], 2.0);
            assert!((cuts[cuts.len() - 1] - 2.5).abs() < 1e-15, "{cuts:?}");
            assert!(cuts.windows(2).all(|w| w[1] > w[0]), "{cuts:?}");
            let widest = cuts.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
            let quarter = steps.div_ceil(4);
            let extra =
                (usize::from(rest.0) + usize::from(rest.1)) * quarter * (REST_REFINEMENT - 1);
            assert_eq!(cuts.len(), steps + extra + 1, "{steps} {rest:?}");
            // The first (last) step next to a rest end is REST_REFINEMENT times finer than
            // the quarter's share of the segment would be at the base density.
            let base = 0.25 * 0.5 / quarter as f64;
            if rest.0 {
                assert!((cuts[1] - cuts[0] - base / REST_REFINEMENT as f64).abs() < 1e-15);
            }
            if rest.1 {
                let n = cuts.len();
                assert!((cuts[n - 1] - cuts[n - 2] - base / REST_REFINEMENT as f64).abs() < 1e-12);
            }
            assert!(widest <= 0.5 / (steps - 2 * quarter).max(1) as f64 + 1e-15);
        }
    }
}
