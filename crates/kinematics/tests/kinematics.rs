//! Forward kinematics: home poses, numeric vs symbolic, Jacobians vs central differences,
//! known poses of the built-in robots, URDF import vs direct composition, file errors.

use std::f64::consts::{FRAC_PI_2, PI};

use armature_kinematics::robots::{self, dh_transform, ur5e_dh};
use armature_kinematics::{
    Chain, Joint, JointKind, Keypoint, KinematicsError, Limits, chain_from_toml_str,
    chain_from_urdf_str, load_robot,
};
use armature_lie::{SE3, SO3};
use armature_symbolic::{Expr, Function};
use nalgebra::{Matrix3xX, Matrix6xX, UnitQuaternion, Vector3, Vector6};

fn random_q(n: usize, seed: usize) -> Vec<f64> {
    (0..n).map(|i| ((seed * 31 + i * 7) as f64 * 0.913).sin() * 2.5).collect()
}

#[test]
fn home_poses_at_zero() {
    for chain in [robots::arm7(), robots::ur5e()] {
        let mut ws = chain.fk_workspace();
        chain.forward(&vec![0.0; chain.dof()], &mut ws).unwrap();
        assert!((ws.ee().matrix() - chain.home().matrix()).amax() < 1e-15, "{}", chain.name());
        for (k, kp) in chain.keypoints().iter().enumerate() {
            assert!((ws.keypoint_position(k) - Vector3::from(kp.position)).norm() < 1e-15);
            assert_eq!(ws.keypoint_frame(&chain, k).matrix(), SE3::identity().matrix());
        }
    }
    // The seed's numbers.
    let arm = robots::arm7();
    assert!((arm.home().translation() - Vector3::new(0.7, 0.0, 0.34)).norm() < 1e-15);
    assert_eq!(arm.keypoints().iter().map(|k| k.after).collect::<Vec<_>>(), [0, 1, 2, 4, 7]);
    let (lo, hi) = arm.position_limits();
    assert!((hi[6] - 175f64.to_radians()).abs() < 1e-15 && lo[1] == -hi[1]);
    assert_eq!(arm.joints()[6].limits.effort, Some(0.5));
}

#[test]
fn known_poses() {
    // arm7: elbow down by 90° at joint 2 puts the whole forearm straight down from the shoulder.
    let arm = robots::arm7();
    let mut ws = arm.fk_workspace();
    arm.forward(&[0.0, FRAC_PI_2, 0.0, 0.0, 0.0, 0.0, 0.0], &mut ws).unwrap();
    assert!((ws.ee().translation() - Vector3::new(0.0, 0.0, 0.34 - 0.7)).norm() < 1e-15);
    assert!((ws.keypoint_position(2) - Vector3::new(0.0, 0.0, 0.04)).norm() < 1e-15);
    // The gripper-down pose of the seed: y joints summing to 90° point the tool's +x at −z.
    arm.forward(&[0.0, 0.6, 0.0, -1.2, 0.0, FRAC_PI_2 + 0.6, 0.0], &mut ws).unwrap();
    let x_axis = ws.ee().rotation().act(&Vector3::x());
    assert!((x_axis - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-15);
    // UR5e at zero: the documented (−(a2 + a3), −(d4 + d6), d1 − d5).
    let ur = robots::ur5e();
    let mut ws = ur.fk_workspace();
    ur.forward(&[0.0; 6], &mut ws).unwrap();
    assert!((ws.ee().translation() - Vector3::new(-0.8172, -0.2329, 0.0628)).norm() < 1e-12);
    // Upright: shoulder lift −90°, wrist 1 −90° → the arm points straight up.
    ur.forward(&[0.0, -FRAC_PI_2, 0.0, -FRAC_PI_2, 0.0, 0.0], &mut ws).unwrap();
    let p = ws.ee().translation();
    assert!(
        (p - Vector3::new(0.0, -0.2329, 0.1625 + 0.425 + 0.3922 + 0.0997)).norm() < 1e-12,
        "{p:?}"
    );
}

#[test]
fn ur5e_poe_equals_direct_dh_product() {
    let ur = robots::ur5e();
    let rows = ur5e_dh();
    let mut ws = ur.fk_workspace();
    for s in 0..100 {
        let q = random_q(6, s);
        ur.forward(&q, &mut ws).unwrap();
        let mut t = SE3::identity();
        for (i, r) in rows.iter().enumerate() {
            t = t * dh_transform(r, q[i]);
            let k = ur
                .keypoint_index(["shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "ee"][i])
                .unwrap();
            assert!((ws.keypoint_position(k) - t.translation()).norm() < 1e-12);
        }
        assert!((ws.ee().matrix() - t.matrix()).amax() < 1e-12);
    }
}

#[test]
fn numeric_equals_symbolic_fk() {
    for chain in [robots::arm7(), robots::ur5e()] {
        let n = chain.dof();
        let angle = Expr::variable("angle", n);
        let s = chain.symbolic_fk(&angle).unwrap();
        let mut outs: Vec<Expr> = s.frames.iter().map(|(_, e)| e.clone()).collect();
        outs.extend(s.positions.iter().map(|(_, e)| e.clone()));
        outs.push(s.t_ee.clone());
        outs.push(s.ee_position());
        let f = Function::compile(&outs, &[&[angle]]).unwrap();
        let mut fws = f.workspace();
        let mut v = vec![0.0; f.n_outputs()];
        let mut ws = chain.fk_workspace();
        let nk = chain.keypoints().len();
        for seed in 0..50 {
            let q = random_q(n, seed);
            chain.forward(&q, &mut ws).unwrap();
            f.eval(&q, &mut fws, &mut v, None).unwrap();
            for k in 0..nk {
                let m = ws.keypoint_frame(&chain, k).matrix();
                for e in 0..16 {
                    assert!((v[k * 16 + e] - m[(e / 4, e % 4)]).abs() < 1e-12);
                }
                let p = ws.keypoint_position(k);
                for i in 0..3 {
                    assert!((v[nk * 16 + k * 3 + i] - p[i]).abs() < 1e-12);
                }
            }
            let base = nk * 19;
            let m = ws.ee().matrix();
            for e in 0..16 {
                assert!((v[base + e] - m[(e / 4, e % 4)]).abs() < 1e-12);
            }
            for i in 0..3 {
                assert!((v[base + 16 + i] - ws.ee().translation()[i]).abs() < 1e-12);
            }
        }
    }
    assert!(matches!(
        robots::arm7().symbolic_fk(&Expr::variable("q", 6)),
        Err(KinematicsError::WrongJointCount { expected: 7, got: 6 })
    ));
}

#[test]
fn jacobians_match_finite_differences() {
    let h = 1e-6;
    for chain in [robots::arm7(), robots::ur5e(), prismatic_chain()] {
        let n = chain.dof();
        let mut ws = chain.fk_workspace();
        let mut wp = chain.fk_workspace();
        let mut wm = chain.fk_workspace();
        let mut body = Matrix6xX::zeros(n);
        let mut pj = Matrix3xX::zeros(n);
        for seed in 0..20 {
            let q = random_q(n, seed);
            chain.forward(&q, &mut ws).unwrap();
            ws.body_jacobian(&mut body).unwrap();
            for i in 0..n {
                let (mut qp, mut qm) = (q.clone(), q.clone());
                qp[i] += h;
                qm[i] -= h;
                chain.forward(&qp, &mut wp).unwrap();
                chain.forward(&qm, &mut wm).unwrap();
                // Space twist: dT·T⁻¹; body twist: T⁻¹·dT.
                let space = (wp.ee().compose(&ws.ee().inverse()).log()
                    - wm.ee().compose(&ws.ee().inverse()).log())
                    / (2.0 * h);
                let bodyfd = (ws.ee().inverse().compose(&wp.ee()).log()
                    - ws.ee().inverse().compose(&wm.ee()).log())
                    / (2.0 * h);
                let col: Vector6<f64> = ws.space_jacobian().column(i).into_owned();
                assert!((col - space).amax() < 1e-8, "{} space col {i}", chain.name());
                assert!((body.column(i) - bodyfd).amax() < 1e-8, "{} body col {i}", chain.name());
                for k in 0..chain.keypoints().len() {
                    let after = chain.keypoints()[k].after;
                    ws.point_jacobian(after, &ws.keypoint_position(k), &mut pj).unwrap();
                    let fd = (wp.keypoint_position(k) - wm.keypoint_position(k)) / (2.0 * h);
                    assert!(
                        (pj.column(i) - fd).amax() < 1e-8,
                        "{} keypoint {k} col {i}",
                        chain.name()
                    );
                }
                // A point rigidly attached to the link after joint 3, off the axes.
                let home = Vector3::new(0.1, -0.2, 0.3);
                let p = ws.point_on_link(3, &home);
                ws.point_jacobian(3, &p, &mut pj).unwrap();
                let fd = (wp.point_on_link(3, &home) - wm.point_on_link(3, &home)) / (2.0 * h);
                assert!((pj.column(i) - fd).amax() < 1e-8);
            }
        }
    }
}

/// Singular poses (arm straight, wrist aligned) give finite, FD-consistent Jacobians.
#[test]
fn singular_poses_are_finite() {
    let arm = robots::arm7();
    let mut ws = arm.fk_workspace();
    arm.forward(&[0.0; 7], &mut ws).unwrap();
    let j = ws.space_jacobian();
    assert!(j.iter().all(|x| x.is_finite()));
    // Joints 1, 3, 5, 7 are collinear (the z axes through the outstretched arm are parallel).
    assert!(
        j.clone().svd(false, false).singular_values.iter().filter(|s| **s < 1e-12).count() >= 1
    );
}

fn prismatic_chain() -> Chain {
    let lim = Limits { lower: Some(-1.0), upper: Some(1.0), velocity: None, effort: None };
    Chain::new(
        "rpr",
        vec![
            Joint::revolute("r1", [0.0, 0.0, 1.0], [0.0, 0.0, 0.0], lim),
            Joint::prismatic("p2", [1.0, 0.0, 0.0], lim),
            Joint::revolute("r3", [0.0, 1.0, 0.0], [0.5, 0.0, 0.2], lim),
            Joint::revolute("r4", [0.6, 0.0, 0.8], [0.5, 0.1, 0.2], lim),
        ],
        SE3::from_parts(SO3::rot_x(0.3), Vector3::new(0.7, 0.1, 0.2)),
        vec![
            Keypoint { name: "a".into(), after: 2, position: [0.5, 0.0, 0.2] },
            Keypoint { name: "b".into(), after: 4, position: [0.7, 0.1, 0.2] },
        ],
    )
    .unwrap()
}

const URDF: &str = r#"<?xml version="1.0"?>
<robot name="test_arm">
  <link name="world"/>
  <link name="base"/>
  <link name="l1"/>
  <link name="l2"/>
  <link name="slider"/>
  <link name="l3"/>
  <link name="tool"/>
  <link name="camera"/>
  <joint name="mount" type="fixed">
    <parent link="world"/><child link="base"/>
    <origin xyz="0.1 0 0.05" rpy="0 0 0.3"/>
  </joint>
  <joint name="j1" type="revolute">
    <parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.2" rpy="0.1 -0.2 0.3"/>
    <axis xyz="0 0 1"/>
    <limit lower="-2" upper="2" effort="30" velocity="2"/>
  </joint>
  <joint name="j2" type="continuous">
    <parent link="l1"/><child link="l2"/>
    <origin xyz="0.05 0.02 0.3" rpy="1.2 0 0.4"/>
    <axis xyz="0 1 1"/>
  </joint>
  <joint name="slide" type="prismatic">
    <parent link="l2"/><child link="slider"/>
    <origin xyz="0.2 0 0" rpy="0 0.5 0"/>
    <axis xyz="1 0 0"/>
    <limit lower="0" upper="0.3" effort="100" velocity="0.5"/>
  </joint>
  <joint name="j3" type="revolute">
    <parent link="slider"/><child link="l3"/>
    <origin xyz="0.1 0.1 0" rpy="-0.3 0.2 0.1"/>
    <axis xyz="1 0 0"/>
    <limit lower="-1" upper="1" effort="10" velocity="3"/>
  </joint>
  <joint name="flange" type="fixed">
    <parent link="l3"/><child link="tool"/>
    <origin xyz="0 0 0.12" rpy="0 0 1.0"/>
  </joint>
  <joint name="cam" type="fixed">
    <parent link="l2"/><child link="camera"/>
    <origin xyz="0 0.1 0" rpy="0 0 0"/>
  </joint>
</robot>"#;

fn urdf_pose(xyz: [f64; 3], rpy: [f64; 3]) -> SE3 {
    SE3::from_parts(
        SO3::from(UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2])),
        Vector3::from(xyz),
    )
}

/// The URDF's joint transforms composed directly: origin · motion(q) per joint.
fn urdf_direct(q: &[f64]) -> SE3 {
    let rot = |axis: [f64; 3], a: f64| {
        SE3::from_rotation(SO3::exp(&(Vector3::from(axis).normalize() * a)))
    };
    urdf_pose([0.0, 0.0, 0.2], [0.1, -0.2, 0.3])
        * rot([0.0, 0.0, 1.0], q[0])
        * urdf_pose([0.05, 0.02, 0.3], [1.2, 0.0, 0.4])
        * rot([0.0, 1.0, 1.0], q[1])
        * urdf_pose([0.2, 0.0, 0.0], [0.0, 0.5, 0.0])
        * SE3::from_translation(Vector3::new(q[2], 0.0, 0.0))
        * urdf_pose([0.1, 0.1, 0.0], [-0.3, 0.2, 0.1])
        * rot([1.0, 0.0, 0.0], q[3])
        * urdf_pose([0.0, 0.0, 0.12], [0.0, 0.0, 1.0])
}

#[test]
fn urdf_chain_equals_direct_composition() {
    let chain = chain_from_urdf_str(URDF, "base", "tool", None).unwrap();
    assert_eq!(chain.dof(), 4);
    assert_eq!(chain.joints()[2].kind, JointKind::Prismatic);
    assert_eq!(
        chain.keypoint_names().collect::<Vec<_>>(),
        ["base", "l1", "l2", "slider", "l3", "tool"]
    );
    assert_eq!(chain.joints()[1].limits.lower, None, "continuous joints have no position limits");
    assert_eq!(chain.joints()[2].limits.upper, Some(0.3));
    let mut ws = chain.fk_workspace();
    for s in 0..100 {
        let q = random_q(4, s);
        chain.forward(&q, &mut ws).unwrap();
        let direct = urdf_direct(&q);
        assert!((ws.ee().matrix() - direct.matrix()).amax() < 1e-12, "seed {s}");
    }
    // From the world link, the fixed mount folds into the geometry.
    let from_world = chain_from_urdf_str(URDF, "world", "tool", Some(&["l3", "tool"])).unwrap();
    let mut w2 = from_world.fk_workspace();
    let q = random_q(4, 7);
    from_world.forward(&q, &mut w2).unwrap();
    let expected = urdf_pose([0.1, 0.0, 0.05], [0.0, 0.0, 0.3]) * urdf_direct(&q);
    assert!((w2.ee().matrix() - expected.matrix()).amax() < 1e-12);
    assert_eq!(from_world.keypoints()[0].after, 4);
}

#[test]
fn urdf_errors_by_class() {
    /// (URDF text, base, tip, keypoint links, expected message).
    type Case<'a> = (String, &'a str, &'a str, Option<Vec<&'a str>>, &'a str);
    let cases: Vec<Case<'_>> = vec![
        ("<robot name='x'><link name='a'/>".into(), "a", "a", None, "malformed URDF"),
        (URDF.into(), "base", "gripper", None, "no link named 'gripper'"),
        (URDF.into(), "tool", "base", None, "link 'base' is not below link 'tool'"),
        (
            URDF.into(),
            "base",
            "tool",
            Some(vec!["camera"]),
            "keypoint link 'camera' is not on the path base → tool",
        ),
        (
            URDF.replace(r#"name="j2" type="continuous""#, r#"name="j2" type="floating""#),
            "base",
            "tool",
            None,
            "joint 'j2' is Floating",
        ),
        (
            URDF.replace(r#"name="j3" type="revolute""#, r#"name="j3" type="planar""#),
            "base",
            "tool",
            None,
            "joint 'j3' is Planar",
        ),
        (
            URDF.replace(
                r#"<axis xyz="1 0 0"/>
    <limit lower="-1""#,
                r#"<axis xyz="0 0 0"/>
    <limit lower="-1""#,
            ),
            "base",
            "tool",
            None,
            "joint 'j3' has a zero axis",
        ),
    ];
    for (xml, base, tip, kps, msg) in cases {
        let kps_ref: Option<Vec<&str>> = kps.clone();
        let err = chain_from_urdf_str(&xml, base, tip, kps_ref.as_deref()).unwrap_err().to_string();
        assert!(err.contains(msg), "{err:?} should contain {msg:?}");
    }
}

const TOML: &str = r#"name = "two-link"
home = { position = [0.5, 0.0, 0.0] }

[[joints]]
name = "j1"
kind = "revolute"
screw = [0.0, 0.0, 0.0, 0.0, 0.0, 1.0]
limits = { lower = -3.0, upper = 3.0, velocity = 2.0, effort = 10.0 }

[[joints]]
name = "j2"
kind = "revolute"
screw = [0.0, -0.25, 0.0, 0.0, 0.0, 1.0]

[[keypoints]]
name = "elbow"
after = 1
position = [0.25, 0.0, 0.0]
"#;

#[test]
fn toml_screw_table_and_its_errors() {
    let chain = chain_from_toml_str(TOML, "two.toml").unwrap();
    let mut ws = chain.fk_workspace();
    chain.forward(&[FRAC_PI_2, FRAC_PI_2], &mut ws).unwrap();
    assert!((ws.ee().translation() - Vector3::new(-0.25, 0.25, 0.0)).norm() < 1e-15);
    let cases = [
        (
            TOML.replace(
                "kind = \"revolute\"\nscrew = [0.0, -0.25",
                "kind = \"revolute\"\nscrew = [0.0, -0.25, 0.0, 0.0, 0.0, 2.0]\n#",
            ),
            "two.toml:10:1",
            "joint 1 ('j2'): rotation axis",
        ),
        (
            TOML.replace("lower = -3.0, upper = 3.0", "lower = 3.0, upper = -3.0"),
            "two.toml:4:1",
            "lower limit 3 exceeds upper limit -3",
        ),
        (
            TOML.replace("after = 1", "after = 3"),
            "two.toml:15:1",
            "keypoint 'elbow': comes after 3 joints but the chain has 2",
        ),
        (
            TOML.replace(
                "kind = \"revolute\"\nscrew = [0.0, 0.0,",
                "kind = \"spinning\"\nscrew = [0.0, 0.0,",
            ),
            "two.toml:6:8",
            "unknown variant `spinning`",
        ),
        (
            TOML.replace("name = \"j1\"", "name = \"j1\"\ncolor = \"red\""),
            "two.toml:6:1",
            "unknown field `color`",
        ),
        (
            TOML.replace("home = {", "home = [ {"),
            "two.toml:4:1",
            "missing comma between array elements",
        ),
    ];
    for (text, loc, msg) in cases {
        let err = chain_from_toml_str(&text, "two.toml").unwrap_err();
        match &err {
            KinematicsError::File { location, message } => {
                assert!(location.starts_with(loc), "{location} should start with {loc}: {message}");
                assert!(message.contains(msg), "{message:?} should contain {msg:?}");
            }
            other => panic!("{other:?}"),
        }
    }
}

#[test]
fn chain_validation_names_the_offender() {
    let ok = Limits::default();
    let bad = |joints: Vec<Joint>, kps: Vec<Keypoint>| {
        Chain::new("t", joints, SE3::identity(), kps).unwrap_err().to_string()
    };
    assert!(
        bad(vec![Joint::revolute("a", [0.0, 0.0, 2.0], [0.0; 3], ok)], vec![])
            .contains("joint 0 ('a'): rotation axis")
    );
    let mut pitched = Joint::revolute("p", [0.0, 0.0, 1.0], [0.0; 3], ok);
    pitched.screw[2] = 0.1;
    assert!(bad(vec![pitched], vec![]).contains("pitch"));
    assert!(
        bad(vec![Joint::prismatic("s", [0.0, 2.0, 0.0], ok)], vec![]).contains("prismatic screw")
    );
    let lim = Limits { velocity: Some(-1.0), ..ok };
    assert!(
        bad(vec![Joint::revolute("v", [1.0, 0.0, 0.0], [0.0; 3], lim)], vec![])
            .contains("velocity limit -1 is not positive")
    );
    let j = || Joint::revolute("j", [1.0, 0.0, 0.0], [0.0; 3], ok);
    assert!(bad(vec![j(), j()], vec![]).contains("duplicate joint name 'j'"));
    let kp = |n: &str, after| Keypoint { name: n.into(), after, position: [0.0; 3] };
    assert!(
        bad(vec![j()], vec![kp("a", 1), kp("b", 0)])
            .contains("keypoint 'b': comes after 0 joints, fewer than")
    );
    assert!(
        bad(vec![j()], vec![kp("a", 2)])
            .contains("keypoint 'a': comes after 2 joints but the chain has 1")
    );
    assert!(bad(vec![j()], vec![kp("a", 0), kp("a", 1)]).contains("duplicate keypoint name 'a'"));
    let arm = robots::arm7();
    let mut ws = arm.fk_workspace();
    assert!(matches!(
        arm.forward(&[0.0; 6], &mut ws),
        Err(KinematicsError::WrongJointCount { expected: 7, got: 6 })
    ));
    assert!(matches!(
        arm.forward(&[0.0, 0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0], &mut ws),
        Err(KinematicsError::NonFiniteJoint { index: 2, .. })
    ));
    let mut other = robots::ur5e().fk_workspace();
    assert!(arm.forward(&[0.0; 7], &mut other).is_err(), "a workspace of another chain");
    assert!(matches!(load_robot("panda", None, None), Err(KinematicsError::UnknownRobot(_))));
    assert!(matches!(load_robot("missing.toml", None, None), Err(KinematicsError::File { .. })));
    assert_eq!(load_robot("ur5e", None, None).unwrap().dof(), 6);
    let _ = PI;
}

/// A URDF with two leaf links needs its tip named: the error lists the leaves as data (and
/// names no command-line flag; the front ends say how to name it).
#[test]
fn a_urdf_with_several_leaves_asks_for_its_tip() {
    let path = std::env::temp_dir().join(format!("armature-leaves-{}.urdf", std::process::id()));
    std::fs::write(&path, URDF).unwrap();
    let e = load_robot(path.to_str().unwrap(), None, None).unwrap_err();
    match &e {
        KinematicsError::AmbiguousTip { leaves } => {
            assert_eq!(leaves.len(), 2, "{leaves:?}");
            assert!(leaves.iter().any(|l| l == "camera") && leaves.iter().any(|l| l == "tool"));
        }
        other => panic!("{other}"),
    }
    assert!(e.to_string().contains("name the tip link") && !e.to_string().contains("--"), "{e}");
    assert_eq!(load_robot(path.to_str().unwrap(), None, Some("tool")).unwrap().dof(), 4);
    std::fs::remove_file(&path).unwrap();
}

/// URDFs that are not trees are refused, naming the link or joint, instead of walking
/// forever (a loop) or picking one of two parents.
#[test]
fn urdfs_that_are_not_trees_are_refused() {
    let joint = |name: &str, parent: &str, child: &str| {
        format!(
            r#"<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>"#
        )
    };
    let robot = |links: &[&str], joints: &[String]| {
        let links: String = links.iter().map(|l| format!(r#"<link name="{l}"/>"#)).collect();
        format!(r#"<robot name="r">{links}{}</robot>"#, joints.concat())
    };
    let cases = [
        // j1: b → a, j2: a → b, and the base elsewhere: the walk from a never reaches it.
        (
            robot(&["base", "a", "b"], &[joint("j1", "b", "a"), joint("j2", "a", "b")]),
            "base",
            "a",
            "loop through link",
        ),
        (
            robot(&["base", "a", "b"], &[joint("j1", "base", "a"), joint("j2", "b", "a")]),
            "base",
            "a",
            "link 'a' has two parent joints ('j1' and 'j2')",
        ),
        (
            robot(&["base", "a", "a"], &[joint("j1", "base", "a")]),
            "base",
            "a",
            "link 'a' is defined twice",
        ),
        (
            robot(&["base", "a"], &[joint("j1", "base", "a"), joint("j1", "a", "a")]),
            "base",
            "a",
            "joint 'j1' is defined twice",
        ),
        (robot(&["base", "a"], &[joint("j1", "a", "a")]), "base", "a", "joins link 'a' to itself"),
        (robot(&["base", "a"], &[joint("j1", "base", "c")]), "base", "a", "names no link 'c'"),
    ];
    for (xml, base, tip, expected) in cases {
        let e = chain_from_urdf_str(&xml, base, tip, None).unwrap_err();
        assert!(e.to_string().contains(expected), "{expected}: {e}");
    }
}

/// Found by fuzzing: the XML parser under `urdf-rs` panicked on an attribute with an empty
/// namespace prefix beside a default namespace; the loader reports a malformed URDF instead.
#[test]
fn a_urdf_the_xml_parser_panics_on_is_a_malformed_urdf() {
    let xml = r#"<?xml version="1.0"?><robot name="r"><link name="a" xmlns="6.2" :elocity="3.1"/></robot>"#;
    let e = chain_from_urdf_str(xml, "a", "a", None).unwrap_err();
    assert!(e.to_string().contains("malformed URDF: the XML parser rejected"), "{e}");
}

/// Base and tip choose a chain within a URDF; given for another robot they are an error, not
/// ignored.
#[test]
fn base_and_tip_for_a_built_in_robot_are_an_error() {
    let e = load_robot("arm7", Some("base"), None).unwrap_err();
    assert!(matches!(e, KinematicsError::BaseTipNotUrdf(_)), "{e}");
    assert!(load_robot("ur5e", None, Some("tool")).is_err());
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(300))]
    /// Hostile URDFs — random joint graphs over a few links (loops, two parents, self-joins,
    /// unknown links), odd joint types, huge or non-numeric values, truncated text — load or
    /// fail with an error, never panic or hang.
    #[test]
    fn hostile_urdfs_never_panic_or_hang(
        links in 1usize..6,
        joints in proptest::collection::vec((0usize..7, 0usize..7, 0usize..5, 0usize..6), 0..9),
        base in 0usize..7,
        tip in 0usize..7,
        cut in proptest::option::of(0usize..2000),
    ) {
        let kinds = ["revolute", "continuous", "prismatic", "fixed", "floating"];
        let values = ["0", "1e308", "-1e308", "nan", "inf", "x"];
        let mut xml = String::from(r#"<?xml version="1.0"?><robot name="h">"#);
        for l in 0..links {
            xml += &format!(r#"<link name="l{l}"/>"#);
        }
        for (i, &(p, c, k, v)) in joints.iter().enumerate() {
            let value = values[v];
            xml += &format!(
                r#"<joint name="j{i}" type="{}"><parent link="l{p}"/><child link="l{c}"/><origin xyz="{value} 0 0.1" rpy="0 {value} 0"/><axis xyz="0 0 1"/><limit lower="-1" upper="{value}" effort="1" velocity="1"/></joint>"#,
                kinds[k]
            );
        }
        xml += "</robot>";
        if let Some(c) = cut {
            let mut c = c.min(xml.len());
            while !xml.is_char_boundary(c) {
                c -= 1;
            }
            xml.truncate(c);
        }
        let start = std::time::Instant::now();
        let _ = chain_from_urdf_str(&xml, &format!("l{base}"), &format!("l{tip}"), None);
        proptest::prop_assert!(start.elapsed().as_secs_f64() < 1.0, "took {:?}", start.elapsed());
    }
}
