//! `armature view`: the interactive 3D view of an existing result file.

use std::io::Write as _;
use std::path::PathBuf;

use clap::Args;

use crate::task::Source;
use crate::view::{Scene, ViewData};
use crate::{CliError, output};

/// Arguments of `armature view`.
#[derive(Debug, Clone, Args)]
pub struct ViewArgs {
    /// The result file (the JSON of `armature solve -o`).
    pub result: PathBuf,
    /// Where to write the page (one self-contained HTML file).
    #[arg(short = 'o', long = "output", value_name = "FILE")]
    pub output: PathBuf,
    /// Take the geometry (robot, obstacles, waypoints, limits) from this task file instead
    /// of the result's own `scene`.
    #[arg(long, value_name = "FILE")]
    pub task: Option<PathBuf>,
    /// Print nothing but errors.
    #[arg(short, long)]
    pub quiet: bool,
}

fn read(path: &std::path::Path) -> Result<String, CliError> {
    crate::read_input(path)
}

/// Runs `armature view`.
///
/// # Errors
/// A result or task file that cannot be read or does not fit ([`crate::exit::BAD_INPUT`]),
/// or a page that cannot be written ([`crate::exit::IO`]).
pub fn run(args: &ViewArgs, _out: &mut dyn std::io::Write) -> Result<(), CliError> {
    let name = args.result.display().to_string();
    let mut data =
        ViewData::from_result_json(&name, &read(&args.result)?).map_err(CliError::bad_input)?;
    if let Some(task) = &args.task {
        let text = read(task)?;
        let task_name = task.display().to_string();
        let loaded = super::solve::load(Source { name: &task_name, text: &text }, Some(task))?;
        let plan = loaded.plan.ok_or_else(|| {
            CliError::bad_input(format!(
                "{task_name}: a problem file has no robot geometry; give a task file"
            ))
        })?;
        data.scene = Some(Scene::from_plan(&plan));
        data.check().map_err(|e| {
            CliError::bad_input(format!("{name} with the geometry of {task_name}: {e}"))
        })?;
    }
    let mut inputs = vec![args.result.as_path()];
    inputs.extend(args.task.as_deref());
    crate::output_set::check_destinations(&[&args.output], &[], &inputs)?;
    let mut set = crate::output_set::OutputSet::default();
    output::write_html(&data, &args.output, &mut set)?;
    for path in set.commit()? {
        if !args.quiet {
            let _ = writeln!(std::io::stderr(), "wrote {}", path.display());
        }
    }
    Ok(())
}
