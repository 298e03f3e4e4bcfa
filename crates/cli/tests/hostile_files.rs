//! Hostile input files through the real binary (issue 25's property): task files, problem
//! files and URDF robots with deep structures, huge or non-finite numbers in what sizes
//! memory and time, loops and truncated UTF-8. Each run must, under a 4 GiB address-space
//! limit and within a time bound, end with exit code 2 and an error located in the file
//! (`file:line:col: reason`), and write nothing.

mod common;

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use proptest::prelude::*;

const TASK: &str = include_str!("../../../examples/pick-and-place-collision.toml");
const PROBLEM: &str = include_str!("../../../examples/double-integrator.toml");

/// Values no sizing field of the examples accepts.
const HUGE: &[&str] =
    &["1e308", "-1e308", "nan", "inf", "-inf", "18446744073709551615", "9223372036854775807e9"];

/// Lines of the task example whose value a huge number replaces (each sizes memory or time,
/// or must lie in a range), and the problem example's.
const TASK_FIELDS: &[&str] = &["per_segment = ", "max = ", "tolerance_deg = ", "margin = "];
const PROBLEM_FIELDS: &[&str] = &["nodes = ", "max = ", "guess = "];

/// What makes a file hostile.
#[derive(Debug, Clone)]
enum Hostility {
    /// A value nested this deep (arrays or inline tables) at the top of the file.
    Deep { depth: usize, tables: bool },
    /// The `field`-th sizing line's value replaced by `HUGE[value]`.
    Huge { field: usize, value: usize },
    /// A settings key that sizes the work, set to `HUGE[value]` or a huge integer.
    Setting { key: usize, value: usize },
    /// The bytes cut after this fraction of the file, inside a multibyte character.
    Truncated { at: f64 },
}

fn hostility() -> impl Strategy<Value = Hostility> {
    prop_oneof![
        (1usize..200_000, any::<bool>())
            .prop_map(|(depth, tables)| Hostility::Deep { depth, tables }),
        (0usize..4, 0..HUGE.len()).prop_map(|(field, value)| Hostility::Huge { field, value }),
        (0usize..4, 0..HUGE.len()).prop_map(|(key, value)| Hostility::Setting { key, value }),
        (0.0..1.0f64).prop_map(|at| Hostility::Truncated { at }),
    ]
}

/// The example `text` made hostile (as bytes: a truncation leaves invalid UTF-8).
fn apply(text: &str, fields: &[&str], h: &Hostility) -> Vec<u8> {
    match *h {
        Hostility::Deep { depth, tables } => {
            let deep = if tables {
                format!("deep = {}1{}\n", "{a = ".repeat(depth), "}".repeat(depth))
            } else {
                format!("deep = {}1{}\n", "[".repeat(depth), "]".repeat(depth))
            };
            (deep + text).into_bytes()
        }
        Hostility::Huge { field, value } => {
            let key = fields[field % fields.len()];
            let out: Vec<String> = text
                .lines()
                .map(|l| match l.strip_prefix(key) {
                    Some(_) => format!("{key}{}", HUGE[value]),
                    None => l.to_string(),
                })
                .collect();
            out.join("\n").into_bytes()
        }
        Hostility::Setting { key, value } => {
            let settings = [
                format!("max_iterations = {}", HUGE[value]),
                format!("dense_dt = {}", HUGE[value]),
                "discretization.substeps = 4294967297".to_string(),
                "discretization.substeps = 1000".to_string(),
            ];
            let nodes = if key == 3 { "per_segment = 1000" } else { "per_segment = 3" };
            let text = text.replacen("per_segment = 3", nodes, 1).replacen(
                "nodes = 41",
                "nodes = 2000",
                1,
            );
            text.replacen("[settings]", &format!("[settings]\n{}", settings[key]), 1).into_bytes()
        }
        Hostility::Truncated { at } => {
            let mut bytes = text.as_bytes().to_vec();
            let cut = ((bytes.len() as f64) * at) as usize;
            bytes.truncate(cut);
            bytes.extend_from_slice("ä".as_bytes().split_at(1).0);
            bytes
        }
    }
}

/// Whether the hostile file is bad input: all are but one, a huge integer iteration cap,
/// which is a valid setting (the history is capped, not reserved; tested elsewhere).
fn expects_refusal(h: &Hostility) -> bool {
    !matches!(*h, Hostility::Setting { key: 0, value } if HUGE[value] == "18446744073709551615")
}

/// Runs `armature solve FILE -o OUT/result.json --csv OUT/csv` under a 4 GiB address-space
/// limit: (exit code, stderr, elapsed). A run past `limit` is killed and reported as such.
fn solve_limited(file: &Path, out: &Path, limit: Duration) -> (i32, String, Duration) {
    let script = r#"ulimit -v 4194304; exec "$0" solve "$1" -q -o "$2/result.json" --csv "$2/csv""#;
    let start = Instant::now();
    let mut child = Command::new("sh")
        .args(["-c", script, env!("CARGO_BIN_EXE_armature")])
        .arg(file)
        .arg(out)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("sh runs");
    loop {
        if let Some(status) = child.try_wait().expect("wait") {
            let mut stderr = String::new();
            use std::io::Read;
            child.stderr.take().unwrap().read_to_string(&mut stderr).unwrap();
            return (status.code().unwrap_or(-1), stderr, start.elapsed());
        }
        if start.elapsed() > limit {
            child.kill().ok();
            child.wait().ok();
            return (-2, "killed: over the time limit".into(), start.elapsed());
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// The property: bad input → exit 2, `FILE:line:col:` in the error, no output written,
/// within 20 s and 4 GiB.
fn check_refused(bytes: &[u8], name: &str, robot: Option<&str>) -> Result<(), TestCaseError> {
    let dir = common::scratch("hostile");
    let file = dir.path().join(name);
    std::fs::write(&file, bytes).unwrap();
    if let Some(urdf) = robot {
        std::fs::write(dir.path().join("robot.urdf"), urdf).unwrap();
    }
    let out = dir.path().join("out");
    let (code, stderr, took) = solve_limited(&file, &out, Duration::from_secs(20));
    prop_assert!(took < Duration::from_secs(20), "took {took:?}: {stderr}");
    prop_assert_eq!(code, 2, "{}", stderr);
    let located = stderr.lines().next().and_then(|l| l.strip_prefix("error: ")).is_some_and(|l| {
        let mut parts = l.splitn(4, ':');
        let (path, line, col) = (parts.next(), parts.next(), parts.next());
        path.is_some_and(|p| p.ends_with(".toml") || p.ends_with(".urdf"))
            && line.is_some_and(|s| s.parse::<usize>().is_ok_and(|n| n >= 1))
            && col.is_some_and(|s| s.parse::<usize>().is_ok_and(|n| n >= 1))
    });
    prop_assert!(located, "not located: {stderr}");
    prop_assert!(!out.exists(), "something was written: {:?}", std::fs::read_dir(&out).ok());
    Ok(())
}

/// A URDF whose joints close a loop through `links` links (or give one link two parents).
fn looped_urdf(links: usize, two_parents: bool) -> String {
    let mut xml = String::from(r#"<?xml version="1.0"?><robot name="loop">"#);
    for l in 0..links {
        xml += &format!(r#"<link name="l{l}"/>"#);
    }
    for l in 0..links {
        let (parent, child) =
            if two_parents && l + 1 == links { (0, 1) } else { (l, (l + 1) % links) };
        xml += &format!(
            r#"<joint name="j{l}" type="revolute"><parent link="l{parent}"/><child link="l{child}"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>"#
        );
    }
    xml + "</robot>"
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    #[test]
    fn hostile_task_files_are_refused_located_and_write_nothing(h in hostility()) {
        if expects_refusal(&h) {
            check_refused(&apply(TASK, TASK_FIELDS, &h), "task.toml", None)?;
        }
    }

    #[test]
    fn hostile_problem_files_are_refused_located_and_write_nothing(h in hostility()) {
        if expects_refusal(&h) {
            check_refused(&apply(PROBLEM, PROBLEM_FIELDS, &h), "problem.toml", None)?;
        }
    }

    #[test]
    fn looped_urdf_robots_are_refused_located_and_write_nothing(
        links in 2usize..40,
        two_parents in any::<bool>(),
    ) {
        let task = TASK
            .replacen("name = \"arm7\"", "name = \"robot.urdf\"\nbase = \"l0\"\ntip = \"l1\"", 1);
        check_refused(task.as_bytes(), "task.toml", Some(&looped_urdf(links, two_parents)))?;
    }
}
