//! A link emulated in user space: a TCP relay that gives the bytes between two hosts a link's
//! delay (latency plus jitter), bandwidth and bounded queue, and can be partitioned. This
//! machine's kernel has no netem qdisc, so the link lives in the stream instead of the packet
//! path (what toxiproxy does): every chunk read is released at the later of the previous
//! chunk's release and its own read time plus a delay drawn for it, so bytes never reorder; a
//! token bucket spends the bandwidth; a full queue stops the reading (TCP's own backpressure, no
//! loss: message loss belongs to radio channels, not to these IP links). Partitioned, the relay
//! forwards nothing and closes new connections at once; what is queued flows on after the heal.
//! The pace is per connection and direction (a link that carries several connections gives
//! each the bandwidth).

use crate::topology::Jitter;
use risktwin_common::histogram::Histogram;
use risktwin_common::rng::Rng;
use risktwin_transport::sync::LockExt;
use std::io;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::tcp::{OwnedReadHalf, OwnedWriteHalf};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{Semaphore, mpsc, watch};
use tokio::task::JoinHandle;
use tokio::time::Instant;

/// Bytes read at most per chunk.
const CHUNK_BYTES: usize = 64 * 1024;

/// Room a read waits for (or the whole queue, if smaller), so that a nearly full queue is not
/// refilled a byte at a time.
const LEAST_READ_BYTES: usize = 4 * 1024;

/// What a link does to the bytes crossing it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkShape {
    pub latency: Duration,
    pub jitter: Option<Jitter>,
    /// `None`: no limit.
    pub bandwidth_bps: Option<f64>,
    /// Bytes queued per direction and connection before reading stops.
    pub queue_bytes: usize,
}

impl LinkShape {
    /// A site's own network: no delay, no limit.
    pub fn lan(queue_bytes: usize) -> LinkShape {
        LinkShape { latency: Duration::ZERO, jitter: None, bandwidth_bps: None, queue_bytes }
    }
}

/// The link's state, changed while it runs (the deployment's event schedule).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LinkState {
    Up(LinkShape),
    Partitioned,
}

/// What crossed a link (every relay of it adds to the same counts).
#[derive(Debug, Default)]
pub struct RelayCounts {
    pub connections: AtomicU64,
    pub refused: AtomicU64,
    /// Bytes written, [toward the upstream, back].
    pub bytes: [AtomicU64; 2],
    /// Each chunk's time in the link, read to written, µs: the delay it measurably got.
    pub delay_us: Histogram,
    /// When each connection was made (the first [`MAX_CONNECTION_TIMES`]): a reconnection after
    /// a router restart or a partition shows when the flow could resume.
    pub connected_at: Mutex<Vec<std::time::Instant>>,
}

/// Connection times kept per link (reconnections are rare; this bounds a flapping link).
pub const MAX_CONNECTION_TIMES: usize = 1000;

impl RelayCounts {
    fn connected(&self) {
        self.connections.fetch_add(1, Ordering::Relaxed);
        let mut times = self.connected_at.locked();
        if times.len() < MAX_CONNECTION_TIMES {
            times.push(std::time::Instant::now());
        }
    }
}

/// A running relay. Dropping it stops it and every connection it carries.
pub struct Relay {
    pub addr: SocketAddr,
    task: JoinHandle<()>,
}

impl Drop for Relay {
    fn drop(&mut self) {
        self.task.abort();
    }
}

/// Starts a relay listening on `listen` (port 0: a free one) that forwards each connection to
/// `upstream` through a link whose state `state` follows; `seed` seeds its jitter.
pub async fn start(
    listen: SocketAddr,
    upstream: SocketAddr,
    state: watch::Receiver<LinkState>,
    counts: Arc<RelayCounts>,
    seed: u64,
) -> io::Result<Relay> {
    let listener = TcpListener::bind(listen).await?;
    let addr = listener.local_addr()?;
    let task = tokio::spawn(accept(listener, upstream, state, counts, seed));
    Ok(Relay { addr, task })
}

/// Accepts connections until the relay is dropped (which aborts this task, and with its set
/// every connection's tasks).
async fn accept(
    listener: TcpListener,
    upstream: SocketAddr,
    state: watch::Receiver<LinkState>,
    counts: Arc<RelayCounts>,
    seed: u64,
) {
    let mut connection = 0u64;
    let mut directions = tokio::task::JoinSet::new();
    loop {
        // Reap the directions that ended, so the set does not grow with the connections.
        while directions.try_join_next().is_some() {}
        let Ok((inbound, _)) = listener.accept().await else {
            // Out of file descriptors, say: wait rather than spin.
            tokio::time::sleep(Duration::from_millis(10)).await;
            continue;
        };
        if *state.borrow() == LinkState::Partitioned {
            counts.refused.fetch_add(1, Ordering::Relaxed);
            continue;
        }
        let Ok(outbound) = TcpStream::connect(upstream).await else {
            counts.refused.fetch_add(1, Ordering::Relaxed);
            continue;
        };
        counts.connected();
        let _ = (inbound.set_nodelay(true), outbound.set_nodelay(true));
        let (in_read, in_write) = inbound.into_split();
        let (out_read, out_write) = outbound.into_split();
        for (k, (from, to)) in [(in_read, out_write), (out_read, in_write)].into_iter().enumerate() {
            let rng = Rng::derive(seed, 2 * connection + k as u64);
            directions.spawn(direction(from, to, k, state.clone(), Arc::clone(&counts), rng));
        }
        connection += 1;
    }
}

/// One direction of one connection: a reader that stamps and queues chunks, a writer that
/// releases them on time and at the link's rate.
async fn direction(
    mut from: OwnedReadHalf,
    mut to: OwnedWriteHalf,
    way: usize,
    state: watch::Receiver<LinkState>,
    counts: Arc<RelayCounts>,
    mut rng: Rng,
) {
    let queue_bytes = match *state.borrow() {
        LinkState::Up(shape) => shape.queue_bytes.max(1),
        LinkState::Partitioned => CHUNK_BYTES,
    };
    let room = Arc::new(Semaphore::new(queue_bytes));
    let (tx, mut rx) = mpsc::unbounded_channel::<(Instant, Instant, Vec<u8>)>();
    let reader = {
        let (room, state) = (Arc::clone(&room), state.clone());
        async move {
            let mut last_release = Instant::now();
            let mut scratch = vec![0u8; CHUNK_BYTES];
            loop {
                // Room for what the queue has left: the queue holds at most its size, and a read
                // never waits for a whole chunk's room to come free.
                let want = room.available_permits().clamp(LEAST_READ_BYTES.min(queue_bytes), CHUNK_BYTES);
                let Ok(permit) = Arc::clone(&room).acquire_many_owned(want as u32).await else { return };
                let n = match from.read(&mut scratch[..want]).await {
                    Ok(0) | Err(_) => return,
                    Ok(n) => n,
                };
                let read_at = Instant::now();
                // A chunk holds what was read, no more: a queue of small reads (a partition
                // holding Zenoh's keep-alives) costs its bytes, not a buffer each.
                let chunk = scratch[..n].to_vec();
                // Only the bytes read stay reserved.
                permit.forget();
                room.add_permits(want - n);
                let delay = match *state.borrow() {
                    LinkState::Up(shape) => delay_of(&shape, &mut rng),
                    LinkState::Partitioned => Duration::ZERO,
                };
                last_release = last_release.max(read_at + delay);
                if tx.send((read_at, last_release, chunk)).is_err() {
                    return;
                }
            }
        }
    };
    let writer = async move {
        // However the writer ends, a reader waiting for room must end too.
        let _close = CloseOnDrop(Arc::clone(&room));
        let mut state = state;
        let mut sent_until = Instant::now();
        while let Some((read_at, release, chunk)) = rx.recv().await {
            // Tokio's timer counts whole milliseconds: a chunk already due must not wait for it.
            if release > Instant::now() {
                tokio::time::sleep_until(release).await;
            }
            // A partition holds everything queued until the heal.
            while matches!(*state.borrow_and_update(), LinkState::Partitioned) {
                if state.changed().await.is_err() {
                    return;
                }
            }
            let now_state = *state.borrow();
            if let LinkState::Up(LinkShape { bandwidth_bps: Some(bps), .. }) = now_state {
                let on_wire = Duration::from_secs_f64(chunk.len() as f64 * 8.0 / bps);
                sent_until = sent_until.max(Instant::now()) + on_wire;
                if sent_until > Instant::now() {
                    tokio::time::sleep_until(sent_until).await;
                }
            }
            if to.write_all(&chunk).await.is_err() {
                return;
            }
            counts.bytes[way].fetch_add(chunk.len() as u64, Ordering::Relaxed);
            counts.delay_us.record(read_at.elapsed().as_micros() as u64);
            room.add_permits(chunk.len());
        }
        let _ = to.shutdown().await;
    };
    tokio::join!(reader, writer);
}

/// Closes a queue's room when dropped: its reader's next wait returns at once.
struct CloseOnDrop(Arc<Semaphore>);

impl Drop for CloseOnDrop {
    fn drop(&mut self) {
        self.0.close();
    }
}

/// A delay drawn for one chunk: the latency plus jitter (normal cut at ± 3 sd, or uniform),
/// never below zero.
fn delay_of(shape: &LinkShape, rng: &mut Rng) -> Duration {
    let jitter_s = match shape.jitter {
        None => 0.0,
        Some(Jitter::Normal { sd_ms }) => (rng.normal().clamp(-3.0, 3.0) * sd_ms) * 1e-3,
        Some(Jitter::Uniform { max_ms }) => rng.uniform(-max_ms, max_ms) * 1e-3,
    };
    Duration::from_secs_f64((shape.latency.as_secs_f64() + jitter_s).max(0.0))
}

/// What the report and the status show of a hop.
pub struct HopView {
    pub name: String,
    pub base: LinkShape,
    /// What it applies now (a degradation changes it).
    pub shape: LinkShape,
    pub counts: Arc<RelayCounts>,
    pub partitioned: bool,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An echo server on a free port.
    async fn echo() -> SocketAddr {
        let listener = TcpListener::bind("127.0.0.1:0").await.expect("binds");
        let addr = listener.local_addr().expect("an address");
        tokio::spawn(async move {
            while let Ok((stream, _)) = listener.accept().await {
                tokio::spawn(async move {
                    let (mut r, mut w) = stream.into_split();
                    let _ = tokio::io::copy(&mut r, &mut w).await;
                });
            }
        });
        addr
    }

    fn shape(latency_ms: u64, bandwidth_bps: Option<f64>) -> LinkShape {
        LinkShape { latency: Duration::from_millis(latency_ms), jitter: None, bandwidth_bps, queue_bytes: 1 << 20 }
    }

    /// A relay to an echo server, the sender of its state and its counts.
    struct Echoed {
        relay: Relay,
        state: watch::Sender<LinkState>,
        counts: Arc<RelayCounts>,
    }

    async fn relay_to_echo(state: LinkState) -> (Echoed, TcpStream) {
        let (tx, rx) = watch::channel(state);
        let counts = Arc::new(RelayCounts::default());
        let listen = "127.0.0.1:0".parse().expect("an address");
        let relay = start(listen, echo().await, rx, Arc::clone(&counts), 1).await.expect("starts");
        let client = TcpStream::connect(relay.addr).await.expect("connects");
        client.set_nodelay(true).expect("nodelay");
        (Echoed { relay, state: tx, counts }, client)
    }

    #[tokio::test]
    async fn a_round_trip_takes_the_latency_both_ways() {
        let (echoed, mut client) = relay_to_echo(LinkState::Up(shape(20, None))).await;
        let mut rtts = Vec::new();
        for k in 0..10u8 {
            let t = std::time::Instant::now();
            client.write_all(&[k]).await.expect("writes");
            let mut b = [0u8];
            client.read_exact(&mut b).await.expect("reads");
            assert_eq!(b[0], k, "in order");
            rtts.push(t.elapsed().as_secs_f64() * 1e3);
        }
        rtts.sort_by(f64::total_cmp);
        // 2 × 20 ms at least (the timer rounds up); the fastest of ten well below a doubled
        // latency, which holds on a loaded 2-core machine.
        assert!((39.0..70.0).contains(&rtts[0]), "fastest {} ms of {rtts:?}", rtts[0]);
        // Each way's chunks measured in the link: 20 ms and a little.
        let p50_ms = echoed.counts.delay_us.quantile(0.5).expect("chunks crossed") / 1e3;
        assert!((19.5..35.0).contains(&p50_ms), "measured p50 {p50_ms} ms");
        assert_eq!(echoed.counts.bytes.each_ref().map(|b| b.load(Ordering::Relaxed)), [10, 10]);
    }

    #[tokio::test]
    async fn a_partition_holds_the_bytes_and_refuses_new_connections_until_the_heal() {
        let (echoed, mut client) = relay_to_echo(LinkState::Up(shape(0, None))).await;
        let mut b = [0u8; 1];
        client.write_all(b"a").await.expect("writes");
        client.read_exact(&mut b).await.expect("reads");
        echoed.state.send(LinkState::Partitioned).expect("the relay runs");
        client.write_all(b"b").await.expect("writes into the queue");
        let held = tokio::time::timeout(Duration::from_millis(300), client.read_exact(&mut b)).await;
        assert!(held.is_err(), "nothing crosses a partition");
        let mut other = TcpStream::connect(echoed.relay.addr).await.expect("the listener accepts");
        let refused = tokio::time::timeout(Duration::from_secs(5), other.read(&mut b)).await.expect("closed at once");
        assert!(matches!(refused, Ok(0) | Err(_)), "a new connection is refused: {refused:?}");
        echoed.state.send(LinkState::Up(shape(0, None))).expect("the relay runs");
        tokio::time::timeout(Duration::from_secs(5), client.read_exact(&mut b)).await.expect("healed").expect("reads");
        assert_eq!(&b, b"b", "what was queued flows on after the heal");
        assert_eq!(echoed.counts.refused.load(Ordering::Relaxed), 1);
    }

    #[tokio::test]
    async fn the_bandwidth_paces_the_bytes() {
        // 1 Mbit/s one way (the echo comes back through the same link): 62,500 bytes take 0.5 s.
        let (_relay, client) = relay_to_echo(LinkState::Up(shape(0, Some(1e6)))).await;
        let (mut r, mut w) = client.into_split();
        let t = std::time::Instant::now();
        let sent = vec![7u8; 62_500];
        let writer = tokio::spawn(async move { w.write_all(&sent).await.map(|()| w) });
        let mut got = vec![0u8; 62_500];
        r.read_exact(&mut got).await.expect("reads");
        let _w = writer.await.expect("joins").expect("writes");
        let s = t.elapsed().as_secs_f64();
        assert!((0.45..2.0).contains(&s), "{s} s for 0.5 s of bytes");
        assert!(got.iter().all(|&b| b == 7));
    }
}
