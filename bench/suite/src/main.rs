//! `cargo run --release -p armature-suite [-- --filter WORD] [--json FILE] [--export FILE]
//! [--reference FILE] [--per-segment K] [--subdivide K] [--refine K] [--starts K] [--settings JSON]
//! [--velocity-peaks true|false] [--time-scaled true|false] [--retime-stall JSON] [--no-retime-stall] [--history]
//! [--no-retime] [--ik-seed S] [--ik-restarts K] [--fallbacks K]`: solves every task of the suite with default settings, by the
//! pipeline the CLI runs (`ArmTask::solve`: starts, fallbacks, refinement, retiming) — each solve
//! stopping its minimization once its path retimed stalls and retiming its verified solution
//! along that path, as the CLI does by default (`ArmTask::retime_stall`, `ArmTask::retime`,
//! `[time] retime`) — verifies the result independently (the retimed trajectory by
//! `retimed.rs`) and prints the table, with T / T_ref where
//! the stored reference (`bench/reference/t_ref.json`) has a verified solution. `--export`
//! writes the tasks (with armature's guesses and solutions) for `bench/reference/t_ref.py`.
//! `--history` prints each task's SCvx iteration table (`IterationTable`: ρ, defects,
//! violations, λ_tr per iteration) before its line, to see how a solve walks. `--no-retime`
//! reports the solve's own timing (and minimizes it to the end); `--no-retime-stall` retimes
//! a solve that minimized to the end.
//!
//! For studies of a candidate default, on every task alike: `--per-segment K` restates every
//! task with K intervals between consecutive waypoints instead of its model's default (3
//! for the decoupled model, 2 for the rigid-body one), the integration's step length kept (`ArmTask::resegmented`); `--subdivide K` splits every
//! segment into K, `--refine K` solves each
//! task and then again on a grid K times finer from that solution (`ArmTask::refined`,
//! `armature_arm::set_refined_guess`; iterations and time count both stages; by default each
//! task's model's factor, `DynamicsModel::default_refine`, as the CLI's: 2 for the decoupled
//! model, 1 for the rigid-body one; `--refine 1` solves every task once), `--starts K`
//! solves each task's first stage from K IK paths (`ArmTask::start`; by default each task's
//! own, 2) in parallel and keeps the best
//! (`ArmTask::solve`, the kept start's path retiming fastest; iterations are the kept start's), `--settings JSON`
//! overrides fields of each task's `PtrSettings` (e.g. `'{"quasi_newton": true}'`);
//! `--velocity-peaks true|false` bounds every task's velocities at the integration grid's
//! points or not (each task's dynamics model chooses by default); `--time-scaled
//! true|false` solves every task for its time-scaled torques or its torques
//! (`ArmTask::time_scaled_torque`; the model chooses by default); `--retime-stall JSON`
//! changes the rule by which minimization stops once the path retimed stalls (the default
//! `RetimeStall` with the object's fields); `--ik-seed S` draws every task's IK branch
//! samples from seed S (`Initialization::seed`, 0 by default: another initialization of the
//! same tasks), `--ik-restarts K` sets every task's IK samples per waypoint
//! (`Initialization::restarts`, 8 by default; a later start draws 8 times more) and `--fallbacks K` sets how many fallback starts a solve that does not
//! converge may try (`armature_arm::solve_fallbacks`, 2 by default; iterations and time count
//! every start).

use std::collections::BTreeMap;
use std::path::Path;

use armature_suite::{generate, reference, run, study, verify};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |flag: &str| args.iter().position(|a| a == flag).and_then(|i| args.get(i + 1));
    let filter = value("--filter").cloned();
    let study = study::Study::from_args(
        (value("--subdivide"), value("--refine"), value("--starts")),
        value("--settings"),
        value("--velocity-peaks"),
    )
    .and_then(|s| s.with_per_segment(value("--per-segment")))
    .and_then(|s| {
        s.with_starts_from((value("--ik-seed"), value("--fallbacks"), value("--ik-restarts")))
    })
    .and_then(|s| s.with_time_scaled(value("--time-scaled")))
    .and_then(|s| {
        let on = !args.iter().any(|a| a == "--no-retime" || a == "--no-retime-stall");
        s.with_retime_stall(on, value("--retime-stall"))
    })
    .unwrap_or_else(|e| {
        eprintln!("error: {e}");
        std::process::exit(2);
    });
    let tasks: Vec<_> = generate::suite()
        .into_iter()
        .filter(|t| filter.as_ref().is_none_or(|f| t.name.contains(f.as_str())))
        .map(|t| study.apply(t))
        .collect::<Result<_, _>>()
        .unwrap_or_else(|e| {
            eprintln!("error: {e}");
            std::process::exit(2);
        });
    let retime = !args.iter().any(|a| a == "--no-retime");
    let tasks: Vec<_> = tasks.into_iter().map(|t| generate::SuiteTask { retime, ..t }).collect();
    eprintln!("{} tasks", tasks.len());
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let ref_path = value("--reference").map_or_else(|| root.join(reference::STORED), Into::into);
    let refs = reference::load(&ref_path).unwrap_or_else(|e| {
        eprintln!("no reference: {e}");
        BTreeMap::new()
    });
    let history = args.iter().any(|a| a == "--history");
    let mut outcomes = Vec::new();
    let mut t_ref = BTreeMap::new();
    for t in &tasks {
        let o = run::run_one(t);
        if history {
            print_history(&o.history);
        }
        let r = refs
            .get(&t.name)
            .and_then(|r| r.final_time.map(|tr| (tr, reference::verify_reference(t, r))));
        let r_cell = match &r {
            Some((tr, w)) if w.value <= verify::TOLERANCE => {
                t_ref.insert(t.name.clone(), *tr);
                format!("T_ref {tr:.4}")
            }
            Some((_, w)) => format!("T_ref unverified ({:.1e} {})", w.value, w.what),
            None => "T_ref –".into(),
        };
        eprintln!(
            "{:<26} {:<22} it {:>3}  T {:>7.4}  {:>7.1} ms  worst {:>9.2e} {}  {r_cell}",
            o.name, o.status, o.iterations, o.final_time, o.solve_ms, o.worst, o.worst_what
        );
        outcomes.push(o);
    }
    println!("{}", run::table(&outcomes, &t_ref));
    // Written whole or not at all: a temporary file beside it, renamed.
    let write = |path: &String, json: String| {
        let tmp = format!("{path}.tmp");
        if let Err(e) = std::fs::write(&tmp, json).and_then(|()| std::fs::rename(&tmp, path)) {
            let _ = std::fs::remove_file(&tmp);
            eprintln!("error: {path}: {e}");
            std::process::exit(4);
        }
    };
    if let Some(path) = value("--json") {
        write(path, serde_json::to_string_pretty(&outcomes).expect("outcomes serialize"));
    }
    if let Some(path) = value("--export") {
        let all: Vec<_> =
            tasks.iter().zip(&outcomes).map(|(t, o)| reference::export(t, Some(o))).collect();
        write(path, serde_json::to_string(&all).expect("tasks serialize"));
    }
}

/// The iteration table of one solve, to standard error.
fn print_history(history: &[armature_scvx::Iteration]) {
    let mut err = std::io::stderr().lock();
    let table = armature_scvx::IterationTable::header(&mut err).and_then(|()| {
        history.iter().try_for_each(|it| armature_scvx::IterationTable::row(&mut err, it))
    });
    if let Err(e) = table {
        eprintln!("error: the iteration table: {e}");
    }
}
