//! Time-optimal path parametrization by reachability analysis (TOPP-RA, Pham & Pham 2018)
//! on a grid of path points `σ_0 < … < σ_M`.
//!
//! Along a fixed path the motion is its speed `ṡ(σ)`; with `x = ṡ²` and `u = s̈`, held
//! constant on each stage `[σ_i, σ_{i+1}]`, `x_{i+1} = x_i + 2Δ_i·u_i` and every constraint
//! linear in the joint accelerations and quadratic in the velocities becomes a row
//! `a·u + b·x ≤ c` of the stage. A backward pass computes each point's controllable set
//! `K_i = [lo_i, hi_i]` (the speeds from which the rest of the path can still be followed
//! to a stop) by eliminating `u` exactly (Fourier–Motzkin on two variables); a forward pass
//! then takes the largest `u_i` that keeps `x_{i+1}` in `K_{i+1}`. The stage's duration is
//! `2Δ_i / (√x_i + √x_{i+1})`.

/// The rows of one stage, `a·u + b·x ≤ c` (flattened triples), and the speed cap `x ≤ x_max`.
#[derive(Debug, Clone, Default)]
pub(crate) struct Stage {
    pub(crate) rows: Vec<[f64; 3]>,
    pub(crate) x_max: f64,
}

/// Why a path cannot be followed within the rows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ToppFailure {
    /// No speed at stage `i` reaches the end at rest.
    Uncontrollable(usize),
    /// The path cannot start from rest.
    StartNotAtRest,
    /// A stage is crossed at zero speed (the path stops in its interior).
    Stalls(usize),
}

/// The time-optimal profile: `x_i = ṡ²` at the points, `u_i = s̈` on the stages, and the
/// times at the points.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Profile {
    pub(crate) x: Vec<f64>,
    pub(crate) u: Vec<f64>,
    pub(crate) t: Vec<f64>,
}

/// Slack of the feasibility tests, relative to the rows' scale.
const SLACK: f64 = 1e-9;

/// The interval of `x ∈ [0, x_max]` for which some `u` satisfies every row (`None`: empty).
fn feasible_x(rows: &[[f64; 3]], x_max: f64) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (0.0f64, x_max);
    let scale = rows.iter().map(|r| r[2].abs()).fold(1.0f64, f64::max);
    let tiny = |a: f64| a.abs() <= 1e-14 * scale;
    let mut bound = |beta: f64, gamma: f64| {
        // β·x ≤ γ
        if beta > 0.0 {
            hi = hi.min(gamma / beta);
        } else if beta < 0.0 {
            lo = lo.max(gamma / beta);
        } else if gamma < -SLACK * scale {
            lo = f64::INFINITY;
        }
    };
    for (i, l) in rows.iter().enumerate() {
        if tiny(l[0]) {
            bound(l[1], l[2]);
            continue;
        }
        for k in &rows[i + 1..] {
            if tiny(k[0]) || (l[0] > 0.0) == (k[0] > 0.0) {
                continue;
            }
            // One row bounds u from below, the other from above: their bounds must not cross.
            let (low, up) = if l[0] < 0.0 { (l, k) } else { (k, l) };
            bound(low[1] * up[0] - up[1] * low[0], low[2] * up[0] - up[2] * low[0]);
        }
    }
    (lo <= hi + SLACK * hi.abs().max(1.0)).then_some((lo, hi.max(lo)))
}

/// The range of `u` the rows allow at speed `x`.
fn u_range(rows: &[[f64; 3]], x: f64) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
    let scale = rows.iter().map(|r| r[2].abs()).fold(1.0f64, f64::max);
    for r in rows {
        if r[0].abs() <= 1e-14 * scale {
            continue;
        }
        let v = (r[2] - r[1] * x) / r[0];
        if r[0] > 0.0 { hi = hi.min(v) } else { lo = lo.max(v) }
    }
    (lo, hi)
}

/// The time-optimal profile over the points of `stages` (one per point; the last point's
/// rows bound the end) with spacings `delta` (`stages.len() − 1` of them), from rest to
/// rest.
pub(crate) fn time_optimal(stages: &[Stage], delta: &[f64]) -> Result<Profile, ToppFailure> {
    let m = delta.len();
    debug_assert_eq!(stages.len(), m + 1);
    let mut lo = vec![0.0; m + 1];
    let mut hi = vec![0.0; m + 1];
    let mut rows = Vec::new();
    for i in (0..m).rev() {
        rows.clear();
        rows.extend_from_slice(&stages[i].rows);
        // x + 2Δu ∈ K_{i+1}
        rows.push([2.0 * delta[i], 1.0, hi[i + 1]]);
        rows.push([-2.0 * delta[i], -1.0, -lo[i + 1]]);
        let (l, h) = feasible_x(&rows, stages[i].x_max).ok_or(ToppFailure::Uncontrollable(i))?;
        (lo[i], hi[i]) = (l, h);
    }
    if lo[0] > SLACK {
        return Err(ToppFailure::StartNotAtRest);
    }
    let mut x = vec![0.0; m + 1];
    let mut u = vec![0.0; m];
    let mut t = vec![0.0; m + 1];
    for i in 0..m {
        let (ulo, uhi) = u_range(&stages[i].rows, x[i]);
        let reach_hi = (hi[i + 1] - x[i]) / (2.0 * delta[i]);
        let reach_lo = (lo[i + 1] - x[i]) / (2.0 * delta[i]);
        let best = uhi.min(reach_hi);
        u[i] = if best >= ulo.max(reach_lo) { best } else { ulo.max(reach_lo) };
        x[i + 1] = (x[i] + 2.0 * delta[i] * u[i]).clamp(lo[i + 1], hi[i + 1]).max(0.0);
        u[i] = (x[i + 1] - x[i]) / (2.0 * delta[i]);
        let speed = x[i].sqrt() + x[i + 1].sqrt();
        if speed <= 0.0 {
            return Err(ToppFailure::Stalls(i));
        }
        t[i + 1] = t[i] + 2.0 * delta[i] / speed;
    }
    Ok(Profile { x, u, t })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A straight path of length `d` for a double integrator, `|q̈| ≤ acc`, `|q̇| ≤ vel`:
    /// with `q(σ) = σ`, the rows are `|u| ≤ acc` and `x ≤ vel²`.
    fn line(d: f64, acc: f64, vel: f64, points: usize) -> (Vec<Stage>, Vec<f64>) {
        let stage = Stage { rows: vec![[1.0, 0.0, acc], [-1.0, 0.0, acc]], x_max: vel * vel };
        (vec![stage; points + 1], vec![d / points as f64; points])
    }

    #[test]
    fn bang_bang_on_a_line_takes_the_analytic_time() {
        // Rest to rest over 1 m with |a| ≤ 2: T = 2·√(d/a) = √2 (the velocity cap unreached).
        let (stages, delta) = line(1.0, 2.0, 10.0, 400);
        let p = time_optimal(&stages, &delta).unwrap();
        assert!((p.t[400] - 2.0f64.sqrt()).abs() < 1e-9, "{}", p.t[400]);
        assert_eq!(p.x[0], 0.0);
        assert!(p.x[400].abs() < 1e-12);
        assert!(p.u.iter().all(|u| u.abs() <= 2.0 + 1e-9));
    }

    #[test]
    fn the_velocity_cap_adds_a_cruise() {
        // With |q̇| ≤ 0.5: accelerate 0.25 s, cruise, decelerate: T = d/v + v/a (the
        // switches, 0.0625 m from either end, fall on the 800-point grid).
        let (stages, delta) = line(1.0, 2.0, 0.5, 800);
        let p = time_optimal(&stages, &delta).unwrap();
        assert!((p.t[800] - (1.0 / 0.5 + 0.5 / 2.0)).abs() < 1e-9, "{}", p.t[800]);
        assert!(p.x.iter().all(|&x| x <= 0.25 + 1e-12));
    }

    #[test]
    fn a_constant_pull_beyond_the_limit_is_uncontrollable() {
        // a·u + b·x ≤ c with c < 0 at x = 0 and no u to help (a = 0): a gravity load the
        // torque cannot hold.
        let mut stages = line(1.0, 2.0, 1.0, 10).0;
        stages[5].rows.push([0.0, 0.0, -1.0]);
        let delta = vec![0.1; 10];
        assert_eq!(time_optimal(&stages, &delta), Err(ToppFailure::Uncontrollable(5)));
    }

    #[test]
    fn a_start_that_cannot_be_at_rest_is_named() {
        // x ≥ 0.5 at the start (−x ≤ −0.5, as a row without u).
        let (mut stages, delta) = line(1.0, 2.0, 1.0, 10);
        stages[0].rows.push([0.0, -1.0, -0.5]);
        assert_eq!(time_optimal(&stages, &delta), Err(ToppFailure::StartNotAtRest));
    }

    #[test]
    fn feasible_x_eliminates_u_exactly() {
        // u ≤ 1 − x, u ≥ x − 1 ⇒ x ≤ 1; with x_max = 3: [0, 1].
        let rows = [[1.0, 1.0, 1.0], [-1.0, 1.0, 1.0]];
        assert_eq!(feasible_x(&rows, 3.0), Some((0.0, 1.0)));
        // u ≤ −1 and u ≥ 0: empty.
        assert_eq!(feasible_x(&[[1.0, 0.0, -1.0], [-1.0, 0.0, 0.0]], 3.0), None);
    }
}
