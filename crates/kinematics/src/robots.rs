//! Built-in robots and the Denavit–Hartenberg conversion.

use armature_lie::{SE3, SO3};
use nalgebra::Vector3;

use crate::{Chain, Inertial, Joint, JointKind, Keypoint, KinematicsError, Limits};

/// Names of the built-in robots accepted by [`builtin`].
pub const BUILTIN: [&str; 2] = ["arm7", "ur5e"];

/// A built-in robot by name.
///
/// # Errors
/// [`KinematicsError::UnknownRobot`].
pub fn builtin(name: &str) -> Result<Chain, KinematicsError> {
    match name {
        "arm7" => Ok(arm7()),
        "ur5e" => Ok(ur5e()),
        other => Err(KinematicsError::UnknownRobot(other.to_string())),
    }
}

/// The seed tutorial's 7-DOF arm: alternating z/y revolute joints, d1 = 0.340, a2 = 0.300,
/// a3 = 0.250, a4 = 0.150; keypoints base/shoulder/elbow/wrist/ee after 0/1/2/4/7 joints;
/// `|q| ≤ [170, 120, 170, 120, 170, 120, 175]°`, `|q̇| ≤ 3 rad/s`,
/// `|τ| ≤ [8, 8, 4, 4, 2, 1, 0.5] N·m`.
pub fn arm7() -> Chain {
    let (d1, a2, a3, a4) = (0.340, 0.300, 0.250, 0.150);
    let qmax = [170.0f64, 120.0, 170.0, 120.0, 170.0, 120.0, 175.0];
    let tmax = [8.0, 8.0, 4.0, 4.0, 2.0, 1.0, 0.5];
    let screws = [
        [0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
        [-d1, 0.0, 0.0, 0.0, 1.0, 0.0],
        [0.0, -a2, 0.0, 0.0, 0.0, 1.0],
        [-d1, 0.0, a2, 0.0, 1.0, 0.0],
        [0.0, -(a2 + a3), 0.0, 0.0, 0.0, 1.0],
        [-d1, 0.0, a2 + a3, 0.0, 1.0, 0.0],
        [0.0, -(a2 + a3 + a4), 0.0, 0.0, 0.0, 1.0],
    ];
    let joints = (0..7)
        .map(|i| Joint {
            name: format!("j{}", i + 1),
            kind: JointKind::Revolute,
            screw: screws[i],
            limits: Limits::symmetric(qmax[i].to_radians(), 3.0, tmax[i]),
            inertial: None,
            link: None,
        })
        .collect();
    let kp = |name: &str, after, position| Keypoint { name: name.into(), after, position };
    let keypoints = vec![
        kp("base", 0, [0.0, 0.0, 0.0]),
        kp("shoulder", 1, [0.0, 0.0, d1]),
        kp("elbow", 2, [a2, 0.0, d1]),
        kp("wrist", 4, [a2 + a3, 0.0, d1]),
        kp("ee", 7, [a2 + a3 + a4, 0.0, d1]),
    ];
    let home = SE3::from_translation(Vector3::new(a2 + a3 + a4, 0.0, d1));
    Chain::new("arm7", joints, home, keypoints).expect("the built-in arm7 is valid")
}

/// One row of a standard Denavit–Hartenberg table: joint `i` moves about `z_{i−1}` and
/// `T_i = T_{i−1}·Rz(θ + offset)·Tz(d)·Tx(a)·Rx(α)` (θ for revolute, d for prismatic joints).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DhRow {
    /// Joint name.
    pub name: &'static str,
    /// Revolute or prismatic.
    pub kind: JointKind,
    /// Link offset d (m).
    pub d: f64,
    /// Joint-angle offset added to θ at q = 0 (rad).
    pub theta_offset: f64,
    /// Link length a (m).
    pub a: f64,
    /// Link twist α (rad).
    pub alpha: f64,
    /// Limits.
    pub limits: Limits,
}

/// The transform of one DH row at joint value `q`.
pub fn dh_transform(row: &DhRow, q: f64) -> SE3 {
    let (theta, d) = match row.kind {
        JointKind::Revolute => (row.theta_offset + q, row.d),
        JointKind::Prismatic => (row.theta_offset, row.d + q),
    };
    SE3::from_rotation(SO3::rot_z(theta))
        * SE3::from_translation(Vector3::new(row.a, 0.0, d))
        * SE3::from_rotation(SO3::rot_x(row.alpha))
}

/// Converts a standard DH table to a product-of-exponentials chain. Keypoints named by
/// `keypoints` sit at the origins of frames `0..=n` (`(name, frame)`: frame `i` moves with
/// joints `1..=i`).
///
/// # Errors
/// As [`Chain::new`] (a keypoint frame beyond the table).
pub fn from_dh(
    name: &str,
    rows: &[DhRow],
    keypoints: &[(&str, usize)],
) -> Result<Chain, KinematicsError> {
    let mut frames = vec![SE3::identity()];
    for r in rows {
        let last = *frames.last().expect("non-empty");
        frames.push(last * dh_transform(r, 0.0));
    }
    let joints = rows
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let f = frames[i];
            let z = f.rotation().matrix().column(2).into_owned();
            let o = f.translation();
            match r.kind {
                JointKind::Revolute => Joint::revolute(r.name, z.into(), o.into(), r.limits),
                JointKind::Prismatic => Joint::prismatic(r.name, z.into(), r.limits),
            }
        })
        .collect();
    let kps = keypoints
        .iter()
        .map(|&(n, i)| Keypoint {
            name: n.into(),
            after: i,
            position: frames.get(i).map(|f| f.translation().into()).unwrap_or([f64::NAN; 3]),
        })
        .collect();
    Chain::new(name, joints, *frames.last().expect("non-empty"), kps)
}

/// The standard DH table of the Universal Robots UR5e (UR's published kinematic parameters;
/// ±360° joints, 180°/s, 150 N·m for the base, shoulder and elbow and 28 N·m for the wrists).
pub fn ur5e_dh() -> [DhRow; 6] {
    use std::f64::consts::{FRAC_PI_2, PI};
    let big = Limits::symmetric(2.0 * PI, PI, 150.0);
    let small = Limits::symmetric(2.0 * PI, PI, 28.0);
    let row = |name, d, a, alpha, limits| DhRow {
        name,
        kind: JointKind::Revolute,
        d,
        theta_offset: 0.0,
        a,
        alpha,
        limits,
    };
    [
        row("shoulder_pan", 0.1625, 0.0, FRAC_PI_2, big),
        row("shoulder_lift", 0.0, -0.425, 0.0, big),
        row("elbow", 0.0, -0.3922, 0.0, big),
        row("wrist_1", 0.1333, 0.0, FRAC_PI_2, small),
        row("wrist_2", 0.0997, 0.0, -FRAC_PI_2, small),
        row("wrist_3", 0.0996, 0.0, 0.0, small),
    ]
}

/// The UR5e's published mass properties per link, in its DH frame (Universal Robots' "DH
/// parameters for calculations of kinematics and dynamics": masses and centres of mass), with
/// the principal inertias of UR's ur_description (BSD-3-Clause) about the centre of mass.
pub fn ur5e_inertials() -> [Inertial; 6] {
    let body = |mass, com, [ixx, iyy, izz]: [f64; 3]| Inertial {
        mass,
        com,
        inertia: [ixx, 0.0, 0.0, iyy, 0.0, izz],
    };
    [
        body(3.761, [0.0, -0.02561, 0.00193], [0.010267495893, 0.010267495893, 0.00666]),
        body(8.058, [0.2125, 0.0, 0.11336], [0.1338857818623325, 0.1338857818623325, 0.0151074]),
        body(2.846, [0.15, 0.0, 0.0265], [0.031209355099586295, 0.031209355099586295, 0.004095]),
        body(1.37, [0.0, -0.0018, 0.01634], [0.00255989897604, 0.00255989897604, 0.0021942]),
        body(1.3, [0.0, 0.0018, 0.01634], [0.00255989897604, 0.00255989897604, 0.0021942]),
        body(
            0.365,
            [0.0, 0.0, -0.001159],
            [9.890410052167731e-05, 9.890410052167731e-05, 0.0001321171875],
        ),
    ]
}

/// The UR5e from [`ur5e_dh`], with keypoints at the DH frame origins:
/// base, shoulder, upper_arm, forearm, wrist_1, wrist_2, ee (frames 0…6), and the mass
/// properties of [`ur5e_inertials`] (so `dynamics = "rigid_body"` works on it).
pub fn ur5e() -> Chain {
    let rows = ur5e_dh();
    let chain = from_dh(
        "ur5e",
        &rows,
        &[
            ("base", 0),
            ("shoulder", 1),
            ("upper_arm", 2),
            ("forearm", 3),
            ("wrist_1", 4),
            ("wrist_2", 5),
            ("ee", 6),
        ],
    )
    .expect("the built-in ur5e is valid");
    let mut frame = SE3::identity();
    let mut joints = chain.joints().to_vec();
    for ((joint, row), inertial) in joints.iter_mut().zip(&rows).zip(ur5e_inertials()) {
        frame = frame * dh_transform(row, 0.0);
        joint.inertial = Some(inertial.transformed(&frame));
    }
    Chain::new("ur5e", joints, chain.home(), chain.keypoints().to_vec())
        .expect("the built-in ur5e is valid")
}
