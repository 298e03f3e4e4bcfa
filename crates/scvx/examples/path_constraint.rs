//! A path constraint: the minimum-time double integrator with a speed limit |v| ≤ 0.7 held
//! in continuous time, checked afterwards on the dense trajectory. As a CTCS integral alone
//! (`.ctcs()`) the limit holds at the nodes but the speed overshoots between them, and the
//! status says `violated_between_nodes`, naming the instant. Enforced also at each
//! segment's peak ([`BetweenNodes`]), it holds on the dense trajectory.
//!
//! `cargo run -p armature-scvx --example path_constraint`

use armature_scvx::{
    BetweenNodes, ConstraintRef, Control, Problem, PtrSettings, PtrStatus, Solution, State, Time,
};

const V_MAX: f64 = 0.7;
const NODES: usize = 11;

fn problem(peaks: bool) -> Problem {
    let p = State::new("p", 1).bounds(&[-10.0], &[10.0]).initial_value(&[0.0]).final_value(&[1.0]);
    let v = State::new("v", 1).bounds(&[-10.0], &[10.0]).initial_value(&[0.0]).final_value(&[0.0]);
    let a = Control::new("a", 1).bounds(&[-1.0], &[1.0]);
    let speed = v.expr().abs() - V_MAX;
    let between_nodes = if peaks {
        let g = &v.expr() * &v.expr() - V_MAX * V_MAX; // v² ≤ v_max², smooth at v = 0
        vec![BetweenNodes {
            name: "speed peaks".into(),
            g,
            first: 0,
            last: NODES - 1,
            activation: None,
            sampling: armature_scvx::Sampling::Peak,
        }]
    } else {
        vec![]
    };
    Problem {
        dynamics: vec![v.expr(), a.expr()],
        constraints: vec![speed.le(0.0).ctcs().named("speed limit").into()],
        between_nodes,
        states: vec![p, v],
        controls: vec![a],
        time: Time::Free { min: 0.0, max: 10.0, guess: 3.0, minimize: true },
        ..Problem::new(NODES)
    }
}

/// The speed-limit check on the dense trajectory, and the fastest dense sample.
fn report(label: &str, s: &Solution) -> f64 {
    let fastest = s.trajectory["v"].iter().map(|r| r[0].abs()).fold(0.0, f64::max);
    let dense = s
        .violations
        .iter()
        .find(|v| v.constraint == ConstraintRef::Dense { name: "speed limit".into() })
        .expect("every path constraint is checked on the dense trajectory");
    println!("{label}: {}, T = {:.4} s, fastest {fastest:.5}", s.status, s.final_time);
    if let Some(t) = dense.time.filter(|_| dense.value > 0.0) {
        println!("  {} exceeded by {:.2e} at t = {t:.3} s", dense.constraint, dense.value);
    }
    fastest
}

pub(crate) fn main() {
    let ctcs = problem(false).compile(PtrSettings::default()).unwrap().solve().unwrap();
    let fastest = report("CTCS only", &ctcs);
    assert_eq!(ctcs.status, PtrStatus::ViolatedBetweenNodes);
    assert!(fastest > V_MAX + 1e-4);
    let peaks = problem(true).compile(PtrSettings::default()).unwrap().solve().unwrap();
    let fastest = report("CTCS and peak rows", &peaks);
    assert_eq!(peaks.status, PtrStatus::Converged);
    assert!(fastest <= V_MAX + 1e-4);
}
