//! Branch search: a continuous joint path where node-by-node IK jumps branches, a fixed start
//! kept, the node cost honoured, unreachable in-between nodes interpolated, keyframe
//! segments charged their own travel, bad weights and shares refused.

use armature_ik::{
    BranchSettings, IkError, IkSettings, IkTrajectory, Keyframe, Mode, Start, ik_branch_search,
    ik_interpolation,
};
use armature_kinematics::{Chain, robots};
use nalgebra::Vector3;

const DOWN: [f64; 4] = [std::f64::consts::FRAC_1_SQRT_2, 0.0, std::f64::consts::FRAC_1_SQRT_2, 0.0];

/// Keyframes `spacing` nodes apart: arm7's home (the identity orientation), then `down`,
/// gripper down.
fn from_home(spacing: usize, down: &[[f64; 3]]) -> Vec<Keyframe> {
    let home = Keyframe {
        node: 0,
        position: [0.69, 0.0, 0.34],
        quaternion_wxyz: Some([1.0, 0.0, 0.0, 0.0]),
    };
    let at = |(i, &position): (usize, &[f64; 3])| Keyframe {
        node: (i + 1) * spacing,
        position,
        quaternion_wxyz: Some(DOWN),
    };
    std::iter::once(home).chain(down.iter().enumerate().map(at)).collect()
}

/// A pick-and-place on arm7 (the suite's arm7-06) on which node-by-node IK from the previous
/// node jumps branches: its warm start fails at the grasp, and a random restart lands on
/// another branch.
fn jumping_pick_and_place() -> Vec<Keyframe> {
    let (pick, place) =
        ([0.3102828815569065, -0.3202638470681547], [0.3147912461474512, 0.2337521192530075]);
    from_home(
        2,
        &[
            [pick[0], pick[1], 0.15135080573911563],
            [pick[0], pick[1], 0.04147667176510572],
            [pick[0], pick[1], 0.15135080573911563],
            [place[0], place[1], 0.1725942553399504],
            [place[0], place[1], 0.06272012136594049],
        ],
    )
}

/// The branch search with unit weights and no cost per node.
fn least_travel(
    chain: &Chain,
    keyframes: &[Keyframe],
    start: Start<'_>,
    settings: &IkSettings,
    search: &BranchSettings,
) -> IkTrajectory {
    let weights = vec![1.0; chain.dof()];
    ik_branch_search(chain, keyframes, start, settings, search, &weights, &mut |_, _| 0.0).unwrap()
}

/// Σ over steps of the largest joint change.
fn travel(ik: &IkTrajectory) -> f64 {
    ik.q.windows(2)
        .map(|w| w[0].iter().zip(&w[1]).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max))
        .sum()
}

/// The keyframes' poses, by the chain's own FK: position error (m) and rotation angle (rad).
fn keyframe_errors(chain: &Chain, ik: &IkTrajectory, keyframes: &[Keyframe]) -> (f64, f64) {
    let mut ws = chain.fk_workspace();
    let (mut pe, mut oe) = (0.0f64, 0.0f64);
    for k in keyframes {
        chain.forward(&ik.q[k.node], &mut ws).unwrap();
        let (r, p) = ws.ee_matrix();
        pe = pe.max((p - Vector3::from(k.position)).norm());
        if let Some([w, x, y, z]) = k.quaternion_wxyz {
            let want =
                nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
            let got = nalgebra::UnitQuaternion::from_matrix(&r);
            oe = oe.max(got.angle_to(&want));
        }
    }
    (pe, oe)
}

#[test]
fn a_pick_and_place_that_node_by_node_ik_jumps_gets_a_continuous_path() {
    let arm = robots::arm7();
    let keyframes = jumping_pick_and_place();
    let settings = IkSettings { restarts: 8, ..IkSettings::default() };
    let seed = [0.0; 7];
    let sequential =
        ik_interpolation(&arm, &keyframes, &seed, &settings, Mode::Sequential).unwrap();
    // The premise: node by node, the path jumps (a joint moves more than 3 rad in one step).
    assert!(sequential.max_joint_step > 3.0, "{}", sequential.max_joint_step);
    let search = BranchSettings::default();
    let ik = least_travel(&arm, &keyframes, Start::Seed(&seed), &settings, &search);
    assert!(ik.all_converged());
    assert!(ik.max_joint_step < 1.0, "{}", ik.max_joint_step);
    assert!(travel(&ik) < 0.5 * travel(&sequential), "{} vs {}", travel(&ik), travel(&sequential));
    let (pe, oe) = keyframe_errors(&arm, &ik, &keyframes);
    assert!(pe < 1e-5 && oe < 1e-5, "{pe} {oe}");
    // Through ik_interpolation's mode too, and reproducibly.
    let again = ik_interpolation(&arm, &keyframes, &seed, &settings, Mode::Branches).unwrap();
    assert!(again.all_converged() && again.max_joint_step < 1.0, "{}", again.max_joint_step);
}

/// A pick-and-place on arm7 (the suite's arm7-ball-21, its ball left out) on which the
/// branch through the pick crawls: from its pre-grasp configuration the warm start of the
/// next node stalls 3 mm short, and without continuation the path left that branch right
/// after the pre-grasp waypoint, by a 1.8 rad step (at four nodes per segment, 2.9 rad).
fn crawling_pick_and_place(spacing: usize) -> Vec<Keyframe> {
    let (pick, place) =
        ([0.341867743334294, -0.34458597184118955], [0.4370404470746707, 0.259624225489386]);
    from_home(
        spacing,
        &[
            [pick[0], pick[1], 0.2238126458704332],
            [pick[0], pick[1], 0.07627329722459306],
            [pick[0], pick[1], 0.2238126458704332],
            [place[0], place[1], 0.20836580365207144],
            [place[0], place[1], 0.060826455006231295],
        ],
    )
}

/// A branch whose warm starts stall is followed by continuation, not left by a jump.
#[test]
fn a_branch_whose_warm_start_stalls_is_followed_not_left() {
    let arm = robots::arm7();
    // As the arm crate's guess: 8 restarts and samples, travel in seconds at 3 rad/s.
    let settings = IkSettings { restarts: 8, ..IkSettings::default() };
    let weights = [1.0 / 3.0; 7];
    for spacing in [3, 4] {
        let keyframes = crawling_pick_and_place(spacing);
        let targets = armature_ik::interpolate_targets(&keyframes[..1]).unwrap();
        let mut ws = armature_ik::IkWorkspace::new(&arm);
        let home = armature_ik::solve(&arm, &targets[0], &[0.0; 7], &settings, &mut ws).unwrap();
        let search = BranchSettings { samples: 8, ..BranchSettings::default() };
        let start = Start::Fixed(&home.q);
        let ik =
            ik_branch_search(&arm, &keyframes, start, &settings, &search, &weights, &mut |_, _| {
                0.0
            })
            .unwrap();
        assert!(ik.all_converged(), "{spacing} per segment");
        assert!(ik.max_joint_step < 1.0, "{spacing} per segment: {}", ik.max_joint_step);
        let (pe, oe) = keyframe_errors(&arm, &ik, &keyframes);
        assert!(pe < 1e-5 && oe < 1e-5, "{pe} {oe}");
    }
}

/// The seed tutorial's waypoints (home, pre-grasp, grasp, lift, pre-place, place), 3 node
/// intervals apart.
fn seed_pick_and_place() -> Vec<Keyframe> {
    from_home(
        3,
        &[
            [0.35, -0.25, 0.2],
            [0.35, -0.25, 0.05],
            [0.35, -0.25, 0.2],
            [0.35, 0.25, 0.2],
            [0.35, 0.25, 0.05],
        ],
    )
}

/// Σ over consecutive keyframes of their largest joint change: the least time the path's
/// segments need at unit velocity limits.
fn keyframe_travel(ik: &IkTrajectory, keyframes: &[Keyframe]) -> f64 {
    keyframes
        .windows(2)
        .map(|w| {
            let (a, b) = (&ik.q[w[0].node], &ik.q[w[1].node]);
            a.iter().zip(b).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max)
        })
        .sum()
}

#[test]
fn keyframe_segments_are_charged_their_own_travel_not_their_steps() {
    // On the seed, the steps' travel alone picks a place configuration that swings joint 2
    // by 1 rad beside joint 0's 1.1 rad (the largest change, which the steps' sum does not
    // see twice); charged from keyframe to keyframe, the search keeps joint 0's change at
    // 0.95 rad (the optimizer's walk from it ends 3.4 % faster).
    let arm = robots::arm7();
    let keyframes = seed_pick_and_place();
    let settings = IkSettings { restarts: 8, ..IkSettings::default() };
    let start = [0.09, -0.15, -0.12, 0.34, -0.1, -0.18, 0.12];
    let search = BranchSettings { samples: 8, ..BranchSettings::default() };
    let steps_only = BranchSettings { step_share: 1.0, ..search.clone() };
    let shared = least_travel(&arm, &keyframes, Start::Fixed(&start), &settings, &search);
    let steps = least_travel(&arm, &keyframes, Start::Fixed(&start), &settings, &steps_only);
    assert!(shared.all_converged() && steps.all_converged());
    let (a, b) = (keyframe_travel(&shared, &keyframes), keyframe_travel(&steps, &keyframes));
    assert!(a < b - 0.05, "keyframe travel {a} (default share) against {b} (steps only)");
    // No jump for it: the steps still carry a share of the cost.
    assert!(shared.max_joint_step < 1.0, "{}", shared.max_joint_step);
    // And the steps-only path is the one of least step travel.
    assert!(travel(&steps) <= travel(&shared) + 1e-12);
}

/// The error of the branch search on arm7's jumping pick-and-place with `search` and
/// `weights`, which must be refused.
fn refusal(search: &BranchSettings, weights: &[f64]) -> IkError {
    let seed = [0.0; 7];
    let keyframes = jumping_pick_and_place();
    let settings = IkSettings::default();
    let start = Start::Seed(&seed);
    ik_branch_search(&robots::arm7(), &keyframes, start, &settings, search, weights, &mut |_, _| {
        0.0
    })
    .unwrap_err()
}

#[test]
fn a_step_share_outside_the_unit_interval_is_refused() {
    for step_share in [-0.1, 1.5, f64::NAN] {
        let e = refusal(&BranchSettings { step_share, ..BranchSettings::default() }, &[1.0; 7]);
        assert!(matches!(&e, IkError::BadSeed(m) if m.contains("step_share")), "{e}");
    }
}

#[test]
fn a_fixed_start_is_kept_and_the_path_leaves_it_continuously() {
    let arm = robots::arm7();
    let mut keyframes = jumping_pick_and_place();
    keyframes.remove(0);
    let start = [0.0, -0.4, 0.0, 1.2, 0.0, 0.8, 0.0];
    let settings = IkSettings { restarts: 8, ..IkSettings::default() };
    let search = BranchSettings::default();
    let ik = least_travel(&arm, &keyframes, Start::Fixed(&start), &settings, &search);
    assert_eq!(ik.q[0], start.to_vec());
    assert!(ik.nodes[1..].iter().all(|r| r.converged));
    assert!(ik.max_joint_step < 1.5, "{}", ik.max_joint_step);
}

#[test]
fn the_node_cost_chooses_the_branch() {
    let ur5e = robots::ur5e();
    let keyframes = [
        Keyframe { node: 0, position: [0.4, -0.3, 0.3], quaternion_wxyz: None },
        Keyframe { node: 4, position: [0.4, 0.3, 0.2], quaternion_wxyz: None },
    ];
    let settings = IkSettings::default();
    let search = BranchSettings::default();
    for elbow_up in [true, false] {
        // Elbow (joint 3) of the wrong sign costs 100 per node.
        let mut cost = |_: usize, q: &[f64]| if (q[2] > 0.0) == elbow_up { 0.0 } else { 100.0 };
        let seed = [0.0; 6];
        let ik = ik_branch_search(
            &ur5e,
            &keyframes,
            Start::Seed(&seed),
            &settings,
            &search,
            &[1.0; 6],
            &mut cost,
        )
        .unwrap();
        assert!(ik.all_converged());
        assert!(ik.q.iter().all(|q| (q[2] > 0.0) == elbow_up), "elbow up {elbow_up}: {:?}", ik.q);
    }
}

#[test]
fn an_unreachable_node_between_keyframes_takes_the_interpolation_of_its_neighbours() {
    let ur5e = robots::ur5e();
    // Straight through the base: the middle node's target lies on the first joint's axis,
    // which the UR5e's shoulder offset keeps the tool from.
    let keyframes = [
        Keyframe { node: 0, position: [0.5, 0.0, 0.3], quaternion_wxyz: None },
        Keyframe { node: 2, position: [-0.5, 0.0, 0.3], quaternion_wxyz: None },
    ];
    let search = BranchSettings { samples: 32, ..BranchSettings::default() };
    let seed = [0.0; 6];
    let ik = least_travel(&ur5e, &keyframes, Start::Seed(&seed), &IkSettings::default(), &search);
    assert!(ik.nodes[0].converged && ik.nodes[2].converged);
    assert!(!ik.nodes[1].converged, "the middle node is unreachable: {:?}", ik.nodes[1]);
    for i in 0..6 {
        let mid = 0.5 * (ik.q[0][i] + ik.q[2][i]);
        assert!((ik.q[1][i] - mid).abs() < 1e-12, "joint {i}: {} vs {mid}", ik.q[1][i]);
    }
}

#[test]
fn weights_of_the_wrong_length_or_sign_are_refused() {
    for weights in [vec![1.0; 6], vec![-1.0; 7], vec![f64::NAN; 7]] {
        let e = refusal(&BranchSettings::default(), &weights);
        assert!(matches!(e, IkError::BadSeed(ref m) if m.contains("weights")), "{e}");
    }
}
