//! A checked task as a problem with its initial guess.

use armature_ik::IkTrajectory;
use armature_scvx::{CompiledProblem, Problem, ProblemError, PtrSettings, Time};

use crate::dynamics::Resolved;
use crate::{ArmError, ArmTask, RetimeStall, TaskItem, check, feasibility, formulation, guess};

/// An [`ArmTask`] as an SCvx [`Problem`], with its initial guess.
#[derive(Debug, Clone)]
pub struct ArmPlan {
    /// The problem (states `angle`, `velocity`; control `torque`; outputs `ee_position`,
    /// `ee_pose`, `T_<keypoint>` and, with collision, `clearance`).
    pub problem: Problem,
    /// The guess of each segment's duration (the time dilation, N values).
    pub dilation_guess: Vec<f64>,
    /// The IK through the waypoints behind the guess.
    pub ik: IkTrajectory,
    /// Solver settings.
    pub settings: PtrSettings,
    /// The task and its [`RetimeStall`] rule when the solve stops minimizing once its path
    /// retimed stalls (`None`: it minimizes to the end).
    pub retime_stall: Option<(RetimeStall, Box<ArmTask>)>,
}

/// Name of the parameter holding waypoint `name`'s position (change it between solves with
/// `CompiledProblem::set_parameter`).
pub fn waypoint_parameter(name: &str) -> String {
    format!("waypoint.{name}")
}

impl ArmTask {
    /// Checks the task and builds the problem and its guess.
    ///
    /// Before the problem is built, what would make it infeasible is named: a waypoint out of
    /// reach within the joint limits (alone, or under the orientation range that holds at its
    /// node), a start configuration in collision.
    ///
    /// # Errors
    /// An [`ArmError`] naming the part of the task at fault ([`TaskItem`]).
    pub fn plan(&self) -> Result<ArmPlan, ArmError> {
        check::check(self)?;
        let dynamics = Resolved::new(&self.dynamics, &self.chain)?;
        let guess = guess::initial_guess(self, &dynamics)?;
        feasibility::start_clear(self, &guess.ik.q[0])?;
        feasibility::waypoints_reachable(self, &guess.ik)?;
        let mut problem = formulation::states_and_dynamics(self, &dynamics, &guess);
        problem.time = Time::Free {
            min: self.time.min,
            max: self.time.max,
            guess: guess.duration,
            minimize: self.time.minimize,
        };
        formulation::add_task_constraints(&mut problem, self)
            .map_err(|e| ArmError::new(TaskItem::Robot, e))?;
        Ok(ArmPlan {
            problem,
            dilation_guess: guess.dilation,
            ik: guess.ik,
            settings: self.settings.clone(),
            retime_stall: self.retime_stall.map(|r| (r, Box::new(self.clone()))),
        })
    }
}

/// Sets `stall`'s monitor (`(rule, task)`, as [`ArmPlan::retime_stall`]) on `c`, if any.
pub fn set_retime_stall(c: &mut CompiledProblem, stall: Option<&(RetimeStall, Box<ArmTask>)>) {
    if let Some((rule, task)) = stall {
        c.set_monitor(Some(rule.monitor((**task).clone(), c.layout().clone())));
    }
}

impl ArmPlan {
    /// Compiles the problem and sets the guess.
    ///
    /// # Errors
    /// The problem layer's (for a planned task, a bug rather than bad input).
    pub fn compile(&self) -> Result<CompiledProblem, ProblemError> {
        let mut c = self.problem.compile(self.settings.clone())?;
        c.set_dilation_guess(&self.dilation_guess)?;
        set_retime_stall(&mut c, self.retime_stall.as_ref());
        Ok(c)
    }
}
