//! The [`LieGroup`] trait shared by [`SO3`](crate::SO3) and [`SE3`](crate::SE3).

use nalgebra::{SMatrix, SVector};

/// A matrix Lie group of dimension `DOF` represented by `DIM`×`DIM` matrices.
///
/// Conventions (those of manif / Solà et al., "A micro Lie theory"):
/// - `exp: R^DOF → G` and `log: G → R^DOF` go through the Lie algebra with
///   [`hat`](Self::hat) / [`vee`](Self::vee).
/// - Perturbations are **right** perturbations unless a name says left:
///   `X ⊕ τ = X·exp(τ)`, `Y ⊖ X = log(X⁻¹·Y)`.
/// - Jacobians `J = ∂f/∂X` are defined by `f(X ⊕ τ) ≈ f(X) ⊕ J τ`.
/// - `jr(τ)` is the right Jacobian of `exp`: `exp(τ + δ) ≈ exp(τ)·exp(jr(τ)·δ)`;
///   `jl(τ)` the left one: `exp(τ + δ) ≈ exp(jl(τ)·δ)·exp(τ)`; `jr(τ) = jl(−τ)`.
/// - `adjoint(X)` is the matrix with `X·exp(τ)·X⁻¹ = exp(adjoint(X)·τ)`.
pub trait LieGroup<const DOF: usize, const DIM: usize>: Copy + Sized {
    /// The identity element.
    fn identity() -> Self;
    /// Exponential map from tangent coordinates.
    fn exp(tau: &SVector<f64, DOF>) -> Self;
    /// Logarithm: the tangent coordinates of the shortest geodesic from the identity.
    fn log(&self) -> SVector<f64, DOF>;
    /// Tangent coordinates → Lie-algebra matrix.
    fn hat(tau: &SVector<f64, DOF>) -> SMatrix<f64, DIM, DIM>;
    /// Lie-algebra matrix → tangent coordinates (reads the skew/translation parts).
    fn vee(m: &SMatrix<f64, DIM, DIM>) -> SVector<f64, DOF>;
    /// Group product `self · other`.
    fn compose(&self, other: &Self) -> Self;
    /// Group inverse.
    fn inverse(&self) -> Self;
    /// The adjoint matrix `Ad_X`.
    fn adjoint(&self) -> SMatrix<f64, DOF, DOF>;
    /// The homogeneous matrix of the element.
    fn matrix(&self) -> SMatrix<f64, DIM, DIM>;
    /// Right Jacobian of `exp` at `tau`.
    fn jr(tau: &SVector<f64, DOF>) -> SMatrix<f64, DOF, DOF>;
    /// Left Jacobian of `exp` at `tau`.
    fn jl(tau: &SVector<f64, DOF>) -> SMatrix<f64, DOF, DOF>;
    /// Inverse of [`jr`](Self::jr).
    fn jr_inv(tau: &SVector<f64, DOF>) -> SMatrix<f64, DOF, DOF>;
    /// Inverse of [`jl`](Self::jl).
    fn jl_inv(tau: &SVector<f64, DOF>) -> SMatrix<f64, DOF, DOF>;

    /// Right-plus: `self · exp(tau)`.
    fn plus(&self, tau: &SVector<f64, DOF>) -> Self {
        self.compose(&Self::exp(tau))
    }
    /// Right-minus: `log(other⁻¹ · self)`, so that `other.plus(&self.minus(other)) == self`.
    fn minus(&self, other: &Self) -> SVector<f64, DOF> {
        other.inverse().compose(self).log()
    }
    /// Jacobians of `self · other` w.r.t. `self` and `other`: `(Ad(other⁻¹), I)`.
    fn compose_jacobians(&self, other: &Self) -> (SMatrix<f64, DOF, DOF>, SMatrix<f64, DOF, DOF>) {
        (other.inverse().adjoint(), SMatrix::identity())
    }
    /// Jacobian of `self⁻¹` w.r.t. `self`: `−Ad(self)`.
    fn inverse_jacobian(&self) -> SMatrix<f64, DOF, DOF> {
        -self.adjoint()
    }
    /// Jacobian of `log(self)` w.r.t. `self` (right perturbation): `jr⁻¹(log self)`.
    fn log_jacobian(&self) -> SMatrix<f64, DOF, DOF> {
        Self::jr_inv(&self.log())
    }
    /// Jacobian of `exp(tau)` w.r.t. `tau` (right perturbation on the result): `jr(tau)`.
    fn exp_jacobian(tau: &SVector<f64, DOF>) -> SMatrix<f64, DOF, DOF> {
        Self::jr(tau)
    }
}
