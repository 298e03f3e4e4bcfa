//! Publisher and subscriber of trajectories and progress over iceoryx2.

use std::time::{Duration, Instant};

use iceoryx2::node::NodeState;
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::{Publisher, PublisherCreateError};
use iceoryx2::port::subscriber::{Subscriber, SubscriberCreateError};
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::prelude::*;
use iceoryx2::sample::Sample;

use crate::wire::{Block, FORMAT_VERSION, Progress, Status, TrajectoryHeader};

/// Buffer sizes of the services. Publishers and subscribers of one run must use the same.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BridgeSettings {
    /// Largest trajectory payload, in `f64` values (rows × row width). Shared memory is
    /// reserved for it per sample slot. Default 131 072 (1 MiB).
    pub max_values: usize,
    /// Trajectories kept for subscribers that connect late. Default 1 (the latest).
    pub history: usize,
    /// Messages a subscriber buffers before the oldest is overwritten (a subscriber that
    /// falls further behind loses the oldest: the publisher never blocks). Default 16.
    pub subscriber_buffer: usize,
    /// Subscribers per service. Default 4.
    pub max_subscribers: usize,
}

impl Default for BridgeSettings {
    fn default() -> Self {
        BridgeSettings {
            max_values: 1 << 17,
            history: 1,
            subscriber_buffer: 16,
            max_subscribers: 4,
        }
    }
}

/// Errors of the bridge.
#[derive(Debug, thiserror::Error)]
pub enum BridgeError {
    /// A run name that cannot be part of a service name.
    #[error("run name '{0}': use 1–64 letters, digits, '-', '_' or '.'")]
    BadRunName(String),
    /// A trajectory larger than the configured maximum.
    #[error(
        "trajectory of {rows} rows × {width} values = {values} values exceeds the configured maximum of {max} values (BridgeSettings::max_values)"
    )]
    PayloadTooLarge {
        /// Rows.
        rows: usize,
        /// Values per row.
        width: usize,
        /// rows × width.
        values: usize,
        /// The maximum.
        max: usize,
    },
    /// Data that does not match its description.
    #[error("{0}")]
    BadData(String),
    /// A message of another wire format.
    #[error(
        "message of format version {got}; this subscriber reads version {expected} (update the older side)"
    )]
    VersionMismatch {
        /// This side's [`FORMAT_VERSION`].
        expected: u32,
        /// The message's.
        got: u32,
    },
    /// Another process already publishes on this run: one publisher per run, so that a
    /// listener never sees two solves interleaved.
    #[error(
        "run '{run}' is already being streamed by another process; give this solve another run name"
    )]
    RunBusy {
        /// The run name.
        run: String,
    },
    /// The run already serves as many listeners as it can.
    #[error(
        "run '{run}' already has {max} listeners, the most a run serves (BridgeSettings::max_subscribers)"
    )]
    TooManyListeners {
        /// The run name.
        run: String,
        /// The limit.
        max: usize,
    },
    /// iceoryx2's shared state (under `/tmp/iceoryx2/`) belongs to another user.
    #[error(
        "{what}: no permission on iceoryx2's shared state in /tmp/iceoryx2/ (another user created it; see the bridge's README, \"Users, permissions and where the state lives\")"
    )]
    PermissionDenied {
        /// What was being done.
        what: &'static str,
    },
    /// An iceoryx2 failure, with what was being done.
    #[error("{what}: {detail}")]
    Ipc {
        /// What was being done.
        what: &'static str,
        /// iceoryx2's error.
        detail: String,
    },
}

/// An iceoryx2 error as ours: a permission failure typed (every iceoryx2 error type names
/// it `InsufficientPermissions`), the rest with iceoryx2's own words.
fn ipc(what: &'static str) -> impl Fn(&dyn std::fmt::Debug) -> BridgeError {
    move |e| {
        let detail = format!("{e:?}");
        if detail.contains("InsufficientPermissions") {
            BridgeError::PermissionDenied { what }
        } else {
            BridgeError::Ipc { what, detail }
        }
    }
}

/// A publisher's creation error: the run's one publisher slot taken is [`BridgeError::RunBusy`].
fn publisher_error(run: &str, what: &'static str) -> impl Fn(PublisherCreateError) -> BridgeError {
    move |e| match e {
        PublisherCreateError::ExceedsMaxSupportedPublishers => {
            BridgeError::RunBusy { run: run.to_string() }
        }
        e => ipc(what)(&e),
    }
}

/// A subscriber's creation error: the run's listener slots full is
/// [`BridgeError::TooManyListeners`].
fn subscriber_error(
    run: &str,
    settings: &BridgeSettings,
    what: &'static str,
) -> impl Fn(SubscriberCreateError) -> BridgeError {
    let max = settings.max_subscribers;
    move |e| match e {
        SubscriberCreateError::ExceedsMaxSupportedSubscribers => {
            BridgeError::TooManyListeners { run: run.to_string(), max }
        }
        e => ipc(what)(&e),
    }
}

/// Service names of run `run`: `armature/<run>/trajectory`, `armature/<run>/progress`.
///
/// # Errors
/// [`BridgeError::BadRunName`].
pub fn service_names(run: &str) -> Result<[String; 2], BridgeError> {
    let ok = !run.is_empty()
        && run.len() <= 64
        && run.chars().all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c));
    if !ok {
        return Err(BridgeError::BadRunName(run.to_string()));
    }
    Ok([format!("armature/{run}/trajectory"), format!("armature/{run}/progress")])
}

/// Removes the resources of dead nodes (processes killed without cleaning up); returns how
/// many were removed. Publishers and subscribers call it when they are created.
///
/// # Errors
/// Listing the nodes failed.
pub fn cleanup_dead_nodes() -> Result<usize, BridgeError> {
    let mut removed = 0;
    Node::<ipc::Service>::list(Config::global_config(), |state| {
        if let NodeState::Dead(view) = state
            && view.try_remove_stale_resources().is_ok()
        {
            removed += 1;
        }
        CallbackProgression::Continue
    })
    .map_err(|e| ipc("listing nodes")(&e))?;
    Ok(removed)
}

fn node(name: &str) -> Result<Node<ipc::Service>, BridgeError> {
    set_log_level_from_env_or(LogLevel::Error);
    cleanup_dead_nodes()?;
    let name: NodeName = name.try_into().map_err(|e| ipc("node name")(&e))?;
    NodeBuilder::new()
        .name(&name)
        // Ctrl-C keeps its usual meaning in the processes that use the bridge.
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .map_err(|e| ipc("creating the node")(&e))
}

type TrajectoryService = iceoryx2::service::port_factory::publish_subscribe::PortFactory<
    ipc::Service,
    [f64],
    TrajectoryHeader,
>;
type ProgressService =
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, Progress, ()>;
type EventService = iceoryx2::service::port_factory::event::PortFactory<ipc::Service>;

/// The four services of a run (data and wake-up events), opened or created.
struct Services {
    trajectory: TrajectoryService,
    progress: ProgressService,
    trajectory_event: EventService,
    progress_event: EventService,
}

fn services(
    node: &Node<ipc::Service>,
    run: &str,
    s: &BridgeSettings,
) -> Result<Services, BridgeError> {
    let [traj, prog] = service_names(run)?;
    let name = |n: &str| -> Result<ServiceName, BridgeError> {
        n.try_into().map_err(|e| ipc("service name")(&e))
    };
    let trajectory = node
        .service_builder(&name(&traj)?)
        .publish_subscribe::<[f64]>()
        .user_header::<TrajectoryHeader>()
        .history_size(s.history)
        .subscriber_max_buffer_size(s.subscriber_buffer)
        .max_subscribers(s.max_subscribers)
        .max_publishers(1)
        .enable_safe_overflow(true)
        .open_or_create()
        .map_err(|e| ipc("opening the trajectory service")(&e))?;
    let progress = node
        .service_builder(&name(&prog)?)
        .publish_subscribe::<Progress>()
        .history_size(s.history)
        .subscriber_max_buffer_size(s.subscriber_buffer.max(64))
        .max_subscribers(s.max_subscribers)
        .max_publishers(1)
        .enable_safe_overflow(true)
        .open_or_create()
        .map_err(|e| ipc("opening the progress service")(&e))?;
    let event = |n: String| {
        node.service_builder(&name(&n)?)
            .event()
            .open_or_create()
            .map_err(|e| ipc("opening an event service")(&e))
    };
    Ok(Services {
        trajectory,
        progress,
        trajectory_event: event(format!("{traj}/event"))?,
        progress_event: event(format!("{prog}/event"))?,
    })
}

/// What a trajectory message says about itself (the rest of the header is derived).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrajectoryMeta {
    /// SCvx iteration.
    pub iteration: u64,
    /// The solve's state.
    pub status: Status,
    /// Final time (s).
    pub final_time: f64,
    /// A dense trajectory (true) or the nodes of an iterate (false).
    pub dense: bool,
    /// Width of each [`Block`] in [`Block::ALL`] order.
    pub widths: [u32; 6],
}

/// Publishes a run's trajectories and progress.
pub struct TrajectoryPublisher {
    trajectory: Publisher<ipc::Service, [f64], TrajectoryHeader>,
    progress: Publisher<ipc::Service, Progress, ()>,
    trajectory_event: Notifier<ipc::Service>,
    progress_event: Notifier<ipc::Service>,
    run_id: u64,
    sequence: u64,
    progress_sequence: u64,
    max_values: usize,
    // Dropped last: ports before their services and node.
    _services: Services,
    _node: Node<ipc::Service>,
}

impl std::fmt::Debug for TrajectoryPublisher {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TrajectoryPublisher")
            .field("run_id", &self.run_id)
            .field("sequence", &self.sequence)
            .finish_non_exhaustive()
    }
}

impl TrajectoryPublisher {
    /// A publisher for run `run` (services `armature/<run>/…`, created if absent). Resources
    /// left by dead processes are removed first.
    ///
    /// # Errors
    /// A bad run name; iceoryx2 failures (e.g. services of the same run with other settings).
    pub fn new(run: &str, settings: &BridgeSettings) -> Result<Self, BridgeError> {
        let node = node("armature-publisher")?;
        let s = services(&node, run, settings)?;
        let trajectory = s
            .trajectory
            .publisher_builder()
            .initial_max_slice_len(settings.max_values)
            .allocation_strategy(AllocationStrategy::Static)
            .max_loaned_samples(2)
            .create()
            .map_err(publisher_error(run, "creating the trajectory publisher"))?;
        let progress = s
            .progress
            .publisher_builder()
            .create()
            .map_err(publisher_error(run, "creating the progress publisher"))?;
        let trajectory_event = s
            .trajectory_event
            .notifier_builder()
            .create()
            .map_err(|e| ipc("creating a notifier")(&e))?;
        let progress_event = s
            .progress_event
            .notifier_builder()
            .create()
            .map_err(|e| ipc("creating a notifier")(&e))?;
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as u64);
        Ok(TrajectoryPublisher {
            trajectory,
            progress,
            trajectory_event,
            progress_event,
            run_id: (u64::from(std::process::id()) << 32) ^ nanos,
            sequence: 0,
            progress_sequence: 0,
            max_values: settings.max_values,
            _services: s,
            _node: node,
        })
    }

    /// This run's id (in every header).
    pub fn run_id(&self) -> u64 {
        self.run_id
    }

    /// Connects subscribers that appeared since the last send and hands them the history
    /// (the latest trajectory). Sending does this implicitly; an idle publisher that should
    /// serve late subscribers calls it now and then — or uses [`serve`](Self::serve).
    ///
    /// # Errors
    /// iceoryx2 failures.
    pub fn update_connections(&self) -> Result<(), BridgeError> {
        self.trajectory.update_connections().map_err(|e| ipc("connecting subscribers")(&e))?;
        self.progress.update_connections().map_err(|e| ipc("connecting subscribers")(&e))?;
        // Wake the newcomers: their history is waiting.
        self.trajectory_event.notify().map_err(|e| ipc("waking subscribers")(&e))?;
        Ok(())
    }

    /// Keeps the published data available for `duration`, handing the latest trajectory to
    /// every subscriber that connects meanwhile (checks every 10 ms). The data lives in this
    /// process's shared memory: it is gone once the publisher is dropped.
    ///
    /// # Errors
    /// iceoryx2 failures.
    pub fn serve(&self, duration: Duration) -> Result<(), BridgeError> {
        let deadline = Instant::now() + duration;
        while Instant::now() < deadline {
            self.update_connections()?;
            std::thread::sleep(Duration::from_millis(10).min(deadline - Instant::now()));
        }
        Ok(())
    }

    /// Publishes a trajectory of `rows` rows, writing each value `value(row, column)` in
    /// place into the loaned shared memory (no intermediate buffer, no serialization), and
    /// wakes the subscribers. Returns the message's sequence number.
    ///
    /// # Errors
    /// [`BridgeError::PayloadTooLarge`] beyond [`BridgeSettings::max_values`]; iceoryx2
    /// failures.
    pub fn publish_with(
        &mut self,
        meta: &TrajectoryMeta,
        rows: usize,
        mut value: impl FnMut(usize, usize) -> f64,
    ) -> Result<u64, BridgeError> {
        let width: usize = meta.widths.iter().map(|&w| w as usize).sum();
        let values = rows * width;
        if values > self.max_values {
            return Err(BridgeError::PayloadTooLarge { rows, width, values, max: self.max_values });
        }
        let mut sample = self
            .trajectory
            .loan_slice_uninit(values)
            .map_err(|e| ipc("loaning shared memory")(&e))?;
        self.sequence += 1;
        *sample.user_header_mut() = self.header(meta, rows);
        let sample = sample.write_from_fn(|i| value(i / width.max(1), i % width.max(1)));
        sample.send().map_err(|e| ipc("sending a trajectory")(&e))?;
        self.trajectory_event.notify().map_err(|e| ipc("waking subscribers")(&e))?;
        Ok(self.sequence)
    }

    /// Loans shared memory for a trajectory of `rows` rows (values zeroed): fill it through
    /// [`TrajectoryLoan::values_mut`], then [`TrajectoryLoan::send`]. Nothing is copied on
    /// the way to the subscribers.
    ///
    /// # Errors
    /// As [`publish_with`](Self::publish_with).
    pub fn loan(
        &mut self,
        meta: &TrajectoryMeta,
        rows: usize,
    ) -> Result<TrajectoryLoan<'_>, BridgeError> {
        let width: usize = meta.widths.iter().map(|&w| w as usize).sum();
        let values = rows * width;
        if values > self.max_values {
            return Err(BridgeError::PayloadTooLarge { rows, width, values, max: self.max_values });
        }
        let mut sample = self
            .trajectory
            .loan_slice_uninit(values)
            .map_err(|e| ipc("loaning shared memory")(&e))?;
        self.sequence += 1;
        *sample.user_header_mut() = self.header(meta, rows);
        Ok(TrajectoryLoan {
            sample: sample.write_from_fn(|_| 0.0),
            notifier: &self.trajectory_event,
        })
    }

    fn header(&self, meta: &TrajectoryMeta, rows: usize) -> TrajectoryHeader {
        TrajectoryHeader {
            format_version: FORMAT_VERSION,
            status: meta.status.code(),
            run_id: self.run_id,
            sequence: self.sequence,
            iteration: meta.iteration,
            final_time: meta.final_time,
            samples: rows as u64,
            dense: u32::from(meta.dense),
            widths: meta.widths,
            reserved: 0,
        }
    }

    /// Publishes a trajectory given as one row-major slice (`rows × width` values).
    ///
    /// # Errors
    /// As [`publish_with`](Self::publish_with); a slice whose length is not a multiple of
    /// the row width.
    pub fn publish(&mut self, meta: &TrajectoryMeta, data: &[f64]) -> Result<u64, BridgeError> {
        let width: usize = meta.widths.iter().map(|&w| w as usize).sum();
        if width == 0 || !data.len().is_multiple_of(width) {
            return Err(BridgeError::BadData(format!(
                "{} values are not whole rows of width {width}",
                data.len()
            )));
        }
        self.publish_with(meta, data.len() / width, |r, c| data[r * width + c])
    }

    /// Publishes one iteration's progress (format version, run id and sequence are set here).
    ///
    /// # Errors
    /// iceoryx2 failures.
    pub fn publish_progress(&mut self, mut p: Progress) -> Result<u64, BridgeError> {
        self.progress_sequence += 1;
        p.format_version = FORMAT_VERSION;
        p.run_id = self.run_id;
        p.sequence = self.progress_sequence;
        self.progress.send_copy(p).map_err(|e| ipc("sending progress")(&e))?;
        self.progress_event.notify().map_err(|e| ipc("waking subscribers")(&e))?;
        Ok(self.progress_sequence)
    }
}

/// A trajectory being written in loaned shared memory (see [`TrajectoryPublisher::loan`]).
pub struct TrajectoryLoan<'a> {
    sample: iceoryx2::sample_mut::SampleMut<ipc::Service, [f64], TrajectoryHeader>,
    notifier: &'a Notifier<ipc::Service>,
}

impl std::fmt::Debug for TrajectoryLoan<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TrajectoryLoan")
            .field("header", self.sample.user_header())
            .finish_non_exhaustive()
    }
}

impl TrajectoryLoan<'_> {
    /// The values, row by row, in shared memory.
    pub fn values_mut(&mut self) -> &mut [f64] {
        self.sample.payload_mut()
    }

    /// The header (set from the meta data at loan time).
    pub fn header(&self) -> &TrajectoryHeader {
        self.sample.user_header()
    }

    /// Delivers it to the subscribers and wakes them; returns its sequence number.
    ///
    /// # Errors
    /// iceoryx2 failures.
    pub fn send(self) -> Result<u64, BridgeError> {
        let seq = self.sample.user_header().sequence;
        self.sample.send().map_err(|e| ipc("sending a trajectory")(&e))?;
        self.notifier.notify().map_err(|e| ipc("waking subscribers")(&e))?;
        Ok(seq)
    }
}

/// A received trajectory: typed views over the shared memory (nothing copied).
pub struct Received {
    sample: Sample<ipc::Service, [f64], TrajectoryHeader>,
}

impl std::fmt::Debug for Received {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Received").field("header", self.header()).finish_non_exhaustive()
    }
}

impl Received {
    /// The header.
    pub fn header(&self) -> &TrajectoryHeader {
        self.sample.user_header()
    }

    /// All values, row by row.
    pub fn data(&self) -> &[f64] {
        self.sample.payload()
    }

    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.header().samples as usize
    }

    /// Row `k`.
    pub fn row(&self, k: usize) -> &[f64] {
        let w = self.header().row_width();
        &self.data()[k * w..(k + 1) * w]
    }

    /// Block `b` of row `k` (empty when the block is absent).
    pub fn block(&self, k: usize, b: Block) -> &[f64] {
        let (o, w) = (self.header().offset(b), self.header().width(b));
        &self.row(k)[o..o + w]
    }

    /// Iterator over the rows.
    pub fn iter_rows(&self) -> impl Iterator<Item = &[f64]> {
        self.data().chunks(self.header().row_width().max(1))
    }
}

/// Receives a run's trajectories and progress; blocking (with a timeout) or polling.
pub struct TrajectorySubscriber {
    trajectory: Subscriber<ipc::Service, [f64], TrajectoryHeader>,
    progress: Subscriber<ipc::Service, Progress, ()>,
    trajectory_event: Listener<ipc::Service>,
    progress_event: Listener<ipc::Service>,
    _services: Services,
    _node: Node<ipc::Service>,
}

impl std::fmt::Debug for TrajectorySubscriber {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TrajectorySubscriber").finish_non_exhaustive()
    }
}

impl TrajectorySubscriber {
    /// A subscriber for run `run` (services created if absent, so it may start before the
    /// publisher). It receives the latest trajectory at once if one was published before.
    ///
    /// # Errors
    /// A bad run name; iceoryx2 failures.
    pub fn new(run: &str, settings: &BridgeSettings) -> Result<Self, BridgeError> {
        let node = node("armature-subscriber")?;
        let s = services(&node, run, settings)?;
        let trajectory = s
            .trajectory
            .subscriber_builder()
            .buffer_size(settings.subscriber_buffer)
            .create()
            .map_err(subscriber_error(run, settings, "creating the trajectory subscriber"))?;
        let progress = s
            .progress
            .subscriber_builder()
            .buffer_size(settings.subscriber_buffer.max(64))
            .create()
            .map_err(subscriber_error(run, settings, "creating the progress subscriber"))?;
        let trajectory_event = s
            .trajectory_event
            .listener_builder()
            .create()
            .map_err(|e| ipc("creating a listener")(&e))?;
        let progress_event = s
            .progress_event
            .listener_builder()
            .create()
            .map_err(|e| ipc("creating a listener")(&e))?;
        Ok(TrajectorySubscriber {
            trajectory,
            progress,
            trajectory_event,
            progress_event,
            _services: s,
            _node: node,
        })
    }

    /// The next trajectory if one is waiting (non-blocking).
    ///
    /// # Errors
    /// [`BridgeError::VersionMismatch`] for a message of another format; iceoryx2 failures.
    pub fn try_receive(&self) -> Result<Option<Received>, BridgeError> {
        let Some(sample) =
            self.trajectory.receive().map_err(|e| ipc("receiving a trajectory")(&e))?
        else {
            return Ok(None);
        };
        let h = sample.user_header();
        if h.format_version != FORMAT_VERSION {
            return Err(BridgeError::VersionMismatch {
                expected: FORMAT_VERSION,
                got: h.format_version,
            });
        }
        if sample.payload().len() != h.samples as usize * h.row_width() {
            return Err(BridgeError::BadData(format!(
                "header says {} rows of {} values, payload has {}",
                h.samples,
                h.row_width(),
                sample.payload().len()
            )));
        }
        Ok(Some(Received { sample }))
    }

    /// Waits for the next trajectory up to `timeout` (no busy loop: sleeps on the run's
    /// event service); `None` if none arrived.
    ///
    /// # Errors
    /// As [`try_receive`](Self::try_receive).
    pub fn receive_timeout(&self, timeout: Duration) -> Result<Option<Received>, BridgeError> {
        wait(
            timeout,
            || self.try_receive(),
            |left| {
                self.trajectory_event
                    .timed_wait(|_| {}, wait_slice(left))
                    .map(|_| ())
                    .map_err(|e| ipc("waiting for a trajectory")(&e))
            },
        )
    }

    /// The next progress message if one is waiting.
    ///
    /// # Errors
    /// [`BridgeError::VersionMismatch`]; iceoryx2 failures.
    pub fn try_receive_progress(&self) -> Result<Option<Progress>, BridgeError> {
        let Some(sample) = self.progress.receive().map_err(|e| ipc("receiving progress")(&e))?
        else {
            return Ok(None);
        };
        let p = *sample.payload();
        if p.format_version != FORMAT_VERSION {
            return Err(BridgeError::VersionMismatch {
                expected: FORMAT_VERSION,
                got: p.format_version,
            });
        }
        Ok(Some(p))
    }

    /// Waits for the next progress message up to `timeout`.
    ///
    /// # Errors
    /// As [`try_receive_progress`](Self::try_receive_progress).
    pub fn receive_progress_timeout(
        &self,
        timeout: Duration,
    ) -> Result<Option<Progress>, BridgeError> {
        wait(
            timeout,
            || self.try_receive_progress(),
            |left| {
                self.progress_event
                    .timed_wait(|_| {}, wait_slice(left))
                    .map(|_| ())
                    .map_err(|e| ipc("waiting for progress")(&e))
            },
        )
    }

    /// Waits up to `timeout` for either kind of message: `(progress, trajectory)`, both
    /// `None` on timeout. Progress is returned first when both are waiting.
    ///
    /// # Errors
    /// As the receive methods.
    pub fn receive_any_timeout(
        &self,
        timeout: Duration,
    ) -> Result<(Option<Progress>, Option<Received>), BridgeError> {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(p) = self.try_receive_progress()? {
                return Ok((Some(p), None));
            }
            if let Some(t) = self.try_receive()? {
                return Ok((None, Some(t)));
            }
            let now = Instant::now();
            if now >= deadline {
                return Ok((None, None));
            }
            // Both listeners are drained; sleep on the trajectory's in short slices so that
            // progress events are noticed too.
            let slice = wait_slice((deadline - now).min(Duration::from_millis(5)));
            self.progress_event.try_wait(|_| {}).map_err(|e| ipc("waiting")(&e))?;
            self.trajectory_event.timed_wait(|_| {}, slice).map_err(|e| ipc("waiting")(&e))?;
        }
    }
}

/// The shortest wait handed to iceoryx2's timed waits. Its datagram-socket waiter turns the
/// duration into `SO_RCVTIMEO`, where a timeout below one microsecond becomes zero, which
/// means *block forever*: a wait of the last few nanoseconds before a deadline hung a
/// listener (seen in `armature listen --timeout`).
const MIN_WAIT: Duration = Duration::from_millis(1);

/// `left`, but never shorter than [`MIN_WAIT`].
fn wait_slice(left: Duration) -> Duration {
    left.max(MIN_WAIT)
}

/// Receive-or-sleep loop until `timeout`.
fn wait<T>(
    timeout: Duration,
    mut poll: impl FnMut() -> Result<Option<T>, BridgeError>,
    mut sleep: impl FnMut(Duration) -> Result<(), BridgeError>,
) -> Result<Option<T>, BridgeError> {
    let deadline = Instant::now() + timeout;
    loop {
        if let Some(v) = poll()? {
            return Ok(Some(v));
        }
        let now = Instant::now();
        if now >= deadline {
            return Ok(None);
        }
        sleep(deadline - now)?;
    }
}

#[cfg(test)]
mod wait_tests {
    use super::*;

    #[test]
    fn waits_are_never_shorter_than_a_millisecond() {
        // A zero or sub-microsecond wait would reach SO_RCVTIMEO as 0: block forever.
        assert_eq!(wait_slice(Duration::ZERO), MIN_WAIT);
        assert_eq!(wait_slice(Duration::from_nanos(300)), MIN_WAIT);
        assert_eq!(wait_slice(Duration::from_millis(4)), Duration::from_millis(4));
    }
}
