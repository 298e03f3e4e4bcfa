//! `armature solve`: the full pipeline from a task file.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

use armature_bridge::{BridgeError, Status};
use armature_scvx::{IterationTable, PtrStatus, Solution};
use clap::Args;

use crate::output::{KeptStage, RefinementReport, ResultFile, StageSummary, StartsReport};
use crate::output_set::OutputSet;
use crate::pipeline::{arm_task, plan_arm, refinement, retiming};
use crate::retimed::RetimedResult;
use crate::streaming::{Streamer, wire_status};
use crate::task::{Source, parse};
use crate::view::{Iterate, Scene, ViewData};
use crate::{CliError, exit, output};

/// Where the results go (shared by `solve` and `demo`).
#[derive(Debug, Clone, Default, Args)]
pub struct OutputArgs {
    /// Write the result as JSON to this file (`-` for standard output).
    #[arg(short = 'o', long = "output")]
    pub output: Option<PathBuf>,
    /// Write `nodes.csv` and `trajectory.csv` into this folder (and `retimed.csv`, the
    /// retimed trajectory, when the task retimes).
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Write plots (SVG and PNG) into this folder.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Write an interactive 3D view of the result (one self-contained HTML file).
    #[arg(long, value_name = "FILE")]
    pub html: Option<PathBuf>,
    /// Print nothing but errors (no iteration table, no summary).
    #[arg(short, long)]
    pub quiet: bool,
    /// Publish every SCvx iterate (nodes and progress) and the final dense trajectory (the
    /// retimed one when the task retimes) over iceoryx2 as run RUN (services
    /// `armature/RUN/trajectory` and `armature/RUN/progress`).
    #[arg(long, value_name = "RUN")]
    pub stream: Option<String>,
    /// With --stream: keep serving the final trajectory to late subscribers this many seconds.
    #[arg(long, value_name = "SECONDS", default_value_t = 0.0, requires = "stream")]
    pub linger: f64,
}

/// Arguments of `armature solve`.
#[derive(Debug, Clone, Args)]
pub struct SolveArgs {
    /// The task file (TOML).
    pub file: PathBuf,
    /// Outputs.
    #[command(flatten)]
    pub output: OutputArgs,
}

/// Runs `armature solve`.
///
/// # Errors
/// Bad input ([`exit::BAD_INPUT`], `file:line:col: reason`), output failures, or a solve
/// that did not converge ([`exit::NOT_CONVERGED`], after writing its result).
pub fn run(args: &SolveArgs, out: &mut dyn std::io::Write) -> Result<(), CliError> {
    let text = crate::read_input(&args.file)?;
    let name = args.file.display().to_string();
    run_task(Source { name: &name, text: &text }, Some(&args.file), &args.output, out)
}

/// A task or problem file, checked and compiled.
#[derive(Debug)]
pub struct Loaded {
    /// The task's plan (robot, waypoints, …); `None` for a problem file.
    pub plan: Option<crate::pipeline::Plan>,
    /// The compiled problem with its guess.
    pub compiled: armature_scvx::CompiledProblem,
    /// Keypoint names (the frames block of streamed trajectories).
    pub keypoints: Vec<String>,
    /// The files read: the task or problem file and a robot file (outputs must not be them).
    pub inputs: Vec<PathBuf>,
    /// With `[nodes] refine = K > 1`: K, and the task on the grid K times finer, planned and
    /// compiled, solved from the first stage's solution.
    pub refined: Option<(usize, crate::pipeline::Plan, armature_scvx::CompiledProblem)>,
    /// With `[initialization] starts = K > 1`: K, and the task, whose other starts plan their
    /// own IK paths ([`armature_arm::ArmTask::start`]).
    pub starts: Option<(usize, armature_arm::ArmTask)>,
    /// With `[time] retime` (the default where the time is minimized): the task, to retime
    /// its solution along the solved path.
    pub retime: Option<armature_arm::ArmTask>,
    /// With `[initialization] fallbacks = K > 0` (the default): the task, to solve it again
    /// from other guesses when the first stage does not converge.
    pub fallback: Option<armature_arm::ArmTask>,
}

/// Parses, checks and compiles a task file or a problem file (recognised by its
/// `[[states]]`).
///
/// # Errors
/// Bad input, as `file:line:col: reason`.
pub fn load(src: Source<'_>, path: Option<&Path>) -> Result<Loaded, CliError> {
    if crate::problem_file::is_problem(src.text) {
        let file = crate::problem_file::parse(src).map_err(CliError::bad_input)?;
        let (problem, settings) =
            crate::problem_file::build(&file, src).map_err(CliError::bad_input)?;
        let compiled = problem
            .compile(settings)
            .map_err(|e| CliError::bad_input(crate::problem_file::locate(&file, src, &e)))?;
        let inputs = path.map(Path::to_path_buf).into_iter().collect();
        let keypoints = Vec::new();
        let (refined, starts, retime, fallback) = (None, None, None, None);
        let loaded =
            Loaded { plan: None, compiled, keypoints, inputs, refined, starts, retime, fallback };
        return Ok(loaded);
    }
    let task = parse(src).map_err(CliError::bad_input)?;
    let arm = arm_task(&task, src, path).map_err(CliError::bad_input)?;
    let factor = refinement(&task, src, &arm).map_err(CliError::bad_input)?;
    let fine = (factor > 1).then(|| arm.refined(factor));
    let starts = (arm.initialization.starts > 1).then(|| (arm.initialization.starts, arm.clone()));
    let fallback = (arm.initialization.fallbacks > 0).then(|| arm.clone());
    let retime = retiming(&task, src).map_err(CliError::bad_input)?.then(|| arm.clone());
    let plan = plan_arm(&task, src, arm).map_err(CliError::bad_input)?;
    let compile = |plan: &crate::pipeline::Plan| {
        plan.compile().map_err(|e| CliError::bad_input(locate(&task, src, &e)))
    };
    let compiled = compile(&plan)?;
    let refined = match fine {
        Some(fine) => {
            let plan = plan_arm(&task, src, fine).map_err(CliError::bad_input)?;
            let compiled = compile(&plan)?;
            Some((factor, plan, compiled))
        }
        None => None,
    };
    let keypoints = plan.chain.keypoint_names().map(str::to_string).collect();
    let robot = crate::task::resolve_robot(task.robot.name.get_ref(), path);
    let inputs = path.map(Path::to_path_buf).into_iter().chain([PathBuf::from(robot)]).collect();
    Ok(Loaded { plan: Some(plan), compiled, keypoints, inputs, refined, starts, retime, fallback })
}

/// A problem-layer error of a planned task (the task's checks let few through): at the
/// `[time]` maximum or the setting it names, else at the file's start.
fn locate(
    task: &crate::task::TaskFile,
    src: Source<'_>,
    e: &armature_scvx::ProblemError,
) -> crate::task::LocatedError {
    let what = crate::settings::error_subject(e);
    let at = match what {
        "time" | "dilation" => Some(task.time.max.span().start),
        _ => crate::settings::setting_span(src.text, what),
    };
    src.error_at(at.unwrap_or(0), e.to_string())
}

/// An error of the solve itself, located: an integration that fails (Dormand–Prince
/// tolerances it cannot meet, a state that stops being finite) at `[settings]`'s integrator
/// where the file chose one, else at the file's start.
fn solve_error(src: Source<'_>, e: &armature_scvx::ProblemError) -> crate::task::LocatedError {
    use armature_scvx::{ProblemError, PtrError};
    let at = match e {
        ProblemError::Ptr(PtrError::Discretization(_)) => {
            crate::settings::setting_span(src.text, "discretization.integrator")
                .or_else(|| crate::settings::setting_span(src.text, "discretization"))
        }
        _ => None,
    };
    src.error_at(at.unwrap_or(0), format!("the solve failed: {e}"))
}

/// Checks the destinations `o` names before solving (see [`crate::output_set`]).
fn check_outputs(o: &OutputArgs, inputs: &[PathBuf]) -> Result<(), CliError> {
    let mut files: Vec<PathBuf> =
        o.output.iter().filter(|p| p.as_os_str() != "-").cloned().collect();
    files.extend(o.html.iter().cloned());
    if let Some(dir) = &o.csv {
        files.extend(["nodes.csv", "trajectory.csv", "retimed.csv"].map(|n| dir.join(n)));
    }
    let files: Vec<&Path> = files.iter().map(PathBuf::as_path).collect();
    let dirs: Vec<&Path> = o.csv.iter().chain(&o.plot).map(PathBuf::as_path).collect();
    let inputs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    crate::output_set::check_destinations(&files, &dirs, &inputs)
}

/// Prints a progress line unless quiet. A closed standard error (`2>&1 | head`) must not
/// stop the solve or the writing of its results: progress lines are best effort.
fn say(quiet: bool, line: &str) {
    if !quiet {
        let _ = writeln!(std::io::stderr(), "{line}");
    }
}

/// The first line: what was loaded.
fn describe(name: &str, loaded: &mut Loaded) -> String {
    match &loaded.plan {
        Some(plan) => {
            let converged_ik = plan.ik.nodes.iter().filter(|r| r.converged).count();
            format!(
                "{}: {} joints, {} nodes, {} waypoints{}; IK initialization: {converged_ik}/{} nodes converged, largest joint step {:.3} rad",
                name,
                plan.chain.dof(),
                plan.nodes,
                plan.waypoints.len(),
                plan.collision
                    .as_ref()
                    .map_or(String::new(), |m| format!(", {} collision pairs", m.pairs().len())),
                plan.nodes,
                plan.ik.max_joint_step
            )
        }
        None => {
            let ocp = loaded.compiled.ptr().ocp();
            format!(
                "{name}: problem file, {} states, {} controls, {} nodes",
                ocp.dynamics.n_x(),
                ocp.dynamics.n_u(),
                ocp.nodes
            )
        }
    }
}

/// The publisher of `--stream RUN`, if asked for (with `--linger` checked first).
fn start_stream(o: &OutputArgs, keypoints: &[String]) -> Result<Option<Streamer>, CliError> {
    let Some(run) = &o.stream else { return Ok(None) };
    let max = crate::streaming::MAX_WAIT_SECONDS;
    if !(o.linger.is_finite() && (0.0..=max).contains(&o.linger)) {
        return Err(CliError::bad_input(format!(
            "--linger {}: give seconds ≥ 0 and at most {max:e}",
            o.linger
        )));
    }
    let s = Streamer::new(run, keypoints)
        .map_err(|e| crate::streaming::bridge_error("--stream: ", e))?;
    say(o.quiet, &format!("streaming on armature/{run}/trajectory and armature/{run}/progress"));
    Ok(Some(s))
}

/// Where a solve stands among the stages of a refinement (see [`solve_observed`]).
#[derive(Debug, Clone, Copy)]
struct Stage {
    offset: usize,
    last: bool,
}

/// Solves, printing the iteration table, collecting the iterates the view draws and
/// publishing each iterate and then the dense trajectory when streaming.
///
/// `stage`: the iterations of the stages before this one, and whether another follows. The
/// iterations are numbered on from the earlier stages' (in the table, the iterates and the
/// stream's sequence), and a stage that converges with another to follow reports its last
/// iteration as still running: only the final stage's end is the solve's.
fn solve_observed(
    loaded: &mut Loaded,
    streamer: &mut Option<Streamer>,
    (src, quiet): (Source<'_>, bool),
    stage: Stage,
) -> Result<(Solution, Vec<Iterate>), CliError> {
    if !quiet {
        let _ = IterationTable::header(&mut std::io::stderr());
    }
    let layout = loaded.compiled.layout().clone();
    let mut stream_error = None;
    let task = loaded.plan.is_some();
    let mut iterates: Vec<Iterate> = loaded.plan.as_ref().map(guess_iterate).into_iter().collect();
    let solution = loaded
        .compiled
        .solve_with(|it, traj| {
            let mut it = it.clone();
            it.iteration += stage.offset;
            if !stage.last && it.status == Some(PtrStatus::Converged) {
                it.status = None;
            }
            let it = &it;
            if !quiet {
                let _ = IterationTable::row(&mut std::io::stderr(), it);
            }
            if task {
                iterates.extend(ee_iterate(&layout, it.iteration, traj));
            }
            if let (Some(s), None) = (streamer.as_mut(), &stream_error) {
                let status = it.status.map_or(Status::Running, wire_status);
                let sent = s.progress(it).and_then(|_| {
                    let tables = layout
                        .nodal_tables(traj)
                        .map_err(|e| BridgeError::BadData(e.to_string()))?;
                    s.publish(&tables, it.iteration as u64, status, traj.final_time, false)
                });
                if let Err(e) = sent {
                    stream_error = Some(e);
                }
            }
        })
        .map_err(|e| CliError::bad_input(solve_error(src, &e)))?;
    if let Some(e) = stream_error {
        // Streaming the iterates failed: the solve went on, its result is still written.
        say(quiet, &format!("warning: --stream stopped: {e}"));
        *streamer = None;
    }
    Ok((solution, iterates))
}

/// Publishes the final dense trajectory (after the outputs are written: streaming never costs
/// the result), decimated when it does not fit one message.
fn publish_final(
    streamer: &mut Option<Streamer>,
    solution: &Solution,
    quiet: bool,
) -> Result<(), CliError> {
    let Some(s) = streamer.as_mut() else { return Ok(()) };
    let (_, stride) = s
        .publish(
            &solution.trajectory,
            solution.iterations as u64,
            wire_status(solution.status),
            solution.final_time,
            true,
        )
        .map_err(|e| CliError { message: format!("--stream: {e}"), code: exit::IO })?;
    if stride > 1 {
        say(
            quiet,
            &format!(
                "streamed every {stride}th dense sample (and the last): the trajectory is larger than one message"
            ),
        );
    }
    Ok(())
}

/// The summary lines: outcome and timings, and the largest violation.
fn summary(solution: &Solution, t0: Instant) -> Vec<String> {
    let mut lines = vec![format!(
        "{}: final time {:.4} s after {} iterations; solve {:.1} ms (discretization {:.1}, subproblems {:.1}), dense propagation {:.1} ms ({} samples); total {:.1} ms",
        solution.status,
        solution.final_time,
        solution.iterations,
        solution.timings.solve_ms,
        solution.timings.discretization_ms,
        solution.timings.subproblem_ms,
        solution.timings.post_processing_ms,
        solution.trajectory["time"].len(),
        t0.elapsed().as_secs_f64() * 1e3
    )];
    if let Some(v) = &solution.max_violation {
        let at = match (v.time, v.node) {
            (Some(t), Some(k)) => format!(" at t = {t:.3} s (segment {k})"),
            (None, Some(k)) => format!(" at node {k}"),
            _ => String::new(),
        };
        lines.push(format!("largest violation: {} = {:.3e}{at}", v.constraint, v.value));
    }
    lines
}

/// The solve's result, and with a retiming the retimed trajectory and the solution as it
/// shows it ([`RetimedResult::shown`]).
#[derive(Debug, Clone, Copy)]
struct Results<'a> {
    solution: &'a Solution,
    shown: Option<&'a Solution>,
    retimed: Option<&'a RetimedResult>,
}

/// Writes what `o` asks for: JSON and CSV (the solve's result, and the retimed trajectory
/// beside it), plots and the 3D view (of the retimed trajectory when there is one).
fn write_outputs(
    o: &OutputArgs,
    (name, plan): (&str, Option<&crate::pipeline::Plan>),
    r: Results<'_>,
    (iterates, starts, refinement): (
        Vec<Iterate>,
        Option<&StartsReport>,
        Option<&RefinementReport>,
    ),
    out: &mut dyn std::io::Write,
) -> Result<Vec<PathBuf>, CliError> {
    let scene = plan.map(Scene::from_plan);
    let result = ResultFile {
        solution: r.solution,
        retimed: r.retimed,
        scene: scene.as_ref(),
        iterates: &iterates,
        starts,
        refinement,
    };
    let mut set = OutputSet::default();
    output::write_solution(&result, o.output.as_deref(), o.csv.as_deref(), out, &mut set)?;
    let shown = r.shown.unwrap_or(r.solution);
    if let Some(dir) = &o.plot {
        crate::plot::write_plots(plan, shown, dir, &mut set)?;
    }
    if let Some(path) = &o.html {
        let data = ViewData::from_solution(name, shown, scene, iterates);
        output::write_html(&data, path, &mut set)?;
    }
    set.commit()
}

/// The converged solution retimed along its path, when the task asks for it (a retiming
/// that fails is reported, and the solve's own timing kept); `done`: its retiming, when
/// choosing among starts already did it.
fn retime_solution(
    loaded: &Loaded,
    (solution, done): (&Solution, Option<armature_arm::Retimed>),
    quiet: bool,
) -> Option<RetimedResult> {
    let task = loaded.retime.as_ref().filter(|_| solution.converged())?;
    let t0 = Instant::now();
    let layout = loaded.compiled.layout();
    let retimed = match done {
        Some(r) => crate::retimed::with_outputs(layout, r),
        None => crate::retimed::retime(task, layout, solution),
    };
    match retimed {
        Ok(r) => {
            say(
                quiet,
                &format!(
                    "retimed along the solved path within the velocity and torque limits: final time {:.4} s ({:+.1} %), {} samples, {:.1} ms",
                    r.final_time,
                    100.0 * (r.final_time / solution.final_time - 1.0),
                    r.trajectory["time"].len(),
                    t0.elapsed().as_secs_f64() * 1e3
                ),
            );
            Some(r)
        }
        Err(e) => {
            say(
                quiet,
                &format!("warning: not retimed ({e}); the solve's own timing is the result"),
            );
            None
        }
    }
}

/// Success, or the not-converged error saying why.
fn outcome(solution: &Solution) -> Result<(), CliError> {
    if solution.converged() {
        return Ok(());
    }
    let message = match (&solution.status, &solution.max_violation) {
        (PtrStatus::ViolatedBetweenNodes, Some(v)) => format!(
            "converged at the nodes, but the dense trajectory violates {} by {:.3e}{} (more than dense_tolerance)",
            v.constraint.name(),
            v.value,
            v.time.map_or(String::new(), |t| format!(" at t = {t:.3} s"))
        ),
        (PtrStatus::LocallyInfeasible, Some(v)) => format!(
            "locally infeasible: {} stayed violated by {:.3e}{} without progress (another initial guess may converge: [initialization] fallbacks, seed)",
            v.constraint.name(),
            v.value,
            v.time.map_or(String::new(), |t| format!(" at t = {t:.3} s"))
        ),
        (status, _) => format!("the solve stopped without converging: {status}"),
    };
    Err(CliError { message, code: exit::NOT_CONVERGED })
}

/// Plans, solves and writes the outputs of one task.
///
/// # Errors
/// As [`run`].
pub fn run_task(
    src: Source<'_>,
    path: Option<&Path>,
    o: &OutputArgs,
    out: &mut dyn std::io::Write,
) -> Result<(), CliError> {
    let t0 = Instant::now();
    let mut loaded = load(src, path)?;
    check_outputs(o, &loaded.inputs)?;
    say(o.quiet, &describe(src.name, &mut loaded));
    let mut streamer = start_stream(o, &loaded.keypoints)?;
    let Solved { solution, iterates, starts, retimed, refinement } =
        solve_stages(&mut loaded, &mut streamer, (src, o.quiet))?;
    for line in summary(&solution, t0) {
        say(o.quiet, &line);
    }
    let retimed = retime_solution(&loaded, (&solution, retimed), o.quiet);
    // What the plots, the view and the stream's last message show: the retimed trajectory
    // when there is one.
    let shown = retimed.as_ref().map(|r| r.shown(&solution));
    let written = write_outputs(
        o,
        (src.name, loaded.plan.as_ref()),
        Results { solution: &solution, shown: shown.as_ref(), retimed: retimed.as_ref() },
        (iterates, starts.as_ref(), refinement.as_ref()),
        out,
    )?;
    for p in &written {
        say(o.quiet, &format!("wrote {}", p.display()));
    }
    publish_final(&mut streamer, shown.as_ref().unwrap_or(&solution), o.quiet)?;
    // Last: serve late subscribers (the summary and the files are already out).
    if let Some(s) = &streamer
        && o.linger > 0.0
    {
        say(o.quiet, &format!("serving the final trajectory for {} s", o.linger));
        s.linger(o.linger)
            .map_err(|e| CliError { message: format!("--stream: {e}"), code: exit::IO })?;
    }
    outcome(&solution)
}

/// The observed solve from the task's guess, and with `[initialization] starts = K > 1`
/// the other K − 1 starts beside it (other IK paths, [`armature_arm::solve_task_starts_with`],
/// their iterates recorded), the best kept ([`choose_start`]) and every start reported in a
/// line. The iteration table and the streamed iterates are the first start's; the iterates
/// the 3D view draws, the result written, streamed at the end and refined are the kept
/// start's.
fn solve_starts(
    loaded: &mut Loaded,
    streamer: &mut Option<Streamer>,
    (src, quiet): (Source<'_>, bool),
    stage: Stage,
) -> Result<Solved, CliError> {
    let Some((count, task)) = loaded.starts.clone() else {
        let (solution, iterates) = solve_observed(loaded, streamer, (src, quiet), stage)?;
        return Ok(Solved { solution, iterates, starts: None, retimed: None, refinement: None });
    };
    let others = count - 1;
    // The other starts' iterates, recorded for the 3D view should one of them be kept.
    let recorded: Vec<Mutex<Vec<Iterate>>> = (0..others).map(|_| Mutex::default()).collect();
    let layout = loaded.compiled.layout().clone();
    let record = |i: usize, c: &mut armature_scvx::CompiledProblem| {
        let mut its = Vec::new();
        let end = c.solve_with(|it, traj| {
            its.extend(ee_iterate(&layout, it.iteration + stage.offset, traj));
        });
        if let Ok(mut slot) = recorded[i - 1].lock() {
            *slot = its;
        }
        end
    };
    let (observed, rest) = std::thread::scope(|scope| {
        let task = &task;
        let rest =
            scope.spawn(move || armature_arm::solve_task_starts_with(task, 1, others, record));
        let observed = solve_observed(loaded, streamer, (src, quiet), stage);
        (observed, rest.join())
    });
    let (first, mut iterates) = observed?;
    let (ends, summaries) = rest.unwrap_or_else(|panic| std::panic::resume_unwind(panic));
    let first_summary = armature_arm::summarize_start(&task, 0, Ok(&first));
    let summaries: Vec<_> = std::iter::once(first_summary).chain(summaries).collect();
    let mut ends: Vec<_> = std::iter::once(Ok(first)).chain(ends).collect();
    let (chosen, mut retimed) = choose_start(loaded, &ends, &summaries, quiet);
    if chosen != 0 {
        // The guess, then the kept start's iterates.
        iterates.truncate(1);
        let kept = recorded.into_iter().nth(chosen - 1).map(Mutex::into_inner);
        iterates.extend(kept.and_then(Result::ok).unwrap_or_default());
    }
    let best = ends.swap_remove(chosen).map_err(|e| CliError::bad_input(solve_error(src, &e)))?;
    let times = retimed.iter().map(|r| r.as_ref().map(|r| r.final_time)).collect();
    let starts = Some(StartsReport { kept: chosen, each: summaries, retimed_final_times: times });
    let retimed = retimed.get_mut(chosen).and_then(Option::take);
    Ok(Solved { solution: best, iterates, starts, retimed, refinement: None })
}

/// Which start to keep, each reported in a line: the converged one of least final time —
/// once retimed along its path when the task retimes ([`armature_arm::best_start_by`]; a
/// start whose retiming fails counts with its own final time). Also each start's retiming
/// (empty without retiming).
fn choose_start(
    loaded: &Loaded,
    ends: &[Result<Solution, armature_scvx::ProblemError>],
    summaries: &[armature_arm::StartSummary],
    quiet: bool,
) -> (usize, Vec<Option<armature_arm::Retimed>>) {
    let retimed: Vec<Option<armature_arm::Retimed>> = match &loaded.retime {
        Some(task) => ends
            .iter()
            .map(|e| task.retime(e.as_ref().ok().filter(|s| s.converged())?).ok())
            .collect(),
        None => Vec::new(),
    };
    let retimed_time = |i: usize| retimed.get(i).and_then(|r| r.as_ref()).map(|r| r.final_time);
    let time = |i: usize, s: &Solution| retimed_time(i).unwrap_or(s.final_time);
    let chosen = armature_arm::best_start_by(ends, time).unwrap_or(0);
    for (i, s) in summaries.iter().enumerate() {
        let outcome = &s.outcome;
        let again = retimed_time(i).map_or(String::new(), |t| format!(" (retimed {t:.4} s)"));
        let kept = if i == chosen { " (kept)" } else { "" };
        say(
            quiet,
            &format!(
                "start {} ({} IK samples per waypoint): {outcome}, T = {:.4} s{again}, {} iterations{kept}",
                i + 1,
                s.ik_samples.unwrap_or_default(),
                s.final_time,
                s.iterations
            ),
        );
    }
    (chosen, retimed)
}

/// What a task's solve hands to the outputs: the solution, the iterates the 3D view draws,
/// with several starts their report, and the solution's retiming if choosing a start did it.
struct Solved {
    solution: Solution,
    iterates: Vec<Iterate>,
    starts: Option<StartsReport>,
    retimed: Option<armature_arm::Retimed>,
    /// With a refinement: how each stage ended, and which one `solution` is.
    refinement: Option<RefinementReport>,
}

/// Solves the task, and with a refinement then the refined task from that solution (when
/// the first stage converged), which takes the place of the first in `loaded` when it
/// converges too (otherwise the first stage's result is kept).
fn solve_stages(
    loaded: &mut Loaded,
    streamer: &mut Option<Streamer>,
    (src, quiet): (Source<'_>, bool),
) -> Result<Solved, CliError> {
    let refined = loaded.refined.take();
    let first = Stage { offset: 0, last: refined.is_none() };
    let mut solved = solve_starts(loaded, streamer, (src, quiet), first)?;
    if let Some(arm) = loaded.fallback.as_ref().filter(|_| !solved.solution.converged()) {
        solved = fall_back(arm, solved, quiet);
    }
    let Some((factor, plan, mut compiled)) = refined else { return Ok(solved) };
    let first_summary = StageSummary::of(&solved.solution);
    if solved.solution.status != PtrStatus::Converged {
        say(quiet, "not refined: the first stage did not converge");
        let refinement = Some(RefinementReport {
            factor,
            kept: KeptStage::FirstStage,
            first_stage: first_summary,
            refined_stage: None,
        });
        return Ok(Solved { refinement, ..solved });
    }
    // The refined stage's solution is retimed afresh.
    let Solved { solution: coarse, mut iterates, starts, .. } = solved;
    armature_arm::set_refined_guess(&mut compiled, &coarse, factor)
        .map_err(|e| CliError::bad_input(solve_error(src, &e)))?;
    say(
        quiet,
        &format!(
            "refining: T = {:.4} s after {} iterations on {} nodes; again on {} nodes",
            coarse.final_time,
            coarse.iterations,
            loaded.compiled.ptr().ocp().nodes,
            plan.nodes
        ),
    );
    let first_stage =
        (loaded.plan.replace(plan), std::mem::replace(&mut loaded.compiled, compiled));
    let second = Stage { offset: coarse.iterations, last: true };
    let (fine, more) = solve_observed(loaded, streamer, (src, quiet), second)?;
    let refined_stage = Some(StageSummary::of(&fine));
    let report =
        |kept| RefinementReport { factor, kept, first_stage: first_summary, refined_stage };
    let (solution, refinement) = match armature_arm::keep_refined(coarse, fine) {
        armature_arm::Refinement::Refined(both) => {
            // The guess's iterate of the second stage is the first stage's result: not
            // drawn again.
            iterates.extend(more.into_iter().skip(1));
            (both, report(KeptStage::Refined))
        }
        armature_arm::Refinement::KeptFirstStage { first, refined } => {
            say(
                quiet,
                &format!(
                    "the refined stage did not converge ({}, {} iterations): keeping the first stage's result",
                    refined.status, refined.iterations
                ),
            );
            // With the plan and the problem that describe it.
            (loaded.plan, loaded.compiled) = first_stage;
            (first, report(KeptStage::FirstStage))
        }
    };
    Ok(Solved { solution, iterates, starts, retimed: None, refinement: Some(refinement) })
}

/// The task solved again from its fallback starts ([`armature_arm::solve_fallbacks`]) after
/// `solved` did not converge, each reported in a line; a kept fallback's solution replaces
/// the first's (the 3D view then draws the guess alone: the iterates were the first's).
fn fall_back(arm: &armature_arm::ArmTask, solved: Solved, quiet: bool) -> Solved {
    say(quiet, &format!("not converged ({}): trying the fallback starts", solved.solution.status));
    let kept = armature_arm::solve_fallbacks(arm, solved.solution);
    for (j, s) in kept.tried.iter().enumerate() {
        let outcome = &s.outcome;
        let mark = if kept.kept == j + 1 { " (kept)" } else { "" };
        say(
            quiet,
            &format!(
                "fallback {} (IK samples from seed {}, guess timing × {:.2}): {outcome}, T = {:.4} s, {} iterations{mark}",
                j + 1,
                armature_arm::fallback_task(arm, j + 1).initialization.seed,
                s.time_scale,
                s.final_time,
                s.iterations
            ),
        );
    }
    if kept.kept == 0 {
        return Solved { solution: kept.solution, ..solved };
    }
    let mut iterates = solved.iterates;
    iterates.truncate(1);
    Solved { solution: kept.solution, iterates, retimed: None, ..solved }
}

/// An iterate as the 3D view draws it: the end effector at the nodes (`None` for a problem
/// without an `ee_position` output).
fn ee_iterate(
    layout: &armature_scvx::SolutionLayout,
    iteration: usize,
    traj: &armature_scvx::Trajectory<'_>,
) -> Option<Iterate> {
    let tables = layout.nodal_tables(traj).ok()?;
    let ee = tables.get("ee_position")?;
    Some(Iterate {
        iteration,
        final_time: traj.final_time,
        ee: ee.iter().map(|p| [p[0], p[1], p[2]]).collect(),
    })
}

/// The initial guess as an iterate: the end effector at the IK configurations of the nodes.
fn guess_iterate(plan: &crate::pipeline::Plan) -> Iterate {
    let mut fk = plan.chain.fk_workspace();
    let ee = plan
        .ik
        .q
        .iter()
        .filter_map(|q| plan.chain.forward(q, &mut fk).ok().map(|()| fk.ee().translation().into()))
        .collect();
    let final_time = match plan.problem.time {
        armature_scvx::Time::Free { guess, .. } => guess,
        armature_scvx::Time::Fixed(t) => t,
    };
    Iterate { iteration: 0, final_time, ee }
}
