//! The cloud role against real Zenoh sessions in this process: a router on a free port, the
//! cloud recording to MCAP, and a raw session that sends real encodings mixed with bad input.

use super::CloudConfig;
use super::test_harness::{Router, STEP, start_cloud, state_publisher};
use risktwin_common::telemetry::VehicleStateSample;
use risktwin_protos::encode;
use risktwin_protos::recording::read_messages;
use risktwin_transport::wall_clock::unix_ns;
use risktwin_transport::{Delivery, EdgeStream, SiteId, SourceId, StreamPublisher, connect, protobuf, shutdown};
use std::collections::BTreeMap;
use std::time::Duration;
use tokio::time::timeout;

/// The `seq`-th state of a 50 Hz stream starting at `epoch_ns`.
fn state(source: &str, seq: u64, epoch_ns: i64) -> VehicleStateSample {
    crate::test_fixtures::state(source, seq, epoch_ns + seq as i64 * 20_000_000)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_wire_input_is_counted_by_reason_and_the_worker_carries_on() {
    let router = Router::start().await;
    let dir = tempfile::tempdir().unwrap();
    let recording = dir.path().join("live.mcap");
    let mut cloud_config = CloudConfig::new(router.client.clone());
    cloud_config.record = Some(recording.clone());
    let (cloud_stop, cloud) = start_cloud(cloud_config).await;

    let sender = connect(&router.client).await.unwrap();
    let key = "risktwin/v1/site/veh-1/state";
    let publisher = state_publisher(&sender, key.to_owned()).await;
    let epoch_ns = unix_ns();
    let record = |source: &str, seq: u64| encode(&state(source, seq, epoch_ns));
    let mut nan = state("veh-1", 3, epoch_ns);
    nan.speed_mps = f64::NAN;
    let wire: Vec<Vec<u8>> = vec![
        record("veh-1", 0),
        b"\x00garbage".to_vec(),
        record("veh-1", 1),
        record("veh-1", 1), // duplicate
        encode(&nan),
        record("veh-9", 2), // another source than the key says
        record("veh-1", 2),
    ];
    for payload in wire {
        publisher.put(payload).await.unwrap();
    }
    // A valid state under another schema version, another type's tag, or no tag: not read.
    for tag in ["application/protobuf;risktwin.v2.VehicleState", "application/protobuf;risktwin.v1.ObjectList", ""] {
        publisher.put(record("veh-1", 5)).encoding(tag).await.unwrap();
    }
    drop(publisher);
    sender.close().await.unwrap();

    cloud_stop.fire();
    let summary = timeout(STEP, cloud).await.unwrap().unwrap().unwrap();
    assert_eq!(summary.ingest.received["veh-1"], BTreeMap::from([("state".to_owned(), 3)]));
    assert_eq!(
        summary.ingest.dropped,
        BTreeMap::from([
            ("malformed".to_owned(), 1),
            ("duplicate".to_owned(), 1),
            ("invalid-field".to_owned(), 1),
            ("source-mismatch".to_owned(), 1),
            ("wrong-schema".to_owned(), 3),
        ])
    );
    assert_eq!((summary.ingest.total_received, summary.ingest.total_dropped), (3, 7));
    assert_eq!(summary.ingest.recorded, 3);
    let bytes = std::fs::read(&recording).unwrap();
    let recorded = read_messages(&bytes).expect("the recording is a complete MCAP file");
    assert_eq!(recorded.len(), 3, "exactly the accepted messages are recorded");
    assert!(recorded.iter().all(|m| m.topic == key), "{recorded:?}");
    assert_eq!(summary.ingest.snapshot_digest.len(), 16);
    router.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn forged_sequence_numbers_far_ahead_do_not_cut_the_genuine_stream_off() {
    // The probe: one forged number far ahead made 1,344 of the next 1,500 genuine states
    // `too-old`. Forged ones now cost only themselves (`seq-jump`).
    let router = Router::start().await;
    let (cloud_stop, cloud) = start_cloud(CloudConfig::new(router.client.clone())).await;
    let sender = connect(&router.client).await.unwrap();
    let publisher = state_publisher(&sender, "risktwin/v1/site/veh-1/state".to_owned()).await;
    let epoch_ns = unix_ns();
    let genuine = 300u64;
    for seq in 0..genuine {
        if seq == 100 || seq == 200 {
            let forged = if seq == 100 { 5_000 } else { 1_000_000_000_000 };
            publisher.put(encode(&state("veh-1", forged, epoch_ns))).await.unwrap();
        }
        publisher.put(encode(&state("veh-1", seq, epoch_ns))).await.unwrap();
    }
    drop(publisher);
    sender.close().await.unwrap();
    cloud_stop.fire();
    let summary = timeout(STEP, cloud).await.unwrap().unwrap().unwrap();
    assert_eq!(summary.ingest.received["veh-1"], BTreeMap::from([("state".to_owned(), genuine)]));
    assert_eq!(summary.ingest.dropped, BTreeMap::from([("seq-jump".to_owned(), 2)]));
    assert_eq!(summary.ingest.total_presumed_lost, 0, "{:?}", summary.ingest.presumed_lost);
    router.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_processes_under_one_id_are_reported() {
    // Two sessions publish the same vehicle's states, each numbering from 0: the second one's are
    // refused as duplicates, and the summary says why.
    let router = Router::start().await;
    let (cloud_stop, cloud) = start_cloud(CloudConfig::new(router.client.clone())).await;
    let (site, id) = (SiteId::new("site").unwrap(), SourceId::new("veh-1").unwrap());
    let (first, second) = (connect(&router.client).await.unwrap(), connect(&router.client).await.unwrap());
    // The edges' own publishers: numbered, so each sample names its session.
    let delivery = Delivery::live(50.0, Duration::from_secs(1));
    let publishers =
        [&first, &second].map(|s| StreamPublisher::declare(s, &site, &id, EdgeStream::State, delivery).unwrap());
    for publisher in &publishers {
        let (_trigger, never) = shutdown::channel();
        assert!(publisher.wait_for_subscriber(STEP, never).await.unwrap(), "the cloud subscribes");
    }
    let epoch_ns = unix_ns();
    for seq in 0..20 {
        for publisher in &publishers {
            publisher.put(encode(&state("veh-1", seq, epoch_ns))).unwrap();
        }
    }
    for publisher in publishers {
        publisher.undeclare().unwrap();
    }
    first.close().await.unwrap();
    second.close().await.unwrap();
    cloud_stop.fire();
    let summary = timeout(STEP, cloud).await.unwrap().unwrap().unwrap();
    assert_eq!(summary.ingest.received["veh-1"]["state"], 20);
    assert_eq!(summary.ingest.dropped, BTreeMap::from([("duplicate".to_owned(), 20)]));
    let switches = summary.ingest.id_conflicts.get("veh-1").copied().unwrap_or(0);
    // Each session's puts may reach the cloud in one batch: at least one switch, whatever the mix.
    assert!(switches >= 1, "{:?}", summary.ingest.id_conflicts);
    router.stop().await;
}

#[test]
fn every_key_is_tagged_with_the_message_the_code_encodes() {
    use risktwin_common::telemetry::{ControlCommand, PolicyUpdate, RoadMap, ScenarioPush, ScenarioResult};
    use risktwin_protos::WireMessage;
    use risktwin_transport::keyexpr::{CloudToEdge, EDGE_MAP_MESSAGE, EdgeReport};
    assert_eq!(CloudToEdge::Scenario.message(), ScenarioPush::PROTO_NAME);
    assert_eq!(CloudToEdge::Policy.message(), PolicyUpdate::PROTO_NAME);
    assert_eq!(CloudToEdge::Control.message(), ControlCommand::PROTO_NAME);
    assert_eq!(CloudToEdge::Warning.message(), risktwin_common::telemetry::HazardWarning::PROTO_NAME);
    assert_eq!(EdgeReport::ScenarioResult.message(), ScenarioResult::PROTO_NAME);
    assert_eq!(EDGE_MAP_MESSAGE, RoadMap::PROTO_NAME);
    assert_eq!(protobuf(RoadMap::PROTO_NAME).to_string(), risktwin_protos::encoding_of(RoadMap::PROTO_NAME));
}
