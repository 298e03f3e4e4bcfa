//! Robot selection shared by the commands (`--robot`, `--base`, `--tip`).

use armature_kinematics::Chain;
use clap::Args;

use crate::CliError;

/// Which robot: a built-in name, a `.toml` screw table or a `.urdf` file.
#[derive(Debug, Clone, Args)]
pub struct RobotArgs {
    /// Built-in name (arm7, ur5e), a .toml screw table, or a .urdf file.
    #[arg(long, default_value = "arm7")]
    pub robot: String,
    /// URDF base link (default: the root link).
    #[arg(long)]
    pub base: Option<String>,
    /// URDF tip link (default: the single leaf link).
    #[arg(long)]
    pub tip: Option<String>,
}

impl RobotArgs {
    /// Loads the chain.
    ///
    /// # Errors
    /// A bad-input [`CliError`] saying what is wrong and where.
    pub fn load(&self) -> Result<Chain, CliError> {
        armature_kinematics::load_robot(&self.robot, self.base.as_deref(), self.tip.as_deref())
            .map_err(|e| {
                let hint = match e {
                    armature_kinematics::KinematicsError::NoRootLink => ": give --base LINK",
                    armature_kinematics::KinematicsError::AmbiguousTip { .. } => {
                        ": give --tip LINK"
                    }
                    _ => "",
                };
                CliError::bad_input(format!("{e}{hint}"))
            })
    }
}

/// Parses a comma-separated list of finite numbers, naming the bad entry.
///
/// # Errors
/// A bad-input [`CliError`].
pub fn parse_list(what: &str, text: &str) -> Result<Vec<f64>, CliError> {
    text.split(',')
        .enumerate()
        .map(|(i, s)| match s.trim().parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            Ok(v) => Err(CliError::bad_input(format!(
                "{what}: entry {} is {v}, not a finite number",
                i + 1
            ))),
            Err(_) => Err(CliError::bad_input(format!(
                "{what}: entry {} ('{}') is not a number",
                i + 1,
                s.trim()
            ))),
        })
        .collect()
}
