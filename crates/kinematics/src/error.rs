//! Errors of the kinematics crate.

/// Why a chain could not be built or loaded.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum KinematicsError {
    /// A joint whose data is invalid.
    #[error("joint {index} ('{name}'): {reason}")]
    BadJoint {
        /// Position in the chain.
        index: usize,
        /// Its name.
        name: String,
        /// What is wrong.
        reason: String,
    },
    /// A keypoint whose data is invalid.
    #[error("keypoint '{name}': {reason}")]
    BadKeypoint {
        /// Its name.
        name: String,
        /// What is wrong.
        reason: String,
    },
    /// The home pose is not a rigid transform.
    #[error("home pose: {0}")]
    BadHome(String),
    /// A name used twice.
    #[error("duplicate {what} name '{name}'")]
    DuplicateName {
        /// `joint` or `keypoint`.
        what: &'static str,
        /// The name.
        name: String,
    },
    /// Base, tip or keypoint links given for a robot that is not a URDF (they choose links
    /// within one).
    #[error("robot '{0}': base, tip and keypoint links apply to URDF robots only")]
    BaseTipNotUrdf(String),
    /// A URDF without a root link (every link is some joint's child): the base must be named.
    #[error("URDF: no root link; name the base link")]
    NoRootLink,
    /// A URDF with several leaf links: the tip must be named.
    #[error("URDF: {} leaf links ({}); name the tip link", leaves.len(), leaves.join(", "))]
    AmbiguousTip {
        /// The leaf links.
        leaves: Vec<String>,
    },
    /// A URDF problem: missing link, a link off the base→tip path, an unsupported joint,
    /// malformed XML.
    #[error("URDF: {0}")]
    Urdf(String),
    /// A robot description file that does not parse or validate, with its location.
    #[error("{location}: {message}")]
    File {
        /// `file:line:col` (or the file alone).
        location: String,
        /// What is wrong.
        message: String,
    },
    /// An unknown built-in robot name.
    #[error(
        "unknown robot '{0}': use a built-in name (arm7, ur5e), a .toml screw table or a .urdf file"
    )]
    UnknownRobot(String),
    /// Joint angles that do not fit the chain.
    #[error("expected {expected} joint values, got {got}")]
    WrongJointCount {
        /// Joints of the chain.
        expected: usize,
        /// Values given.
        got: usize,
    },
    /// A non-finite joint value.
    #[error("joint value {index} is {value}, not a finite number")]
    NonFiniteJoint {
        /// Its index.
        index: usize,
        /// The value.
        value: f64,
    },
    /// A joint whose body has no mass properties, for the rigid-body dynamics.
    #[error("joint '{joint}'{}: no mass properties for the rigid-body dynamics ({})",
        link.as_ref().map(|l| format!(" (link '{l}')")).unwrap_or_default(),
        if link.is_some() { "the URDF gives the links it moves no <inertial>" } else { "give the joint an `inertial`" })]
    NoInertial {
        /// The joint.
        joint: String,
        /// The link it moves, where the source names one.
        link: Option<String>,
    },
    /// A mass matrix that is not positive definite at `q = 0`.
    #[error(
        "the mass matrix is singular at q = 0 from joint '{joint}' on: the bodies after it have no inertia about its axis"
    )]
    SingularMassMatrix {
        /// The first joint whose pivot vanished.
        joint: String,
    },
    /// A gravity vector with a non-finite entry.
    #[error("gravity {0:?} is not finite")]
    BadGravity([f64; 3]),
}
