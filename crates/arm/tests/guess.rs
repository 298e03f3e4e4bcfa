//! The initial guess: the IK branch search keeps the links clear of an obstacle where another
//! branch allows it.

use armature_arm::{ArmTask, fixtures};

/// The smallest distance of any collision pair of `task` over the configurations `qs` (m;
/// negative: the pair overlaps).
fn closest(task: &ArmTask, qs: &[Vec<f64>]) -> f64 {
    let c = task.collision.as_ref().expect("a task with collision");
    let mut ws = c.model.workspace(&task.chain);
    let mut closest = f64::INFINITY;
    for q in qs {
        let pairs = c.model.evaluate(&task.chain, q, &mut ws, false).expect("valid angles");
        closest = pairs.iter().map(|p| p.distance).fold(closest, f64::min);
    }
    closest
}

#[test]
fn the_guess_goes_around_a_ball_its_links_would_pass_through() {
    // The seed without obstacles: its guess swings the arm through where the ball will be.
    let free = fixtures::pick_and_place();
    let free_guess = free.plan().expect("the seed plans").ik.q;
    let mut task = free.clone();
    fixtures::with_seed_ball(&mut task, [0.3, 0.4, 0.3], 0.06);
    let through = closest(&task, &free_guess);
    assert!(through < -0.01, "the obstacle-free guess overlaps the ball: {through}");
    // With the ball, the branch search charges the overlap and takes another branch.
    let guess = task.plan().expect("the task with the ball plans").ik.q;
    let clear = closest(&task, &guess);
    assert!(clear > 0.0, "the guess keeps every pair apart: {clear}");
}
