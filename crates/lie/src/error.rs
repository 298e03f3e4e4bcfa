//! Errors of the `armature-lie` crate.

/// What went wrong when building a group element from raw data.
///
/// Every variant carries the measured defect and the tolerance it was checked against, so a
/// caller can tell a slightly drifted matrix (renormalise it) from garbage input.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LieError {
    /// A 3×3 matrix (or the rotation block of a 4×4 transform) is not a rotation.
    #[error(
        "not a rotation matrix: |RᵀR − I|_max = {orthogonality_error:.3e}, det(R) = {determinant:.9} \
         (tolerance {tolerance:.1e})"
    )]
    NotARotation {
        /// Largest absolute entry of `RᵀR − I`.
        orthogonality_error: f64,
        /// Determinant of the matrix (a rotation has +1; −1 means a reflection).
        determinant: f64,
        /// Tolerance the check used.
        tolerance: f64,
    },
    /// The bottom row of a 4×4 matrix is not `[0, 0, 0, 1]`.
    #[error(
        "not a rigid transform: bottom row {bottom_row:?} differs from [0, 0, 0, 1] by {error:.3e} \
         (tolerance {tolerance:.1e})"
    )]
    NotRigidTransform {
        /// The bottom row as given.
        bottom_row: [f64; 4],
        /// Largest absolute difference from `[0, 0, 0, 1]`.
        error: f64,
        /// Tolerance the check used.
        tolerance: f64,
    },
    /// A quaternion given as `[w, x, y, z]` does not have unit norm.
    #[error(
        "quaternion [w, x, y, z] = {wxyz:?} has norm {norm}, not 1 (tolerance {tolerance:.1e})"
    )]
    NonUnitQuaternion {
        /// The quaternion as given, `[w, x, y, z]`.
        wxyz: [f64; 4],
        /// Its Euclidean norm.
        norm: f64,
        /// Tolerance the check used on |norm − 1|.
        tolerance: f64,
    },
    /// An input contained NaN or ±∞.
    #[error("{what} contains a non-finite value (NaN or infinity)")]
    NonFinite {
        /// Which input was not finite.
        what: &'static str,
    },
}
