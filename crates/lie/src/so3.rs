//! The rotation group SO(3).

use core::ops::Mul;

use nalgebra::{Matrix3, Quaternion, Rotation3, SMatrix, SVector, UnitQuaternion, Vector3};

use crate::LieError;
use crate::group::LieGroup;
use crate::trig_coefficients::{RotationCoefficients, inverse_jacobian_coefficient, log_factor};

/// Default tolerance of [`SO3::from_matrix`] on `|RᵀR − I|_max` and `|det R − 1|`, and of
/// [`SO3::from_quaternion_wxyz`] on `|‖q‖ − 1|`: loose enough for matrices printed with
/// 7 significant digits, tight enough to reject anything that is not a rotation.
pub const ROTATION_TOLERANCE: f64 = 1e-6;

/// A 3D rotation, stored as a unit quaternion canonicalised to `w ≥ 0`.
///
/// # Math
/// Tangent vectors are rotation vectors `ω ∈ R³` (axis × angle, rad);
/// `exp(ω) = I + sin θ/θ · ω^ + (1 − cos θ)/θ² · ω^²` with `θ = |ω|` (Rodrigues), and
/// `log` returns the rotation vector with `|ω| ≤ π`. At exactly `θ = π` both `ω` and `−ω`
/// are valid logarithms; `log` returns the one whose first nonzero component is positive.
/// Jacobians follow the right-perturbation convention of [`LieGroup`]:
///
/// - `jr(ω) = I − (1 − cos θ)/θ² ω^ + (θ − sin θ)/θ³ ω^²`, `jl(ω) = jr(−ω)`,
/// - `jr⁻¹(ω) = I + ½ω^ + (1/θ² − cot(θ/2)/(2θ)) ω^²`.
///
/// Every formula switches to a Taylor series below
/// [`SMALL_ANGLE`](crate::SMALL_ANGLE), so nothing is NaN for finite input.
///
/// # Example
/// ```
/// use armature_lie::SO3;
/// use nalgebra::Vector3;
/// use std::f64::consts::FRAC_PI_2;
///
/// // Ry(90°) turns the gripper's +x axis to world −z (the seed's "gripper down").
/// let down = SO3::rot_y(FRAC_PI_2);
/// let x = down.act(&Vector3::x());
/// assert!((x - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-15);
/// assert!((down.log() - Vector3::new(0.0, FRAC_PI_2, 0.0)).norm() < 1e-15);
/// assert_eq!(down.quaternion_wxyz()[0] >= 0.0, true);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SO3 {
    /// Invariant: unit norm, `w > 0`, or `w == 0` with the first nonzero of (x, y, z) positive.
    q: UnitQuaternion<f64>,
}

/// `ω^² = ωωᵀ − |ω|² I`, without a matrix product.
#[inline]
fn hat_squared(omega: &Vector3<f64>) -> Matrix3<f64> {
    omega * omega.transpose() - Matrix3::from_diagonal_element(omega.norm_squared())
}

/// Canonicalises a (unit) quaternion to the hemisphere `w ≥ 0`.
#[inline]
fn canonical(q: Quaternion<f64>) -> UnitQuaternion<f64> {
    let flip = if q.w != 0.0 {
        q.w < 0.0
    } else if q.i != 0.0 {
        q.i < 0.0
    } else if q.j != 0.0 {
        q.j < 0.0
    } else {
        q.k < 0.0
    };
    UnitQuaternion::new_unchecked(if flip { -q } else { q })
}

impl SO3 {
    /// The identity rotation.
    #[inline]
    pub fn identity() -> Self {
        Self { q: UnitQuaternion::identity() }
    }

    /// Rotation about the x axis by `angle` rad.
    pub fn rot_x(angle: f64) -> Self {
        Self::exp(&Vector3::new(angle, 0.0, 0.0))
    }

    /// Rotation about the y axis by `angle` rad.
    pub fn rot_y(angle: f64) -> Self {
        Self::exp(&Vector3::new(0.0, angle, 0.0))
    }

    /// Rotation about the z axis by `angle` rad.
    pub fn rot_z(angle: f64) -> Self {
        Self::exp(&Vector3::new(0.0, 0.0, angle))
    }

    /// Exponential map of a rotation vector.
    #[inline]
    pub fn exp(omega: &Vector3<f64>) -> Self {
        let k = RotationCoefficients::new(omega.norm_squared());
        Self { q: canonical(Quaternion::new(k.w, k.h * omega.x, k.h * omega.y, k.h * omega.z)) }
    }

    /// Logarithm: the rotation vector `ω` with `|ω| ≤ π` and `exp(ω) = self`.
    ///
    /// Computed from the quaternion as `ω = 2·atan2(|v|, w)·v/|v|`, which stays exact up to
    /// and including `θ = π` (no `acos` of a trace).
    #[inline]
    pub fn log(&self) -> Vector3<f64> {
        let q = self.q.quaternion();
        let v = q.imag();
        v * log_factor(v.norm_squared(), q.w)
    }

    /// The skew-symmetric matrix `ω^` with `ω^ x = ω × x`.
    #[inline]
    pub fn hat(omega: &Vector3<f64>) -> Matrix3<f64> {
        Matrix3::new(0.0, -omega.z, omega.y, omega.z, 0.0, -omega.x, -omega.y, omega.x, 0.0)
    }

    /// Inverse of [`hat`](Self::hat); reads the skew-symmetric part `(M − Mᵀ)/2` of `m`.
    #[inline]
    pub fn vee(m: &Matrix3<f64>) -> Vector3<f64> {
        Vector3::new(
            0.5 * (m[(2, 1)] - m[(1, 2)]),
            0.5 * (m[(0, 2)] - m[(2, 0)]),
            0.5 * (m[(1, 0)] - m[(0, 1)]),
        )
    }

    /// Group product `self · other` (apply `other` first).
    #[inline]
    pub fn compose(&self, other: &Self) -> Self {
        Self { q: canonical((self.q * other.q).into_inner()) }
    }

    /// The inverse rotation.
    #[inline]
    pub fn inverse(&self) -> Self {
        // The conjugate keeps w, so it stays canonical except for the w = 0 tie-break.
        Self { q: canonical(self.q.conjugate().into_inner()) }
    }

    /// Rotates a vector (or a point: SO(3) fixes the origin).
    #[inline]
    pub fn act(&self, v: &Vector3<f64>) -> Vector3<f64> {
        self.q.transform_vector(v)
    }

    /// Jacobians of `self.act(p)` w.r.t. `self` (right perturbation) and `p`:
    /// `(−R p^, R)`.
    pub fn act_jacobians(&self, p: &Vector3<f64>) -> (Matrix3<f64>, Matrix3<f64>) {
        let r = self.matrix();
        (-r * Self::hat(p), r)
    }

    /// The adjoint matrix; for SO(3) it is the rotation matrix itself.
    #[inline]
    pub fn adjoint(&self) -> Matrix3<f64> {
        self.matrix()
    }

    /// The 3×3 rotation matrix.
    #[inline]
    pub fn matrix(&self) -> Matrix3<f64> {
        let q = self.q.quaternion();
        let (w, x, y, z) = (q.w, q.i, q.j, q.k);
        let (x2, y2, z2) = (x + x, y + y, z + z);
        let (xx, yy, zz) = (x * x2, y * y2, z * z2);
        let (xy, xz, yz) = (x * y2, x * z2, y * z2);
        let (wx, wy, wz) = (w * x2, w * y2, w * z2);
        Matrix3::new(
            1.0 - yy - zz,
            xy - wz,
            xz + wy,
            xy + wz,
            1.0 - xx - zz,
            yz - wx,
            xz - wy,
            yz + wx,
            1.0 - xx - yy,
        )
    }

    /// The rotation of a 3×3 matrix, checked with [`ROTATION_TOLERANCE`].
    ///
    /// # Errors
    /// [`LieError::NotARotation`] (with the measured defect) when `RᵀR` differs from `I` or
    /// `det R` from 1 by more than the tolerance; [`LieError::NonFinite`] for NaN/∞ entries.
    pub fn from_matrix(m: &Matrix3<f64>) -> Result<Self, LieError> {
        Self::from_matrix_with_tolerance(m, ROTATION_TOLERANCE)
    }

    /// [`from_matrix`](Self::from_matrix) with an explicit tolerance.
    ///
    /// # Errors
    /// As [`from_matrix`](Self::from_matrix).
    pub fn from_matrix_with_tolerance(m: &Matrix3<f64>, tolerance: f64) -> Result<Self, LieError> {
        if m.iter().any(|x| !x.is_finite()) {
            return Err(LieError::NonFinite { what: "rotation matrix" });
        }
        let orthogonality_error = (m.transpose() * m - Matrix3::identity()).amax();
        let determinant = m.determinant();
        if orthogonality_error > tolerance || (determinant - 1.0).abs() > tolerance {
            return Err(LieError::NotARotation { orthogonality_error, determinant, tolerance });
        }
        Ok(Self::from_matrix_unchecked(m))
    }

    /// The rotation whose quaternion Shepperd's method extracts from `m`, renormalised; no
    /// check. For a matrix near SO(3) this is a rotation close to it; for a rotation matrix it
    /// is exact, including at θ = π. NaN entries give a NaN rotation.
    pub fn from_matrix_unchecked(m: &Matrix3<f64>) -> Self {
        let (m00, m11, m22) = (m[(0, 0)], m[(1, 1)], m[(2, 2)]);
        let tr = m00 + m11 + m22;
        let q = if tr > 0.0 {
            let s = 2.0 * (tr + 1.0).sqrt();
            Quaternion::new(
                0.25 * s,
                (m[(2, 1)] - m[(1, 2)]) / s,
                (m[(0, 2)] - m[(2, 0)]) / s,
                (m[(1, 0)] - m[(0, 1)]) / s,
            )
        } else if m00 > m11 && m00 > m22 {
            let s = 2.0 * (1.0 + m00 - m11 - m22).sqrt();
            Quaternion::new(
                (m[(2, 1)] - m[(1, 2)]) / s,
                0.25 * s,
                (m[(0, 1)] + m[(1, 0)]) / s,
                (m[(0, 2)] + m[(2, 0)]) / s,
            )
        } else if m11 > m22 {
            let s = 2.0 * (1.0 + m11 - m00 - m22).sqrt();
            Quaternion::new(
                (m[(0, 2)] - m[(2, 0)]) / s,
                (m[(0, 1)] + m[(1, 0)]) / s,
                0.25 * s,
                (m[(1, 2)] + m[(2, 1)]) / s,
            )
        } else {
            let s = 2.0 * (1.0 + m22 - m00 - m11).sqrt();
            Quaternion::new(
                (m[(1, 0)] - m[(0, 1)]) / s,
                (m[(0, 2)] + m[(2, 0)]) / s,
                (m[(1, 2)] + m[(2, 1)]) / s,
                0.25 * s,
            )
        };
        // Shepperd's branch choice makes |s| ≥ 1 for any matrix near SO(3); NaN input gives a
        // NaN rotation (use `from_matrix` to get an error instead).
        let n = q.norm();
        if n == 0.0 {
            return Self::identity();
        }
        Self { q: canonical(q / n) }
    }

    /// The rotation of a quaternion given as `[w, x, y, z]`, checked to be unit within
    /// [`ROTATION_TOLERANCE`] and then renormalised.
    ///
    /// # Errors
    /// [`LieError::NonUnitQuaternion`] or [`LieError::NonFinite`].
    pub fn from_quaternion_wxyz(wxyz: [f64; 4]) -> Result<Self, LieError> {
        if wxyz.iter().any(|x| !x.is_finite()) {
            return Err(LieError::NonFinite { what: "quaternion" });
        }
        let q = Quaternion::new(wxyz[0], wxyz[1], wxyz[2], wxyz[3]);
        let norm = q.norm();
        if (norm - 1.0).abs() > ROTATION_TOLERANCE {
            return Err(LieError::NonUnitQuaternion { wxyz, norm, tolerance: ROTATION_TOLERANCE });
        }
        Ok(Self { q: canonical(q / norm) })
    }

    /// The quaternion as `[w, x, y, z]` with `w ≥ 0`.
    pub fn quaternion_wxyz(&self) -> [f64; 4] {
        let q = self.q.quaternion();
        [q.w, q.i, q.j, q.k]
    }

    /// The canonical (`w ≥ 0`) unit quaternion.
    pub fn quaternion(&self) -> UnitQuaternion<f64> {
        self.q
    }

    /// The rotation angle in `[0, π]`.
    pub fn angle(&self) -> f64 {
        let q = self.q.quaternion();
        2.0 * q.imag().norm().atan2(q.w)
    }

    /// Spherical linear interpolation `self · exp(t · log(self⁻¹ · other))`: constant angular
    /// velocity along the shortest arc, `t = 0 → self`, `t = 1 → other`.
    pub fn slerp(&self, other: &Self, t: f64) -> Self {
        self.compose(&Self::exp(&(t * self.inverse().compose(other).log())))
    }

    /// Right Jacobian of `exp`: `exp(ω + δ) ≈ exp(ω)·exp(jr(ω)·δ)`.
    pub fn jr(omega: &Vector3<f64>) -> Matrix3<f64> {
        let k = RotationCoefficients::new(omega.norm_squared());
        Matrix3::identity() - k.b * Self::hat(omega) + k.c * hat_squared(omega)
    }

    /// Left Jacobian of `exp`: `exp(ω + δ) ≈ exp(jl(ω)·δ)·exp(ω)`.
    pub fn jl(omega: &Vector3<f64>) -> Matrix3<f64> {
        let k = RotationCoefficients::new(omega.norm_squared());
        Matrix3::identity() + k.b * Self::hat(omega) + k.c * hat_squared(omega)
    }

    /// Inverse of [`jr`](Self::jr); finite for `|ω| < 2π`.
    pub fn jr_inv(omega: &Vector3<f64>) -> Matrix3<f64> {
        let d = inverse_jacobian_coefficient(omega.norm_squared());
        Matrix3::identity() + 0.5 * Self::hat(omega) + d * hat_squared(omega)
    }

    /// Inverse of [`jl`](Self::jl); finite for `|ω| < 2π`.
    pub fn jl_inv(omega: &Vector3<f64>) -> Matrix3<f64> {
        let d = inverse_jacobian_coefficient(omega.norm_squared());
        Matrix3::identity() - 0.5 * Self::hat(omega) + d * hat_squared(omega)
    }

    /// Derivative of the matrix `R(ω) = exp(ω)` w.r.t. each tangent coordinate:
    /// `∂R/∂ω_j = R · (jr(ω) e_j)^`, for the chain rule through matrix-valued expressions.
    pub fn dexp_dtangent_matrix(omega: &Vector3<f64>) -> [Matrix3<f64>; 3] {
        let r = Self::exp(omega).matrix();
        let jr = Self::jr(omega);
        core::array::from_fn(|j| r * Self::hat(&jr.column(j).into_owned()))
    }

    /// Gradient matrices of `log(R)` w.r.t. the entries of `R`: component `i` changes by
    /// `⟨G_i, dR⟩ = Σ_rc G_i[r,c]·dR[r,c]`, with `G_i = ½ R (jr⁻¹(ω)ᵀ e_i)^`.
    ///
    /// This is the derivative along SO(3) (it sees `dR` through `vee(skew(Rᵀ dR))`), which is
    /// exact for any `R(q)` that stays a rotation — the only case a chain rule meets. `log`
    /// is discontinuous at θ = π, where this returns the one-sided limit.
    pub fn dlog_dmatrix(&self) -> [Matrix3<f64>; 3] {
        let r = self.matrix();
        let jinv = Self::jr_inv(&self.log());
        core::array::from_fn(|i| 0.5 * r * Self::hat(&jinv.row(i).transpose()))
    }
}

impl Default for SO3 {
    fn default() -> Self {
        Self::identity()
    }
}

impl Mul for SO3 {
    type Output = SO3;
    fn mul(self, rhs: SO3) -> SO3 {
        self.compose(&rhs)
    }
}

impl Mul<Vector3<f64>> for SO3 {
    type Output = Vector3<f64>;
    fn mul(self, rhs: Vector3<f64>) -> Vector3<f64> {
        self.act(&rhs)
    }
}

impl From<UnitQuaternion<f64>> for SO3 {
    fn from(q: UnitQuaternion<f64>) -> Self {
        Self { q: canonical(q.into_inner()) }
    }
}

impl From<SO3> for UnitQuaternion<f64> {
    fn from(r: SO3) -> Self {
        r.q
    }
}

impl From<Rotation3<f64>> for SO3 {
    fn from(r: Rotation3<f64>) -> Self {
        Self::from_matrix_unchecked(r.matrix())
    }
}

impl From<SO3> for Rotation3<f64> {
    fn from(r: SO3) -> Self {
        Rotation3::from_matrix_unchecked(r.matrix())
    }
}

impl TryFrom<Matrix3<f64>> for SO3 {
    type Error = LieError;
    fn try_from(m: Matrix3<f64>) -> Result<Self, LieError> {
        Self::from_matrix(&m)
    }
}

impl LieGroup<3, 3> for SO3 {
    fn identity() -> Self {
        SO3::identity()
    }
    fn exp(tau: &SVector<f64, 3>) -> Self {
        SO3::exp(tau)
    }
    fn log(&self) -> SVector<f64, 3> {
        SO3::log(self)
    }
    fn hat(tau: &SVector<f64, 3>) -> SMatrix<f64, 3, 3> {
        SO3::hat(tau)
    }
    fn vee(m: &SMatrix<f64, 3, 3>) -> SVector<f64, 3> {
        SO3::vee(m)
    }
    fn compose(&self, other: &Self) -> Self {
        SO3::compose(self, other)
    }
    fn inverse(&self) -> Self {
        SO3::inverse(self)
    }
    fn adjoint(&self) -> SMatrix<f64, 3, 3> {
        SO3::adjoint(self)
    }
    fn matrix(&self) -> SMatrix<f64, 3, 3> {
        SO3::matrix(self)
    }
    fn jr(tau: &SVector<f64, 3>) -> SMatrix<f64, 3, 3> {
        SO3::jr(tau)
    }
    fn jl(tau: &SVector<f64, 3>) -> SMatrix<f64, 3, 3> {
        SO3::jl(tau)
    }
    fn jr_inv(tau: &SVector<f64, 3>) -> SMatrix<f64, 3, 3> {
        SO3::jr_inv(tau)
    }
    fn jl_inv(tau: &SVector<f64, 3>) -> SMatrix<f64, 3, 3> {
        SO3::jl_inv(tau)
    }
}
