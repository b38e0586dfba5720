//! Two real peer sessions over TCP loopback (one listens on a free port, the other connects):
//! typed publishers reach the typed subscribers on the right stream, and liveliness reports an
//! edge joining and leaving.

use risktwin_transport::recovery::DEFAULT_OUTAGE;
use risktwin_transport::{
    Delivery, EdgeStream, Liveness, Mode, SiteId, SourceId, StreamLoss, StreamPublisher, TransportConfig,
    TransportError, connect, declare_alive, declare_alive_within, listening_locators, shutdown, subscribe_edge_streams,
    watch_liveliness,
};
use std::time::Duration;
use tokio::sync::mpsc;
use tokio::time::timeout;

const STEP: Duration = Duration::from_secs(30);

/// A live 50 Hz stream's delivery.
fn live() -> Delivery {
    Delivery::live(50.0, DEFAULT_OUTAGE)
}

async fn peer_pair() -> (risktwin_transport::zenoh::Session, risktwin_transport::zenoh::Session) {
    let listen = TransportConfig { mode: Mode::Peer, listen: vec!["tcp/127.0.0.1:0".into()], ..Default::default() };
    let a = connect(&listen).await.unwrap();
    let locators = listening_locators(&a).await;
    assert!(locators.iter().any(|l| l.starts_with("tcp/127.0.0.1:") && !l.ends_with(":0")), "{locators:?}");
    let b = connect(&TransportConfig { mode: Mode::Peer, connect: locators, ..Default::default() }).await.unwrap();
    (a, b)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn streams_arrive_on_their_subscriber_and_liveliness_tracks_the_edge() {
    let (cloud, edge) = peer_pair().await;
    let site = SiteId::new("s1").unwrap();
    let source = SourceId::new("veh-7").unwrap();

    let (sample_tx, mut samples) = mpsc::unbounded_channel();
    let on_sample = move |stream, sample: &risktwin_transport::zenoh::sample::Sample| {
        let tagged = (sample.key_expr().to_string(), sample.encoding().to_string());
        let _ = sample_tx.send((stream, tagged, sample.payload().to_bytes().into_owned()));
    };
    // Called on a Zenoh thread, where a panic would not fail the test: checked at the end.
    let (loss_tx, mut losses) = mpsc::unbounded_channel();
    let on_loss = move |loss: StreamLoss| drop(loss_tx.send(loss));
    let _subs = subscribe_edge_streams(&cloud, Some(&site), on_sample, on_loss).await.unwrap();
    let (live_tx, mut lives) = mpsc::unbounded_channel();
    let _watch = watch_liveliness(&cloud, Some(&site), move |change| drop(live_tx.send(change))).await.unwrap();

    let token = declare_alive(&edge, &site, &source).await.unwrap();
    let joined = timeout(STEP, lives.recv()).await.unwrap().unwrap();
    assert_eq!(joined, Liveness { site: "s1".into(), source: "veh-7".into(), alive: true });

    let (_trigger, shutdown) = shutdown::channel();
    for (i, stream) in [EdgeStream::Can, EdgeStream::Signal].into_iter().enumerate() {
        let publisher = StreamPublisher::declare(&edge, &site, &source, stream, live()).unwrap();
        assert!(publisher.wait_for_subscriber(STEP, shutdown.clone()).await.unwrap());
        publisher.put(vec![i as u8; 3]).unwrap();
        let (got_stream, (key, encoding), payload) = timeout(STEP, samples.recv()).await.unwrap().unwrap();
        assert_eq!((got_stream, key.as_str(), payload), (stream, publisher.key(), vec![i as u8; 3]));
        assert_eq!(key, format!("risktwin/v1/s1/veh-7/{}", stream.as_str()));
        // Tagged with the stream's message, as outside clients see it.
        assert_eq!(encoding, format!("application/protobuf;{}", stream.message()));
        assert_eq!(encoding, risktwin_transport::protobuf(stream.message()).to_string());
    }

    // A stream of another site is not ours.
    let other = SiteId::new("s2").unwrap();
    let stranger = StreamPublisher::declare(&edge, &other, &source, EdgeStream::State, live()).unwrap();
    let (_t, quick) = shutdown::channel();
    assert!(!stranger.wait_for_subscriber(Duration::from_millis(300), quick).await.unwrap());

    token.undeclare().await.unwrap();
    let left = timeout(STEP, lives.recv()).await.unwrap().unwrap();
    assert_eq!(left, Liveness { site: "s1".into(), source: "veh-7".into(), alive: false });
    assert!(losses.try_recv().is_err(), "nothing is lost on a healthy link");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_second_process_under_a_live_id_is_refused_and_welcome_once_the_first_has_gone() {
    let (first, second) = peer_pair().await;
    let site = SiteId::new("s1").unwrap();
    let id = SourceId::new("veh-7").unwrap();
    let (live_tx, mut lives) = mpsc::unbounded_channel();
    let _watch = watch_liveliness(&second, Some(&site), move |change| drop(live_tx.send(change))).await.unwrap();
    let token = declare_alive(&first, &site, &id).await.unwrap();
    // The first process has been running a while: the second's side has heard of its token.
    assert!(timeout(STEP, lives.recv()).await.unwrap().unwrap().alive);
    let wait = Duration::from_millis(800);
    match declare_alive_within(&second, &site, &id, wait).await {
        Err(TransportError::DuplicateId { site, id, .. }) => assert_eq!((site.as_str(), id.as_str()), ("s1", "veh-7")),
        other => panic!("a second veh-7 must be refused: {:?}", other.map(|_| ())),
    }
    // Another id is free, and so is this one once its holder has gone (within the wait).
    let other = SourceId::new("veh-8").unwrap();
    let _veh8 = declare_alive_within(&second, &site, &other, wait).await.expect("veh-8 is free");
    let gone = async {
        tokio::time::sleep(Duration::from_millis(200)).await;
        token.undeclare().await.unwrap();
    };
    let (taken, ()) = tokio::join!(declare_alive_within(&second, &site, &id, STEP), gone);
    let _veh7 = taken.expect("veh-7 is free once its first process has gone");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn waiting_for_a_subscriber_ends_on_shutdown() {
    let (_a, edge) = peer_pair().await;
    let site = SiteId::new("s1").unwrap();
    let source = SourceId::new("lonely").unwrap();
    let publisher = StreamPublisher::declare(&edge, &site, &source, EdgeStream::State, live()).unwrap();
    let (trigger, shutdown) = shutdown::channel();
    let wait = tokio::spawn(async move { publisher.wait_for_subscriber(Duration::from_secs(3600), shutdown).await });
    trigger.fire();
    assert!(!timeout(STEP, wait).await.unwrap().unwrap().unwrap());
}
