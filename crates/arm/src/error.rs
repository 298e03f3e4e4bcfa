//! Why a task cannot become a problem.

/// The part of an [`ArmTask`](crate::ArmTask) an error is about, so that a front end can
/// point at where the user wrote it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TaskItem {
    /// The robot (its dynamics model, limits, kinematics).
    Robot,
    /// The dynamics model.
    Dynamics,
    /// The velocity limits.
    VelocityLimit,
    /// The torque limits.
    TorqueLimit,
    /// The start configuration.
    Start,
    /// The time window.
    Time,
    /// The node count.
    Nodes,
    /// Waypoint `i`.
    Waypoint(usize),
    /// Orientation range `i`.
    Orientation(usize),
    /// The table height.
    Table,
    /// The collision model.
    Collision,
    /// The initial guess (IK, spline).
    Initialization,
    /// The solution given to [`ArmTask::retime`](crate::ArmTask::retime).
    Solution,
}

/// A task that cannot become a problem: what is wrong and which part of the task it is.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{message}")]
pub struct ArmError {
    /// Where in the task.
    pub item: TaskItem,
    /// What is wrong.
    pub message: String,
}

impl ArmError {
    pub(crate) fn new(item: TaskItem, message: impl Into<String>) -> ArmError {
        ArmError { item, message: message.into() }
    }
}
