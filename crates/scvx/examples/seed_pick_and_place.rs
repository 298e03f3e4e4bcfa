//! The seed tutorial's 7-DOF pick-and-place through the scvx core — an exploratory driver
//! for issue #7, **not yet converging**: with the constant trust region the defects grow;
//! with `adaptive` the dynamics close (defects ~1e-8) but the waypoint buffers stall near
//! 3 cm when λ_tr reaches its cap. Iterations also cost ~30 ms here against the targets of
//! ≤ 1 ms discretization + ≤ 5 ms subproblem.
//!
//! Run: `cargo run --release -p armature-scvx --example seed_pick_and_place [iterations] [adaptive]`

use armature_ik::{IkSettings, Keyframe, Mode, ik_interpolation};
use armature_kinematics::robots;
use armature_scvx::{CtcsGroup, Dynamics, NodalConstraint, Ocp, Ptr, PtrSettings, ctcs_states};
use armature_symbolic::{Expr, Function};
use std::f64::consts::FRAC_1_SQRT_2;

fn main() {
    let arm = robots::arm7();
    let nodes = 11;
    let angle = Expr::variable("angle", 7);
    let velocity = Expr::variable("velocity", 7);
    let torque = Expr::variable("torque", 7);
    let inertia = [0.08, 0.06, 0.05, 0.04, 0.02, 0.01, 0.005];
    let i_inv = Expr::constant_vector(&inertia.map(|i| 1.0 / i));
    let fk = arm.symbolic_fk(&angle).unwrap();
    let p_ee = fk.ee_position();
    let r_ee = fk.ee_rotation();
    let (qlo, qhi) = arm.position_limits();
    let qmax = Expr::constant_vector(&qhi);
    let qmin = Expr::constant_vector(&qlo);
    let vmax = Expr::constant_vector(&[3.0; 7]);
    let down =
        armature_lie::SO3::from_quaternion_wxyz([FRAC_1_SQRT_2, 0.0, FRAC_1_SQRT_2, 0.0]).unwrap();
    let r_des_t = Expr::from_matrix(&down.matrix().transpose());
    let ori = r_des_t.matmul(&r_ee).so3_log().norm2();
    let groups = [
        CtcsGroup {
            constraints: vec![
                &angle - &qmax,
                &qmin - &angle,
                &velocity - &vmax,
                -&vmax - &velocity,
                -p_ee.at(2),
            ],
            first: 0,
            last: nodes - 1,
        },
        CtcsGroup { constraints: vec![&ori - 5f64.to_radians()], first: 2, last: 10 },
        CtcsGroup { constraints: vec![&ori - 0.1f64.to_radians()], first: 2, last: 6 },
        CtcsGroup { constraints: vec![&ori - 0.1f64.to_radians()], first: 8, last: 10 },
    ];
    let aug = ctcs_states(&groups);
    let mut states = vec![angle.clone(), velocity.clone()];
    let mut rhs = vec![velocity.clone(), &i_inv * &torque];
    for (y, f) in &aug {
        states.push(y.clone());
        rhs.push(f.clone());
    }
    let mut dynamics = Dynamics::new(&states, &[torque.clone()], &rhs, &[true; 7]).unwrap();
    for (i, g) in groups.iter().enumerate() {
        dynamics = dynamics.gate(14 + i, g.first, g.last).unwrap();
    }
    let n = 14 + groups.len();
    let q_down = [FRAC_1_SQRT_2, 0.0, FRAC_1_SQRT_2, 0.0];
    let wps: [([f64; 3], [f64; 4]); 6] = [
        ([0.69, 0.0, 0.34], [1.0, 0.0, 0.0, 0.0]),
        ([0.35, -0.25, 0.2], q_down),
        ([0.35, -0.25, 0.05], q_down),
        ([0.35, -0.25, 0.2], q_down),
        ([0.35, 0.25, 0.2], q_down),
        ([0.35, 0.25, 0.05], q_down),
    ];
    let mut nodal = Vec::new();
    for (w, (p, _)) in wps.iter().enumerate() {
        let g = (&p_ee - Expr::constant_vector(p)).norm2() - 0.01;
        let f = Function::compile(&[g], &[&states, &[torque.clone()]]).unwrap();
        nodal.push(NodalConstraint {
            name: format!("waypoint {w}"),
            function: f,
            nodes: vec![2 * w],
        });
    }
    let keyframes: Vec<Keyframe> = wps
        .iter()
        .enumerate()
        .map(|(w, (p, q))| Keyframe { node: 2 * w, position: *p, quaternion_wxyz: Some(*q) })
        .collect();
    let ik = ik_interpolation(
        &arm,
        &keyframes,
        &[0.0; 7],
        &IkSettings { restarts: 8, ..IkSettings::default() },
        Mode::Sequential,
    )
    .unwrap();
    let mut x = vec![0.0; nodes * n];
    for k in 0..nodes {
        x[k * n..k * n + 7].copy_from_slice(&ik.q[k]);
    }
    let mut x_min = qlo.clone();
    x_min.extend([-3.0; 7]);
    x_min.extend([0.0; 4]);
    let mut x_max = qhi.clone();
    x_max.extend([3.0; 7]);
    x_max.extend([1e3; 4]);
    let mut x_initial: Vec<Option<f64>> = ik.q[0].iter().map(|&v| Some(v)).collect();
    x_initial.extend([Some(0.0); 7]);
    x_initial.extend([Some(0.0); 4]);
    let mut x_final: Vec<Option<f64>> = vec![None; 7];
    x_final.extend([Some(0.0); 7]);
    x_final.extend([None; 4]);
    let tmax = [8.0, 8.0, 4.0, 4.0, 2.0, 1.0, 0.5];
    let increments = (0..4).map(|i| (14 + i, 1e-4, groups[i].first, groups[i].last)).collect();
    let ocp = Ocp {
        dynamics,
        nodes,
        x_min,
        x_max,
        u_min: tmax.iter().map(|t| -t).collect(),
        u_max: tmax.to_vec(),
        x_initial,
        x_final,
        s_min: 0.3,
        s_max: 4.0,
        time_weight: 1.0,
        increments,
        nodal,
    };
    let iters: usize = std::env::args().nth(1).and_then(|a| a.parse().ok()).unwrap_or(100);
    let adaptive = std::env::args().nth(2).as_deref() == Some("adaptive");
    let trust_region = if adaptive {
        armature_scvx::TrustRegionUpdate::Adaptive { eta: [0.0, 0.1, 0.7] }
    } else {
        armature_scvx::TrustRegionUpdate::Constant
    };
    let mut ptr = Ptr::new(
        ocp,
        PtrSettings { max_iterations: iters, trust_region, ..PtrSettings::default() },
    );
    let t0 = std::time::Instant::now();
    let r = ptr.solve(&x, &vec![0.0; nodes * 7], &vec![4.0; nodes]).unwrap();
    for h in &r.history {
        println!(
            "it {:3} J_tr {:.2e} J_vc {:.2e} defect {:.2e} viol {:.2e} tf {:.4} lam {:.1e}",
            h.iteration, h.j_tr, h.j_vc, h.max_defect, h.max_violation, h.final_time, h.lam_tr
        );
    }
    println!(
        "{:?} after {} iterations, T = {:.4} s, {:.1} ms",
        r.status,
        r.history.len(),
        r.final_time,
        t0.elapsed().as_secs_f64() * 1e3
    );
}
