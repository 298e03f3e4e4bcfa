//! Re-solve after a parameter change: the actuator's gain is a parameter of the compiled
//! problem, so a new value needs no recompilation, and the last solution warm-starts the next
//! solve.
//!
//! `cargo run -p armature-scvx --example resolve_parameter`

use armature_scvx::{Control, Problem, PtrSettings, PtrStatus, State, Time};
use armature_symbolic::{Expr, Shape};

pub(crate) fn main() {
    let p = State::new("p", 1).initial_value(&[0.0]).final_value(&[1.0]);
    let v = State::new("v", 1).bounds(&[-10.0], &[10.0]).initial_value(&[0.0]).final_value(&[0.0]);
    let a = Control::new("a", 1).bounds(&[-1.0], &[1.0]);
    // v' = gain·a: the minimum time 0 → 1 at rest is 2/√gain.
    let gain = Expr::parameter("gain", Shape::Scalar, &[1.0]);
    let problem = Problem {
        dynamics: vec![v.expr(), &gain * &a.expr()],
        states: vec![p, v],
        controls: vec![a],
        time: Time::Free { min: 0.0, max: 10.0, guess: 3.0, minimize: true },
        ..Problem::new(21)
    };
    let mut compiled = problem.compile(PtrSettings::default()).unwrap();
    let first = compiled.solve().unwrap();
    println!("gain 1: T = {:.4} s in {} iterations", first.final_time, first.iterations);
    assert_eq!(first.status, PtrStatus::Converged);
    assert!((first.final_time - 2.0).abs() < 0.02);
    // A stronger actuator: the same compiled problem, warm-started from the last solution.
    compiled.set_parameter("gain", &[1.21]).unwrap();
    let last = compiled.last_result().unwrap();
    compiled.warm_start(&last).unwrap();
    let second = compiled.solve().unwrap();
    println!("gain 1.21: T = {:.4} s in {} iterations", second.final_time, second.iterations);
    assert_eq!(second.status, PtrStatus::Converged);
    assert!((second.final_time - 2.0 / 1.1).abs() < 0.02);
}
