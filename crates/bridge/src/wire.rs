//! What travels in shared memory: the `#[repr(C)]` trajectory header (followed by a slice of
//! `f64` samples, row by row) and the fixed-size progress message.

use iceoryx2::prelude::*;
use serde::Serialize;

/// Version of the wire layout; a subscriber refuses messages of another version. 2: the
/// progress message marks the iterations that only restored feasibility
/// ([`Progress::feasibility`]).
pub const FORMAT_VERSION: u32 = 2;

/// The blocks of a trajectory row, in order: `[time | angle | velocity | control |
/// ee_position | frames]`. Each block's width is in the header (0 when absent).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Block {
    /// Time (s), width 1.
    Time,
    /// Joint angles (rad).
    Angle,
    /// Joint velocities (rad/s).
    Velocity,
    /// Controls (torques, N·m).
    Control,
    /// End-effector position (m), width 3.
    EePosition,
    /// Keypoint frames, 16 values (4×4 row-major) per keypoint.
    Frames,
}

impl Block {
    /// All blocks in row order.
    pub const ALL: [Block; 6] = [
        Block::Time,
        Block::Angle,
        Block::Velocity,
        Block::Control,
        Block::EePosition,
        Block::Frames,
    ];

    /// The block's column-name stem.
    pub fn name(self) -> &'static str {
        match self {
            Block::Time => "time",
            Block::Angle => "angle",
            Block::Velocity => "velocity",
            Block::Control => "control",
            Block::EePosition => "ee_position",
            Block::Frames => "frames",
        }
    }
}

/// The state of the solve a message comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// An intermediate SCvx iterate.
    Running,
    /// The solve converged.
    Converged,
    /// The iteration cap was reached.
    MaxIterations,
    /// The trust region could not find an acceptable step.
    Stalled,
    /// A subproblem was infeasible.
    SubproblemInfeasible,
    /// The subproblem solver failed.
    NumericalFailure,
    /// Converged at the nodes, but a continuous-time constraint is violated between them.
    ViolatedBetweenNodes,
    /// A constraint stayed violated without progress: a local infeasibility.
    LocallyInfeasible,
}

impl Status {
    /// The wire code.
    pub fn code(self) -> u32 {
        self as u32
    }

    /// From a wire code (`None` for an unknown code).
    pub fn from_code(code: u32) -> Option<Status> {
        [
            Status::Running,
            Status::Converged,
            Status::MaxIterations,
            Status::Stalled,
            Status::SubproblemInfeasible,
            Status::NumericalFailure,
            Status::ViolatedBetweenNodes,
            Status::LocallyInfeasible,
        ]
        .into_iter()
        .find(|s| s.code() == code)
    }

    /// From the solver's status word (`converged`, `max_iterations`, …).
    pub fn from_word(word: &str) -> Option<Status> {
        match word {
            "running" => Some(Status::Running),
            "converged" => Some(Status::Converged),
            "max_iterations" => Some(Status::MaxIterations),
            "stalled" => Some(Status::Stalled),
            "subproblem_infeasible" => Some(Status::SubproblemInfeasible),
            "numerical_failure" => Some(Status::NumericalFailure),
            "violated_between_nodes" => Some(Status::ViolatedBetweenNodes),
            "locally_infeasible" => Some(Status::LocallyInfeasible),
            _ => None,
        }
    }

    /// The status word.
    pub fn word(self) -> &'static str {
        match self {
            Status::Running => "running",
            Status::Converged => "converged",
            Status::MaxIterations => "max_iterations",
            Status::Stalled => "stalled",
            Status::SubproblemInfeasible => "subproblem_infeasible",
            Status::NumericalFailure => "numerical_failure",
            Status::ViolatedBetweenNodes => "violated_between_nodes",
            Status::LocallyInfeasible => "locally_infeasible",
        }
    }
}

/// Header of a trajectory message; `samples` rows of `row_width()` values follow it.
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[type_name("armature::TrajectoryHeader")]
#[repr(C)]
pub struct TrajectoryHeader {
    /// [`FORMAT_VERSION`] of the publisher.
    pub format_version: u32,
    /// [`Status`] code.
    pub status: u32,
    /// Identifies one publisher run (its process id and start time).
    pub run_id: u64,
    /// Message counter of the publisher (1, 2, …).
    pub sequence: u64,
    /// SCvx iteration this trajectory comes from.
    pub iteration: u64,
    /// Final time (s).
    pub final_time: f64,
    /// Number of rows.
    pub samples: u64,
    /// 1 for a dense (post-processed) trajectory, 0 for the nodes of an iterate.
    pub dense: u32,
    /// Width of each [`Block`], in [`Block::ALL`] order.
    pub widths: [u32; 6],
    /// Padding (zero).
    pub reserved: u32,
}

impl TrajectoryHeader {
    /// Values per row.
    pub fn row_width(&self) -> usize {
        self.widths.iter().map(|&w| w as usize).sum()
    }

    /// Column offset of `block` in a row.
    pub fn offset(&self, block: Block) -> usize {
        let i = Block::ALL.iter().position(|b| *b == block).expect("in ALL");
        self.widths[..i].iter().map(|&w| w as usize).sum()
    }

    /// Width of `block`.
    pub fn width(&self, block: Block) -> usize {
        self.widths[Block::ALL.iter().position(|b| *b == block).expect("in ALL")] as usize
    }

    /// Column names: `time`, `angle[0]`, …, `frames[k][i]`.
    pub fn columns(&self) -> Vec<String> {
        let mut names = Vec::with_capacity(self.row_width());
        for b in Block::ALL {
            let w = self.width(b);
            match (b, w) {
                (_, 0) => {}
                (Block::Time, 1) => names.push("time".into()),
                (Block::Frames, _) => {
                    names.extend((0..w).map(|i| format!("frames[{}][{}]", i / 16, i % 16)))
                }
                _ => names.extend((0..w).map(|i| format!("{}[{i}]", b.name()))),
            }
        }
        names
    }

    /// The status (`None` for an unknown code).
    pub fn status(&self) -> Option<Status> {
        Status::from_code(self.status)
    }
}

/// One SCvx iteration's progress (fixed size).
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend, Serialize)]
#[type_name("armature::Progress")]
#[repr(C)]
pub struct Progress {
    /// [`FORMAT_VERSION`] of the publisher.
    pub format_version: u32,
    /// [`Status`] code.
    pub status: u32,
    /// The publisher run.
    pub run_id: u64,
    /// Message counter.
    pub sequence: u64,
    /// SCvx iteration.
    pub iteration: u64,
    /// 1 if the step was accepted.
    pub accepted: u32,
    /// Interior-point iterations of the subproblem.
    pub subproblem_iterations: u32,
    /// 1 if the iteration only restored feasibility (the solve had dropped its cost, which
    /// then reads 0; format version 2 on).
    pub feasibility: u32,
    /// Unused (keeps the fields after it 8-byte aligned without implicit padding).
    pub reserved: u32,
    /// Cost of the candidate.
    pub cost: f64,
    /// Trust-region term ‖Δz‖².
    pub j_tr: f64,
    /// Virtual control.
    pub j_vc: f64,
    /// Virtual buffers.
    pub j_vb: f64,
    /// Largest dynamics defect.
    pub max_defect: f64,
    /// Largest nodal violation.
    pub max_violation: f64,
    /// Final time of the candidate (s).
    pub final_time: f64,
    /// Trust-region weight.
    pub lam_tr: f64,
    /// Discretization wall time (ms).
    pub discretization_ms: f64,
    /// Subproblem wall time (ms).
    pub subproblem_ms: f64,
}
