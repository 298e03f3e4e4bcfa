//! Two processes: this test binary re-runs itself as the peer (`peer` below, which does
//! nothing unless `ARMATURE_PEER` names a role), so every case crosses a process boundary.
//!
//! - bytes published equal bytes received (trajectory and progress);
//! - a subscriber that starts late gets the latest trajectory;
//! - a publisher killed with SIGKILL and restarted under the same run name works;
//! - a killed subscriber does not block the publisher;
//! - an oversized payload and a message of another format version give their errors;
//! - the `controller` example samples a published trajectory at 1 kHz.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use armature_bridge::{
    Block, BridgeError, BridgeSettings, FORMAT_VERSION, Progress, Status, TrajectoryHeader,
    TrajectoryMeta, TrajectoryPublisher, TrajectorySubscriber,
};

const ROWS: usize = 401;
const WIDTHS: [u32; 6] = [1, 7, 7, 7, 3, 0];

/// The deterministic test trajectory: value of (row, column).
fn value(r: usize, c: usize) -> f64 {
    if c == 0 { r as f64 * 0.004 } else { ((r * 31 + c * 7) as f64 * 0.013).sin() }
}

fn meta(iteration: u64, status: Status) -> TrajectoryMeta {
    TrajectoryMeta { iteration, status, final_time: 1.6, dense: true, widths: WIDTHS }
}

fn run_name(tag: &str) -> String {
    format!("test-{tag}-{}", std::process::id())
}

/// Starts this binary as peer `role` for `run`; returns it once it printed `ready`.
fn spawn_peer(role: &str, run: &str, count: usize) -> Child {
    let mut child = Command::new(std::env::current_exe().unwrap())
        .args(["peer", "--exact", "--nocapture", "--test-threads=1"])
        .env("ARMATURE_PEER", role)
        .env("ARMATURE_RUN", run)
        .env("ARMATURE_COUNT", count.to_string())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    loop {
        match lines.next() {
            Some(Ok(l)) if l.trim_end().ends_with("ready") => break,
            Some(Ok(_)) => continue,
            other => panic!("peer {role} ended before it was ready: {other:?}"),
        }
    }
    // Keep draining its output so it never blocks on a full pipe.
    std::thread::spawn(move || for _ in lines {});
    child
}

/// The peer process: publishes `ARMATURE_COUNT` trajectories (and as many progress
/// messages), or subscribes, prints `ready`, then waits to be killed or for 30 s.
#[test]
fn peer() {
    let Ok(role) = std::env::var("ARMATURE_PEER") else { return };
    let run = std::env::var("ARMATURE_RUN").unwrap();
    let count: u64 = std::env::var("ARMATURE_COUNT").unwrap().parse().unwrap();
    let settings = BridgeSettings::default();
    match role.as_str() {
        "publisher" => {
            let mut p = TrajectoryPublisher::new(&run, &settings).unwrap();
            for i in 1..=count {
                let status = if i == count { Status::Converged } else { Status::Running };
                p.publish_with(&meta(i, status), ROWS, value).unwrap();
                let progress = Progress {
                    iteration: i,
                    cost: 1.5 + i as f64,
                    j_tr: 1e-3 / i as f64,
                    accepted: 1,
                    ..Progress::default()
                };
                p.publish_progress(progress).unwrap();
            }
            println!("ready");
            p.serve(Duration::from_secs(30)).unwrap();
        }
        "subscriber" => {
            let _s = TrajectorySubscriber::new(&run, &settings).unwrap();
            println!("ready");
            std::thread::sleep(Duration::from_secs(30));
        }
        other => panic!("unknown role {other}"),
    }
}

fn finish(mut child: Child) {
    let _ = child.kill();
    let _ = child.wait();
}

#[test]
fn bytes_published_equal_bytes_received() {
    let run = run_name("bytes");
    let settings = BridgeSettings::default();
    let sub = TrajectorySubscriber::new(&run, &settings).unwrap();
    let child = spawn_peer("publisher", &run, 1);
    let t = sub.receive_timeout(Duration::from_secs(10)).unwrap().expect("a trajectory");
    let h = *t.header();
    assert_eq!(h.format_version, FORMAT_VERSION);
    assert_eq!((h.samples, h.widths, h.sequence, h.iteration), (ROWS as u64, WIDTHS, 1, 1));
    assert_eq!(h.status(), Some(Status::Converged));
    assert_eq!(t.data().len(), ROWS * 25);
    for r in 0..ROWS {
        for c in 0..25 {
            assert_eq!(t.row(r)[c].to_bits(), value(r, c).to_bits(), "({r}, {c})");
        }
    }
    assert_eq!(t.block(10, Block::Velocity), &t.row(10)[8..15]);
    assert!(t.block(0, Block::Frames).is_empty());
    assert_eq!(h.columns().len(), 25);
    let p = sub.receive_progress_timeout(Duration::from_secs(10)).unwrap().expect("progress");
    assert_eq!((p.iteration, p.cost, p.run_id), (1, 2.5, h.run_id));
    finish(child);
}

#[test]
fn a_late_subscriber_gets_the_latest_trajectory() {
    let run = run_name("late");
    let child = spawn_peer("publisher", &run, 3);
    // Everything was published before this subscriber existed.
    let sub = TrajectorySubscriber::new(&run, &BridgeSettings::default()).unwrap();
    let t = sub.receive_timeout(Duration::from_secs(10)).unwrap().expect("history");
    assert_eq!(t.header().sequence, 3);
    assert_eq!(t.header().status(), Some(Status::Converged));
    assert!(sub.try_receive().unwrap().is_none(), "only the latest is kept");
    finish(child);
}

#[test]
fn a_publisher_killed_with_sigkill_can_be_restarted_under_the_same_name() {
    let run = run_name("restart");
    let first = spawn_peer("publisher", &run, 2);
    let first_pid = first.id();
    finish(first); // SIGKILL: its node and shared memory stay behind
    let second = spawn_peer("publisher", &run, 1);
    let sub = TrajectorySubscriber::new(&run, &BridgeSettings::default()).unwrap();
    let t = sub.receive_timeout(Duration::from_secs(10)).unwrap().expect("from the new publisher");
    assert_eq!(t.header().sequence, 1, "a fresh publisher numbers from 1");
    assert_ne!(t.header().run_id >> 32, u64::from(first_pid));
    finish(second);
}

#[test]
fn a_killed_subscriber_does_not_block_the_publisher() {
    let run = run_name("deadsub");
    let settings = BridgeSettings::default();
    let child = spawn_peer("subscriber", &run, 0);
    finish(child);
    let mut p = TrajectoryPublisher::new(&run, &settings).unwrap();
    let start = std::time::Instant::now();
    for i in 1..=200 {
        p.publish_with(&meta(i, Status::Running), ROWS, value).unwrap();
    }
    assert!(start.elapsed() < Duration::from_secs(10), "publishing blocked: {:?}", start.elapsed());
    let sub = TrajectorySubscriber::new(&run, &settings).unwrap();
    p.update_connections().unwrap();
    let t = sub.receive_timeout(Duration::from_secs(5)).unwrap().expect("latest");
    assert_eq!(t.header().sequence, 200);
}

/// One publisher per run: a second one is refused (two solves on one run name would
/// interleave), typed and worded for people; so is a listener past the run's slots. The
/// run is free again once the first publisher is gone.
#[test]
fn a_second_publisher_and_a_listener_past_the_slots_are_typed_errors() {
    let run = run_name("busy");
    let settings = BridgeSettings::default();
    let p = TrajectoryPublisher::new(&run, &settings).unwrap();
    let err = TrajectoryPublisher::new(&run, &settings).unwrap_err();
    assert!(matches!(&err, BridgeError::RunBusy { run: r } if *r == run), "{err:?}");
    assert!(err.to_string().contains("already being streamed"), "{err}");
    let subs: Vec<_> = (0..settings.max_subscribers)
        .map(|_| TrajectorySubscriber::new(&run, &settings).unwrap())
        .collect();
    let err = TrajectorySubscriber::new(&run, &settings).unwrap_err();
    assert!(matches!(err, BridgeError::TooManyListeners { max: 4, .. }), "{err:?}");
    assert!(err.to_string().contains("4 listeners"), "{err}");
    drop((p, subs));
    assert!(TrajectoryPublisher::new(&run, &settings).is_ok());
}

#[test]
fn oversized_payloads_and_bad_names_are_errors_with_sizes() {
    let run = run_name("big");
    let settings = BridgeSettings { max_values: 1000, ..BridgeSettings::default() };
    let mut p = TrajectoryPublisher::new(&run, &settings).unwrap();
    let err = p.publish_with(&meta(1, Status::Running), ROWS, value).unwrap_err();
    assert!(matches!(
        err,
        BridgeError::PayloadTooLarge { rows: 401, width: 25, values: 10025, max: 1000 }
    ));
    assert!(err.to_string().contains("10025") && err.to_string().contains("1000"));
    assert!(p.publish(&meta(1, Status::Running), &[1.0, 2.0]).is_err(), "not whole rows");
    for bad in ["", "a/b", "has space", &"x".repeat(65)] {
        assert!(
            matches!(TrajectoryPublisher::new(bad, &settings), Err(BridgeError::BadRunName(_))),
            "{bad:?}"
        );
    }
}

#[test]
fn a_message_of_another_format_version_is_refused() {
    use iceoryx2::prelude::*;
    let run = run_name("version");
    let settings = BridgeSettings::default();
    let sub = TrajectorySubscriber::new(&run, &settings).unwrap();
    // A publisher of a future format, speaking raw iceoryx2 on the same service.
    let node = NodeBuilder::new().create::<ipc::Service>().unwrap();
    let name: ServiceName = format!("armature/{run}/trajectory").as_str().try_into().unwrap();
    let svc = node
        .service_builder(&name)
        .publish_subscribe::<[f64]>()
        .user_header::<TrajectoryHeader>()
        .open()
        .unwrap();
    let publisher = svc.publisher_builder().initial_max_slice_len(4).create().unwrap();
    let mut s = publisher.loan_slice_uninit(1).unwrap();
    *s.user_header_mut() = TrajectoryHeader {
        format_version: FORMAT_VERSION + 1,
        samples: 1,
        widths: [1, 0, 0, 0, 0, 0],
        ..TrajectoryHeader::default()
    };
    s.write_from_fn(|_| 0.0).send().unwrap();
    let err = sub.receive_timeout(Duration::from_secs(5)).unwrap_err();
    assert!(
        matches!(err, BridgeError::VersionMismatch { expected: FORMAT_VERSION, got } if got == FORMAT_VERSION + 1)
    );
    assert!(err.to_string().contains("format version"));
}

#[test]
fn the_controller_example_samples_a_published_trajectory_at_1khz() {
    let run = run_name("controller");
    // `cargo test` builds the package's examples next to the test binaries.
    let exe = std::env::current_exe().unwrap();
    let example = exe.parent().unwrap().parent().unwrap().join("examples").join("controller");
    assert!(example.exists(), "{} (built by cargo test)", example.display());
    let child = Command::new(&example)
        .args([run.as_str(), "--timeout", "20"])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    // A smooth dense trajectory: q_j(t) = sin(t + j), q̇_j = cos(t + j), 2 s at 10 ms.
    let settings = BridgeSettings::default();
    let mut p = TrajectoryPublisher::new(&run, &settings).unwrap();
    let widths = [1, 7, 7, 7, 3, 0];
    let f = |r: usize, c: usize| {
        let t = r as f64 * 0.01;
        match c {
            0 => t,
            1..=7 => (t + (c - 1) as f64).sin(),
            8..=14 => (t + (c - 8) as f64).cos(),
            _ => 0.0,
        }
    };
    // The intermediate (nodal) message is skipped by the controller; the final dense one is used.
    let nodal = TrajectoryMeta {
        iteration: 1,
        status: Status::Running,
        final_time: 2.0,
        dense: false,
        widths,
    };
    std::thread::sleep(Duration::from_millis(300));
    p.publish_with(&nodal, 11, f).unwrap();
    let dense = TrajectoryMeta {
        iteration: 9,
        status: Status::Converged,
        final_time: 2.0,
        dense: true,
        widths,
    };
    p.publish_with(&dense, 201, f).unwrap();
    let out = child.wait_with_output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    assert!(text.contains("2001 samples at 1 kHz"), "{text}");
    // Cubic Hermite through positions and velocities: exact at the published samples, and
    // within 1e-6 of the true sine between them.
    let err_at = |key: &str| -> f64 {
        let line =
            text.lines().find(|l| l.starts_with(key)).unwrap_or_else(|| panic!("{key} in {text}"));
        line.rsplit(' ').next().unwrap().parse().unwrap()
    };
    assert!(err_at("max error at the published samples") < 1e-12, "{text}");
    assert!(err_at("max interpolation error against the published samples") < 1e-6, "{text}");
}
