//! A downstream controller in its own process: waits for the final dense trajectory of a run,
//! samples q(t) at 1 kHz (cubic Hermite through the published positions and velocities, as
//! a joint-position controller would), and prints the sampling error against the published
//! samples.
//!
//! ```sh
//! cargo run --release -p armature-cli -- demo --stream demo &   # or start this first
//! cargo run --release -p armature-bridge --example controller -- demo --timeout 30
//! ```

use std::time::Duration;

use armature_bridge::{Block, BridgeSettings, Received, Status, TrajectorySubscriber};

/// Cubic Hermite interpolation of one joint on [t0, t1].
fn hermite(t: f64, (t0, q0, v0): (f64, f64, f64), (t1, q1, v1): (f64, f64, f64)) -> f64 {
    let h = t1 - t0;
    if h <= 0.0 {
        return q0;
    }
    let s = (t - t0) / h;
    let (s2, s3) = (s * s, s * s * s);
    (2.0 * s3 - 3.0 * s2 + 1.0) * q0
        + (s3 - 2.0 * s2 + s) * h * v0
        + (-2.0 * s3 + 3.0 * s2) * q1
        + (s3 - s2) * h * v1
}

/// q_j(t) from samples `idx` (sorted by time) of the trajectory.
fn sample(tr: &Received, idx: &[usize], j: usize, t: f64) -> f64 {
    let time = |k: usize| tr.block(k, Block::Time)[0];
    let point = |k: usize| {
        let v = tr.block(k, Block::Velocity);
        (time(k), tr.block(k, Block::Angle)[j], v.get(j).copied().unwrap_or(0.0))
    };
    let pos = idx.partition_point(|&k| time(k) <= t).clamp(1, idx.len() - 1);
    hermite(t, point(idx[pos - 1]), point(idx[pos]))
}

fn main() {
    let mut args = std::env::args().skip(1);
    let run = args.next().unwrap_or_else(|| {
        eprintln!("usage: controller RUN [--timeout SECONDS]");
        std::process::exit(2);
    });
    let timeout = match (args.next().as_deref(), args.next()) {
        (Some("--timeout"), Some(s)) => s.parse().unwrap_or(30.0),
        _ => 30.0,
    };
    let sub = TrajectorySubscriber::new(&run, &BridgeSettings::default()).unwrap_or_else(|e| {
        eprintln!("error: {e}");
        std::process::exit(2);
    });
    let deadline = std::time::Instant::now() + Duration::from_secs_f64(timeout);
    let tr = loop {
        let left = deadline.saturating_duration_since(std::time::Instant::now());
        match sub.receive_timeout(left) {
            Ok(Some(t))
                if t.header().dense == 1 && t.header().status() != Some(Status::Running) =>
            {
                break t;
            }
            Ok(Some(t)) => println!(
                "skipping iteration {} ({} rows, not final)",
                t.header().iteration,
                t.rows()
            ),
            Ok(None) => {
                eprintln!("error: no final trajectory on run '{run}' within {timeout} s");
                std::process::exit(3);
            }
            Err(e) => {
                eprintln!("error: {e}");
                std::process::exit(2);
            }
        }
    };
    let h = *tr.header();
    let joints = h.width(Block::Angle);
    if tr.rows() < 3 || joints == 0 || h.width(Block::Time) != 1 {
        eprintln!("error: the trajectory has no time and angle blocks to sample");
        std::process::exit(2);
    }
    println!(
        "received sequence {} (iteration {}, {}): {} rows × {} joints, final time {:.4} s",
        h.sequence,
        h.iteration,
        h.status().map_or("unknown", Status::word),
        tr.rows(),
        joints,
        h.final_time
    );
    let all: Vec<usize> = (0..tr.rows()).collect();
    let t_end = tr.block(tr.rows() - 1, Block::Time)[0];
    let n = (t_end * 1000.0 + 1e-9).floor() as usize + 1;
    let mut command = vec![0.0; joints];
    for i in 0..n {
        let t = i as f64 * 1e-3;
        for (j, c) in command.iter_mut().enumerate() {
            *c = sample(&tr, &all, j, t);
        }
    }
    println!(
        "{n} samples at 1 kHz, last command {:?}",
        command.iter().map(|v| (v * 1e4).round() / 1e4).collect::<Vec<_>>()
    );
    // The interpolant at the published sample times reproduces them.
    let mut at_samples = 0.0f64;
    for k in 0..tr.rows() {
        let t = tr.block(k, Block::Time)[0];
        for j in 0..joints {
            at_samples =
                at_samples.max((sample(&tr, &all, j, t) - tr.block(k, Block::Angle)[j]).abs());
        }
    }
    // Leave-one-out: interpolating from every other sample, the error at the skipped ones
    // bounds the interpolation error between samples.
    let even: Vec<usize> = (0..tr.rows()).step_by(2).collect();
    let mut between = 0.0f64;
    for k in (1..tr.rows() - 1).step_by(2) {
        let t = tr.block(k, Block::Time)[0];
        for j in 0..joints {
            between = between.max((sample(&tr, &even, j, t) - tr.block(k, Block::Angle)[j]).abs());
        }
    }
    println!("max error at the published samples {at_samples:e}");
    println!("max interpolation error against the published samples {between:e}");
}
