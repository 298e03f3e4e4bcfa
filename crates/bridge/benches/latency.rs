//! Publish → receive latency of a trajectory: the seed's dense trajectory (401 × 21 values)
//! and a 1 MiB payload, which should cost the same because nothing is copied.
//!
//! - `in_process/*`: from `send` to the subscriber's view, one process (the payload is
//!   already in loaned shared memory; filling it is the producer's work).
//! - `two_process/*`: round trip to a second process (this binary re-run as an echo peer,
//!   busy-polling) that answers every trajectory with a progress message: an upper bound of
//!   the one-way latency across processes.

use std::hint::black_box;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use armature_bridge::{
    BridgeSettings, Progress, Status, TrajectoryMeta, TrajectoryPublisher, TrajectorySubscriber,
};
use criterion::{Criterion, criterion_group};

const CASES: [(&str, usize, u32); 2] = [("dense_401x21", 401, 21), ("payload_1MiB", 8192, 16)];

fn meta(width: u32) -> TrajectoryMeta {
    TrajectoryMeta {
        iteration: 1,
        status: Status::Running,
        final_time: 1.0,
        dense: true,
        widths: [1, width - 1, 0, 0, 0, 0],
    }
}

/// The echo peer: answers each trajectory on `<base>-ping` with a progress message on
/// `<base>-pong`, spinning, until killed.
fn echo(base: &str) {
    let settings = BridgeSettings::default();
    let sub = TrajectorySubscriber::new(&format!("{base}-ping"), &settings).unwrap();
    let mut publisher = TrajectoryPublisher::new(&format!("{base}-pong"), &settings).unwrap();
    println!("ready");
    loop {
        if let Some(t) = sub.try_receive().unwrap() {
            let iteration = t.header().sequence;
            drop(t);
            publisher.publish_progress(Progress { iteration, ..Progress::default() }).unwrap();
        }
    }
}

fn spawn_echo(base: &str) -> Child {
    use std::io::{BufRead, BufReader};
    let mut child = Command::new(std::env::current_exe().unwrap())
        .env("ARMATURE_ECHO", base)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    assert!(lines.next().unwrap().unwrap().contains("ready"));
    child
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("bridge");
    let settings = BridgeSettings::default();
    for (name, rows, width) in CASES {
        let run = format!("bench-{name}-{}", std::process::id());
        let mut publisher = TrajectoryPublisher::new(&run, &settings).unwrap();
        let subscriber = TrajectorySubscriber::new(&run, &settings).unwrap();
        g.bench_function(format!("in_process/{name}"), |b| {
            b.iter_custom(|iters| {
                let mut total = Duration::ZERO;
                for i in 0..iters {
                    let mut loan = publisher.loan(&meta(width), rows).unwrap();
                    loan.values_mut()[0] = i as f64;
                    let start = Instant::now();
                    loan.send().unwrap();
                    let t = subscriber.try_receive().unwrap().expect("delivered");
                    black_box(t.row(0)[0]);
                    total += start.elapsed();
                }
                total
            })
        });
    }
    for (name, rows, width) in CASES {
        let base = format!("bench-rt-{name}-{}", std::process::id());
        let pong = TrajectorySubscriber::new(&format!("{base}-pong"), &settings).unwrap();
        let mut publisher = TrajectoryPublisher::new(&format!("{base}-ping"), &settings).unwrap();
        let mut child = spawn_echo(&base);
        g.bench_function(format!("two_process_round_trip/{name}"), |b| {
            b.iter_custom(|iters| {
                let mut total = Duration::ZERO;
                for _ in 0..iters {
                    let loan = publisher.loan(&meta(width), rows).unwrap();
                    let seq = loan.header().sequence;
                    let start = Instant::now();
                    loan.send().unwrap();
                    loop {
                        if let Some(p) = pong.try_receive_progress().unwrap()
                            && p.iteration == seq
                        {
                            break;
                        }
                    }
                    total += start.elapsed();
                }
                total
            })
        });
        let _ = child.kill();
        let _ = child.wait();
    }
    g.finish();
}

criterion_group!(benches, bench);

fn main() {
    if let Ok(base) = std::env::var("ARMATURE_ECHO") {
        echo(&base);
        return;
    }
    benches();
    Criterion::default().configure_from_args().final_summary();
}
