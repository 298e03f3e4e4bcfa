//! Forward kinematics of the seed tutorial's 7-DOF arm by the product of exponentials,
//! using nothing but `armature-lie`: keypoint positions at the home pose and at a sample
//! configuration, and the end effector's orientation error to "gripper down" (Ry(90°)).
//!
//! Run: `cargo run --release -p armature-lie --example arm7_fk [q1 … q7]` (radians).

use armature_lie::{SE3, SO3};
use nalgebra::{Vector3, Vector6};
use std::f64::consts::FRAC_PI_2;

const D1: f64 = 0.340;
const A2: f64 = 0.300;
const A3: f64 = 0.250;
const A4: f64 = 0.150;

fn main() {
    // Screw axes [v; ω] in the base frame at q = 0, exactly as the seed writes them.
    let screws = [
        [0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
        [-D1, 0.0, 0.0, 0.0, 1.0, 0.0],
        [0.0, -A2, 0.0, 0.0, 0.0, 1.0],
        [-D1, 0.0, A2, 0.0, 1.0, 0.0],
        [0.0, -(A2 + A3), 0.0, 0.0, 0.0, 1.0],
        [-D1, 0.0, A2 + A3, 0.0, 1.0, 0.0],
        [0.0, -(A2 + A3 + A4), 0.0, 0.0, 0.0, 1.0],
    ]
    .map(|s| Vector6::from_column_slice(&s));
    let keypoints = [
        ("base", 0, Vector3::new(0.0, 0.0, 0.0)),
        ("shoulder", 1, Vector3::new(0.0, 0.0, D1)),
        ("elbow", 2, Vector3::new(A2, 0.0, D1)),
        ("wrist", 4, Vector3::new(A2 + A3, 0.0, D1)),
        ("ee", 7, Vector3::new(A2 + A3 + A4, 0.0, D1)),
    ];
    let home = SE3::from_translation(Vector3::new(A2 + A3 + A4, 0.0, D1));

    let args: Vec<String> = std::env::args().skip(1).collect();
    let q: [f64; 7] = match args.len() {
        0 => [0.0, 0.6, 0.0, -1.2, 0.0, 2.17, 0.0],
        7 => {
            let mut q = [0.0; 7];
            for (i, a) in args.iter().enumerate() {
                match a.parse::<f64>() {
                    Ok(v) if v.is_finite() => q[i] = v,
                    _ => {
                        eprintln!("error: joint angle {} is {a:?}, not a finite number", i + 1);
                        std::process::exit(2);
                    }
                }
            }
            q
        }
        n => {
            eprintln!("error: expected 7 joint angles (rad) or none, got {n}");
            std::process::exit(2);
        }
    };
    println!("q = {q:?} rad");

    // Accumulate the chain once, snapshotting the partial product at each keypoint.
    let mut chain = SE3::identity();
    let mut joint = 0;
    for (name, after, home_pos) in keypoints {
        while joint < after {
            chain = chain * SE3::exp(&(screws[joint] * q[joint]));
            joint += 1;
        }
        let p = chain.act(&home_pos);
        println!("{name:>9}: [{:+.4}, {:+.4}, {:+.4}] m", p.x, p.y, p.z);
    }
    let ee = chain * home;
    let down = SO3::rot_y(FRAC_PI_2);
    let err = down.inverse().compose(&ee.rotation()).log().norm();
    println!("ee quaternion [w, x, y, z] = {:.4?}", ee.rotation().quaternion_wxyz());
    println!("orientation error to gripper-down: {:.3}°", err.to_degrees());
}
