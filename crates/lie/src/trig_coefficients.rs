//! Scalar coefficient functions of the rotation angle θ that appear in the closed forms of
//! exp, log and the Jacobians, each with a Taylor branch near θ = 0.
//!
//! All functions take θ² (never θ alone where avoidable) so callers need no square root for
//! the small-angle branch. Each Taylor series is carried to the θ⁸ term, so that at the
//! switching threshold the truncation error is far below f64 round-off, and each closed form
//! is only used where its cancellation error is below ~1e-11 relative.

/// Below this rotation angle (rad) the first-order coefficient functions `sin θ/θ`,
/// `(1−cos θ)/θ²`, `sin(θ/2)/θ`, `cos(θ/2)` and the SO(3) log use their Taylor series (to θ⁸:
/// truncation ~1e-20 here). Their closed forms do not cancel badly, so the switch is early.
pub const SMALL_ANGLE: f64 = 1e-2;

/// Below this rotation angle (rad) the higher-order coefficients — `(θ − sin θ)/θ³`,
/// `1/θ² − cot(θ/2)/(2θ)` (of `jr⁻¹`) and the SE(3) `Q` coefficients up to
/// `(2θ − 3 sin θ + θ cos θ)/(2θ⁵)` — use their Taylor series (to θ⁸: truncation < 1e-16
/// relative at 0.2). Their closed forms cancel to O(ε/θ²)…O(ε/θ⁴) relative, which is
/// below 1e-11 only from about this angle on.
pub const SMALL_ANGLE_HIGH_ORDER: f64 = 0.2;

const SMALL2: f64 = SMALL_ANGLE * SMALL_ANGLE;
const SMALL2_HIGH: f64 = SMALL_ANGLE_HIGH_ORDER * SMALL_ANGLE_HIGH_ORDER;

/// Evaluates `c0 + c1 t + c2 t² + c3 t³ + c4 t⁴` (with t = θ²) by Horner's rule.
#[inline(always)]
fn series(t: f64, c: [f64; 5]) -> f64 {
    c[0] + t * (c[1] + t * (c[2] + t * (c[3] + t * c[4])))
}

/// The coefficients of the SO(3) exponential and its Jacobians for a rotation angle θ.
///
/// `a = sin θ / θ`, `b = (1 − cos θ)/θ²`, `c = (θ − sin θ)/θ³`, so that
/// `exp(ω^) = I + a ω^ + b ω^²`, `Jl(ω) = I + b ω^ + c ω^²`, `Jr(ω) = I − b ω^ + c ω^²`;
/// `h = sin(θ/2)/θ` and `w = cos(θ/2)` give the unit quaternion `exp(ω) = (w, h ω)`.
/// One `sin_cos` call computes all five.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct RotationCoefficients {
    pub(crate) a: f64,
    pub(crate) b: f64,
    pub(crate) c: f64,
    pub(crate) h: f64,
    pub(crate) w: f64,
}

impl RotationCoefficients {
    /// Coefficients from θ² (θ ≥ 0).
    #[inline]
    pub(crate) fn new(theta2: f64) -> Self {
        let c = if theta2 < SMALL2_HIGH {
            series(
                theta2,
                [1.0 / 6.0, -1.0 / 120.0, 1.0 / 5040.0, -1.0 / 362880.0, 1.0 / 39916800.0],
            )
        } else {
            let theta = theta2.sqrt();
            (theta - theta.sin()) / (theta2 * theta)
        };
        if theta2 < SMALL2 {
            Self {
                a: series(theta2, [1.0, -1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0, 1.0 / 362880.0]),
                b: series(theta2, [0.5, -1.0 / 24.0, 1.0 / 720.0, -1.0 / 40320.0, 1.0 / 3628800.0]),
                c,
                h: series(
                    theta2,
                    [0.5, -1.0 / 48.0, 1.0 / 3840.0, -1.0 / 645120.0, 1.0 / 185794560.0],
                ),
                w: series(theta2, [1.0, -1.0 / 8.0, 1.0 / 384.0, -1.0 / 46080.0, 1.0 / 10321920.0]),
            }
        } else {
            let theta = theta2.sqrt();
            // sin θ = 2 sin(θ/2) cos(θ/2) and 1 − cos θ = 2 sin²(θ/2): one sin_cos call,
            // and no cancellation in b.
            let (sh, ch) = (0.5 * theta).sin_cos();
            Self { a: 2.0 * sh * ch / theta, b: 2.0 * sh * sh / theta2, c, h: sh / theta, w: ch }
        }
    }
}

/// `d(θ) = 1/θ² − (1 + cos θ)/(2 θ sin θ) = 1/θ² − cot(θ/2)/(2θ)`, the ω^² coefficient of
/// `Jl⁻¹(ω) = I − ½ω^ + d ω^²` and `Jr⁻¹(ω) = I + ½ω^ + d ω^²`.
///
/// Written with cot(θ/2) it is finite at θ = π (d(π) = 1/π²); it is singular only at
/// θ = 2π, where Jl is singular.
#[inline]
pub(crate) fn inverse_jacobian_coefficient(theta2: f64) -> f64 {
    if theta2 < SMALL2_HIGH {
        series(theta2, [1.0 / 12.0, 1.0 / 720.0, 1.0 / 30240.0, 1.0 / 1209600.0, 1.0 / 47900160.0])
    } else {
        let theta = theta2.sqrt();
        let (sh, ch) = (0.5 * theta).sin_cos();
        1.0 / theta2 - ch / (2.0 * theta * sh)
    }
}

/// Coefficients of Barfoot's `Q(ρ, φ)` block of the SE(3) left Jacobian:
/// `c1 = (θ − sin θ)/θ³`, `c2 = (θ²/2 + cos θ − 1)/θ⁴`, `c3 = (2θ − 3 sin θ + θ cos θ)/(2θ⁵)`.
#[inline]
pub(crate) fn q_coefficients(theta2: f64) -> (f64, f64, f64) {
    if theta2 < SMALL2_HIGH {
        (
            series(
                theta2,
                [1.0 / 6.0, -1.0 / 120.0, 1.0 / 5040.0, -1.0 / 362880.0, 1.0 / 39916800.0],
            ),
            series(
                theta2,
                [1.0 / 24.0, -1.0 / 720.0, 1.0 / 40320.0, -1.0 / 3628800.0, 1.0 / 479001600.0],
            ),
            series(
                theta2,
                [1.0 / 120.0, -1.0 / 2520.0, 1.0 / 120960.0, -1.0 / 9979200.0, 1.0 / 1245404160.0],
            ),
        )
    } else {
        let theta = theta2.sqrt();
        let (s, c) = theta.sin_cos();
        // cos θ − 1 = −2 sin²(θ/2): the numerator of c2 then cancels only to ε·θ², not ε.
        let sh = (0.5 * theta).sin();
        (
            (theta - s) / (theta2 * theta),
            (0.5 * theta2 - 2.0 * sh * sh) / (theta2 * theta2),
            (2.0 * theta - 3.0 * s + theta * c) / (2.0 * theta2 * theta2 * theta),
        )
    }
}

/// `atan(x)/x`-based factor of the SO(3) log from a canonical quaternion (w ≥ 0, |v| = n):
/// returns `θ/n` where `θ = 2·atan2(n, w)`, so that `ω = (θ/n)·v`.
#[inline]
pub(crate) fn log_factor(n2: f64, w: f64) -> f64 {
    // θ < SMALL_ANGLE  ⇔  n = sin(θ/2) < sin(SMALL_ANGLE/2) ≈ SMALL_ANGLE/2.
    if n2 < 0.25 * SMALL2 && w > 0.0 {
        // θ/n = (2/w)·atan(x)/x with x = n/w ≤ 5e-3: series to x⁸ (error ~1e-21).
        let x2 = n2 / (w * w);
        (2.0 / w) * series(x2, [1.0, -1.0 / 3.0, 1.0 / 5.0, -1.0 / 7.0, 1.0 / 9.0])
    } else {
        let n = n2.sqrt();
        2.0 * n.atan2(w) / n
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Both branches agree at and around every threshold.
    #[test]
    fn branches_are_continuous_at_thresholds() {
        for &t in &[SMALL_ANGLE, SMALL_ANGLE_HIGH_ORDER] {
            let lo = (t * (1.0 - 1e-12)).powi(2);
            let hi = (t * (1.0 + 1e-12)).powi(2);
            let (a, b) = (RotationCoefficients::new(lo), RotationCoefficients::new(hi));
            assert!((a.a - b.a).abs() < 1e-13 && (a.b - b.b).abs() < 1e-13);
            assert!((a.c - b.c).abs() < 1e-12);
            assert!(
                (inverse_jacobian_coefficient(lo) - inverse_jacobian_coefficient(hi)).abs() < 1e-12
            );
            let (qa, qb) = (q_coefficients(lo), q_coefficients(hi));
            assert!((qa.0 - qb.0).abs() < 1e-12);
            assert!((qa.1 - qb.1).abs() < 1e-11);
            assert!((qa.2 - qb.2).abs() < 1e-11, "{qa:?} {qb:?}");
            assert!((a.h - b.h).abs() < 1e-13 && (a.w - b.w).abs() < 1e-13);
        }
    }

    #[test]
    fn known_values() {
        let c = RotationCoefficients::new(0.0);
        assert_eq!((c.a, c.b, c.c), (1.0, 0.5, 1.0 / 6.0));
        let pi2 = std::f64::consts::PI.powi(2);
        assert!((inverse_jacobian_coefficient(pi2) - 1.0 / pi2).abs() < 1e-15);
        let c = RotationCoefficients::new(pi2);
        assert!(c.a.abs() < 1e-15 && (c.b - 2.0 / pi2).abs() < 1e-15);
        assert!((log_factor(1.0, 0.0) - std::f64::consts::PI).abs() < 1e-15);
        assert_eq!(log_factor(0.0, 1.0), 2.0);
    }
}
