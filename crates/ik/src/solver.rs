//! Damped-least-squares (Levenberg–Marquardt) inverse kinematics.

use armature_kinematics::{Chain, FkWorkspace};
use armature_lie::SO3;
use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use serde::Serialize;

use crate::IkError;

/// What the secondary (nullspace) objective pulls toward, for redundant arms.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub enum Nullspace {
    /// No secondary objective.
    #[default]
    None,
    /// Stay near the seed configuration.
    Seed,
    /// Stay near the middle of the joint ranges (joints without limits: near the seed).
    MidRange,
}

/// Solver settings; every field has a documented default.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IkSettings {
    /// Position tolerance (m). Default 1e-6.
    pub position_tolerance: f64,
    /// Orientation tolerance (rad). Default 1e-6.
    pub orientation_tolerance: f64,
    /// Iteration cap per attempt. Default 50.
    pub max_iterations: usize,
    /// Initial damping λ of `(J Jᵀ + λ I)`. Default 1e-2.
    pub damping: f64,
    /// Smallest damping the adaptation goes down to. Default 1e-9.
    pub min_damping: f64,
    /// Damping at which an attempt gives up (no descent possible: a local minimum, often at a
    /// joint limit). Default 1.
    pub max_damping: f64,
    /// Weight of the position error (1/m). Default 1.
    pub position_weight: f64,
    /// Weight of the orientation error (1/rad). Default 1.
    pub orientation_weight: f64,
    /// Secondary objective. Default none.
    pub nullspace: Nullspace,
    /// Gain of the secondary objective per iteration. Default 0.1.
    pub nullspace_gain: f64,
    /// Extra attempts when the first does not converge: the first [`LOCAL_RESTARTS`] from
    /// random perturbations of the seed, the rest from random in-limit configurations.
    /// Default 0.
    pub restarts: usize,
    /// Seed of the restart generator (results are reproducible). Default 0.
    pub rng_seed: u64,
    /// Factor applied to λ after an accepted step (< 1). Default 0.5.
    pub damping_decrease: f64,
    /// Factor applied to λ after a rejected step (> 1). Default 4.
    pub damping_increase: f64,
    /// Stagnation test: an attempt stops early when, after 6 iterations, its cost is above this
    /// fraction of the cost 3 iterations before while the position error is still above 1 mm
    /// (a local minimum: a restart is cheaper). 0 disables. Default 0.7.
    pub stall_ratio: f64,
    /// Largest joint step per iteration (rad or m, ∞-norm); larger steps are scaled down,
    /// which keeps steps from singular seeds from jumping into limit minima. Default 0.5.
    pub max_step: f64,
}

impl Default for IkSettings {
    fn default() -> Self {
        IkSettings {
            position_tolerance: 1e-6,
            orientation_tolerance: 1e-6,
            max_iterations: 50,
            damping: 1e-2,
            min_damping: 1e-9,
            max_damping: 1.0,
            position_weight: 1.0,
            orientation_weight: 1.0,
            nullspace: Nullspace::None,
            nullspace_gain: 0.1,
            restarts: 0,
            rng_seed: 0,
            max_step: 0.5,
            damping_decrease: 0.5,
            stall_ratio: 0.7,
            damping_increase: 4.0,
        }
    }
}

impl IkSettings {
    /// Checks that every field is usable.
    ///
    /// # Errors
    /// [`IkError::BadSettings`] naming the field.
    pub fn validate(&self) -> Result<(), IkError> {
        let bad = |field: &'static str, reason: &str| {
            Err(IkError::BadSettings { field, reason: reason.into() })
        };
        let positive = [
            ("position_tolerance", self.position_tolerance),
            ("orientation_tolerance", self.orientation_tolerance),
            ("damping", self.damping),
            ("min_damping", self.min_damping),
            ("max_damping", self.max_damping),
            ("position_weight", self.position_weight),
            ("orientation_weight", self.orientation_weight),
            ("max_step", self.max_step),
        ];
        for (field, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return bad(field, "must be a positive finite number");
            }
        }
        if !(1..=MAX_IK_ITERATIONS).contains(&self.max_iterations) {
            return bad("max_iterations", "must be 1 to 100000");
        }
        if self.restarts > MAX_RESTARTS {
            return bad("restarts", "must be at most 1000");
        }
        if !(self.min_damping <= self.damping && self.damping <= self.max_damping) {
            return bad("damping", "must lie between min_damping and max_damping");
        }
        if !(self.stall_ratio.is_finite() && (0.0..1.0).contains(&self.stall_ratio)) {
            return bad("stall_ratio", "must be in [0, 1)");
        }
        if !(self.damping_decrease > 0.0 && self.damping_decrease < 1.0) {
            return bad("damping_decrease", "must be in (0, 1)");
        }
        if !(self.damping_increase > 1.0 && self.damping_increase.is_finite()) {
            return bad("damping_increase", "must be a finite number above 1");
        }
        if !(self.nullspace_gain.is_finite() && (0.0..=1.0).contains(&self.nullspace_gain)) {
            return bad("nullspace_gain", "must be in [0, 1]");
        }
        Ok(())
    }
}

/// An end-effector target: a position, and optionally an orientation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Target {
    /// Desired position (m).
    pub position: Vector3<f64>,
    /// Desired orientation, or `None` for a position-only target.
    pub orientation: Option<SO3>,
}

impl Target {
    /// A position-only target.
    pub fn position(p: Vector3<f64>) -> Self {
        Target { position: p, orientation: None }
    }

    /// A full pose target from a position and a quaternion `[w, x, y, z]`.
    ///
    /// # Errors
    /// [`IkError::BadTarget`] for a non-finite position or a non-unit quaternion.
    pub fn pose(p: Vector3<f64>, quaternion_wxyz: [f64; 4]) -> Result<Self, IkError> {
        let r = SO3::from_quaternion_wxyz(quaternion_wxyz)
            .map_err(|e| IkError::BadTarget(e.to_string()))?;
        let t = Target { position: p, orientation: Some(r) };
        t.check()?;
        Ok(t)
    }

    fn check(&self) -> Result<(), IkError> {
        if self.position.iter().any(|x| !x.is_finite()) {
            return Err(IkError::BadTarget(format!(
                "position {:?} is not finite",
                self.position.as_slice()
            )));
        }
        Ok(())
    }
}

/// The outcome of a solve: always data, also when it did not converge.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IkResult {
    /// Best joint values found (within limits).
    pub q: Vec<f64>,
    /// Whether both tolerances were met.
    pub converged: bool,
    /// Iterations over all attempts.
    pub iterations: usize,
    /// Attempts made (1 + restarts used).
    pub attempts: usize,
    /// Forward-kinematics evaluations over all attempts (iterations plus rejected trials).
    pub evaluations: usize,
    /// Final position error (m).
    pub position_error: f64,
    /// Final orientation error (rad); 0 for position-only targets.
    pub orientation_error: f64,
}

/// Cholesky factor `L` (row-major, lower) of a symmetric positive-definite 6×6 matrix, or
/// `None` if it is not positive definite. Fixed-size loops the compiler unrolls: several times
/// faster than a generic factorisation at this size, and it runs once per damping trial.
#[inline]
fn cholesky6(a: &Matrix6<f64>) -> Option<[[f64; 6]; 6]> {
    let mut l = [[0.0; 6]; 6];
    for j in 0..6 {
        let mut d = a[(j, j)];
        for k in 0..j {
            d -= l[j][k] * l[j][k];
        }
        if d <= 0.0 || !d.is_finite() {
            return None;
        }
        let djj = d.sqrt();
        l[j][j] = djj;
        let inv = 1.0 / djj;
        for i in j + 1..6 {
            let mut v = a[(i, j)];
            for k in 0..j {
                v -= l[i][k] * l[j][k];
            }
            l[i][j] = v * inv;
        }
    }
    Some(l)
}

/// Solves `L Lᵀ x = b` with the factor of [`cholesky6`].
#[inline]
fn cholesky6_solve(l: &[[f64; 6]; 6], b: &Vector6<f64>) -> Vector6<f64> {
    let mut y = [0.0; 6];
    for i in 0..6 {
        let mut v = b[i];
        for k in 0..i {
            v -= l[i][k] * y[k];
        }
        y[i] = v / l[i][i];
    }
    let mut x = Vector6::zeros();
    for i in (0..6).rev() {
        let mut v = y[i];
        for k in i + 1..6 {
            v -= l[k][i] * x[k];
        }
        x[i] = v / l[i][i];
    }
    x
}

/// Most restarts an IK solve makes ([`IkSettings::restarts`]): each costs up to
/// `max_iterations` FK evaluations, so the cap bounds the time an unreachable target takes.
pub const MAX_RESTARTS: usize = 1_000;

/// Most iterations of one IK attempt ([`IkSettings::max_iterations`]).
pub const MAX_IK_ITERATIONS: usize = 100_000;

/// The first this-many restarts perturb the seed (by up to `LOCAL_RESTART_STEP · k` rad per
/// joint on restart `k`); later restarts draw uniformly within the limits (∩ [−π, π]).
pub const LOCAL_RESTARTS: usize = 3;
/// Perturbation step of the local restarts (rad or m).
pub const LOCAL_RESTART_STEP: f64 = 0.1;

/// Caller-owned scratch of the solver (allocation-free inner loop).
#[derive(Debug, Clone)]
pub struct IkWorkspace {
    fk: FkWorkspace,
    q: Vec<f64>,
    trial: Vec<f64>,
    best: Vec<f64>,
    reference: Vec<f64>,
    z: Vec<f64>,
    jac: Vec<Vector6<f64>>,
    locked: Vec<bool>,
    lo: Vec<f64>,
    hi: Vec<f64>,
}

impl IkWorkspace {
    /// A workspace for `chain`.
    pub fn new(chain: &Chain) -> Self {
        let n = chain.dof();
        let (lo, hi) = chain.position_limits();
        IkWorkspace {
            fk: chain.fk_workspace(),
            q: vec![0.0; n],
            trial: vec![0.0; n],
            best: vec![0.0; n],
            reference: vec![0.0; n],
            z: vec![0.0; n],
            jac: vec![Vector6::zeros(); n],
            locked: vec![false; n],
            lo,
            hi,
        }
    }
}

/// Residuals above this (in their largest entry) are scaled down before the step's solve.
const RESIDUAL_SCALE_ABOVE: f64 = 1e100;

/// Weighted residual `[w_p (p* − p); w_o log(R* Rᵀ)]` and the two unweighted error norms.
fn residual(
    ws: &IkWorkspace,
    target: &Target,
    rt: &Option<Matrix3<f64>>,
    s: &IkSettings,
) -> (Vector6<f64>, f64, f64) {
    let (r, p) = ws.fk.ee_matrix();
    let ep = target.position - p;
    let eo = match rt {
        Some(rt) => SO3::from_matrix_unchecked(&(rt * r.transpose())).log(),
        None => Vector3::zeros(),
    };
    let res = Vector6::new(
        s.position_weight * ep.x,
        s.position_weight * ep.y,
        s.position_weight * ep.z,
        s.orientation_weight * eo.x,
        s.orientation_weight * eo.y,
        s.orientation_weight * eo.z,
    );
    (res, safe_norm(&ep), safe_norm(&eo))
}

/// ‖v‖ without overflow or underflow of the squares (a target at 1e300 m is 1e300 m away).
fn safe_norm(v: &Vector3<f64>) -> f64 {
    let scale = v.amax();
    if scale > 0.0 && scale.is_finite() { scale * (v / scale).norm() } else { scale }
}

fn converged(pe: f64, oe: f64, s: &IkSettings) -> bool {
    pe < s.position_tolerance && oe < s.orientation_tolerance
}

/// Solves IK for `target` from `seed`, reusing `ws`.
///
/// Each iteration takes the damped-least-squares step `δ = Jᵀ (J Jᵀ + λ I)⁻¹ r` on the
/// weighted residual `r = [w_p (p* − p); w_o log(R* Rᵀ)]` (world frame) with
/// `J = [w_p J_p; w_o jr⁻¹(e_o) J_ω]` (the exact derivative of the residual), adds the nullspace term `(I − J⁺J) k (q_ref − q)`,
/// projects onto the joint limits, and accepts the step only if the residual decreases
/// (λ halves) — otherwise λ grows ×4 and the step is retried (Levenberg–Marquardt). An
/// attempt stops at convergence, at `max_iterations` or when λ exceeds `max_damping`. With
/// `restarts > 0`, unconverged attempts restart from random in-limit configurations; the best
/// result over all attempts is returned.
///
/// # Errors
/// Only for bad input: [`IkError::BadSettings`], [`IkError::BadTarget`],
/// [`IkError::BadSeed`]. An unreachable target is `Ok` with `converged = false`.
pub fn solve(
    chain: &Chain,
    target: &Target,
    seed: &[f64],
    settings: &IkSettings,
    ws: &mut IkWorkspace,
) -> Result<IkResult, IkError> {
    settings.validate()?;
    target.check()?;
    chain.check_q(seed).map_err(|e| IkError::BadSeed(e.to_string()))?;
    if ws.q.len() != chain.dof() {
        return Err(IkError::BadSeed(format!(
            "workspace is for {} joints, the chain has {}",
            ws.q.len(),
            chain.dof()
        )));
    }
    let mut rng = Pcg64Mcg::seed_from_u64(settings.rng_seed);
    // (cost, position error, orientation error) of the best attempt; the first attempt is
    // always taken, so an overflowing cost cannot leave zero errors behind.
    let mut best = (f64::INFINITY, f64::INFINITY, f64::INFINITY);
    let mut iterations = 0;
    let mut attempts = 0;
    let mut evaluations = 0;
    for attempt in 0..=settings.restarts {
        attempts += 1;
        for i in 0..chain.dof() {
            ws.q[i] = if attempt == 0 {
                seed[i].clamp(ws.lo[i], ws.hi[i])
            } else if attempt <= LOCAL_RESTARTS {
                // Near the seed first: escapes singular seeds (an outstretched arm) without
                // leaving the seed's IK branch.
                let r = LOCAL_RESTART_STEP * attempt as f64;
                (seed[i] + rng.random_range(-r..=r)).clamp(ws.lo[i], ws.hi[i])
            } else {
                let (lo, hi) =
                    (ws.lo[i].max(-std::f64::consts::PI), ws.hi[i].min(std::f64::consts::PI));
                rng.random_range(lo..=hi)
            };
            ws.reference[i] = match settings.nullspace {
                Nullspace::MidRange if ws.lo[i].is_finite() && ws.hi[i].is_finite() => {
                    0.5 * (ws.lo[i] + ws.hi[i])
                }
                _ => seed[i],
            };
        }
        let (cost, pe, oe, it, ev) = attempt_solve(chain, target, settings, ws)?;
        iterations += it;
        evaluations += ev;
        if attempt == 0 || cost < best.0 {
            best = (cost, pe, oe);
            ws.best.copy_from_slice(&ws.q);
        }
        if converged(pe, oe, settings) {
            break;
        }
    }
    Ok(IkResult {
        q: ws.best.clone(),
        converged: converged(best.1, best.2, settings),
        iterations,
        attempts,
        evaluations,
        position_error: best.1,
        orientation_error: best.2,
    })
}

/// One Levenberg–Marquardt attempt from `ws.q`; returns (cost, position error, orientation
/// error, iterations, FK evaluations) with the final configuration in `ws.q`.
fn attempt_solve(
    chain: &Chain,
    target: &Target,
    s: &IkSettings,
    ws: &mut IkWorkspace,
) -> Result<(f64, f64, f64, usize, usize), IkError> {
    let n = chain.dof();
    let fk = |ws: &mut IkWorkspace, trial: bool| {
        let q = if trial { &ws.trial } else { &ws.q };
        chain.forward_ee(q, &mut ws.fk).map_err(|e| IkError::BadSeed(e.to_string()))
    };
    fk(ws, false)?;
    let mut evals = 1;
    let rt = target.orientation.map(|o| o.matrix());
    let (mut r, mut pe, mut oe) = residual(ws, target, &rt, s);
    let mut cost = r.norm_squared();
    let mut lambda = s.damping;
    let has_orientation = target.orientation.is_some();
    let mut it = 0;
    let mut history = [f64::INFINITY; 3];
    while it < s.max_iterations && !converged(pe, oe, s) && lambda <= s.max_damping {
        if s.stall_ratio > 0.0 && it >= 6 && cost > s.stall_ratio * history[it % 3] && pe > 1e-3 {
            break;
        }
        history[it % 3] = cost;
        it += 1;
        // Weighted Jacobian of the residual's decrease: position rows w_p (v + ω × p); the
        // orientation error e = log(R* Rᵀ) changes by −jr⁻¹(e)·ω under the world rotation
        // rate ω, so its rows are w_o jr⁻¹(e) ω (exact Gauss–Newton, not just J_ω).
        let p = ws.fk.ee_matrix().1;
        let jr_inv = if has_orientation {
            let e = Vector3::new(r[3], r[4], r[5]) / s.orientation_weight;
            SO3::jr_inv(&e) * s.orientation_weight
        } else {
            nalgebra::Matrix3::zeros()
        };
        for i in 0..n {
            let c = ws.fk.space_jacobian().column(i);
            let (v, w) = (Vector3::new(c[0], c[1], c[2]), Vector3::new(c[3], c[4], c[5]));
            let jp = (v + w.cross(&p)) * s.position_weight;
            let jo = jr_inv * w;
            ws.jac[i] = Vector6::new(jp.x, jp.y, jp.z, jo.x, jo.y, jo.z);
        }
        // Active set: a joint on a limit that the step pushes further out is locked (its
        // column dropped) and the step recomputed, so the other joints compensate instead of
        // the solver crawling along the limit.
        ws.locked.fill(false);
        let use_null = s.nullspace != Nullspace::None && s.nullspace_gain > 0.0;
        if use_null {
            for i in 0..n {
                ws.z[i] = s.nullspace_gain * (ws.reference[i] - ws.q[i]);
            }
        }
        loop {
            // J Jᵀ over the free columns (fixed-size rank-1 updates, vectorised).
            let mut jjt = Matrix6::zeros();
            let mut jz = Vector6::zeros();
            for i in 0..n {
                if !ws.locked[i] {
                    let c = &ws.jac[i];
                    jjt.ger(1.0, c, c, 1.0);
                    if use_null {
                        jz += c * ws.z[i];
                    }
                }
            }
            for k in 0..6 {
                jjt[(k, k)] += lambda;
            }
            let Some(chol) = cholesky6(&jjt) else {
                lambda *= s.damping_increase;
                if lambda > s.max_damping {
                    break;
                }
                continue;
            };
            // The step is linear in r: for an astronomically large residual solve with r
            // scaled down and carry the factor, so nothing overflows (the step is capped at
            // `max_step` anyway).
            let factor = if r.amax() > RESIDUAL_SCALE_ABOVE { r.amax() } else { 1.0 };
            let y = cholesky6_solve(&chol, &(r / factor));
            let yz = if use_null { cholesky6_solve(&chol, &jz) } else { Vector6::zeros() };
            let mut newly_locked = false;
            let mut dmax: f64 = 0.0;
            for i in 0..n {
                ws.trial[i] = if ws.locked[i] {
                    0.0
                } else {
                    let mut d = ws.jac[i].dot(&y);
                    if use_null {
                        d += (ws.z[i] - ws.jac[i].dot(&yz)) / factor;
                    }
                    d
                };
                dmax = dmax.max(ws.trial[i].abs());
            }
            // In units of `factor`: the true step is factor·trial.
            let scale = if dmax * factor > s.max_step { s.max_step / dmax } else { factor };
            for i in 0..n {
                let d = ws.trial[i] * scale;
                let at_lo = ws.q[i] <= ws.lo[i] && d < 0.0;
                let at_hi = ws.q[i] >= ws.hi[i] && d > 0.0;
                if !ws.locked[i] && (at_lo || at_hi) {
                    ws.locked[i] = true;
                    newly_locked = true;
                }
                ws.trial[i] = (ws.q[i] + d).clamp(ws.lo[i], ws.hi[i]);
            }
            if newly_locked {
                continue;
            }
            fk(ws, true)?;
            evals += 1;
            let (r_new, pe_new, oe_new) = residual(ws, target, &rt, s);
            let c_new = r_new.norm_squared();
            if c_new < cost {
                ws.q.copy_from_slice(&ws.trial);
                (r, pe, oe, cost) = (r_new, pe_new, oe_new, c_new);
                lambda = (lambda * s.damping_decrease).max(s.min_damping);
                break;
            }
            lambda *= s.damping_increase;
            if lambda > s.max_damping {
                break;
            }
        }
    }
    Ok((cost, pe, oe, it, evals))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The hand-written factorisation agrees with nalgebra's on random SPD matrices and
    /// rejects indefinite ones.
    #[test]
    fn cholesky6_matches_nalgebra() {
        for seed in 0..50u32 {
            let m =
                Matrix6::from_fn(|i, j| ((seed as usize * 36 + i * 6 + j) as f64 * 0.731).sin());
            let a = m * m.transpose() + Matrix6::identity() * 1e-3;
            let b = Vector6::from_fn(|i, _| (i as f64 + seed as f64).cos());
            let x = cholesky6_solve(&cholesky6(&a).unwrap(), &b);
            let reference = a.cholesky().unwrap().solve(&b);
            assert!((x - reference).amax() < 1e-9 * reference.amax().max(1.0));
        }
        assert!(cholesky6(&(-Matrix6::identity())).is_none());
        assert!(cholesky6(&Matrix6::zeros()).is_none());
    }
}
