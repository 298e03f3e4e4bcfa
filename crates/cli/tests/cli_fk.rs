//! `armature fk` end to end: the real binary, its JSON, its errors and exit codes.

mod common;

use common::{armature, temp_file};
use serde_json::Value;

#[test]
fn fk_prints_stable_json() {
    let (code, out, err) = armature(&["fk", "--robot", "arm7", "--q", "0,0.6,0,-1.2,0,2.17,0"]);
    assert_eq!(code, 0, "{err}");
    let v: Value = serde_json::from_str(&out).unwrap();
    let kps = v["keypoints"].as_object().unwrap();
    assert_eq!(kps.keys().collect::<Vec<_>>(), ["base", "shoulder", "elbow", "wrist", "ee"]);
    let elbow = &kps["elbow"]["position"];
    assert!((elbow[0].as_f64().unwrap() - 0.3 * 0.6f64.cos()).abs() < 1e-12);
    assert!((elbow[2].as_f64().unwrap() - (0.34 - 0.3 * 0.6f64.sin())).abs() < 1e-12);
    let frame = kps["shoulder"]["frame"].as_array().unwrap();
    assert_eq!(frame.len(), 4);
    assert_eq!(frame[3], serde_json::json!([0.0, 0.0, 0.0, 1.0]), "row-major, bottom row last");
    let ee = &v["ee"];
    let q = ee["quaternion_wxyz"].as_array().unwrap();
    assert_eq!(q.len(), 4);
    assert!(q[0].as_f64().unwrap() >= 0.0);
    assert_eq!(ee["frame"].as_array().unwrap().len(), 4);
    let p = ee["position"].as_array().unwrap();
    assert_eq!(p, &kps["ee"]["position"].as_array().unwrap().clone());
    // Zero pose: the documented home.
    let (_, out, _) = armature(&["fk", "--q", "0,0,0,0,0,0,0"]);
    let v: Value = serde_json::from_str(&out).unwrap();
    let p: Vec<f64> =
        v["ee"]["position"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    assert!((p[0] - 0.7).abs() < 1e-15 && p[1] == 0.0 && (p[2] - 0.34).abs() < 1e-15, "{p:?}");
    assert_eq!(v["ee"]["quaternion_wxyz"], serde_json::json!([1.0, 0.0, 0.0, 0.0]));
}

#[test]
fn fk_reads_toml_and_urdf_robots() {
    let toml = temp_file(
        "fk",
        "two.toml",
        "name = \"two\"\nhome = { position = [0.5, 0.0, 0.0] }\n\n[[joints]]\nname = \"j1\"\nkind = \"revolute\"\nscrew = [0.0, 0.0, 0.0, 0.0, 0.0, 1.0]\n\n[[joints]]\nname = \"j2\"\nkind = \"revolute\"\nscrew = [0.0, -0.25, 0.0, 0.0, 0.0, 1.0]\n",
    );
    let (code, out, err) =
        armature(&["fk", "--robot", toml.to_str().unwrap(), "--q", "1.5707963267948966,0"]);
    assert_eq!(code, 0, "{err}");
    let v: Value = serde_json::from_str(&out).unwrap();
    let p = v["ee"]["position"].as_array().unwrap();
    assert!(p[0].as_f64().unwrap().abs() < 1e-15 && (p[1].as_f64().unwrap() - 0.5).abs() < 1e-15);
    let urdf = temp_file(
        "fk",
        "arm.urdf",
        r#"<robot name="tiny"><link name="base"/><link name="l1"/><link name="tool"/>
           <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
             <origin xyz="0 0 0.1"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
           <joint name="t" type="fixed"><parent link="l1"/><child link="tool"/><origin xyz="0.2 0 0"/></joint></robot>"#,
    );
    let (code, out, err) =
        armature(&["fk", "--robot", urdf.to_str().unwrap(), "--q", "1.5707963267948966"]);
    assert_eq!(code, 0, "{err}");
    let v: Value = serde_json::from_str(&out).unwrap();
    let p = v["ee"]["position"].as_array().unwrap();
    assert!(
        (p[1].as_f64().unwrap() - 0.2).abs() < 1e-15
            && (p[2].as_f64().unwrap() - 0.1).abs() < 1e-15
    );
    assert!(v["keypoints"].as_object().unwrap().contains_key("l1"));
    let (code, _, err) =
        armature(&["fk", "--robot", urdf.to_str().unwrap(), "--tip", "nowhere", "--q", "0"]);
    assert_eq!(code, 2);
    assert!(err.contains("no link named 'nowhere'"), "{err}");
    let bad =
        temp_file("fk", "bad.toml", "name = \"x\"\nhome = { position = [0, 0, 0] }\njoints = 3\n");
    let (code, _, err) = armature(&["fk", "--robot", bad.to_str().unwrap(), "--q", "0"]);
    assert_eq!(code, 2);
    assert!(err.contains("bad.toml:3:10"), "{err}");
}

#[test]
fn fk_rejects_bad_input_with_exit_code_2() {
    let cases: [(&[&str], &str); 5] = [
        (&["fk", "--q", "0,1"], "expected 7 joint values, got 2"),
        (&["fk", "--q", "0,0,nan,0,0,0,0"], "entry 3 is NaN"),
        (&["fk", "--q", "0,0,x,0,0,0,0"], "entry 3 ('x') is not a number"),
        (&["fk", "--robot", "panda", "--q", "0"], "unknown robot 'panda'"),
        (&["fk", "--robot", "missing.urdf", "--q", "0"], "missing.urdf"),
    ];
    for (args, msg) in cases {
        let (code, out, err) = armature(args);
        assert_eq!(code, 2, "{args:?}");
        assert!(out.is_empty(), "no partial output on error");
        assert!(err.starts_with("error: ") && err.contains(msg), "{args:?}: {err}");
    }
    let (code, _, _) = armature(&["fk"]);
    assert_eq!(code, 2, "a missing --q is a usage error");
    let (code, out, _) = armature(&["fk", "--q", "-0.5,0,0,0,0,0,0"]);
    assert_eq!(code, 0, "negative first value: {out}");
}

/// Two leaf links: the error lists them and says how to name the tip where the robot was
/// given — a flag on the command line, a key in a task file.
#[test]
fn a_urdf_with_two_leaves_asks_for_the_tip_in_the_inputs_own_words() {
    let urdf = r#"<robot name="fork">
  <link name="base"/><link name="a"/><link name="b"/>
  <joint name="ja" type="continuous"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/></joint>
  <joint name="jb" type="continuous"><parent link="base"/><child link="b"/><axis xyz="0 0 1"/></joint>
</robot>"#;
    let path = temp_file("fork", "fork.urdf", urdf);
    let (code, _, err) = armature(&["fk", "--robot", path.to_str().unwrap(), "--q", "0"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("2 leaf links (a, b)") && err.contains("give --tip LINK"), "{err}");
    let task = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../examples/pick-and-place.toml"
    ))
    .unwrap()
    .replacen("name = \"arm7\"", &format!("name = {:?}", path.to_str().unwrap()), 1);
    let task = temp_file("fork-task", "task.toml", &task);
    let (code, _, err) = armature(&["solve", task.to_str().unwrap(), "-q"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("give `tip = \"LINK\"` in [robot]") && !err.contains("--tip"), "{err}");
}
