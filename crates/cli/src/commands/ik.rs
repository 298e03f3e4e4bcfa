//! `armature ik`: inverse kinematics for one target or a keyframe file.

use std::path::PathBuf;

use armature_ik::{IkSettings, IkWorkspace, Keyframe, Mode, Target, ik_interpolation, solve};
use clap::Args;
use nalgebra::Vector3;
use serde::Deserialize;
use serde_json::json;

use super::robot::{RobotArgs, parse_list};
use crate::{CliError, exit};

/// Arguments of `armature ik`.
#[derive(Debug, Clone, Args)]
pub struct IkArgs {
    /// The robot.
    #[command(flatten)]
    pub robot: RobotArgs,
    /// Target position x,y,z (m).
    #[arg(
        long,
        allow_hyphen_values = true,
        conflicts_with = "keyframes",
        required_unless_present = "keyframes"
    )]
    pub pos: Option<String>,
    /// Target orientation as a quaternion w,x,y,z (default: position only).
    #[arg(long, allow_hyphen_values = true, requires = "pos")]
    pub quat: Option<String>,
    /// Seed joint values (default: zeros).
    #[arg(long, allow_hyphen_values = true)]
    pub seed: Option<String>,
    /// Random restarts when an attempt does not converge (at most 1,000).
    #[arg(long, default_value_t = 8)]
    pub restarts: usize,
    /// A TOML file of keyframes (`[[keyframes]] node, position, quaternion_wxyz`; optional
    /// top-level `seed`): IK at every node of the interpolated path.
    #[arg(long)]
    pub keyframes: Option<PathBuf>,
    /// With --keyframes: seed each node from the previous one (continuous path) instead of
    /// solving all nodes in parallel from the same seed.
    #[arg(long, requires = "keyframes", conflicts_with = "branches")]
    pub sequential: bool,
    /// With --keyframes: the path of least joint travel over IK branches (a beam search:
    /// no jumps between branches where a continuous path exists; --restarts random
    /// configurations at each keyframe).
    #[arg(long, requires = "keyframes")]
    pub branches: bool,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct KeyframeFile {
    #[serde(default)]
    seed: Option<Vec<f64>>,
    keyframes: Vec<Keyframe>,
}

fn print(out: &mut dyn std::io::Write, v: &serde_json::Value) -> Result<(), CliError> {
    let text = serde_json::to_string_pretty(v)
        .map_err(|e| CliError { message: e.to_string(), code: exit::IO })?;
    writeln!(out, "{text}")
        .map_err(|e| CliError { message: format!("writing the result: {e}"), code: exit::IO })
}

/// Runs `armature ik`. Exit code 0 when every solve converged, [`exit::NOT_CONVERGED`] when
/// one did not (the JSON still reports the best configuration), [`exit::BAD_INPUT`] for bad
/// input.
///
/// # Errors
/// Bad robot, target, seed or keyframe file; output failures; not converged.
pub fn run(args: &IkArgs, out: &mut dyn std::io::Write) -> Result<(), CliError> {
    if args.restarts > armature_ik::MAX_RESTARTS {
        return Err(CliError::bad_input(format!(
            "--restarts {}: at most {}",
            args.restarts,
            armature_ik::MAX_RESTARTS
        )));
    }
    let chain = args.robot.load()?;
    let settings = IkSettings { restarts: args.restarts, ..IkSettings::default() };
    let mut seed = match &args.seed {
        Some(s) => parse_list("--seed", s)?,
        None => vec![0.0; chain.dof()],
    };
    let converged = if let Some(path) = &args.keyframes {
        let text = crate::read_input(path)?;
        let file: KeyframeFile = toml::from_str(&text).map_err(|e| {
            let at = e.span().map(|s| {
                let before = &text[..s.start];
                format!(
                    ":{}:{}",
                    before.matches('\n').count() + 1,
                    before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1
                )
            });
            CliError::bad_input(format!(
                "{}{}: {}",
                path.display(),
                at.unwrap_or_default(),
                e.message()
            ))
        })?;
        if let (Some(s), None) = (&file.seed, &args.seed) {
            seed.clone_from(s);
        }
        let mode = match (args.sequential, args.branches) {
            (true, _) => Mode::Sequential,
            (_, true) => Mode::Branches,
            _ => Mode::Parallel,
        };
        let t = ik_interpolation(&chain, &file.keyframes, &seed, &settings, mode)
            .map_err(CliError::bad_input)?;
        print(
            out,
            &json!({"robot": chain.name(), "mode": mode, "max_joint_step": t.max_joint_step, "nodes": t.nodes}),
        )?;
        t.all_converged()
    } else {
        let pos = parse_list("--pos", args.pos.as_deref().unwrap_or_default())?;
        if pos.len() != 3 {
            return Err(CliError::bad_input(format!(
                "--pos: expected 3 values, got {}",
                pos.len()
            )));
        }
        let p = Vector3::new(pos[0], pos[1], pos[2]);
        let target = match &args.quat {
            Some(q) => {
                let q = parse_list("--quat", q)?;
                let q: [f64; 4] = q.try_into().map_err(|q: Vec<f64>| {
                    CliError::bad_input(format!(
                        "--quat: expected 4 values (w,x,y,z), got {}",
                        q.len()
                    ))
                })?;
                Target::pose(p, q).map_err(|e| CliError::bad_input(format!("--quat: {e}")))?
            }
            None => Target::position(p),
        };
        let r = solve(&chain, &target, &seed, &settings, &mut IkWorkspace::new(&chain))
            .map_err(CliError::bad_input)?;
        print(out, &json!(r))?;
        r.converged
    };
    if converged {
        Ok(())
    } else {
        Err(CliError {
            message: "IK did not converge (the best configuration found is printed)".into(),
            code: exit::NOT_CONVERGED,
        })
    }
}
