//! Minimum time: a double integrator from rest at 0 to rest at 1 with |a| ≤ 1, the final
//! time free and minimized. The optimum is bang–bang, 2 s.
//!
//! `cargo run -p armature-scvx --example minimum_time`

use armature_scvx::{Control, Problem, PtrSettings, PtrStatus, State, Time};

pub(crate) fn main() {
    let p = State::new("p", 1).initial_value(&[0.0]).final_value(&[1.0]);
    let v = State::new("v", 1).bounds(&[-10.0], &[10.0]).initial_value(&[0.0]).final_value(&[0.0]);
    let a = Control::new("a", 1).bounds(&[-1.0], &[1.0]);
    let problem = Problem {
        dynamics: vec![v.expr(), a.expr()], // p' = v, v' = a
        states: vec![p, v],
        controls: vec![a],
        time: Time::Free { min: 0.0, max: 10.0, guess: 3.0, minimize: true },
        ..Problem::new(21)
    };
    let solution = problem.compile(PtrSettings::default()).unwrap().solve().unwrap();
    println!(
        "{}: T = {:.4} s after {} iterations",
        solution.status, solution.final_time, solution.iterations
    );
    assert_eq!(solution.status, PtrStatus::Converged);
    assert!((solution.final_time - 2.0).abs() < 0.02, "bang–bang takes 2 s");
}
