//! Collision distances against brute force and an independent closed form, gradients
//! against finite differences, degenerate inputs, the symbolic node, pairs and scenes.

use armature_collision::geometry::{
    capsule_box, capsule_capsule, capsule_halfspace, capsule_sphere,
};
use armature_collision::{
    CollisionError, CollisionModel, Obstacle, ObstacleShape, PairOptions, scene_from_toml_str,
};
use armature_kinematics::robots;
use armature_lie::{SE3, SO3};
use armature_symbolic::{Expr, Function};
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

type V = Vector3<f64>;

fn random_q(rng: &mut Pcg64Mcg) -> Vec<f64> {
    let (lo, hi) = robots::arm7().position_limits();
    (0..7).map(|i| rng.random_range(lo[i]..=hi[i])).collect()
}

/// Independent segment–segment distance: minimise over s of the exact distance from
/// `a(s)` to segment B (point–segment in closed form), by golden-section search on the
/// convex function of s, refined to 1e-12.
fn reference_segment_distance(a0: &V, a1: &V, b0: &V, b1: &V) -> f64 {
    let point_seg = |p: &V| {
        let d = b1 - b0;
        let l2 = d.norm_squared();
        let t = if l2 > 0.0 { ((p - b0).dot(&d) / l2).clamp(0.0, 1.0) } else { 0.0 };
        (p - (b0 + d * t)).norm()
    };
    let f = |s: f64| point_seg(&(a0 + (a1 - a0) * s));
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    let g = (5f64.sqrt() - 1.0) / 2.0;
    for _ in 0..200 {
        let (m1, m2) = (hi - g * (hi - lo), lo + g * (hi - lo));
        if f(m1) < f(m2) {
            hi = m2;
        } else {
            lo = m1;
        }
    }
    f(0.5 * (lo + hi)).min(f(0.0)).min(f(1.0))
}

/// Closed-form segment–segment distance, by a different route than parry's clamped
/// parameters: the unconstrained minimiser of |a(s) − b(t)|² from its 2×2 normal equations if
/// it lies in [0, 1]², else the best of the four boundary point–segment distances (the
/// minimum of a convex quadratic over a square is interior or on an edge).
fn closed_form_segment_distance(a0: &V, a1: &V, b0: &V, b1: &V) -> f64 {
    let point_seg = |p: &V, q0: &V, q1: &V| {
        let d = q1 - q0;
        let l2 = d.norm_squared();
        let t = if l2 > 0.0 { ((p - q0).dot(&d) / l2).clamp(0.0, 1.0) } else { 0.0 };
        (p - (q0 + d * t)).norm()
    };
    let (u, v, w) = (a1 - a0, b1 - b0, a0 - b0);
    let (a, b, c, d, e) = (u.dot(&u), u.dot(&v), v.dot(&v), u.dot(&w), v.dot(&w));
    let det = a * c - b * b;
    if det > 1e-12 * a * c {
        let (s, t) = ((b * e - c * d) / det, (a * e - b * d) / det);
        if (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&t) {
            return (w + u * s - v * t).norm();
        }
    }
    point_seg(a0, b0, b1)
        .min(point_seg(a1, b0, b1))
        .min(point_seg(b0, a0, a1))
        .min(point_seg(b1, a0, a1))
}

fn sampled_segment_distance(a0: &V, a1: &V, b0: &V, b1: &V, n: usize) -> f64 {
    let mut best = f64::INFINITY;
    for i in 0..=n {
        let p = a0 + (a1 - a0) * (i as f64 / n as f64);
        for j in 0..=n {
            let q = b0 + (b1 - b0) * (j as f64 / n as f64);
            best = best.min((p - q).norm());
        }
    }
    best
}

#[test]
fn distances_match_brute_force_and_closed_form() {
    let arm = robots::arm7();
    let model = CollisionModel::seed_arm7(&arm).unwrap();
    let mut ws = model.workspace(&arm);
    let mut fk = arm.fk_workspace();
    let mut rng = Pcg64Mcg::seed_from_u64(1);
    for _ in 0..1500 {
        let q = random_q(&mut rng);
        let results = model.evaluate(&arm, &q, &mut ws, false).unwrap().to_vec();
        arm.forward(&q, &mut fk).unwrap();
        let kp: Vec<V> = (0..5).map(|k| fk.keypoint_position(k)).collect();
        for (r, pair) in results.iter().zip(model.pairs()) {
            let link = |name: &str| model.links().iter().find(|l| l.name == name).unwrap();
            let a = link(&pair.a);
            let (a0, a1) = (kp[a.start], kp[a.end]);
            // The sampled distance is off by at most half a sampling step along each segment.
            let (exact, sampled, step) = if let Some(b) =
                model.links().iter().find(|l| l.name == pair.b)
            {
                let (b0, b1) = (kp[b.start], kp[b.end]);
                let closed = closed_form_segment_distance(&a0, &a1, &b0, &b1) - a.radius - b.radius;
                assert!(
                    (r.distance - closed).abs() < 1e-9,
                    "{} vs closed form {closed}",
                    r.distance
                );
                (
                    reference_segment_distance(&a0, &a1, &b0, &b1) - a.radius - b.radius,
                    sampled_segment_distance(&a0, &a1, &b0, &b1, 200) - a.radius - b.radius,
                    ((a1 - a0).norm() + (b1 - b0).norm()) / 400.0,
                )
            } else {
                let c = V::new(0.35, 0.0, 0.25);
                let sampled = (0..=2000)
                    .map(|i| (a0 + (a1 - a0) * (i as f64 / 2000.0) - c).norm())
                    .fold(f64::INFINITY, f64::min);
                let d = reference_segment_distance(&a0, &a1, &c, &c);
                (d - a.radius - 0.06, sampled - a.radius - 0.06, (a1 - a0).norm() / 4000.0)
            };
            assert!(
                (r.distance - exact).abs() < 1e-9,
                "{}|{}: {} vs closed form {exact}",
                pair.a,
                pair.b,
                r.distance
            );
            assert!(
                r.distance <= sampled + 1e-12 && sampled - r.distance <= step + 1e-12,
                "{} vs sampled {sampled} (step {step})",
                r.distance
            );
            // Witness points: on the surfaces, `distance` apart along the normal.
            let gap = (V::from(r.point_a) - V::from(r.point_b)).norm();
            assert!((gap - r.distance.abs()).abs() < 1e-9);
        }
    }
}

#[test]
fn gradients_match_finite_differences_away_from_kinks() {
    let arm = robots::arm7();
    let model = CollisionModel::seed_arm7(&arm).unwrap();
    let mut ws = model.workspace(&arm);
    let mut wp = model.workspace(&arm);
    let mut rng = Pcg64Mcg::seed_from_u64(2);
    let (mut checked, mut skipped) = (0, 0);
    for _ in 0..300 {
        let q = random_q(&mut rng);
        let analytic = model.evaluate(&arm, &q, &mut ws, true).unwrap().to_vec();
        for i in 0..7 {
            let mut fd = |h: f64| {
                let (mut qp, mut qm) = (q.clone(), q.clone());
                qp[i] += h;
                qm[i] -= h;
                let p: Vec<f64> = model
                    .evaluate(&arm, &qp, &mut wp, false)
                    .unwrap()
                    .iter()
                    .map(|r| r.distance)
                    .collect();
                let m: Vec<f64> = model
                    .evaluate(&arm, &qm, &mut wp, false)
                    .unwrap()
                    .iter()
                    .map(|r| r.distance)
                    .collect();
                p.iter().zip(&m).map(|(a, b)| (a - b) / (2.0 * h)).collect::<Vec<f64>>()
            };
            let (f1, f2) = (fd(1e-6), fd(2e-6));
            for (k, r) in analytic.iter().enumerate() {
                // Where the two step sizes disagree the distance is not smooth here.
                if (f1[k] - f2[k]).abs() > 1e-6 {
                    skipped += 1;
                    continue;
                }
                checked += 1;
                assert!(
                    (r.gradient[i] - f1[k]).abs() < 1e-6,
                    "pair {k} joint {i}: {} vs FD {}",
                    r.gradient[i],
                    f1[k]
                );
            }
        }
    }
    assert!(checked > 10 * skipped, "checked {checked}, skipped {skipped}");
}

#[test]
fn obstacle_shapes_match_brute_force() {
    let mut rng = Pcg64Mcg::seed_from_u64(3);
    let pose = SE3::from_parts(SO3::exp(&V::new(0.3, -0.2, 0.5)), V::new(0.4, 0.1, 0.2));
    let half = V::new(0.1, 0.05, 0.2);
    let point_box = |p: &V| {
        let l = pose.inverse().act(p);
        let q = V::new(l.x.abs() - half.x, l.y.abs() - half.y, l.z.abs() - half.z);
        q.map(|x| x.max(0.0)).norm() + q.max().min(0.0)
    };
    for _ in 0..2000 {
        let a0 = V::new(
            rng.random_range(-0.3..0.9),
            rng.random_range(-0.5..0.5),
            rng.random_range(-0.3..0.7),
        );
        let a1 = a0
            + V::new(
                rng.random_range(-0.3..0.3),
                rng.random_range(-0.3..0.3),
                rng.random_range(-0.3..0.3),
            );
        let r = 0.03;
        let samples = |f: &dyn Fn(&V) -> f64| {
            (0..=2000)
                .map(|i| f(&(a0 + (a1 - a0) * (i as f64 / 2000.0))))
                .fold(f64::INFINITY, f64::min)
        };
        let b = capsule_box(&a0, &a1, r, &pose, &half);
        let sampled = samples(&point_box) - r;
        assert!((b.distance - sampled).abs() < 1e-3, "box {} vs {sampled}", b.distance);
        let n = V::new(0.0, 0.0, 1.0);
        let h = capsule_halfspace(&a0, &a1, r, &n, 0.05);
        assert!((h.distance - (samples(&|p: &V| p.z - 0.05) - r)).abs() < 1e-12);
        let (c0, c1) = (V::new(0.3, 0.0, 0.0), V::new(0.3, 0.2, 0.3));
        let cc = capsule_capsule(&a0, &a1, r, &c0, &c1, 0.02);
        assert!(
            (cc.distance - (reference_segment_distance(&a0, &a1, &c0, &c1) - r - 0.02)).abs()
                < 1e-9
        );
        let closed = closed_form_segment_distance(&a0, &a1, &c0, &c1) - r - 0.02;
        assert!((cc.distance - closed).abs() < 1e-9, "{} vs closed form {closed}", cc.distance);
    }
}

#[test]
fn degenerate_inputs_are_finite() {
    let z = V::zeros();
    let x = V::new(1.0, 0.0, 0.0);
    let y = V::new(0.0, 0.3, 0.0);
    let cases = [
        capsule_capsule(&z, &z, 0.1, &y, &y, 0.1), // two points
        capsule_capsule(&z, &x, 0.1, &y, &(x + y), 0.1), // parallel
        capsule_capsule(&z, &x, 0.1, &z, &x, 0.1), // coincident
        capsule_capsule(&z, &x, 0.1, &V::new(0.5, -1.0, 0.0), &V::new(0.5, 1.0, 0.0), 0.1), // crossing axes
        capsule_capsule(&z, &z, 0.1, &z, &z, 0.1), // same point
        capsule_sphere(&z, &x, 0.1, &V::new(0.5, 0.0, 0.0), 0.1), // centre on the axis
        capsule_sphere(&z, &z, 0.1, &z, 0.1),      // zero length, same centre
        capsule_halfspace(&z, &x, 0.1, &V::z(), 0.0), // lying on the table
        capsule_box(&z, &z, 0.1, &SE3::identity(), &V::new(0.1, 0.1, 0.1)), // zero length inside a box
    ];
    for (i, c) in cases.iter().enumerate() {
        let finite = c.distance.is_finite() && c.s.is_finite() && c.t.is_finite();
        let vecs = [c.point_a, c.point_b, c.normal];
        assert!(finite && vecs.iter().all(|v| v.iter().all(|x| x.is_finite())), "case {i}: {c:?}");
        assert!((c.normal.norm() - 1.0).abs() < 1e-9, "case {i}: unit normal");
    }
    assert!((cases[1].distance - 0.1).abs() < 1e-12, "parallel: 0.3 − 0.2");
    assert!((cases[2].distance + 0.2).abs() < 1e-12, "coincident: fully penetrating");
    assert!((cases[3].distance + 0.2).abs() < 1e-12, "crossing: −(r₁ + r₂)");
}

#[test]
fn symbolic_node_matches_numeric_and_finite_differences() {
    let arm = robots::arm7();
    let scene = r#"
        [[links]]
        start = "base"
        end = "shoulder"
        radius = 0.06
        [[links]]
        start = "shoulder"
        end = "elbow"
        radius = 0.05
        [[links]]
        start = "elbow"
        end = "wrist"
        radius = 0.04
        [[links]]
        start = "wrist"
        end = "ee"
        radius = 0.035
        [[obstacles]]
        name = "ball"
        sphere = { center = [0.35, 0.0, 0.25], radius = 0.06 }
        [[obstacles]]
        name = "table"
        halfspace = { normal = [0.0, 0.0, 1.0], offset = 0.0 }
        [[obstacles]]
        name = "crate"
        box = { center = [0.4, -0.3, 0.1], half_extents = [0.1, 0.1, 0.1] }
        [[obstacles]]
        name = "pole"
        capsule = { a = [-0.3, 0.3, 0.0], b = [-0.3, 0.3, 0.8], radius = 0.03 }
    "#;
    let model = scene_from_toml_str(scene, "scene.toml").unwrap().model(&arm).unwrap();
    assert_eq!(model.pairs().len(), 3 + 4 * 4);
    let angle = Expr::variable("angle", 7);
    let fk = arm.symbolic_fk(&angle).unwrap();
    let positions: Vec<Expr> = fk.positions.iter().map(|(_, p)| p.clone()).collect();
    let d: Vec<Expr> = model.symbolic_distances(&positions).into_iter().map(|(_, e)| e).collect();
    let f = Function::compile(&d, &[&[angle]]).unwrap();
    let mut fws = f.workspace();
    let mut ws = model.workspace(&arm);
    let mut v = vec![0.0; f.n_outputs()];
    let mut nz = vec![0.0; f.jacobian_pattern().nnz()];
    let mut rng = Pcg64Mcg::seed_from_u64(4);
    for _ in 0..100 {
        let q = random_q(&mut rng);
        f.eval(&q, &mut fws, &mut v, Some(&mut nz)).unwrap();
        let jac = f.jacobian_pattern().to_dense(&nz);
        let numeric = model.evaluate(&arm, &q, &mut ws, true).unwrap();
        for (k, r) in numeric.iter().enumerate() {
            assert!((v[k] - r.distance).abs() < 1e-12, "pair {k}");
            for i in 0..7 {
                assert!(
                    (jac[k * 7 + i] - r.gradient[i]).abs() < 1e-9,
                    "pair {k} joint {i}: {} vs {} (d = {}, {}|{})",
                    jac[k * 7 + i],
                    r.gradient[i],
                    r.distance,
                    model.pairs()[k].a,
                    model.pairs()[k].b
                );
            }
        }
    }
    // The base–shoulder capsule moves only with joint 1: its pairs with fixed obstacles
    // depend on joint 1 alone in the pattern.
    let bs_ball =
        model.pairs().iter().position(|p| p.a == "base-shoulder" && p.b == "ball").unwrap();
    for c in 1..7 {
        assert!(!f.jacobian_pattern().contains(bs_ball, c));
    }
}

#[test]
fn pair_selection_and_errors() {
    let arm = robots::arm7();
    let model = CollisionModel::seed_arm7(&arm).unwrap();
    let names: Vec<(String, String)> =
        model.pairs().iter().map(|p| (p.a.clone(), p.b.clone())).collect();
    assert_eq!(
        names[..3],
        [
            ("base-shoulder".to_string(), "elbow-wrist".to_string()),
            ("base-shoulder".into(), "wrist-ee".into()),
            ("shoulder-elbow".into(), "wrist-ee".into()),
        ]
    );
    let links = [("base", "shoulder", 0.06), ("shoulder", "elbow", 0.05), ("elbow", "wrist", 0.04)];
    let opts = PairOptions {
        self_collision: true,
        allowed: vec![("elbow-wrist".into(), "base-shoulder".into())],
        extra: vec![("shoulder-elbow".into(), "elbow-wrist".into())],
    };
    let m = CollisionModel::new(&arm, &links, vec![], &opts).unwrap();
    assert_eq!(m.pairs().len(), 1, "one allowed away, one adjacent pair added");
    assert_eq!(m.pairs()[0].a, "shoulder-elbow");
    let err = |links: &[(&str, &str, f64)], obs: Vec<Obstacle>| {
        CollisionModel::new(&arm, links, obs, &PairOptions::default()).unwrap_err().to_string()
    };
    assert_eq!(
        err(&[("base", "hand", 0.1)], vec![]),
        "unknown keypoint 'hand' (the robot's keypoints: base, shoulder, elbow, wrist, ee)"
    );
    assert!(err(&[("base", "shoulder", -0.1)], vec![]).contains("radius -0.1"));
    let sphere = |r| Obstacle {
        name: "s".into(),
        shape: ObstacleShape::Sphere { center: V::zeros(), radius: r },
    };
    assert!(err(&[], vec![sphere(f64::NAN)]).contains("obstacle 's'"));
    assert!(err(&[], vec![sphere(0.1), sphere(0.2)]).contains("duplicate name 's'"));
    let tilted = Obstacle {
        name: "t".into(),
        shape: ObstacleShape::HalfSpace { normal: V::new(0.0, 0.0, 2.0), offset: 0.0 },
    };
    assert!(err(&[], vec![tilted]).contains("unit vector"));
    let e = scene_from_toml_str(
        "[[links]]\nstart = \"base\"\nend = \"shoulder\"\nradius = \"big\"\n",
        "s.toml",
    )
    .unwrap_err();
    assert!(
        matches!(&e, CollisionError::File { location, .. } if location == "s.toml:4:10"),
        "{e}"
    );
    let two = scene_from_toml_str("[[obstacles]]\nname = \"x\"\n", "s.toml")
        .unwrap()
        .model(&arm)
        .unwrap_err();
    assert!(two.to_string().contains("exactly one of"));
    let mut ws = model.workspace(&arm);
    assert!(model.evaluate(&arm, &[0.0; 6], &mut ws, true).is_err());
}

#[test]
fn links_meeting_at_one_point_of_the_arm_are_adjacent_whatever_their_names() {
    // In this URDF the shoulder link's origin lies on the next joint's axis, where the upper
    // arm link starts: two keypoints, one point of the arm for every q.
    let xml = include_str!("../../cli/tests/fixtures/ur5e-like.urdf");
    let arm = armature_kinematics::chain_from_urdf_str(xml, "base_link", "tool0", None).unwrap();
    let links = [
        ("base_link", "shoulder_link", 0.06),
        ("upper_arm_link", "forearm_link", 0.05),
        ("forearm_link", "wrist_1_link", 0.04),
    ];
    let opts = PairOptions { self_collision: true, ..PairOptions::default() };
    let m = CollisionModel::new(&arm, &links, vec![], &opts).unwrap();
    let names: Vec<(&str, &str)> = m.pairs().iter().map(|p| (p.a.as_str(), p.b.as_str())).collect();
    assert_eq!(names, [("base_link-shoulder_link", "forearm_link-wrist_1_link")]);
    // The pair that is checked is apart at q = 0; the one skipped would always "collide".
    let mut ws = m.workspace(&arm);
    let r = m.evaluate(&arm, &[0.0; 6], &mut ws, false).unwrap();
    assert!(r.iter().all(|p| p.distance > 0.0), "{r:?}");
    // Points that coincide only at q = 0 are not adjacent: a keypoint at the elbow's place
    // but moved by the elbow joint's neighbour, whose axis misses it.
    let mut kps = arm.keypoints().to_vec();
    let elbow = kps.iter().find(|k| k.name == "forearm_link").unwrap().clone();
    kps.push(armature_kinematics::Keypoint {
        name: "ghost".into(),
        after: elbow.after + 1,
        ..elbow
    });
    kps.sort_by_key(|k| k.after);
    let ghosted =
        armature_kinematics::Chain::new("ghost", arm.joints().to_vec(), arm.home(), kps).unwrap();
    let links = [("upper_arm_link", "forearm_link", 0.05), ("ghost", "tool0", 0.04)];
    let m = CollisionModel::new(&ghosted, &links, vec![], &opts).unwrap();
    assert_eq!(m.pairs().len(), 1, "the ghost moves off the elbow: a pair to check");
}
