//! `armature collide` end to end.

mod common;

use common::{armature, temp_file};
use serde_json::Value;

#[test]
fn collide_prints_pairs_and_minimum() {
    let (code, out, err) = armature(&["collide", "--q", "0,0,0,0,0,0,0"]);
    assert_eq!(code, 0, "{err}");
    let v: Value = serde_json::from_str(&out).unwrap();
    let pairs = v["pairs"].as_array().unwrap();
    assert_eq!(pairs.len(), 7);
    for p in pairs {
        for key in ["a", "b", "distance", "point_a", "point_b", "in_contact"] {
            assert!(p.get(key).is_some(), "missing {key}");
        }
    }
    let ball = pairs.iter().find(|p| p["a"] == "elbow-wrist" && p["b"] == "sphere").unwrap();
    assert!((ball["distance"].as_f64().unwrap() - (0.09 - 0.06 - 0.04)).abs() < 1e-12);
    assert_eq!(ball["in_contact"], true);
    let min = v["min_distance"].as_f64().unwrap();
    assert!(pairs.iter().all(|p| p["distance"].as_f64().unwrap() >= min));
    // A scene file with a table below the base: the base capsule touches it.
    let scene = temp_file(
        "collide",
        "table.toml",
        "self_collision = false\n[[links]]\nstart = \"base\"\nend = \"shoulder\"\nradius = 0.06\n[[obstacles]]\nname = \"table\"\nhalfspace = { normal = [0.0, 0.0, 1.0], offset = 0.0 }\n",
    );
    let (code, out, err) =
        armature(&["collide", "--q", "0,0,0,0,0,0,0", "--scene", scene.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let v: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["pairs"].as_array().unwrap().len(), 1);
    assert!((v["min_distance"].as_f64().unwrap() + 0.06).abs() < 1e-15);
    let bad = temp_file(
        "collide",
        "bad.toml",
        "[[links]]\nstart = \"base\"\nend = \"hand\"\nradius = 0.1\n",
    );
    let (code, out, err) =
        armature(&["collide", "--q", "0,0,0,0,0,0,0", "--scene", bad.to_str().unwrap()]);
    assert_eq!(code, 2);
    assert!(out.is_empty() && err.contains("unknown keypoint 'hand'"), "{err}");
    let (code, _, err) = armature(&["collide", "--robot", "ur5e", "--q", "0,0,0,0,0,0"]);
    assert_eq!(code, 2);
    assert!(err.contains("no default scene"), "{err}");
    let (code, _, err) = armature(&["collide", "--q", "0,0"]);
    assert_eq!(code, 2);
    assert!(err.contains("expected 7 joint values"), "{err}");
}
