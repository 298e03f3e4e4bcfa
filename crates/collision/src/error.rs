//! Errors of the collision crate.

/// What is wrong with a collision model, scene or query.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CollisionError {
    /// A link names a keypoint the chain does not have.
    #[error("unknown keypoint '{name}' (the robot's keypoints: {})", valid.join(", "))]
    UnknownKeypoint {
        /// The name given.
        name: String,
        /// The chain's keypoint names.
        valid: Vec<String>,
    },
    /// Invalid model data.
    #[error("{0}")]
    Bad(String),
    /// A scene file problem with its location (`file:line:col`).
    #[error("{location}: {message}")]
    File {
        /// Where.
        location: String,
        /// What.
        message: String,
    },
    /// Bad joint values.
    #[error("{0}")]
    Kinematics(String),
}
