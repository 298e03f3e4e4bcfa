//! Specific behaviour beyond the generic suite: exactness at π through every construction
//! path, finiteness for any finite input, checked constructors and their messages,
//! conversions, quaternion canonicalisation and interpolation.

use std::f64::consts::{FRAC_PI_2, PI};

use armature_lie::{LieError, LieGroup, SE3, SO3};
use nalgebra::{
    Isometry3, Matrix3, Matrix4, Rotation3, Translation3, Unit, UnitQuaternion, Vector3, Vector6,
};
use proptest::prelude::*;

fn axes() -> Vec<Vector3<f64>> {
    vec![
        Vector3::x(),
        Vector3::y(),
        Vector3::z(),
        -Vector3::z(),
        Vector3::new(1.0, 2.0, -2.0) / 3.0,
        Vector3::new(-0.6, 0.0, 0.8),
        Vector3::new(1e-9, 1.0, 0.0).normalize(),
    ]
}

/// `log` is exact within 1e-12 rad of π, whether the rotation comes from `exp`, a quaternion
/// or a rotation matrix: the axis is right and |ω| is the angle (π itself at π).
#[test]
fn log_is_exact_near_and_at_pi() {
    for axis in axes() {
        for delta in [0.0, 1e-15, 1e-13, 1e-12, 1e-9, 1e-6] {
            let angle = PI - delta;
            let omega = axis * angle;
            let from_exp = SO3::exp(&omega);
            let from_matrix = SO3::from_matrix(&Rotation3::new(omega).into_inner()).unwrap();
            let from_quat = SO3::from(UnitQuaternion::from_scaled_axis(omega));
            for (how, r) in [("exp", from_exp), ("matrix", from_matrix), ("quaternion", from_quat)]
            {
                let l = r.log();
                let err_angle = (l.norm() - angle).abs();
                assert!(err_angle < 1e-14, "{how}: |ω| = {} for angle π − {delta}", l.norm());
                // The axis is ±axis (exactly π is two-valued), and the angle never exceeds π.
                let err_axis = (l.normalize() - axis).norm().min((l.normalize() + axis).norm());
                assert!(err_axis < 1e-7, "{how}: axis error {err_axis} at π − {delta}");
                assert!(l.norm() <= PI);
                if delta > 1e-12 {
                    // Away from the tie the sign is the original one.
                    assert!((l.normalize() - axis).norm() < 1e-3, "{how} flipped at π − {delta}");
                }
            }
        }
    }
    // At exactly π the angle is π to the last bit.
    assert_eq!(SO3::exp(&(Vector3::y() * PI)).log().norm(), PI);
    assert_eq!(SO3::exp(&(Vector3::y() * PI)).angle(), PI);
}

/// Beyond π, `log` wraps to the equivalent rotation vector of norm ≤ π.
#[test]
fn log_wraps_angles_beyond_pi() {
    let axis = Vector3::new(0.0, 0.6, 0.8);
    for angle in [PI + 1e-9, 1.5 * PI, 2.0 * PI - 1e-6, 2.0 * PI, 3.0 * PI + 0.5, 100.0] {
        let l = SO3::exp(&(axis * angle)).log();
        let wrapped = (angle + PI).rem_euclid(2.0 * PI) - PI;
        assert!((l - axis * wrapped).norm() < 1e-9 || (l + axis * wrapped).norm() < 1e-9);
    }
}

/// No NaN or infinity for any finite input, over magnitudes from 1e-300 to 1e6.
#[test]
fn finite_everywhere_for_finite_input() {
    let mags = [0.0, 1e-300, 1e-150, 1e-20, 1e-8, 1e-3, 0.2, 1.0, PI, 10.0, 1e3, 1e6];
    for axis in axes() {
        for &m in &mags {
            let w = axis * m;
            let xi = Vector6::new(m, -m, 0.5, w.x, w.y, w.z);
            let r = SO3::exp(&w);
            let t = SE3::exp(&xi);
            let finite3 = |v: &[f64]| v.iter().all(|x| x.is_finite());
            assert!(finite3(r.log().as_slice()) && finite3(r.matrix().as_slice()), "{m}");
            assert!(finite3(t.log().as_slice()) && finite3(t.matrix().as_slice()), "{m}");
            assert!(finite3(SO3::jr(&w).as_slice()) && finite3(SO3::jl(&w).as_slice()));
            assert!(finite3(SE3::jr(&xi).as_slice()) && finite3(SE3::jl(&xi).as_slice()));
            assert!(finite3(t.adjoint().as_slice()) && finite3(t.log_jacobian().as_slice()));
            for g in t.dlog_dmatrix() {
                assert!(finite3(g.as_slice()));
            }
            for g in SE3::dexp_dtangent_matrix(&xi) {
                assert!(finite3(g.as_slice()));
            }
            // jr⁻¹ is singular only at |ω| = 2πk; on the principal range it is finite.
            let l = r.log();
            let lxi = t.log();
            assert!(finite3(SO3::jr_inv(&l).as_slice()) && finite3(SE3::jl_inv(&lxi).as_slice()));
        }
    }
}

#[test]
fn from_matrix_rejects_non_rotations_and_says_by_how_much() {
    let reflection = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0));
    match SO3::from_matrix(&reflection) {
        Err(LieError::NotARotation { determinant, .. }) => assert_eq!(determinant, -1.0),
        other => panic!("{other:?}"),
    }
    let scaled = Matrix3::identity() * 1.01;
    let err = SO3::from_matrix(&scaled).unwrap_err();
    let msg = err.to_string();
    assert!(msg.contains("2.010e-2"), "{msg}");
    assert!(msg.contains("not a rotation"), "{msg}");
    // Within tolerance: accepted and renormalised to an exact rotation.
    let drift = Rotation3::new(Vector3::new(0.1, 0.2, 0.3)).into_inner() * (1.0 + 1e-8);
    let r = SO3::from_matrix(&drift).unwrap();
    assert!((r.matrix().transpose() * r.matrix() - Matrix3::identity()).amax() < 1e-15);
    assert!(SO3::from_matrix_with_tolerance(&drift, 1e-10).is_err());
    let mut nan = Matrix3::identity();
    nan[(1, 2)] = f64::NAN;
    assert!(matches!(SO3::from_matrix(&nan), Err(LieError::NonFinite { .. })));

    let mut m = SE3::exp(&Vector6::new(0.1, 0.2, 0.3, 0.4, 0.5, 0.6)).matrix();
    m[(3, 1)] = 0.5;
    match SE3::from_matrix(&m) {
        Err(LieError::NotRigidTransform { error, bottom_row, .. }) => {
            assert_eq!(error, 0.5);
            assert_eq!(bottom_row[1], 0.5);
        }
        other => panic!("{other:?}"),
    }
    let mut m = Matrix4::identity();
    m[(0, 0)] = 2.0;
    assert!(matches!(SE3::from_matrix(&m), Err(LieError::NotARotation { .. })));
    m[(0, 0)] = f64::INFINITY;
    assert!(matches!(SE3::from_matrix(&m), Err(LieError::NonFinite { .. })));
    assert!(SE3::try_from(Matrix4::identity()).is_ok());
    assert!(SO3::try_from(Matrix3::identity() * 2.0).is_err());
}

#[test]
fn quaternions_are_wxyz_and_canonical() {
    let r = SO3::rot_y(FRAC_PI_2);
    let [w, x, y, z] = r.quaternion_wxyz();
    let h = FRAC_PI_2.cos().sqrt().max((0.5f64).sqrt());
    assert!((w - h).abs() < 1e-15 && x == 0.0 && (y - h).abs() < 1e-15 && z == 0.0);
    // A 300° rotation is stored as the equivalent −60° one, with w ≥ 0.
    let r = SO3::exp(&(Vector3::z() * (300f64).to_radians()));
    assert!(r.quaternion_wxyz()[0] > 0.0);
    assert!((r.log() - Vector3::z() * (-60f64).to_radians()).norm() < 1e-14);
    // −q and q are the same rotation and the same SO3.
    let q = UnitQuaternion::from_scaled_axis(Vector3::new(0.3, -0.2, 0.1));
    assert_eq!(SO3::from(q), SO3::from(UnitQuaternion::new_unchecked(-q.into_inner())));
    assert!(SO3::from_quaternion_wxyz([-1.0, 0.0, 0.0, 0.0]).unwrap().quaternion_wxyz()[0] == 1.0);
    match SO3::from_quaternion_wxyz([1.0, 1.0, 0.0, 0.0]) {
        Err(LieError::NonUnitQuaternion { norm, .. }) => {
            assert!((norm - 2f64.sqrt()).abs() < 1e-15)
        }
        other => panic!("{other:?}"),
    }
    assert!(SO3::from_quaternion_wxyz([f64::NAN, 0.0, 0.0, 1.0]).is_err());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Composition keeps the quaternion canonical.
    #[test]
    fn compose_and_inverse_stay_canonical(
        a in prop::array::uniform3(-4.0f64..4.0), b in prop::array::uniform3(-4.0f64..4.0)
    ) {
        let (ra, rb) = (SO3::exp(&Vector3::from(a)), SO3::exp(&Vector3::from(b)));
        prop_assert!(ra.compose(&rb).quaternion_wxyz()[0] >= 0.0);
        prop_assert!(ra.inverse().quaternion_wxyz()[0] >= 0.0);
        prop_assert!((ra * rb).quaternion().norm() - 1.0 < 1e-15);
    }

    /// Conversions to and from nalgebra round-trip exactly (to round-off).
    #[test]
    fn nalgebra_conversions_round_trip(
        w in prop::array::uniform3(-3.0f64..3.0), t in prop::array::uniform3(-2.0f64..2.0),
        p in prop::array::uniform3(-1.0f64..1.0)
    ) {
        let xi = Vector6::new(t[0], t[1], t[2], w[0], w[1], w[2]);
        let g = SE3::exp(&xi);
        let iso: Isometry3<f64> = g.into();
        let p = Vector3::from(p);
        prop_assert!((iso.transform_point(&p.into()).coords - g.act(&p)).norm() < 1e-14);
        prop_assert!((SE3::from(iso).matrix() - g.matrix()).amax() < 1e-14);
        prop_assert!((iso.to_homogeneous() - Matrix4::from(g)).amax() < 1e-14);
        let rot: Rotation3<f64> = g.rotation().into();
        prop_assert!((SO3::from(rot).matrix() - g.rotation().matrix()).amax() < 1e-14);
        prop_assert!((rot.matrix() - g.rotation().matrix()).amax() < 1e-15);
        let uq: UnitQuaternion<f64> = g.rotation().into();
        prop_assert!((uq.to_rotation_matrix().into_inner() - rot.into_inner()).amax() < 1e-15);
        let back = SE3::from_matrix(&g.matrix()).unwrap();
        prop_assert!((back.matrix() - g.matrix()).amax() < 1e-14);
        // Our rotation matrix agrees with nalgebra's Rodrigues.
        let na = Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::from(w)), Vector3::from(w).norm());
        prop_assert!((na.into_inner() - SO3::exp(&Vector3::from(w)).matrix()).amax() < 1e-14);
    }

    /// Slerp: endpoints, constant angular speed along the shortest arc.
    #[test]
    fn slerp_is_constant_speed_geodesic(
        a in prop::array::uniform3(-3.0f64..3.0), b in prop::array::uniform3(-3.0f64..3.0),
        t in 0.0f64..1.0
    ) {
        let (ra, rb) = (SO3::exp(&Vector3::from(a)), SO3::exp(&Vector3::from(b)));
        let total = ra.inverse().compose(&rb).angle();
        prop_assert!((ra.slerp(&rb, 0.0).matrix() - ra.matrix()).amax() < 1e-14);
        prop_assert!((ra.slerp(&rb, 1.0).matrix() - rb.matrix()).amax() < 1e-12);
        let rt = ra.slerp(&rb, t);
        prop_assert!((ra.inverse().compose(&rt).angle() - t * total).abs() < 1e-10);
        prop_assert!((rt.inverse().compose(&rb).angle() - (1.0 - t) * total).abs() < 1e-10);
        prop_assert!(total <= PI + 1e-15);
    }
}

#[test]
fn se3_interpolate_moves_translation_linearly() {
    let a = SE3::from_parts(SO3::identity(), Vector3::new(0.64, 0.0, 0.34));
    let b = SE3::from_parts(SO3::rot_y(FRAC_PI_2), Vector3::new(0.35, -0.25, 0.2));
    for t in [0.0, 0.25, 0.5, 1.0] {
        let m = a.interpolate(&b, t);
        let expect = a.translation() * (1.0 - t) + b.translation() * t;
        assert!((m.translation() - expect).norm() < 1e-15);
        assert!((m.rotation().angle() - t * FRAC_PI_2).abs() < 1e-14);
    }
}

/// The product of exponentials of a revolute screw leaves its axis fixed and rotates the
/// rest about it — the kinematics crate builds on exactly this.
#[test]
fn revolute_screw_rotates_about_its_axis() {
    let point = Vector3::new(0.3, 0.0, 0.34);
    let omega = Vector3::y();
    let screw = Vector6::new(
        -omega.cross(&point).x,
        -omega.cross(&point).y,
        -omega.cross(&point).z,
        0.0,
        1.0,
        0.0,
    );
    for theta in [-2.0, -1e-9, 0.0, 0.7, PI] {
        let t = SE3::exp(&(screw * theta));
        let expected = Isometry3::from_parts(Translation3::from(point), UnitQuaternion::identity())
            * Isometry3::rotation(omega * theta)
            * Isometry3::translation(-point.x, -point.y, -point.z);
        assert!((t.matrix() - expected.to_homogeneous()).amax() < 1e-15, "θ = {theta}");
    }
}

#[test]
fn plus_minus_round_trip() {
    let x = SE3::exp(&Vector6::new(0.2, -0.1, 0.4, 1.0, -2.0, 0.5));
    let d = Vector6::new(0.01, 0.02, -0.03, 0.3, -0.1, 0.2);
    assert!((x.plus(&d).minus(&x) - d).norm() < 1e-14);
    assert!(<SE3 as LieGroup<6, 4>>::identity() == SE3::identity());
}
