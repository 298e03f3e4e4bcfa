//! Publish → receive latency of a trajectory, timed from `send` to the subscriber's view
//! (the payload is already in loaned shared memory; filling it is the producer's work):
//! the seed's dense trajectory (401 × 21 values) and a 1 MiB payload, which should cost the
//! same because nothing is copied.

use std::hint::black_box;
use std::time::{Duration, Instant};

use armature_bridge::{
    BridgeSettings, Status, TrajectoryMeta, TrajectoryPublisher, TrajectorySubscriber,
};
use criterion::{Criterion, criterion_group, criterion_main};

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("bridge");
    for (name, rows, width) in [("dense_401x21", 401usize, 21u32), ("payload_1MiB", 8192, 16)] {
        let run = format!("bench-{name}-{}", std::process::id());
        let settings = BridgeSettings::default();
        let mut publisher = TrajectoryPublisher::new(&run, &settings).unwrap();
        let subscriber = TrajectorySubscriber::new(&run, &settings).unwrap();
        let meta = TrajectoryMeta {
            iteration: 1,
            status: Status::Running,
            final_time: 1.0,
            dense: true,
            widths: [1, width - 1, 0, 0, 0, 0],
        };
        g.bench_function(name, |b| {
            b.iter_custom(|iters| {
                let mut total = Duration::ZERO;
                for i in 0..iters {
                    let mut loan = publisher.loan(&meta, rows).unwrap();
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
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
