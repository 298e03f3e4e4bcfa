//! The step API with an observer: the solver-level [`Ptr`] started from a guess and stepped
//! one SCvx iteration at a time, reading the reference trajectory after each step — what a
//! streaming front end or a custom stopping rule does. `solve_with` does the same in a loop.
//!
//! `cargo run -p armature-scvx --example step_observer`

use armature_scvx::{Control, IterationTable, Problem, PtrSettings, PtrStatus, State, Time};

pub(crate) fn main() {
    let p = State::new("p", 1).initial_value(&[0.0]).final_value(&[1.0]);
    let v = State::new("v", 1).bounds(&[-10.0], &[10.0]).initial_value(&[0.0]).final_value(&[0.0]);
    let a = Control::new("a", 1).bounds(&[-1.0], &[1.0]);
    let problem = Problem {
        dynamics: vec![v.expr(), a.expr()],
        states: vec![p, v],
        controls: vec![a],
        time: Time::Free { min: 0.0, max: 10.0, guess: 3.0, minimize: true },
        ..Problem::new(21)
    };
    let mut compiled = problem.compile(PtrSettings::default()).unwrap();
    let (x, u, s) = compiled.guess();
    let (x, u, s) = (x.to_vec(), u.to_vec(), s.to_vec());
    let ptr = compiled.ptr();
    ptr.start(&x, &u, &s).unwrap();
    let mut out = std::io::stdout();
    IterationTable::header(&mut out).unwrap();
    let mut times = Vec::new();
    loop {
        let it = ptr.step().unwrap();
        IterationTable::row(&mut out, &it).unwrap();
        // The reference after this step (the accepted trajectory so far).
        let traj = ptr.trajectory().expect("a running solve has a reference");
        times.push(traj.final_time);
        if it.status.is_some() {
            break;
        }
    }
    let r = ptr.result().unwrap();
    assert_eq!(r.status, PtrStatus::Converged);
    assert_eq!(times.len(), r.history.len(), "one observation per iteration");
    assert!((times.last().unwrap() - r.final_time).abs() < 1e-12);
    // Once it ends, the solve takes no more steps.
    assert!(ptr.step().is_err());
}
