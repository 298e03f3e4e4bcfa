//! Two processes: `armature demo --stream RUN` publishes, `armature listen RUN` receives.

mod common;

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};

use common::{armature, assert_solved, scratch};
use serde_json::Value;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_armature"))
}

/// Waits until the child's stderr says `what`; returns the rest of its stderr lines.
fn wait_for(
    child: &mut std::process::Child,
    what: &str,
) -> std::io::Lines<BufReader<std::process::ChildStderr>> {
    let mut lines = BufReader::new(child.stderr.take().unwrap()).lines();
    for line in lines.by_ref() {
        if line.unwrap().contains(what) {
            return lines;
        }
    }
    panic!("the process ended without saying '{what}'");
}

/// Starts `armature ARGS` (a `listen`) and waits until it listens; its remaining stderr lines
/// are returned to keep the pipe open.
fn listen(
    args: &[&str],
) -> (std::process::Child, std::io::Lines<BufReader<std::process::ChildStderr>>) {
    let mut child = bin().args(args).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    let rest = wait_for(&mut child, "listening on");
    (child, rest)
}

/// Waits for a `listen --json` to end, successfully; its messages, one JSON value each.
fn json_messages(listener: std::process::Child) -> Vec<Value> {
    let out = listener.wait_with_output().unwrap();
    assert!(out.status.success());
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

#[test]
fn listen_receives_every_iteration_and_the_dense_trajectory_bit_for_bit() {
    let run = format!("cli-json-{}", std::process::id());
    let (listener, _rest) = listen(&["listen", &run, "--json", "--timeout", "120"]);
    let dir = scratch("stream");
    let result = dir.path().join("result.json");
    let (code, _, stderr) =
        armature(&["demo", "-q", "--stream", &run, "-o", result.to_str().unwrap()]);
    let lines = json_messages(listener);
    let r: Value = serde_json::from_str(&std::fs::read_to_string(&result).unwrap()).unwrap();
    assert_solved(code, &r, &stderr);
    let iterations = r["iterations"].as_u64().unwrap() as usize;
    // Nodal trajectories of the iterations in order, then the dense one. (A listener that
    // falls more than its buffer behind loses the oldest — the publisher never blocks — so
    // under load some intermediate iterates may be missing; the order and the final
    // trajectory are guaranteed.)
    assert!(lines.len() >= 2, "{} lines", lines.len());
    let seqs: Vec<u64> = lines.iter().map(|l| l["sequence"].as_u64().unwrap()).collect();
    assert!(seqs.windows(2).all(|w| w[0] < w[1]), "{seqs:?}");
    for l in &lines[..lines.len() - 1] {
        assert_eq!(l["dense"], false);
        assert_eq!(l["sequence"], l["iteration"], "one message per iteration");
    }
    assert_eq!(lines.last().unwrap()["sequence"], iterations as u64 + 1);
    assert_eq!(lines.last().unwrap()["dense"], true);
    let last = lines.last().unwrap();
    assert_eq!(last["status"], r["status"], "the wire carries the result's status");
    // The final trajectory is the retimed one (the demo retimes by default), decimated to
    // fit one message: every `stride`-th sample and the last.
    let retimed = &r["retimed"];
    assert_eq!(last["final_time"], retimed["final_time"]);
    let columns: Vec<&str> =
        last["columns"].as_array().unwrap().iter().map(|c| c.as_str().unwrap()).collect();
    assert_eq!(columns[0], "time");
    let angle0 = columns.iter().position(|c| *c == "angle[0]").unwrap();
    let ee0 = columns.iter().position(|c| *c == "ee_position[0]").unwrap();
    let rows = last["rows"].as_array().unwrap();
    let dense = &retimed["trajectory"];
    let all = dense["time"].as_array().unwrap().len();
    let stride = (all - 1).div_ceil(rows.len() - 1);
    assert_eq!((all - 1).div_ceil(stride) + 1, rows.len(), "{all} samples, {} rows", rows.len());
    for (row, k) in rows.iter().zip((0..).map(|r| (r * stride).min(all - 1))) {
        assert_eq!(row[0], dense["time"][k][0]);
        for j in 0..7 {
            assert_eq!(row[angle0 + j], dense["angle"][k][j], "row {k} joint {j}");
        }
        for i in 0..3 {
            assert_eq!(row[ee0 + i], dense["ee_position"][k][i]);
        }
    }
}

#[test]
fn a_late_listener_gets_the_final_trajectory_while_the_publisher_lingers() {
    let run = format!("cli-late-{}", std::process::id());
    let mut publisher = bin()
        .args(["demo", "--stream", &run, "--linger", "60"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The summary line comes after the solve; the dense trajectory follows it at once.
    let rest = wait_for(&mut publisher, ": final time");
    std::thread::spawn(move || for _ in rest {});
    std::thread::sleep(std::time::Duration::from_millis(300));
    let (code, stdout, stderr) = armature(&["listen", &run, "--once", "--timeout", "30"]);
    let _ = publisher.kill();
    let _ = publisher.wait();
    assert_eq!(code, 0, "{stderr}");
    assert!(
        stdout.contains("violated_between_nodes: dense") || stdout.contains("converged: dense"),
        "{stdout}"
    );
}

#[test]
fn listen_gives_up_after_its_timeout_and_names_are_checked() {
    let (code, _, stderr) =
        armature(&["listen", &format!("nobody-{}", std::process::id()), "--timeout", "0.5"]);
    assert_eq!(code, 3, "{stderr}");
    assert!(stderr.contains("no message"), "{stderr}");
    let (code, _, stderr) = armature(&["listen", "a/b", "--timeout", "1"]);
    assert_eq!(code, 2);
    assert!(stderr.contains("run name"), "{stderr}");
    let (code, _, stderr) = armature(&["demo", "-q", "--stream", "has space"]);
    assert_eq!(code, 2);
    assert!(stderr.contains("run name"), "{stderr}");
}

/// Durations that do not fit the clock are bad input, not a panic (issue 25, class 3).
#[test]
fn huge_timeouts_and_lingers_are_refused_before_anything_runs() {
    for (args, flag) in [
        (vec!["listen", "huge-timeout", "--timeout", "1e20"], "--timeout 100000000000000000000"),
        (vec!["listen", "huge-timeout", "--timeout", "inf"], "--timeout inf"),
        (
            vec!["demo", "-q", "--stream", "huge-linger", "--linger", "1e20"],
            "--linger 100000000000000000000",
        ),
        (vec!["demo", "-q", "--stream", "huge-linger", "--linger=-1"], "--linger -1"),
    ] {
        let (code, stdout, stderr) = armature(&args);
        assert_eq!(code, 2, "{args:?}: {stderr}");
        assert!(stderr.contains(flag) && stderr.contains("at most 1e9"), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked") && stdout.is_empty(), "{stderr}");
    }
}

/// A final trajectory larger than one message (dense_dt = 1e-4: about 14,700 samples) no
/// longer costs the result: the files are written first, and the stream carries the
/// trajectory decimated to fit, with its first and last samples.
#[test]
fn a_trajectory_too_large_for_one_message_is_streamed_decimated_after_the_result() {
    let run = format!("cli-big-{}", std::process::id());
    let (listener, _rest) = listen(&["listen", &run, "--json", "--timeout", "120"]);
    let task = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../examples/pick-and-place.toml"
    ))
    .unwrap()
    .replacen("[settings]\n", "[settings]\ndense_dt = 1e-4\n", 1)
    .replacen("[time]\n", "[time]\nretime = false\n", 1);
    let dir = scratch("stream-big");
    let (task_path, result) = (dir.path().join("task.toml"), dir.path().join("result.json"));
    std::fs::write(&task_path, task).unwrap();
    let (code, _, stderr) = armature(&[
        "solve",
        task_path.to_str().unwrap(),
        "--stream",
        &run,
        "-o",
        result.to_str().unwrap(),
    ]);
    let out = listener.wait_with_output().unwrap();
    let r: Value = serde_json::from_str(&std::fs::read_to_string(&result).unwrap()).unwrap();
    assert_solved(code, &r, &stderr);
    assert!(stderr.contains("streamed every"), "{stderr}");
    let dense = r["trajectory"]["time"].as_array().unwrap();
    assert!(dense.len() > 10_000, "{} samples", dense.len());
    let last = String::from_utf8(out.stdout).unwrap().lines().last().unwrap().to_string();
    let last: Value = serde_json::from_str(&last).unwrap();
    assert_eq!(last["dense"], true);
    let rows = last["rows"].as_array().unwrap();
    assert!(rows.len() < dense.len() && rows.len() > 100, "{} rows", rows.len());
    assert_eq!(rows[0][0], dense[0][0]);
    assert_eq!(rows.last().unwrap()[0], dense.last().unwrap()[0], "the last sample is kept");
}

/// `listen --follow --timeout S` that received a final trajectory ends its session with exit
/// 0 when the run goes quiet (exit 3 is for a timeout without one).
#[test]
fn a_following_listener_that_got_the_final_trajectory_exits_0_on_its_timeout() {
    let run = format!("cli-follow-{}", std::process::id());
    let (listener, _rest) = listen(&["listen", &run, "--follow", "--timeout", "3"]);
    let (code, _, stderr) = armature(&["demo", "-q", "--stream", &run]);
    assert!(code == 0 || code == 3, "{stderr}");
    let out = listener.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("dense"), "{stdout}");
    assert_eq!(out.status.code(), Some(0), "{stdout}");
}

/// Two solves on one run name: the second is refused before it solves (exit 2, the run
/// named), so a listener never sees two solves interleaved; the first is unaffected.
#[test]
fn a_second_solve_streaming_on_a_busy_run_is_refused() {
    let run = format!("cli-busy-{}", std::process::id());
    let dir = scratch("busy");
    let first_out = dir.path().join("first.json");
    let mut first = bin()
        .args(["demo", "--stream", &run, "--linger", "60", "-o", first_out.to_str().unwrap()])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let _rest = wait_for(&mut first, "streaming on");
    let second_out = dir.path().join("second.json");
    let (code, _, stderr) =
        armature(&["demo", "-q", "--stream", &run, "-o", second_out.to_str().unwrap()]);
    first.kill().ok();
    first.wait().ok();
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains(&format!("run '{run}' is already being streamed")), "{stderr}");
    assert!(!second_out.exists(), "the refused solve wrote its result");
}

/// A refined task (the example's default, as `[nodes] refine = 2`) streams both stages as one
/// solve: sequences rising across the stages, the first stage's convergence not on the wire
/// as the end, and then the refined dense trajectory with the result's status.
#[test]
fn a_refined_solve_streams_both_stages_as_one() {
    let run = format!("cli-refine-{}", std::process::id());
    let (listener, _rest) = listen(&["listen", &run, "--json", "--timeout", "120"]);
    let dir = scratch("stream-refine");
    let task = dir.path().join("task.toml");
    std::fs::write(&task, include_str!("../../../examples/pick-and-place.toml")).unwrap();
    let result = dir.path().join("result.json");
    let (code, _, stderr) = armature(&[
        "solve",
        task.to_str().unwrap(),
        "-q",
        "--stream",
        &run,
        "-o",
        result.to_str().unwrap(),
    ]);
    let lines = json_messages(listener);
    let r: Value = serde_json::from_str(&std::fs::read_to_string(&result).unwrap()).unwrap();
    assert_solved(code, &r, &stderr);
    let seqs: Vec<u64> = lines.iter().map(|l| l["sequence"].as_u64().unwrap()).collect();
    assert!(seqs.windows(2).all(|w| w[0] < w[1]), "{seqs:?}");
    let iterations = r["iterations"].as_u64().unwrap();
    let (last, nodal) = lines.split_last().unwrap();
    assert_eq!(last["sequence"], iterations + 1);
    assert_eq!((&last["dense"], &last["status"]), (&Value::Bool(true), &r["status"]));
    // Only the refined stage's last iterate ends the solve; it has the refined grid's nodes.
    let (end, before) = nodal.split_last().unwrap();
    assert_eq!(end["status"], r["status"]);
    assert!(before.iter().all(|l| l["status"] == "running"), "one end only");
    assert_eq!(end["rows"].as_array().unwrap().len(), 31);
}

#[test]
fn the_progress_stream_marks_the_iterations_that_only_restored_feasibility() {
    let run = format!("cli-feasible-{}", std::process::id());
    let (listener, _rest) = listen(&["listen", &run, "--timeout", "120"]);
    let dir = scratch("stream-feasible");
    let result = dir.path().join("result.json");
    let (code, _, stderr) = armature(&[
        "demo",
        "pick-and-place-collision",
        "-q",
        "--stream",
        &run,
        "-o",
        result.to_str().unwrap(),
    ]);
    let out = listener.wait_with_output().unwrap();
    assert!(out.status.success());
    let r: Value = serde_json::from_str(&std::fs::read_to_string(&result).unwrap()).unwrap();
    assert_solved(code, &r, &stderr);
    // The collision demo stops minimizing once its retimed path stalls (the seed's demo
    // converges before its path stalls): its last iterations only restored feasibility, and
    // the listener says so instead of a cost of 0.
    let history = r["history"].as_array().unwrap();
    assert_eq!(history.last().unwrap()["feasibility"], true);
    let stdout = String::from_utf8(out.stdout).unwrap();
    let progress: Vec<&str> = stdout.lines().filter(|l| l.starts_with("progress")).collect();
    let last = progress.last().unwrap();
    assert!(last.contains(&format!("iteration {:>3}", history.len())), "{last}");
    assert!(last.contains("cost feasible"), "{last}");
    // The others carry the solve's final time as their cost.
    let costs: Vec<f64> = progress
        .iter()
        .filter(|l| !l.contains("cost feasible"))
        .map(|l| l.split("cost ").nth(1).unwrap().split(' ').next().unwrap().parse().unwrap())
        .collect();
    let minimizing: Vec<f64> = history
        .iter()
        .filter(|h| h["feasibility"] == false)
        .map(|h| h["cost"].as_f64().unwrap())
        .collect();
    assert_eq!(costs.len(), minimizing.len(), "{costs:?} against {minimizing:?}");
    for (c, h) in costs.iter().zip(&minimizing) {
        assert!((c - h).abs() <= 1e-5 * h, "streamed {c}, history {h}");
    }
}
