//! The rigid-motion group SE(3).

use core::ops::Mul;

use nalgebra::{
    Isometry3, Matrix3, Matrix4, Matrix6, Point3, SMatrix, SVector, Translation3, Vector3, Vector6,
};

use crate::LieError;
use crate::group::LieGroup;
use crate::so3::{ROTATION_TOLERANCE, SO3};
use crate::trig_coefficients::{
    RotationCoefficients, inverse_jacobian_coefficient, q_coefficients,
};

/// A rigid transform `x ↦ R x + t`, stored as an [`SO3`] and a translation.
///
/// # Math
/// Tangent vectors are twists `ξ = [v; ω]` (**linear part first**, as in the seed tutorial and
/// Barfoot; sophus uses `[ω; v]`). The Lie-algebra matrix is `ξ^ = [[ω^, v], [0, 0]]` and
///
/// - `exp(ξ) = (exp(ω), Jl_SO3(ω) v)`, `log(T) = [Jl_SO3(ω)⁻¹ t; ω]` with `ω = log(R)`,
/// - `Ad(T) = [[R, t^ R], [0, R]]`,
/// - `jl(ξ) = [[Jl(ω), Q(v, ω)], [0, Jl(ω)]]` with Barfoot's `Q` (State Estimation for
///   Robotics, eq. 7.86), `jr(ξ) = jl(−ξ)`,
///   `jl⁻¹(ξ) = [[Jl⁻¹, −Jl⁻¹ Q Jl⁻¹], [0, Jl⁻¹]]`.
///
/// A screw axis `ξ = [−ω × p; ω]` of a revolute joint through the point `p` gives the joint's
/// motion `exp(ξ θ)`: this is the product-of-exponentials building block.
///
/// # Example
/// ```
/// use armature_lie::SE3;
/// use nalgebra::{Vector3, Vector6};
///
/// // Joint 2 of the seed arm: rotation about y through [0, 0, 0.34].
/// let screw = Vector6::new(-0.34, 0.0, 0.0, 0.0, 1.0, 0.0);
/// let t = SE3::exp(&(screw * 0.3));
/// // Points on the joint axis do not move.
/// let on_axis = Vector3::new(0.0, 0.7, 0.34);
/// assert!((t.act(&on_axis) - on_axis).norm() < 1e-15);
/// assert!((t.log() - screw * 0.3).norm() < 1e-15);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SE3 {
    rotation: SO3,
    translation: Vector3<f64>,
}

/// Barfoot's `Q(ρ, φ)` block of the SE(3) left Jacobian (ρ linear, φ angular):
///
/// `Q = ½ρ^ + c1 (φ^ρ^ + ρ^φ^ + φ^ρ^φ^) + c2 (φ^φ^ρ^ + ρ^φ^φ^ − 3φ^ρ^φ^)
///      + c3 (φ^ρ^φ^φ^ + φ^φ^ρ^φ^)`.
///
/// With `a^b^ = b aᵀ − (a·b) I` and `a^b^a^ = −(a·b) a^` (d = φ·ρ) the seven matrix products
/// collapse to one skew part and a few outer products:
/// `Q = (½ρ + (c2 − c1) d φ + c2 φ×(φ×ρ))^ + c1 (ρφᵀ + φρᵀ) − 2 c3 d φφᵀ
///      + 2d (c3 θ² − c1) I`.
fn q_block(rho: &Vector3<f64>, phi: &Vector3<f64>) -> Matrix3<f64> {
    let theta2 = phi.norm_squared();
    let (c1, c2, c3) = q_coefficients(theta2);
    let d = phi.dot(rho);
    let skew = 0.5 * rho + (c2 - c1) * d * phi + c2 * phi.cross(&phi.cross(rho));
    let mut q = SO3::hat(&skew);
    let diag = 2.0 * d * (c3 * theta2 - c1);
    let e = -2.0 * c3 * d;
    for r in 0..3 {
        for c in 0..3 {
            q[(r, c)] += c1 * (rho[r] * phi[c] + phi[r] * rho[c]) + e * phi[r] * phi[c];
        }
        q[(r, r)] += diag;
    }
    q
}

/// Writes a 6×6 matrix from its four 3×3 blocks.
fn blocks(
    tl: &Matrix3<f64>,
    tr: &Matrix3<f64>,
    bl: &Matrix3<f64>,
    br: &Matrix3<f64>,
) -> Matrix6<f64> {
    let mut m = Matrix6::zeros();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(tl);
    m.fixed_view_mut::<3, 3>(0, 3).copy_from(tr);
    m.fixed_view_mut::<3, 3>(3, 0).copy_from(bl);
    m.fixed_view_mut::<3, 3>(3, 3).copy_from(br);
    m
}

/// Splits a twist into its linear and angular parts.
#[inline]
fn split(xi: &Vector6<f64>) -> (Vector3<f64>, Vector3<f64>) {
    (xi.fixed_rows::<3>(0).into_owned(), xi.fixed_rows::<3>(3).into_owned())
}

impl SE3 {
    /// The identity transform.
    #[inline]
    pub fn identity() -> Self {
        Self { rotation: SO3::identity(), translation: Vector3::zeros() }
    }

    /// The transform with the given rotation and translation.
    #[inline]
    pub fn from_parts(rotation: SO3, translation: Vector3<f64>) -> Self {
        Self { rotation, translation }
    }

    /// A pure translation.
    #[inline]
    pub fn from_translation(translation: Vector3<f64>) -> Self {
        Self { rotation: SO3::identity(), translation }
    }

    /// A pure rotation.
    #[inline]
    pub fn from_rotation(rotation: SO3) -> Self {
        Self { rotation, translation: Vector3::zeros() }
    }

    /// The rotation part.
    #[inline]
    pub fn rotation(&self) -> SO3 {
        self.rotation
    }

    /// The translation part.
    #[inline]
    pub fn translation(&self) -> Vector3<f64> {
        self.translation
    }

    /// Exponential map of a twist `[v; ω]`.
    #[inline]
    pub fn exp(xi: &Vector6<f64>) -> Self {
        let (v, w) = split(xi);
        let k = RotationCoefficients::new(w.norm_squared());
        let wv = w.cross(&v);
        let translation = v + k.b * wv + k.c * w.cross(&wv);
        // Same as SO3::exp, reusing the coefficients computed above.
        let rotation = SO3::from(nalgebra::UnitQuaternion::new_unchecked(
            nalgebra::Quaternion::new(k.w, k.h * w.x, k.h * w.y, k.h * w.z),
        ));
        Self { rotation, translation }
    }

    /// Logarithm: the twist `[v; ω]` with `|ω| ≤ π` and `exp(ξ) = self`.
    #[inline]
    pub fn log(&self) -> Vector6<f64> {
        let w = self.rotation.log();
        let d = inverse_jacobian_coefficient(w.norm_squared());
        let t = &self.translation;
        let wt = w.cross(t);
        let v = t - 0.5 * wt + d * w.cross(&wt);
        Vector6::new(v.x, v.y, v.z, w.x, w.y, w.z)
    }

    /// The Lie-algebra matrix `[[ω^, v], [0, 0]]` of a twist `[v; ω]`.
    pub fn hat(xi: &Vector6<f64>) -> Matrix4<f64> {
        let (v, w) = split(xi);
        let mut m = Matrix4::zeros();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&SO3::hat(&w));
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&v);
        m
    }

    /// Inverse of [`hat`](Self::hat): `[m[0..3, 3]; vee(m[0..3, 0..3])]`.
    pub fn vee(m: &Matrix4<f64>) -> Vector6<f64> {
        let w = SO3::vee(&m.fixed_view::<3, 3>(0, 0).into_owned());
        Vector6::new(m[(0, 3)], m[(1, 3)], m[(2, 3)], w.x, w.y, w.z)
    }

    /// Group product `self · other` (apply `other` first).
    #[inline]
    pub fn compose(&self, other: &Self) -> Self {
        Self {
            rotation: self.rotation.compose(&other.rotation),
            translation: self.rotation.act(&other.translation) + self.translation,
        }
    }

    /// The inverse transform `(Rᵀ, −Rᵀ t)`.
    #[inline]
    pub fn inverse(&self) -> Self {
        let r = self.rotation.inverse();
        Self { rotation: r, translation: -r.act(&self.translation) }
    }

    /// Transforms a point: `R p + t`.
    #[inline]
    pub fn act(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rotation.act(p) + self.translation
    }

    /// Rotates a free vector (no translation): `R v`.
    #[inline]
    pub fn act_vector(&self, v: &Vector3<f64>) -> Vector3<f64> {
        self.rotation.act(v)
    }

    /// Jacobians of `self.act(p)` w.r.t. `self` (right perturbation, 3×6) and `p` (3×3):
    /// `([R, −R p^], R)`.
    pub fn act_jacobians(&self, p: &Vector3<f64>) -> (SMatrix<f64, 3, 6>, Matrix3<f64>) {
        let r = self.rotation.matrix();
        let mut j = SMatrix::<f64, 3, 6>::zeros();
        j.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
        j.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-r * SO3::hat(p)));
        (j, r)
    }

    /// The 6×6 adjoint `[[R, t^ R], [0, R]]` for twists `[v; ω]`.
    pub fn adjoint(&self) -> Matrix6<f64> {
        let r = self.rotation.matrix();
        blocks(&r, &(SO3::hat(&self.translation) * r), &Matrix3::zeros(), &r)
    }

    /// The 4×4 homogeneous matrix `[[R, t], [0, 1]]`.
    pub fn matrix(&self) -> Matrix4<f64> {
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.rotation.matrix());
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&self.translation);
        m
    }

    /// The transform of a 4×4 homogeneous matrix, checked with
    /// [`ROTATION_TOLERANCE`] (bottom row and rotation block).
    ///
    /// # Errors
    /// [`LieError::NotRigidTransform`] for a bottom row other than `[0, 0, 0, 1]`,
    /// [`LieError::NotARotation`] for a bad rotation block, [`LieError::NonFinite`] for NaN/∞.
    pub fn from_matrix(m: &Matrix4<f64>) -> Result<Self, LieError> {
        Self::from_matrix_with_tolerance(m, ROTATION_TOLERANCE)
    }

    /// [`from_matrix`](Self::from_matrix) with an explicit tolerance.
    ///
    /// # Errors
    /// As [`from_matrix`](Self::from_matrix).
    pub fn from_matrix_with_tolerance(m: &Matrix4<f64>, tolerance: f64) -> Result<Self, LieError> {
        if m.iter().any(|x| !x.is_finite()) {
            return Err(LieError::NonFinite { what: "transform matrix" });
        }
        let bottom_row = [m[(3, 0)], m[(3, 1)], m[(3, 2)], m[(3, 3)]];
        let error = bottom_row
            .iter()
            .zip([0.0, 0.0, 0.0, 1.0])
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        if error > tolerance {
            return Err(LieError::NotRigidTransform { bottom_row, error, tolerance });
        }
        let rotation =
            SO3::from_matrix_with_tolerance(&m.fixed_view::<3, 3>(0, 0).into_owned(), tolerance)?;
        Ok(Self { rotation, translation: m.fixed_view::<3, 1>(0, 3).into_owned() })
    }

    /// Interpolation with the translation linear and the rotation by [`SO3::slerp`]
    /// (`t = 0 → self`, `t = 1 → other`): the task-space interpolation of the seed's
    /// `ik_interpolation`. Unlike the SE(3) geodesic it moves the origin on a straight line.
    pub fn interpolate(&self, other: &Self, t: f64) -> Self {
        Self {
            rotation: self.rotation.slerp(&other.rotation, t),
            translation: self.translation + t * (other.translation - self.translation),
        }
    }

    /// Right Jacobian of `exp`: `exp(ξ + δ) ≈ exp(ξ)·exp(jr(ξ)·δ)`.
    pub fn jr(xi: &Vector6<f64>) -> Matrix6<f64> {
        Self::jl(&-xi)
    }

    /// Left Jacobian of `exp`: `exp(ξ + δ) ≈ exp(jl(ξ)·δ)·exp(ξ)`.
    pub fn jl(xi: &Vector6<f64>) -> Matrix6<f64> {
        let (v, w) = split(xi);
        let jl = SO3::jl(&w);
        blocks(&jl, &q_block(&v, &w), &Matrix3::zeros(), &jl)
    }

    /// Inverse of [`jr`](Self::jr); finite for `|ω| < 2π`.
    pub fn jr_inv(xi: &Vector6<f64>) -> Matrix6<f64> {
        Self::jl_inv(&-xi)
    }

    /// Inverse of [`jl`](Self::jl); finite for `|ω| < 2π`.
    pub fn jl_inv(xi: &Vector6<f64>) -> Matrix6<f64> {
        let (v, w) = split(xi);
        let jli = SO3::jl_inv(&w);
        let q = q_block(&v, &w);
        blocks(&jli, &(-jli * q * jli), &Matrix3::zeros(), &jli)
    }

    /// Derivative of the matrix `T(ξ) = exp(ξ)` w.r.t. each twist coordinate:
    /// `∂T/∂ξ_j = T · (jr(ξ) e_j)^`.
    pub fn dexp_dtangent_matrix(xi: &Vector6<f64>) -> [Matrix4<f64>; 6] {
        let t = Self::exp(xi).matrix();
        let jr = Self::jr(xi);
        core::array::from_fn(|j| t * Self::hat(&jr.column(j).into_owned()))
    }

    /// Gradient matrices of `log(T)` w.r.t. the entries of `T`: component `i` changes by
    /// `⟨G_i, dT⟩`. With `g = jr⁻¹(ξ)ᵀ e_i = [g_v; g_ω]`, `G_i` has `½ R g_ω^` in its rotation
    /// block, `R g_v` in its translation column and zeros in the bottom row.
    ///
    /// Like [`SO3::dlog_dmatrix`] this is the derivative along SE(3)
    /// (`δ = [Rᵀ dt; vee(skew(Rᵀ dR))]`), exact for any `T(q)` that stays rigid.
    pub fn dlog_dmatrix(&self) -> [Matrix4<f64>; 6] {
        let r = self.rotation.matrix();
        let jinv = Self::jr_inv(&self.log());
        core::array::from_fn(|i| {
            let g = jinv.row(i).transpose();
            let (gv, gw) = split(&g);
            let mut m = Matrix4::zeros();
            m.fixed_view_mut::<3, 3>(0, 0).copy_from(&(0.5 * r * SO3::hat(&gw)));
            m.fixed_view_mut::<3, 1>(0, 3).copy_from(&(r * gv));
            m
        })
    }
}

impl Default for SE3 {
    fn default() -> Self {
        Self::identity()
    }
}

impl Mul for SE3 {
    type Output = SE3;
    fn mul(self, rhs: SE3) -> SE3 {
        self.compose(&rhs)
    }
}

impl Mul<Point3<f64>> for SE3 {
    type Output = Point3<f64>;
    fn mul(self, rhs: Point3<f64>) -> Point3<f64> {
        Point3::from(self.act(&rhs.coords))
    }
}

impl From<Isometry3<f64>> for SE3 {
    fn from(iso: Isometry3<f64>) -> Self {
        Self { rotation: SO3::from(iso.rotation), translation: iso.translation.vector }
    }
}

impl From<SE3> for Isometry3<f64> {
    fn from(t: SE3) -> Self {
        Isometry3::from_parts(Translation3::from(t.translation), t.rotation.quaternion())
    }
}

impl From<SE3> for Matrix4<f64> {
    fn from(t: SE3) -> Self {
        t.matrix()
    }
}

impl TryFrom<Matrix4<f64>> for SE3 {
    type Error = LieError;
    fn try_from(m: Matrix4<f64>) -> Result<Self, LieError> {
        Self::from_matrix(&m)
    }
}

impl LieGroup<6, 4> for SE3 {
    fn identity() -> Self {
        SE3::identity()
    }
    fn exp(tau: &SVector<f64, 6>) -> Self {
        SE3::exp(tau)
    }
    fn log(&self) -> SVector<f64, 6> {
        SE3::log(self)
    }
    fn hat(tau: &SVector<f64, 6>) -> SMatrix<f64, 4, 4> {
        SE3::hat(tau)
    }
    fn vee(m: &SMatrix<f64, 4, 4>) -> SVector<f64, 6> {
        SE3::vee(m)
    }
    fn compose(&self, other: &Self) -> Self {
        SE3::compose(self, other)
    }
    fn inverse(&self) -> Self {
        SE3::inverse(self)
    }
    fn adjoint(&self) -> SMatrix<f64, 6, 6> {
        SE3::adjoint(self)
    }
    fn matrix(&self) -> SMatrix<f64, 4, 4> {
        SE3::matrix(self)
    }
    fn jr(tau: &SVector<f64, 6>) -> SMatrix<f64, 6, 6> {
        SE3::jr(tau)
    }
    fn jl(tau: &SVector<f64, 6>) -> SMatrix<f64, 6, 6> {
        SE3::jl(tau)
    }
    fn jr_inv(tau: &SVector<f64, 6>) -> SMatrix<f64, 6, 6> {
        SE3::jr_inv(tau)
    }
    fn jl_inv(tau: &SVector<f64, 6>) -> SMatrix<f64, 6, 6> {
        SE3::jl_inv(tau)
    }
}
