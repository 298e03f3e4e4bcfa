//! `armature collide`: distances between capsule links and obstacles.

use std::path::PathBuf;

use armature_collision::{CollisionModel, scene_from_toml_str};
use clap::Args;
use serde_json::json;

use super::robot::{RobotArgs, parse_list};
use crate::{CliError, exit};

/// Arguments of `armature collide`.
#[derive(Debug, Clone, Args)]
pub struct CollideArgs {
    /// The robot.
    #[command(flatten)]
    pub robot: RobotArgs,
    /// Joint values, comma-separated.
    #[arg(long, allow_hyphen_values = true)]
    pub q: String,
    /// A TOML scene (links, obstacles, pair options); default for arm7: the seed's collision
    /// variant (four capsules, self-collision, a ball at (0.35, 0, 0.25)).
    #[arg(long)]
    pub scene: Option<PathBuf>,
}

/// Runs `armature collide`: prints `{"pairs": [{"a", "b", "distance", "point_a", "point_b",
/// "in_contact", "gradient"}], "min_distance", "closest_pair"}`.
///
/// # Errors
/// Bad robot, scene or joint values; output failures.
pub fn run(args: &CollideArgs, out: &mut dyn std::io::Write) -> Result<(), CliError> {
    let chain = args.robot.load()?;
    let q = parse_list("--q", &args.q)?;
    chain.check_q(&q).map_err(|e| CliError::bad_input(format!("--q: {e}")))?;
    let model = match &args.scene {
        Some(path) => {
            let text = crate::read_input(path)?;
            let scene = scene_from_toml_str(&text, &path.display().to_string())
                .map_err(CliError::bad_input)?;
            scene
                .model(&chain)
                .map_err(|e| CliError::bad_input(format!("{}: {e}", path.display())))?
        }
        None if chain.name() == "arm7" => {
            CollisionModel::seed_arm7(&chain).map_err(CliError::bad_input)?
        }
        None => {
            return Err(CliError::bad_input(format!(
                "robot '{}' has no default scene: give --scene",
                chain.name()
            )));
        }
    };
    let mut ws = model.workspace(&chain);
    let results = model.evaluate(&chain, &q, &mut ws, true).map_err(CliError::bad_input)?;
    let pairs: Vec<_> = results
        .iter()
        .zip(model.pairs())
        .map(|(r, p)| {
            json!({"a": p.a, "b": p.b, "distance": r.distance, "point_a": r.point_a, "point_b": r.point_b,
                   "in_contact": r.distance <= 0.0, "gradient": r.gradient})
        })
        .collect();
    let closest =
        results.iter().zip(model.pairs()).min_by(|x, y| x.0.distance.total_cmp(&y.0.distance));
    let doc = json!({
        "robot": chain.name(),
        "pairs": pairs,
        "min_distance": closest.map(|c| c.0.distance),
        "closest_pair": closest.map(|c| [c.1.a.clone(), c.1.b.clone()]),
    });
    let text = serde_json::to_string_pretty(&doc)
        .map_err(|e| CliError { message: e.to_string(), code: exit::IO })?;
    writeln!(out, "{text}")
        .map_err(|e| CliError { message: format!("writing the result: {e}"), code: exit::IO })
}
