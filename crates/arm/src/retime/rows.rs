//! The limits along a path as TOPP rows: the joint torques `τ = a(σ)·s̈ + b(σ)·ṡ² + c(σ)`
//! and the velocities `q̇ = q′(σ)·ṡ`.
//!
//! For `M(q)q̈ + C(q, q̇)q̇ + g(q) = τ` on `q(σ)`: `q̇ = q′ṡ`, `q̈ = q″ṡ² + q′s̈`, and the
//! velocity terms are quadratic in `ṡ`, so `a = M q′`, `b = M q″ + C(q, q′)q′`, `c = g(q)`
//! — three RNEA calls: `c = RNEA(q, 0, 0)`, `a = RNEA(q, 0, q′) − c`,
//! `b = RNEA(q, q′, q″) − c`. For `q̈ = τ / I`: `a = I q′`, `b = I q″`, `c = 0`.

use super::path::{Model, PathSamples};
use super::topp::Stage;
use crate::dynamics::Resolved;

/// The limits the rows hold, relative to the task's: the torque between two samples follows
/// the path's curvature over a stage, and this keeps it within the task's limit there
/// (measured on the benchmark suite: up to 4e-5 of the limit over it without a margin).
pub(crate) const LIMIT_SHARE: f64 = 1.0 - 1e-4;

/// Per point, per joint: the torque's `(a, b, c)`, and `b` where the interval before the
/// point ends (it differs where `q″` jumps, [`PathSamples::ddq_before`]).
pub(crate) type Coefficients = Vec<Vec<[f64; 4]>>;

/// The torque coefficients at every point of `path` (NaN where the model fails).
pub(crate) fn torque_coefficients(model: &mut Model<'_>, path: &PathSamples) -> Coefficients {
    let n = path.q.first().map_or(0, Vec::len);
    let zero = vec![0.0; n];
    let (mut g, mut ma, mut mb, mut mb0) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    (0..path.q.len())
        .map(|i| {
            let (q, dq, ddq, ddq0) = (&path.q[i], &path.dq[i], &path.ddq[i], &path.ddq_before[i]);
            match (model.resolved, model.ws.as_mut()) {
                (Resolved::RigidBody(m), Some(ws)) => {
                    let ok = m.rnea(ws, q, &zero, &zero, &mut g).is_ok()
                        && m.rnea(ws, q, &zero, dq, &mut ma).is_ok()
                        && m.rnea(ws, q, dq, ddq, &mut mb).is_ok()
                        && m.rnea(ws, q, dq, ddq0, &mut mb0).is_ok();
                    (0..n)
                        .map(|j| match ok {
                            true => [ma[j] - g[j], mb[j] - g[j], g[j], mb0[j] - g[j]],
                            false => [f64::NAN; 4],
                        })
                        .collect()
                }
                (Resolved::Decoupled(inertia), _) => (0..n)
                    .map(|j| {
                        let i = inertia[j];
                        [i * dq[j], i * ddq[j], 0.0, i * ddq0[j]]
                    })
                    .collect(),
                (Resolved::RigidBody(_), None) => vec![[f64::NAN; 4]; n],
            }
        })
        .collect()
}

/// The stages: at each point `i < M`, `|τ_j| ≤ τ_max,j` (times [`LIMIT_SHARE`]) at the stage's start `(s̈_i, ṡ²_i)`
/// and at its end `(s̈_i, ṡ²_i + 2Δ_i s̈_i)` (so the torque holds on both sides of every
/// point, and between them up to the path's curvature over a stage), and
/// `ṡ² ≤ min_j (q̇_max,j / |q′_j|)²`.
pub(crate) fn stages(
    path: &PathSamples,
    coef: &Coefficients,
    delta: &[f64],
    velocity_limit: &[f64],
    torque_limit: &[f64],
) -> Vec<Stage> {
    let points = path.q.len();
    (0..points)
        .map(|i| {
            let x_max = path.dq[i]
                .iter()
                .zip(velocity_limit)
                .map(|(d, v)| if *d == 0.0 { f64::INFINITY } else { (LIMIT_SHARE * v / d).powi(2) })
                .fold(f64::INFINITY, f64::min);
            let mut rows = Vec::with_capacity(4 * torque_limit.len());
            for (j, &limit) in torque_limit.iter().enumerate() {
                let limit = LIMIT_SHARE * limit;
                let [a, b, c, _] = coef[i][j];
                rows.push([a, b, limit - c]);
                rows.push([-a, -b, limit + c]);
                if i + 1 < points {
                    let [a1, _, c1, b1] = coef[i + 1][j];
                    let a_end = a1 + 2.0 * delta[i] * b1;
                    rows.push([a_end, b1, limit - c1]);
                    rows.push([-a_end, -b1, limit + c1]);
                }
            }
            Stage { rows, x_max }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::retime::path::Model;

    #[test]
    fn rigid_body_rows_give_the_inverse_dynamics_torque() {
        // τ = a·s̈ + b·ṡ² + c against RNEA(q, q′ṡ, q″ṡ² + q′s̈) at an arbitrary point.
        let task = crate::fixtures::ur5e_rigid_body();
        let resolved = Resolved::new(&task.dynamics, &task.chain).unwrap();
        let Resolved::RigidBody(model) = &resolved else { panic!("rigid body") };
        let q = vec![0.3, -1.1, 0.8, -0.4, 1.2, 0.2];
        let dq = vec![0.5, -0.2, 0.9, 0.1, -0.7, 0.3];
        let ddq = vec![-1.0, 2.0, 0.4, -0.3, 0.8, 1.5];
        let path = PathSamples {
            sigma: vec![0.0],
            q: vec![q.clone()],
            dq: vec![dq.clone()],
            ddq: vec![ddq.clone()],
            ddq_before: vec![ddq.clone()],
            nodes: vec![0],
        };
        let coef = torque_coefficients(&mut Model::new(&resolved), &path);
        let (x, u) = (2.3f64, -0.7);
        let qd: Vec<f64> = dq.iter().map(|d| d * x.sqrt()).collect();
        let qdd: Vec<f64> = dq.iter().zip(&ddq).map(|(d, dd)| dd * x + d * u).collect();
        let mut tau = vec![0.0; 6];
        model.rnea(&mut model.workspace(), &q, &qd, &qdd, &mut tau).unwrap();
        for j in 0..6 {
            let [a, b, c, _] = coef[0][j];
            assert!((a * u + b * x + c - tau[j]).abs() < 1e-10, "joint {j}");
        }
    }
}
