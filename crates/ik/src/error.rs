//! Errors of the IK crate (bad input only; an unreachable target is a result, not an error).

/// Bad input to the IK solver.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum IkError {
    /// A settings field out of range.
    #[error("IK settings: {field} {reason}")]
    BadSettings {
        /// The field.
        field: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// A target that is not finite or has a non-unit quaternion.
    #[error("IK target: {0}")]
    BadTarget(String),
    /// A seed of the wrong length or with non-finite values.
    #[error("IK seed: {0}")]
    BadSeed(String),
    /// Keyframes out of order or invalid.
    #[error("keyframes: {0}")]
    BadKeyframes(String),
}
