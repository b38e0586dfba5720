//! A router restart between an edge and a cloud, both Zenoh clients of it, in one process: the
//! edge's stream publisher keeps publishing into its cache while the router is gone; once both
//! are back, the cloud's edge-stream subscriber recovers what the cache holds and reports the
//! rest as lost, so that received + lost = sent.

use risktwin_transport::zenoh::Session;
use risktwin_transport::zenoh::sample::Sample;
use risktwin_transport::{
    Delivery, EdgeStream, Mode, SiteId, SourceId, StreamLoss, StreamPublisher, TransportConfig, close, connect,
    listening_locators, subscribe_edge_streams,
};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

const STEP: Duration = Duration::from_secs(30);

async fn router(listen: &str) -> Session {
    let config = TransportConfig { mode: Mode::Router, listen: vec![listen.to_owned()], ..Default::default() };
    connect(&config).await.expect("the router opens")
}

async fn client(router: &str) -> Session {
    let config = TransportConfig { mode: Mode::Client, connect: vec![router.to_owned()], ..Default::default() };
    connect(&config).await.expect("the client reaches the router")
}

/// What the cloud side saw: the `seq` payloads received in order, and the samples lost.
#[derive(Default)]
struct Seen {
    received: Vec<u32>,
    lost: u64,
    lost_keys: Vec<Option<String>>,
    /// Samples on another stream or with a payload that is not a 4-byte number (checked at the
    /// end: a panic in the callback would not fail the test).
    strays: usize,
}

/// Polls `done` on what was seen every 10 ms until it holds, at most [`STEP`].
async fn wait_until(seen: &Mutex<Seen>, what: &str, done: impl Fn(&Seen) -> bool) {
    let deadline = Instant::now() + STEP;
    loop {
        {
            let seen = seen.lock().unwrap();
            if done(&seen) {
                return;
            }
            assert!(Instant::now() < deadline, "{what}: received {:?}, lost {}", seen.received, seen.lost);
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
}

/// Sends `count` samples numbered from `first` (4-byte little-endian payloads).
async fn put_range(publisher: &StreamPublisher, first: u32, count: u32) {
    for seq in first..first + count {
        publisher.put(seq.to_le_bytes().to_vec()).expect("a put never fails while the session is open");
    }
}

/// Runs the scenario: 10 samples through, the router closed, `during` samples into the cache,
/// the router back on the same port, then samples until the cloud has accounted for every one.
async fn restart_with_cache(cache_samples: usize, during: u32) -> (Seen, u32) {
    let first = router("tcp/127.0.0.1:0").await;
    let locator = listening_locators(&first).await.into_iter().find(|l| l.starts_with("tcp/127.0.0.1:")).unwrap();
    let (cloud, edge) = (client(&locator).await, client(&locator).await);
    let (site, source) = (SiteId::new("s1").unwrap(), SourceId::new("veh-1").unwrap());
    let seen = Arc::new(Mutex::new(Seen::default()));
    let (on_sample_seen, on_loss_seen) = (Arc::clone(&seen), Arc::clone(&seen));
    let on_sample = move |stream, sample: &Sample| {
        let mut seen = on_sample_seen.lock().unwrap();
        match <[u8; 4]>::try_from(sample.payload().to_bytes().as_ref()) {
            Ok(bytes) if stream == EdgeStream::Can => seen.received.push(u32::from_le_bytes(bytes)),
            _ => seen.strays += 1,
        }
    };
    let on_loss = move |loss: StreamLoss| {
        let mut seen = on_loss_seen.lock().unwrap();
        seen.lost += u64::from(loss.samples);
        seen.lost_keys.push(loss.key);
    };
    let subscriber = subscribe_edge_streams(&cloud, Some(&site), on_sample, on_loss).await.unwrap();
    let delivery = Delivery { cache_samples, ..Delivery::live(1.0, Duration::ZERO) };
    let publisher = StreamPublisher::declare(&edge, &site, &source, EdgeStream::Can, delivery).unwrap();
    let (_trigger, shutdown) = risktwin_transport::shutdown::channel();
    assert!(publisher.wait_for_subscriber(STEP, shutdown).await.unwrap());

    put_range(&publisher, 0, 10).await;
    wait_until(&seen, "before the restart", |s| s.received.len() == 10).await;
    close(first).await.unwrap();
    put_range(&publisher, 10, during).await;
    let second = router(&locator).await;
    // Live samples until the cloud has accounted for all of them (received or lost).
    let mut sent = 10 + during;
    let deadline = Instant::now() + STEP;
    while seen.lock().map(|s| s.received.len() as u64 + s.lost).unwrap() < u64::from(sent) {
        assert!(Instant::now() < deadline, "no recovery after the router came back");
        put_range(&publisher, sent, 1).await;
        sent += 1;
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    // Nothing more arrives: the heartbeat announces nothing new.
    tokio::time::sleep(Duration::from_millis(1200)).await;
    publisher.undeclare().unwrap();
    subscriber.undeclare().await.unwrap();
    for session in [edge, cloud, second] {
        close(session).await.unwrap();
    }
    let seen = Arc::try_unwrap(seen).ok().expect("the callbacks are gone").into_inner().unwrap();
    assert_eq!(seen.strays, 0, "only the numbered `can` samples arrive");
    (seen, sent)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_router_restart_within_the_cache_loses_nothing() {
    let (seen, sent) = restart_with_cache(100, 30).await;
    assert_eq!(seen.lost, 0, "{:?}", seen.lost_keys);
    let expected: Vec<u32> = (0..sent).collect();
    assert_eq!(seen.received, expected, "every sample once, in order");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_outage_longer_than_the_cache_is_counted_to_the_sample() {
    let (seen, sent) = restart_with_cache(5, 30).await;
    assert!(seen.lost > 0, "30 samples into a cache of 5");
    assert_eq!(seen.received.len() as u64 + seen.lost, u64::from(sent), "received {:?}", seen.received);
    assert!(seen.received.windows(2).all(|w| w[0] < w[1]), "in order, no duplicate: {:?}", seen.received);
    assert_eq!(seen.received[..10], (0..10).collect::<Vec<_>>());
    let key = Some("risktwin/v1/s1/veh-1/can".to_owned());
    assert!(seen.lost_keys.iter().all(|k| *k == key), "losses are named by their key: {:?}", seen.lost_keys);
}

/// The second ask for a range zenoh-ext reported missed: what the cache holds comes back once,
/// as recovered; what it no longer holds is counted; a router that is back within the retries
/// costs nothing.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_missed_range_is_asked_for_again_and_only_the_evicted_part_is_lost() {
    use risktwin_transport::recovery::is_recovered;
    use risktwin_transport::{Missed, requery};
    let first = router("tcp/127.0.0.1:0").await;
    let locator = listening_locators(&first).await.into_iter().find(|l| l.starts_with("tcp/127.0.0.1:")).unwrap();
    let (cloud, edge) = (client(&locator).await, client(&locator).await);
    let (site, source) = (SiteId::new("s1").unwrap(), SourceId::new("veh-1").unwrap());
    let delivery = Delivery { cache_samples: 10, ..Delivery::live(1.0, Duration::ZERO) };
    let publisher = StreamPublisher::declare(&edge, &site, &source, EdgeStream::Can, delivery).unwrap();
    let key = publisher.key().to_owned();
    let live = cloud.declare_subscriber(&key).await.unwrap();
    let (_trigger, shutdown) = risktwin_transport::shutdown::channel();
    assert!(publisher.wait_for_subscriber(STEP, shutdown).await.unwrap());
    put_range(&publisher, 0, 20).await;
    let sample = tokio::time::timeout(STEP, live.recv_async()).await.unwrap().unwrap();
    let id = *sample.source_info().expect("numbered").source_id();
    let ask = |first_sn, samples| Missed { key: key.clone(), publisher: id, first_sn, samples };
    let payload = |s: &Sample| u32::from_le_bytes(<[u8; 4]>::try_from(s.payload().to_bytes().as_ref()).unwrap());

    // Held: all of it, once, as recovered (the cache holds numbers 10..=19).
    let mut got = Vec::new();
    let lost = requery(&cloud, &ask(12, 5), |s| got.push((payload(s), is_recovered(s)))).await;
    assert_eq!((lost, got), (0, (12..17).map(|n| (n, true)).collect::<Vec<_>>()));
    // Half evicted: the held half comes back at the first answer, the rest is counted.
    let (mut got, started) = (Vec::new(), Instant::now());
    let lost = requery(&cloud, &ask(5, 10), |s| got.push(payload(s))).await;
    assert_eq!((lost, got), (5, (10..15).collect::<Vec<_>>()));
    assert!(started.elapsed() < risktwin_transport::edge_subscriber::REQUERY_DELAY, "no second ask");
    // All evicted: asked REQUERY_ATTEMPTS times, all counted.
    let lost = requery(&cloud, &ask(0, 5), |_| panic!("nothing is held")).await;
    assert_eq!(lost, 5);

    // The router gone when the range is first asked for, back within the retries.
    close(first).await.unwrap();
    let asked = tokio::spawn({
        let (cloud, missed) = (cloud.clone(), ask(17, 3));
        async move {
            let mut got = Vec::new();
            (requery(&cloud, &missed, |s| got.push(payload(s))).await, got)
        }
    });
    tokio::time::sleep(Duration::from_millis(200)).await;
    let second = router(&locator).await;
    let (lost, got) = tokio::time::timeout(STEP, asked).await.unwrap().unwrap();
    assert_eq!((lost, got), (0, vec![17, 18, 19]));

    live.undeclare().await.unwrap();
    publisher.undeclare().unwrap();
    for session in [edge, cloud, second] {
        close(session).await.unwrap();
    }
}
