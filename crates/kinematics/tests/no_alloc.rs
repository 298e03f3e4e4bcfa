//! Numeric FK and its Jacobians allocate nothing per call (counting global allocator).

use armature_kinematics::robots;
use armature_testing::{Counting, allocations_during};
use nalgebra::{Matrix3xX, Matrix6xX, Vector3};

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn forward_and_jacobians_do_not_allocate() {
    for chain in [robots::arm7(), robots::ur5e()] {
        let n = chain.dof();
        let mut ws = chain.fk_workspace();
        let mut body = Matrix6xX::zeros(n);
        let mut pj = Matrix3xX::zeros(n);
        let mut q = vec![0.3; n];
        let count = allocations_during(|| {
            for k in 0..200 {
                q[k % n] += 0.01;
                chain.forward(&q, &mut ws).unwrap();
                ws.body_jacobian(&mut body).unwrap();
                let p = ws.keypoint_position(1);
                ws.point_jacobian(chain.keypoints()[1].after, &p, &mut pj).unwrap();
                std::hint::black_box(ws.point_on_link(2, &Vector3::new(0.1, 0.0, 0.0)));
            }
        });
        assert_eq!(count, 0, "{}", chain.name());
    }
    assert!(
        allocations_during(|| drop(std::hint::black_box(vec![0u8; 16]))) > 0,
        "the counter sees allocations"
    );
}

#[test]
fn dynamics_do_not_allocate() {
    let xml = include_str!("fixtures/dynamics/arm7.urdf");
    let chain = armature_kinematics::chain_from_urdf_str(xml, "base", "ee", None).unwrap();
    let model = armature_kinematics::RigidBodyModel::new(&chain, [0.0, 0.0, -9.81]).unwrap();
    let mut ws = model.workspace();
    let n = model.dof();
    let (mut q, qd, mut out) = (vec![0.3; n], vec![0.5; n], vec![0.0; n]);
    let mut m = nalgebra::DMatrix::zeros(n, n);
    let mut d = armature_kinematics::DynamicsPartials::new(n);
    let count = allocations_during(|| {
        for k in 0..100 {
            q[k % n] += 0.01;
            model.rnea(&mut ws, &q, &qd, &qd, &mut out).unwrap();
            model.crba(&mut ws, &q, &mut m).unwrap();
            model.aba(&mut ws, &q, &qd, &qd, &mut out).unwrap();
            model.nonlinear_effects(&mut ws, &q, &qd, &mut out).unwrap();
            model.rnea_derivatives(&mut ws, &q, &qd, &qd, &mut out, &mut d).unwrap();
            model.aba_derivatives(&mut ws, &q, &qd, &qd, &mut out, &mut d).unwrap();
        }
    });
    assert_eq!(count, 0);
}
