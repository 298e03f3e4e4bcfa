//! Time-parameterization of a node path: the clamped cubic spline through joint values at
//! given knot times, with zero velocity at both ends.
//!
//! # Math
//! Over normalised time τ ∈ [0, 1] with N nodes and interval lengths `h_k` (Σ h_k = 1), each
//! joint is a cubic per interval with continuous first and second derivatives; the knot
//! accelerations `M_k` solve the tridiagonal system (`Δ_k = (q_{k+1} − q_k)/h_k`)
//!
//! ```text
//! 2h₀M₀ + h₀M₁                               = 6 Δ₀                     (q'(0) = 0)
//! h_{k−1}M_{k−1} + 2(h_{k−1} + h_k)M_k + h_kM_{k+1} = 6 (Δ_k − Δ_{k−1})
//! h_{N−2}M_{N−2} + 2h_{N−2}M_{N−1}            = −6 Δ_{N−2}               (q'(1) = 0)
//! ```
//!
//! The acceleration is piecewise linear in time, so torques `τ = I q̈` sampled at the nodes
//! and held first-order between them reproduce the spline exactly under `q̈ = τ / I`
//! dynamics: the spline is a dynamically consistent initial guess for trajectory
//! optimization. For a duration `T`, velocities scale by `1/T` and accelerations by `1/T²`.
//!
//! [`JointSpline::time_optimal_knots`] chooses the interval lengths: each proportional to the
//! time its largest joint move needs at the velocity limits, so a long move gets a long
//! interval (with uniform knots one long move would slow the whole path).

use crate::IkError;

/// The clamped cubic spline through a joint path: knot accelerations from the clamped
/// tridiagonal system, so FOH torques `τ = I q̈` at the nodes reproduce it exactly.
///
/// ```
/// use armature_ik::JointSpline;
/// let path = vec![vec![0.0], vec![1.0], vec![2.0]];
/// let spline = JointSpline::through(&path).unwrap();
/// // Starts and ends at rest, passes through the middle node moving.
/// assert_eq!(spline.velocity(0, 2.0)[0], 0.0);
/// assert!(spline.velocity(1, 2.0)[0] > 0.0);
/// // The shortest duration with |q̇| ≤ 1 and |q̈| ≤ 10:
/// let t = spline.min_duration(&[1.0], &[10.0]);
/// assert!(spline.peak_velocity()[0] / t <= 1.0 + 1e-12);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct JointSpline {
    nodes: usize,
    dim: usize,
    /// Joint values, node-major.
    q: Vec<f64>,
    /// d²q/dτ² at the nodes, node-major.
    m: Vec<f64>,
    /// Interval lengths in τ (sum 1).
    h: Vec<f64>,
}

impl JointSpline {
    /// Fits the spline through `path` (N ≥ 2 nodes, each of the same length) at uniformly
    /// spaced knots.
    ///
    /// # Errors
    /// [`IkError::BadKeyframes`] for fewer than two nodes, ragged rows or non-finite values.
    pub fn through(path: &[Vec<f64>]) -> Result<JointSpline, IkError> {
        let n = path.len().max(2) - 1;
        JointSpline::through_timed(path, &vec![1.0 / n as f64; n])
    }

    /// Interval lengths for `path` that give each interval the time its largest joint move
    /// needs at `v_max` (at least 5 % of an even share, so standing-still intervals keep some
    /// time to decelerate), normalised to sum 1.
    ///
    /// # Errors
    /// As [`through`](Self::through), and `v_max` of the wrong length or not positive.
    pub fn time_optimal_knots(path: &[Vec<f64>], v_max: &[f64]) -> Result<Vec<f64>, IkError> {
        JointSpline::through(path)?;
        if v_max.len() != path[0].len() || v_max.iter().any(|&v| v.is_nan() || v <= 0.0) {
            return Err(IkError::BadKeyframes(format!(
                "v_max needs {} positive values",
                path[0].len()
            )));
        }
        // The lengths are proportions: limits so small that the steps overflow against them
        // are measured relative to the largest (the same knots for any common scale).
        let steps = |scale: f64| -> Vec<f64> {
            path.windows(2)
                .map(|w| {
                    let step = |j: usize| (w[1][j] - w[0][j]).abs() / (v_max[j] / scale);
                    (0..v_max.len()).map(step).fold(0.0, f64::max)
                })
                .collect()
        };
        let mut d = steps(1.0);
        if !d.iter().sum::<f64>().is_finite() {
            d = steps(v_max.iter().copied().fold(0.0, f64::max));
        }
        let total: f64 = d.iter().sum();
        if !total.is_finite() {
            return Err(IkError::BadKeyframes(
                "v_max: the limits differ too much (the steps overflow against them)".into(),
            ));
        }
        let floor = 0.05 * total.max(1e-9) / d.len() as f64;
        d.iter_mut().for_each(|v| *v = v.max(floor));
        let total: f64 = d.iter().sum();
        Ok(d.into_iter().map(|v| v / total).collect())
    }

    /// Fits the spline through `path` with interval lengths `h` (N − 1 positive values; they
    /// are normalised to sum 1).
    ///
    /// # Errors
    /// [`IkError::BadKeyframes`] for fewer than two nodes, ragged rows, non-finite values or
    /// interval lengths of the wrong count or not positive.
    pub fn through_timed(path: &[Vec<f64>], h: &[f64]) -> Result<JointSpline, IkError> {
        let nodes = path.len();
        if nodes < 2 {
            return Err(IkError::BadKeyframes(format!("a spline needs ≥ 2 nodes, got {nodes}")));
        }
        let dim = path[0].len();
        for (k, row) in path.iter().enumerate() {
            if row.len() != dim || row.iter().any(|v| !v.is_finite()) {
                return Err(IkError::BadKeyframes(format!(
                    "node {k}: {} values (expected {dim}), all finite",
                    row.len()
                )));
            }
        }
        if h.len() != nodes - 1 || h.iter().any(|v| !(*v > 0.0 && v.is_finite())) {
            return Err(IkError::BadKeyframes(format!(
                "{} interval lengths for {nodes} nodes; they must be positive",
                h.len()
            )));
        }
        let total: f64 = h.iter().sum();
        let h: Vec<f64> = h.iter().map(|v| v / total).collect();
        let q: Vec<f64> = path.iter().flatten().copied().collect();
        let mut m = vec![0.0; nodes * dim];
        // Thomas algorithm per joint on the tridiagonal system of the module docs.
        let mut c = vec![0.0; nodes];
        let mut d = vec![0.0; nodes];
        let last = nodes - 1;
        let sub = |k: usize| if k == 0 { 0.0 } else { h[k - 1] };
        let sup = |k: usize| if k == last { 0.0 } else { h[k] };
        let diag = |k: usize| 2.0 * (sub(k) + sup(k));
        for j in 0..dim {
            let slope = |k: usize| (q[(k + 1) * dim + j] - q[k * dim + j]) / h[k];
            let rhs = |k: usize| -> f64 {
                let right = if k == last { 0.0 } else { slope(k) };
                let left = if k == 0 { 0.0 } else { slope(k - 1) };
                6.0 * (right - left)
            };
            c[0] = sup(0) / diag(0);
            d[0] = rhs(0) / diag(0);
            for k in 1..nodes {
                let den = diag(k) - sub(k) * c[k - 1];
                c[k] = sup(k) / den;
                d[k] = (rhs(k) - sub(k) * d[k - 1]) / den;
            }
            m[(nodes - 1) * dim + j] = d[nodes - 1];
            for k in (0..nodes - 1).rev() {
                m[k * dim + j] = d[k] - c[k] * m[(k + 1) * dim + j];
            }
        }
        Ok(JointSpline { nodes, dim, q, m, h })
    }

    /// Number of nodes.
    pub fn nodes(&self) -> usize {
        self.nodes
    }

    /// Interval lengths in normalised time (sum 1): interval `k` lasts `h[k]·T`.
    pub fn intervals(&self) -> &[f64] {
        &self.h
    }

    /// dq/dτ of joint `j` on interval `k` at local fraction `f ∈ [0, 1]`.
    fn dq_dtau(&self, k: usize, j: usize, f: f64) -> f64 {
        let h = self.h[k];
        let (y0, y1) = (self.q[k * self.dim + j], self.q[(k + 1) * self.dim + j]);
        let (m0, m1) = (self.m[k * self.dim + j], self.m[(k + 1) * self.dim + j]);
        let (a, b) = (1.0 - f, f);
        (y1 - y0) / h - (3.0 * a * a - 1.0) / 6.0 * h * m0 + (3.0 * b * b - 1.0) / 6.0 * h * m1
    }

    /// Joint velocities at node `k` for a total duration `duration` (s).
    pub fn velocity(&self, k: usize, duration: f64) -> Vec<f64> {
        (0..self.dim)
            .map(|j| {
                let v = if k + 1 < self.nodes {
                    self.dq_dtau(k, j, 0.0)
                } else {
                    self.dq_dtau(k - 1, j, 1.0)
                };
                v / duration
            })
            .collect()
    }

    /// Joint accelerations at node `k` for a total duration `duration` (s).
    pub fn acceleration(&self, k: usize, duration: f64) -> Vec<f64> {
        self.m[k * self.dim..(k + 1) * self.dim].iter().map(|a| a / (duration * duration)).collect()
    }

    /// Per joint, the largest |dq/dτ| anywhere on the spline (velocities are quadratic per
    /// interval: the extremum is at an end or where the acceleration changes sign).
    pub fn peak_velocity(&self) -> Vec<f64> {
        (0..self.dim)
            .map(|j| {
                let mut peak = 0.0f64;
                for k in 0..self.nodes - 1 {
                    let (m0, m1) = (self.m[k * self.dim + j], self.m[(k + 1) * self.dim + j]);
                    peak =
                        peak.max(self.dq_dtau(k, j, 0.0).abs()).max(self.dq_dtau(k, j, 1.0).abs());
                    if m0 * m1 < 0.0 {
                        peak = peak.max(self.dq_dtau(k, j, m0 / (m0 - m1)).abs());
                    }
                }
                peak
            })
            .collect()
    }

    /// Per joint, the largest |d²q/dτ²| (at a node: the acceleration is piecewise linear).
    pub fn peak_acceleration(&self) -> Vec<f64> {
        (0..self.dim)
            .map(|j| (0..self.nodes).map(|k| self.m[k * self.dim + j].abs()).fold(0.0, f64::max))
            .collect()
    }

    /// The shortest duration for which every joint stays within `|q̇| ≤ v_max` and
    /// `|q̈| ≤ a_max` along the whole spline (0 for a path that does not move).
    pub fn min_duration(&self, v_max: &[f64], a_max: &[f64]) -> f64 {
        let (pv, pa) = (self.peak_velocity(), self.peak_acceleration());
        let mut t = 0.0f64;
        for j in 0..self.dim {
            t = t.max(pv[j] / v_max[j]).max((pa[j] / a_max[j]).sqrt());
        }
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fd_check(s: &JointSpline) {
        // Velocity inside an interval equals the central difference of the cubic.
        for k in 0..s.nodes - 1 {
            let h = s.h[k];
            for j in 0..s.dim {
                let pos = |f: f64| {
                    let (y0, y1) = (s.q[k * s.dim + j], s.q[(k + 1) * s.dim + j]);
                    let (m0, m1) = (s.m[k * s.dim + j], s.m[(k + 1) * s.dim + j]);
                    let (a, b) = (1.0 - f, f);
                    a * y0 + b * y1 + ((a * a * a - a) * m0 + (b * b * b - b) * m1) * h * h / 6.0
                };
                let e = 1e-6;
                let fd = (pos(0.5 + e) - pos(0.5 - e)) / (2.0 * e * h);
                assert!((fd - s.dq_dtau(k, j, 0.5)).abs() < 1e-6 * (1.0 + fd.abs()));
            }
        }
    }

    #[test]
    fn passes_through_nodes_at_rest_at_the_ends_and_is_c1() {
        let path = vec![vec![0.0, 1.0], vec![0.5, -1.0], vec![2.0, 0.0], vec![1.0, 3.0]];
        let s = JointSpline::through(&path).unwrap();
        fd_check(&s);
        for j in 0..2 {
            assert!(s.velocity(0, 1.0)[j].abs() < 1e-12);
            assert!(s.velocity(3, 1.0)[j].abs() < 1e-12);
            // Velocity continuous at interior nodes.
            for k in 1..3 {
                assert!((s.dq_dtau(k - 1, j, 1.0) - s.dq_dtau(k, j, 0.0)).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn timed_knots_follow_the_moves_and_stay_c1() {
        let path = vec![vec![0.0, 0.0], vec![2.0, 0.1], vec![2.1, 0.0], vec![2.1, 1.0]];
        let h = JointSpline::time_optimal_knots(&path, &[1.0, 1.0]).unwrap();
        assert!((h.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert!(h[0] > 10.0 * h[1] && h[2] > 5.0 * h[1]);
        let s = JointSpline::through_timed(&path, &h).unwrap();
        fd_check(&s);
        for j in 0..2 {
            assert!(s.velocity(0, 1.0)[j].abs() < 1e-12 && s.velocity(3, 1.0)[j].abs() < 1e-12);
            for k in 1..3 {
                assert!((s.dq_dtau(k - 1, j, 1.0) - s.dq_dtau(k, j, 0.0)).abs() < 1e-9);
            }
        }
        assert!(JointSpline::through_timed(&path, &[1.0, 0.0, 1.0]).is_err());
        assert!(JointSpline::time_optimal_knots(&path, &[1.0]).is_err());
        // Proportions: limits of any common scale give the same knots, even 1e-308.
        let tiny = JointSpline::time_optimal_knots(&path, &[1e-308, 1e-308]).unwrap();
        assert!(tiny.iter().zip(&h).all(|(a, b)| (a - b).abs() < 1e-12), "{tiny:?}");
        // Limits too far apart for the steps to be measured: an error, not NaN knots.
        assert!(JointSpline::time_optimal_knots(&path, &[1e-308, 1e10]).is_err());
    }

    #[test]
    fn min_duration_meets_both_limits_with_one_active() {
        let path = vec![vec![0.0], vec![1.0], vec![0.0]];
        let s = JointSpline::through(&path).unwrap();
        let t = s.min_duration(&[2.0], &[3.0]);
        let v = s.peak_velocity()[0] / t;
        let a = s.peak_acceleration()[0] / (t * t);
        assert!(v <= 2.0 + 1e-12 && a <= 3.0 + 1e-12);
        assert!((v - 2.0).abs() < 1e-12 || (a - 3.0).abs() < 1e-12);
    }

    #[test]
    fn rejects_bad_paths() {
        assert!(JointSpline::through(&[vec![0.0]]).is_err());
        assert!(JointSpline::through(&[vec![0.0], vec![0.0, 1.0]]).is_err());
        assert!(JointSpline::through(&[vec![0.0], vec![f64::NAN]]).is_err());
    }
}
