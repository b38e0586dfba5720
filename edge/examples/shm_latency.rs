//! One-way latency of the iceoryx2 hop: our `ShmPublisher`/`ShmSubscriber` against a raw iceoryx2
//! publisher/subscriber pair, in the same run, as a ping-pong between two processes.
//!
//! `cargo run --release -p risktwin-edge --example shm_latency -- [--rounds N]`
//!
//! The parent sends an 88-byte `ShmVehicleState` ping, the child (this binary re-executed with
//! `--pong`) sends it straight back, and one way is half the round trip. Four variants:
//! raw and ours, each with a busy-polling receiver and with a receiver asleep on an iceoryx2
//! event (blocking wake-up). The raw blocking pair uses the same event-service pattern as ours
//! (send, then notify; receive, else wait), so the ratio isolates the wrapper's own cost
//! (validation, typed errors, the always-on notify in poll mode). Busy polling needs two free
//! cores; on a loaded machine its tail is the scheduler's, not iceoryx2's.

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use iceoryx2::node::Node;
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::{NodeBuilder, ServiceName, SignalHandlingMode, ipc};
use iceoryx2::service::port_factory::{event, publish_subscribe};
use risktwin_edge::shm::{ShmPayload, ShmPublisher, ShmQos, ShmSubscriber, ShmVehicleState};

const WARMUP_ROUNDS: usize = 1_000;
const HANDSHAKE_TIMEOUT: Duration = Duration::from_secs(10);
const HELLO_SEQ: u64 = u64::MAX;
const STOP_SEQ: u64 = u64::MAX - 1;

/// One side of a ping-pong: sends on one service, receives on the other.
trait Endpoint {
    fn send(&self, value: &ShmVehicleState);
    /// Busy-polls until a sample arrives.
    fn recv_poll(&self) -> ShmVehicleState;
    /// Sleeps on the event service until a sample arrives (or the timeout, which panics).
    fn recv_block(&self, timeout: Duration) -> ShmVehicleState;
}

struct Ours {
    publisher: ShmPublisher<ShmVehicleState>,
    subscriber: ShmSubscriber<ShmVehicleState>,
}

impl Ours {
    fn new(send_id: &str, recv_id: &str) -> Self {
        let qos = ShmQos::default();
        let subscriber = ShmSubscriber::new(recv_id, qos).expect("our subscriber");
        let publisher = ShmPublisher::new(send_id, qos).expect("our publisher");
        Self { publisher, subscriber }
    }
}

impl Endpoint for Ours {
    fn send(&self, value: &ShmVehicleState) {
        self.publisher.publish(value).expect("publish");
    }

    fn recv_poll(&self) -> ShmVehicleState {
        loop {
            if let Some(sample) = self.subscriber.try_receive().expect("receive") {
                return *sample;
            }
            std::hint::spin_loop();
        }
    }

    fn recv_block(&self, timeout: Duration) -> ShmVehicleState {
        *self.subscriber.receive_timeout(timeout).expect("receive").expect("sample before the timeout")
    }
}

/// The raw iceoryx2 pair, with the same service QoS as ours; the notifier/listener are used only
/// by the blocking variant.
struct Raw {
    publisher: Publisher<ipc::Service, ShmVehicleState, ()>,
    notifier: Notifier<ipc::Service>,
    subscriber: Subscriber<ipc::Service, ShmVehicleState, ()>,
    listener: Listener<ipc::Service>,
    notify: bool,
    _services:
        Vec<(publish_subscribe::PortFactory<ipc::Service, ShmVehicleState, ()>, event::PortFactory<ipc::Service>)>,
    _node: Node<ipc::Service>,
}

impl Raw {
    fn new(send_name: &str, recv_name: &str, notify: bool) -> Self {
        let qos = ShmQos::default();
        let node = NodeBuilder::new()
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<ipc::Service>()
            .expect("node");
        let open = |name: &str| {
            let name = ServiceName::new(name).expect("service name");
            let pubsub = node
                .service_builder(&name)
                .publish_subscribe::<ShmVehicleState>()
                .subscriber_max_buffer_size(qos.subscriber_buffer)
                .enable_safe_overflow(false)
                .open_or_create()
                .expect("pub-sub service");
            let events = node.service_builder(&name).event().open_or_create().expect("event service");
            (pubsub, events)
        };
        let recv = open(recv_name);
        let send = open(send_name);
        let subscriber = recv.0.subscriber_builder().buffer_size(qos.subscriber_buffer).create().expect("subscriber");
        let listener = recv.1.listener_builder().create().expect("listener");
        let publisher = send.0.publisher_builder().create().expect("publisher");
        let notifier = send.1.notifier_builder().create().expect("notifier");
        Self { publisher, notifier, subscriber, listener, notify, _services: vec![recv, send], _node: node }
    }
}

impl Endpoint for Raw {
    fn send(&self, value: &ShmVehicleState) {
        let sample = self.publisher.loan_uninit().expect("loan");
        sample.write_payload(*value).send().expect("send");
        if self.notify {
            self.notifier.notify().expect("notify");
        }
    }

    fn recv_poll(&self) -> ShmVehicleState {
        loop {
            if let Some(sample) = self.subscriber.receive().expect("receive") {
                return *sample.payload();
            }
            std::hint::spin_loop();
        }
    }

    fn recv_block(&self, timeout: Duration) -> ShmVehicleState {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(sample) = self.subscriber.receive().expect("receive") {
                return *sample.payload();
            }
            let left = deadline.saturating_duration_since(Instant::now());
            assert!(!left.is_zero(), "no sample before the timeout");
            self.listener.timed_wait(|_| {}, left).expect("wait");
        }
    }
}

#[derive(Clone, Copy)]
enum Variant {
    RawPoll,
    OursPoll,
    RawBlock,
    OursBlock,
}

impl Variant {
    const ALL: [Variant; 4] = [Variant::RawPoll, Variant::OursPoll, Variant::RawBlock, Variant::OursBlock];

    fn name(self) -> &'static str {
        match self {
            Variant::RawPoll => "raw-poll",
            Variant::OursPoll => "ours-poll",
            Variant::RawBlock => "raw-block",
            Variant::OursBlock => "ours-block",
        }
    }

    fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|v| v.name() == name)
    }

    fn blocking(self) -> bool {
        matches!(self, Variant::RawBlock | Variant::OursBlock)
    }

    /// The endpoint of one side; `ping` is the parent.
    fn endpoint(self, tag: &str, ping: bool) -> Box<dyn Endpoint> {
        let (a, b) = (format!("{tag}-ping"), format!("{tag}-pong"));
        let (send, recv) = if ping { (a, b) } else { (b, a) };
        match self {
            Variant::OursPoll | Variant::OursBlock => Box::new(Ours::new(&send, &recv)),
            Variant::RawPoll | Variant::RawBlock => Box::new(Raw::new(
                &format!("rawbench/{send}/state"),
                &format!("rawbench/{recv}/state"),
                self.blocking(),
            )),
        }
    }
}

fn recv(endpoint: &dyn Endpoint, variant: Variant) -> ShmVehicleState {
    if variant.blocking() { endpoint.recv_block(HANDSHAKE_TIMEOUT) } else { endpoint.recv_poll() }
}

fn sample(seq: u64) -> ShmVehicleState {
    ShmVehicleState { seq, speed_mps: 10.0, length_m: 4.5, width_m: 1.8, ..ShmVehicleState::EMPTY }
}

/// The child: echoes every ping until the stop message.
fn pong(variant: Variant, tag: &str) {
    let endpoint = variant.endpoint(tag, false);
    endpoint.send(&sample(HELLO_SEQ));
    loop {
        let ping = recv(endpoint.as_ref(), variant);
        if ping.seq == STOP_SEQ {
            return;
        }
        endpoint.send(&ping);
    }
}

/// The parent: returns the one-way latencies (half round trips) of `rounds` pings, in ns.
fn ping(variant: Variant, rounds: usize) -> Vec<f64> {
    let tag = format!("bench{}-{}", std::process::id(), variant.name());
    let endpoint = variant.endpoint(&tag, true);
    let exe = std::env::current_exe().expect("own path");
    let mut child = Command::new(exe)
        .args(["--pong", variant.name(), &tag])
        .stdin(Stdio::null())
        .spawn()
        .expect("spawn the pong process");
    // The hello proves the child's subscriber exists, so no ping can be lost.
    assert_eq!(recv(endpoint.as_ref(), variant).seq, HELLO_SEQ);
    let mut one_way_ns = Vec::with_capacity(rounds);
    for round in 0..WARMUP_ROUNDS + rounds {
        let start = Instant::now();
        endpoint.send(&sample(round as u64));
        let back = recv(endpoint.as_ref(), variant);
        let elapsed = start.elapsed();
        assert_eq!(back.seq, round as u64, "pong out of order");
        if round >= WARMUP_ROUNDS {
            one_way_ns.push(elapsed.as_nanos() as f64 / 2.0);
        }
    }
    endpoint.send(&sample(STOP_SEQ));
    let status = child.wait().expect("wait for the pong process");
    assert!(status.success(), "pong process failed: {status}");
    one_way_ns
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    let index = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[index]
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("--pong") {
        let variant = args.get(1).and_then(|name| Variant::parse(name)).expect("--pong <variant> <tag>");
        pong(variant, args.get(2).expect("--pong <variant> <tag>"));
        return;
    }
    let rounds = match args.as_slice() {
        [flag, n] if flag == "--rounds" => n.parse().expect("--rounds N"),
        [] => 10_000,
        _ => panic!("usage: shm_latency [--rounds N]"),
    };
    println!("iceoryx2 one-way latency, {rounds} round trips after {WARMUP_ROUNDS} warm-up, 88-byte payload");
    println!("{:<11} {:>10} {:>10} {:>10}", "variant", "p50 µs", "p99 µs", "mean µs");
    let mut p50 = [0.0; 4];
    let mut p99 = [0.0; 4];
    for (i, variant) in Variant::ALL.into_iter().enumerate() {
        let mut ns = ping(variant, rounds);
        ns.sort_by(f64::total_cmp);
        let mean = ns.iter().sum::<f64>() / ns.len() as f64;
        p50[i] = percentile(&ns, 0.5);
        p99[i] = percentile(&ns, 0.99);
        println!("{:<11} {:>10.3} {:>10.3} {:>10.3}", variant.name(), p50[i] / 1e3, p99[i] / 1e3, mean / 1e3);
    }
    println!("ratio ours/raw, busy poll:        p50 {:.2}x  p99 {:.2}x", p50[1] / p50[0], p99[1] / p99[0]);
    println!("ratio ours/raw, blocking wake-up: p50 {:.2}x  p99 {:.2}x", p50[3] / p50[2], p99[3] / p99[2]);
}
