//! The cloud role against real Zenoh sessions in this process: a router on a free port, the
//! cloud, and a raw session that sends good records mixed with bad wire input.

use super::{CloudConfig, run};
use risktwin_transport::router::{RouterConfig, run as run_router};
use risktwin_transport::standin::StandIn;
use risktwin_transport::zenoh::qos::CongestionControl;
use risktwin_transport::{Mode, TransportConfig, connect, shutdown};
use std::collections::BTreeMap;
use std::time::Duration;
use tokio::sync::oneshot;
use tokio::time::timeout;

const STEP: Duration = Duration::from_secs(30);

fn record(source: &str, seq: u64) -> Vec<u8> {
    StandIn { source, seq, capture_time_ns: 1, publish_time_ns: 2 }.encode(100).unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_wire_input_is_counted_by_reason_and_the_worker_carries_on() {
    let (router_stop, router_shutdown) = shutdown::channel();
    let (port_tx, port_rx) = oneshot::channel();
    let router_config = RouterConfig { listen: vec!["tcp/127.0.0.1:0".into()], connect: vec![] };
    let router = tokio::spawn(async move {
        run_router(&router_config, router_shutdown, |locators| {
            let _ = port_tx.send(locators.to_vec());
        })
        .await
    });
    let locators = timeout(STEP, port_rx).await.unwrap().unwrap();
    assert!(locators.iter().all(|l| l.starts_with("tcp/127.0.0.1:") && !l.ends_with(":0")), "{locators:?}");
    let client = TransportConfig { mode: Mode::Client, connect: locators, ..TransportConfig::default() };

    let (cloud_stop, cloud_shutdown) = shutdown::channel();
    let (ready_tx, ready_rx) = oneshot::channel();
    let cloud_config = CloudConfig::new(client.clone());
    let cloud = tokio::spawn(async move {
        run(&cloud_config, cloud_shutdown, || {
            let _ = ready_tx.send(());
        })
        .await
    });
    timeout(STEP, ready_rx).await.unwrap().unwrap();

    let sender = connect(&client).await.unwrap();
    let key = "risktwin/v1/site/veh-1/state";
    let publisher = sender.declare_publisher(key).congestion_control(CongestionControl::Block).await.unwrap();
    let matched = async {
        let listener = publisher.matching_listener().await.unwrap();
        if !publisher.matching_status().await.unwrap().matching() {
            while !listener.recv_async().await.unwrap().matching() {}
        }
    };
    timeout(STEP, matched).await.unwrap();
    let wire: Vec<Vec<u8>> = vec![
        record("veh-1", 0),
        b"\x00garbage".to_vec(),
        record("veh-1", 1),
        record("veh-1", 1), // duplicate
        record("veh-1", 0), // reordered, late
        record("veh-9", 2), // another source than the key says
        [&b"XXXX"[..], &record("veh-1", 2)[4..]].concat(),
        record("veh-1", 2)[..60].to_vec(), // truncated
        record("veh-1", 2),
    ];
    for payload in wire {
        publisher.put(payload).await.unwrap();
    }
    drop(publisher);
    sender.close().await.unwrap();

    cloud_stop.fire();
    let summary = timeout(STEP, cloud).await.unwrap().unwrap().unwrap();
    assert_eq!(summary.ingest.received["veh-1"], BTreeMap::from([("state".to_owned(), 3)]));
    assert_eq!(
        summary.ingest.dropped,
        BTreeMap::from([
            ("too_short".to_owned(), 1),
            ("stale_seq".to_owned(), 2),
            ("source_mismatch".to_owned(), 1),
            ("bad_magic".to_owned(), 1),
            ("length_mismatch".to_owned(), 1),
        ])
    );
    router_stop.fire();
    timeout(STEP, router).await.unwrap().unwrap().unwrap();
}
