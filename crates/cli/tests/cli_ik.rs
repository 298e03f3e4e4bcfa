//! `armature ik` end to end: converged, not converged, keyframes, bad input.

mod common;

use common::{armature, temp_file};
use serde_json::Value;

const SEED_KEYFRAMES: &str = r#"
seed = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]

[[keyframes]]
node = 0
position = [0.69, 0.0, 0.34]
quaternion_wxyz = [1.0, 0.0, 0.0, 0.0]

[[keyframes]]
node = 2
position = [0.35, -0.25, 0.2]
quaternion_wxyz = [0.7071067811865476, 0.0, 0.7071067811865476, 0.0]

[[keyframes]]
node = 4
position = [0.35, -0.25, 0.05]
quaternion_wxyz = [0.7071067811865476, 0.0, 0.7071067811865476, 0.0]

[[keyframes]]
node = 6
position = [0.35, -0.25, 0.2]
quaternion_wxyz = [0.7071067811865476, 0.0, 0.7071067811865476, 0.0]

[[keyframes]]
node = 8
position = [0.35, 0.25, 0.2]
quaternion_wxyz = [0.7071067811865476, 0.0, 0.7071067811865476, 0.0]

[[keyframes]]
node = 10
position = [0.35, 0.25, 0.05]
quaternion_wxyz = [0.7071067811865476, 0.0, 0.7071067811865476, 0.0]
"#;

#[test]
fn single_target_converges_or_reports_best_effort() {
    let (code, out, err) = armature(&[
        "ik",
        "--pos",
        "0.35,-0.25,0.2",
        "--quat",
        "0.7071067811865476,0,0.7071067811865476,0",
    ]);
    assert_eq!(code, 0, "{err}");
    let v: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["converged"], true);
    assert_eq!(v["q"].as_array().unwrap().len(), 7);
    assert!(
        v["position_error"].as_f64().unwrap() < 1e-6
            && v["orientation_error"].as_f64().unwrap() < 1e-6
    );
    assert!(v["iterations"].as_u64().unwrap() > 0);
    // Check the answer with `armature fk`.
    let q: Vec<String> = v["q"].as_array().unwrap().iter().map(|x| x.to_string()).collect();
    let (_, fk, _) = armature(&["fk", "--q", &q.join(",")]);
    let fk: Value = serde_json::from_str(&fk).unwrap();
    let p = fk["ee"]["position"].as_array().unwrap();
    assert!((p[1].as_f64().unwrap() + 0.25).abs() < 1e-6);
    // Unreachable: JSON with the best effort, exit code 3.
    let (code, out, err) = armature(&["ik", "--pos", "2,0,0", "--restarts", "2"]);
    assert_eq!(code, 3);
    assert!(err.contains("did not converge"));
    let v: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["converged"], false);
    assert!(v["position_error"].as_f64().unwrap().is_finite());
    // So far away that the squared error overflows: still not converged (issue 25, class 5).
    let (code, out, err) = armature(&["ik", "--pos", "1e300,0,0"]);
    assert_eq!(code, 3, "{err}");
    let v: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["converged"], false);
    assert!((v["position_error"].as_f64().unwrap() / 1e300 - 1.0).abs() < 1e-6, "{v}");
    // Restarts size the time an unreachable target takes: capped, bad input above the cap.
    let (code, _, err) = armature(&["ik", "--pos", "2,0,0", "--restarts", "1000000000"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--restarts 1000000000: at most 1000"), "{err}");
}

#[test]
fn keyframes_in_every_mode() {
    let path = temp_file("ik", "seed.toml", SEED_KEYFRAMES);
    for extra in [&[][..], &["--sequential"][..], &["--branches"][..]] {
        let mut args = vec!["ik", "--keyframes", path.to_str().unwrap()];
        args.extend_from_slice(extra);
        let (code, out, err) = armature(&args);
        assert_eq!(code, 0, "{extra:?}: {err}");
        let v: Value = serde_json::from_str(&out).unwrap();
        let nodes = v["nodes"].as_array().unwrap();
        assert_eq!(nodes.len(), 11);
        assert!(nodes.iter().all(|n| n["converged"] == true));
        assert!(v["max_joint_step"].as_f64().unwrap() > 0.0);
        let mode = if extra.is_empty() {
            "Parallel"
        } else if extra[0] == "--sequential" {
            "Sequential"
        } else {
            "Branches"
        };
        assert_eq!(v["mode"], mode);
    }
    // One mode at a time.
    let (code, _, err) =
        armature(&["ik", "--keyframes", path.to_str().unwrap(), "--sequential", "--branches"]);
    assert_eq!(code, 2, "{err}");
}

#[test]
fn bad_input_exits_2() {
    let bad_file = temp_file(
        "ik",
        "bad.toml",
        "[[keyframes]]\nnode = 0\nposition = [0.5, 0.0, 0.3]\nspeed = 3\n",
    );
    let unordered =
        temp_file("ik", "unordered.toml", &SEED_KEYFRAMES.replace("node = 4", "node = 1"));
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["ik", "--pos", "0.3,0.1"], "--pos: expected 3 values, got 2"),
        (vec!["ik", "--pos", "0.3,nan,0.2"], "--pos: entry 2 is NaN"),
        (vec!["ik", "--pos", "0.3,0.1,0.2", "--quat", "1,1,0,0"], "--quat: IK target: quaternion"),
        (vec!["ik", "--pos", "0.3,0.1,0.2", "--quat", "1,0,0"], "--quat: expected 4 values"),
        (vec!["ik", "--pos", "0.3,0.1,0.2", "--seed", "0,0"], "expected 7 joint values, got 2"),
        (
            vec!["ik", "--keyframes", bad_file.to_str().unwrap()],
            "bad.toml:4:1: unknown field `speed`",
        ),
        (
            vec!["ik", "--keyframes", unordered.to_str().unwrap()],
            "keyframe 2: node 1 does not come after node 2",
        ),
        (vec!["ik", "--keyframes", "nope.toml"], "nope.toml"),
    ];
    for (args, msg) in cases {
        let (code, out, err) = armature(&args);
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(out.is_empty(), "{args:?}");
        assert!(err.contains(msg), "{args:?}: {err}");
    }
    let (code, _, _) = armature(&["ik"]);
    assert_eq!(code, 2, "neither --pos nor --keyframes");
}

/// The README's main-job command works on the shipped example file.
#[test]
fn readme_example_file_solves() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/pick-and-place-keyframes.toml");
    let (code, out, err) = armature(&["ik", "--keyframes", path, "--sequential"]);
    assert_eq!(code, 0, "{err}");
    let v: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["nodes"].as_array().unwrap().len(), 11);
}
