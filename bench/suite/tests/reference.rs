//! The committed independent reference (`bench/reference/t_ref.json`, CasADi + IPOPT) holds up
//! under the suite's own verification: every stored trajectory with a final time passes it
//! (but three that graze the ball's margin between IPOPT's check points), the rigid-body ones
//! on their own parametrization (accelerations integrated exactly, torques from the suite's
//! RNEA), and a perturbed one does not.

use std::path::Path;

use armature_suite::generate::suite;
use armature_suite::reference::{self, ReferenceSolution};
use armature_suite::verify::TOLERANCE;

fn stored() -> reference::References {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").join(reference::STORED);
    reference::load(&path).unwrap()
}

#[test]
fn every_stored_reference_passes_the_suites_verification() {
    let refs = stored();
    let tasks = suite();
    let (mut verified, mut grazing, mut rigid) = (0, Vec::new(), 0);
    for (name, r) in &refs {
        let Some(t_ref) = r.final_time else { continue };
        let task = tasks.iter().find(|t| &t.name == name).unwrap_or_else(|| panic!("{name}"));
        assert!((r.times.last().unwrap() - t_ref).abs() < 1e-9, "{name}");
        let worst = reference::verify_reference(task, r);
        if worst.value <= TOLERANCE {
            verified += 1;
            rigid += usize::from(!r.accelerations.is_empty());
            continue;
        }
        // IPOPT holds the clearance at the nodes and the interval midpoints only: a few of
        // its trajectories graze the ball's 2 mm margin between them by a fraction of a
        // millimetre (the suite then uses no T_ref for the task). Nothing else may fail.
        assert!(
            worst.what.contains("against the ball") && worst.value < 1e-3,
            "{name}: {} ({})",
            worst.value,
            worst.what
        );
        grazing.push(name.clone());
    }
    assert!(verified >= 155, "only {verified} stored references");
    // Every rigid-body task has one, on its acceleration parametrization.
    assert_eq!(rigid, 20);
    assert!(grazing.len() <= 3, "{grazing:?}");
    // The seed's continuous-time optimum (the 1.043 s).
    let seed = refs["seed"].final_time.unwrap();
    assert!((seed - 1.043).abs() < 5e-3, "{seed}");
}

/// A rigid-body reference (accelerations, integrated exactly; torques from the suite's RNEA)
/// made faster, or with its accelerations off, fails.
#[test]
fn a_perturbed_rigid_body_reference_fails_verification() {
    let refs = stored();
    let tasks = suite();
    let name = "ur5e-rigid-body-00";
    let task = tasks.iter().find(|t| t.name == name).unwrap();
    let r = &refs[name];
    assert!(!r.accelerations.is_empty(), "{name} has no rigid-body reference");
    assert!(reference::verify_reference(task, r).value <= TOLERANCE);
    let mut fast = r.clone();
    fast.times.iter_mut().for_each(|t| *t *= 0.98);
    let worst = reference::verify_reference(task, &fast);
    assert!(worst.value > TOLERANCE && worst.what.contains("torque"), "{worst:?}");
    // The accelerations set the motion: a small change misses a waypoint or the rest.
    let mut off = r.clone();
    off.accelerations.iter_mut().for_each(|a| a[0] += 0.5);
    assert!(reference::verify_reference(task, &off).value > 1e-3);
    // Stored for a task without rigid-body dynamics, they are refused.
    let decoupled = tasks.iter().find(|t| t.name == "ur5e-urdf-00").unwrap();
    assert!(reference::verify_reference(decoupled, r).value.is_infinite());
}

#[test]
fn a_perturbed_reference_fails_verification() {
    let refs = stored();
    let tasks = suite();
    let seed = tasks.iter().find(|t| t.name == "seed").unwrap();
    let mut r: ReferenceSolution = refs["seed"].clone();
    // Time-optimal trajectories ride their limits: 2 % faster breaks one.
    r.times.iter_mut().for_each(|t| *t *= 0.98);
    let worst = reference::verify_reference(seed, &r);
    assert!(worst.value > TOLERANCE, "{}", worst.value);
    // And one that starts elsewhere is not the task's.
    let mut moved = refs["seed"].clone();
    moved.q0[0] += 0.01;
    assert!(reference::verify_reference(seed, &moved).value >= 0.01 - 1e-12);
}
