//! `armature fk`: forward kinematics as JSON.

use clap::Args;
use serde_json::{Map, Value, json};

use super::robot::{RobotArgs, parse_list};
use crate::{CliError, exit};

/// Arguments of `armature fk`.
#[derive(Debug, Clone, Args)]
pub struct FkArgs {
    /// The robot.
    #[command(flatten)]
    pub robot: RobotArgs,
    /// Joint values, comma-separated (rad or m), e.g. `--q 0,0.6,0,-1.2,0,2.17,0`.
    #[arg(long, allow_hyphen_values = true)]
    pub q: String,
}

fn rows(m: &nalgebra::Matrix4<f64>) -> Value {
    json!((0..4).map(|r| (0..4).map(|c| m[(r, c)]).collect::<Vec<_>>()).collect::<Vec<_>>())
}

/// Runs `armature fk`: prints
/// `{"robot", "q", "keypoints": {name: {"position", "frame"}}, "ee": {"position",
/// "quaternion_wxyz", "frame"}}` (frames row-major).
///
/// # Errors
/// Bad robot, wrong number of joint values, non-finite values; output failures.
pub fn run(args: &FkArgs, out: &mut dyn std::io::Write) -> Result<(), CliError> {
    let chain = args.robot.load()?;
    let q = parse_list("--q", &args.q)?;
    let mut ws = chain.fk_workspace();
    chain.forward(&q, &mut ws).map_err(|e| CliError::bad_input(format!("--q: {e}")))?;
    let mut keypoints = Map::new();
    for (k, kp) in chain.keypoints().iter().enumerate() {
        let p = ws.keypoint_position(k);
        keypoints.insert(
            kp.name.clone(),
            json!({"position": [p.x, p.y, p.z], "frame": rows(&ws.keypoint_frame(&chain, k).matrix())}),
        );
    }
    let ee = ws.ee();
    let p = ee.translation();
    let doc = json!({
        "robot": chain.name(),
        "q": q,
        "keypoints": keypoints,
        "ee": {
            "position": [p.x, p.y, p.z],
            "quaternion_wxyz": ee.rotation().quaternion_wxyz(),
            "frame": rows(&ee.matrix()),
        },
    });
    let text = serde_json::to_string_pretty(&doc)
        .map_err(|e| CliError { message: e.to_string(), code: exit::IO })?;
    writeln!(out, "{text}")
        .map_err(|e| CliError { message: format!("writing the result: {e}"), code: exit::IO })
}
