#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

mod check;
mod dynamics;
mod error;
mod fallback;
mod feasibility;
pub mod fixtures;
mod formulation;
mod guess;
mod multi_start;
mod node_tables;
mod pipeline;
mod plan;
mod refine;
mod resegment;
mod retime;
mod stages;
mod task;

pub use error::{ArmError, TaskItem};
pub use fallback::{Fallbacks, fallback_task, solve_fallbacks};
pub use multi_start::{
    MAX_START_SAMPLES, MultiStart, StartOutcome, StartSummary, best_start, best_start_by,
    scale_timing, solve_starts, solve_starts_with, solve_task_starts_with, start_ik_samples,
    start_time_scale, summarize, summarize_start,
};
pub use pipeline::{Pipeline, PipelineError, Solved};
pub use plan::{ArmPlan, set_retime_stall, waypoint_parameter};
pub use refine::{
    REFINED_TRUST_REGION_WEIGHT, Refinement, join_stages, keep_refined, set_refined_guess,
};
pub use retime::{RetimeStall, Retimed};
pub use stages::{KeptStage, RefinementReport, StageSummary, StartsReport};
pub use task::{
    ArmTask, Clearance, DECOUPLED_STEPS_PER_WAYPOINT_SEGMENT, DynamicsModel, Initialization,
    OrientationRange, RIGID_BODY_SUBSTEPS, TimeWindow, Waypoint,
};
