//! Delivery acknowledgements end to end (docs/keyexpr.md, "Delivery acknowledgements"): an edge
//! whose messages the cloud took reports them acknowledged and exits 0; an edge whose cloud is
//! killed mid-run reports what no cloud accounted for as undelivered and exits 1. And the
//! maximum payload size: an oversized sample from a raw Zenoh publisher on a vehicle's key is
//! counted `too-large` while the vehicle's own stream goes on untouched.

use crate::support::{Proc, runtime, session, start_router};
use risktwin_transport::protobuf;
use risktwin_transport::zenoh::qos::CongestionControl;
use serde_json::Value;
use std::time::Duration;

const STEP: Duration = Duration::from_secs(60);

fn cloud(locator: &str) -> Proc {
    let mut cloud = Proc::spawn("cloud", &["cloud", "--roles", "ingest", "--mode", "client", "--connect", locator]);
    cloud.wait_line(STEP, |l| l == "ready");
    cloud
}

fn vehicle(id: &str, locator: &str, extra: &[&str]) -> Proc {
    let mut args = vec!["edge", "vehicle", "--id", id, "--site", "track", "--mode", "client", "--connect", locator];
    args.extend(extra);
    Proc::spawn(id, &args)
}

/// Per stream of an edge's summary: (sent, acknowledged, lost, undelivered).
fn rows(edge: &Value) -> Vec<(String, [u64; 4])> {
    let sent = edge["sent"].as_object().expect("sent per stream");
    let count = |field: &str, stream: &str| {
        edge[field][stream].as_u64().unwrap_or_else(|| panic!("{field}.{stream} in the edge summary: {edge}"))
    };
    sent.keys()
        .map(|s| (s.clone(), [count("sent", s), count("acknowledged", s), count("lost", s), count("undelivered", s)]))
        .collect()
}

#[test]
fn a_run_the_cloud_took_in_full_is_acknowledged_in_full() {
    let (router, locator) = start_router();
    let mut cloud = cloud(&locator);
    let mut edge = vehicle("veh-a", &locator, &["--count", "150", "--rate-hz", "100"]);
    let summary = edge.exit_json(STEP);
    for (stream, [sent, acknowledged, lost, undelivered]) in rows(&summary) {
        assert!(sent > 0, "{stream}: {summary}");
        assert_eq!((acknowledged, lost, undelivered), (sent, 0, 0), "{stream}: {summary}");
    }
    assert_eq!(summary["cloud"]["seen"], true, "{summary}");
    assert_eq!(summary["cloud"]["acknowledged_by"], 1, "{summary}");
    assert_eq!(summary["cloud"]["gone_s"], 0.0, "{summary}");
    cloud.terminate();
    let ingest = cloud.exit_json(STEP);
    assert_eq!(ingest["received"]["veh-a"], summary["sent"], "{ingest}");
    router.terminate();
}

#[test]
fn an_edge_whose_cloud_is_killed_reports_what_was_not_delivered_and_exits_1() {
    let (router, locator) = start_router();
    let mut cloud = cloud(&locator);
    let mut edge = vehicle("veh-k", &locator, &[]);
    edge.wait_line(STEP, |l| l == "edge veh-k: publishing");
    // Acknowledged for a while (the cloud acknowledges every 500 ms), then the cloud dies.
    std::thread::sleep(Duration::from_millis(1500));
    cloud.kill();
    cloud.wait_exit(STEP);
    edge.wait_line(STEP, |l| l.contains("cloud gone"));
    std::thread::sleep(Duration::from_millis(1000));
    edge.terminate();
    let (status, stdout) = edge.wait_exit(STEP);
    let stderr = edge.drain_stderr();
    assert_eq!(status.code(), Some(1), "undelivered messages fail the run:\n{stdout}\n{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    let error = stderr.lines().find(|l| l.starts_with("error: edge veh-k: ")).unwrap_or_else(|| panic!("{stderr}"));
    assert!(error.contains("messages undelivered") && error.contains("the cloud was gone for"), "{error}");
    let summary: Value = serde_json::from_str(&stdout).unwrap_or_else(|e| panic!("{e}: {stdout}"));
    for (stream, [sent, acknowledged, lost, undelivered]) in rows(&summary) {
        assert_eq!(acknowledged + lost + undelivered, sent, "{stream}: {summary}");
        assert!(acknowledged > 0, "{stream}: acknowledged before the kill: {summary}");
        assert!(undelivered > 0, "{stream}: sent after the kill: {summary}");
    }
    assert_eq!(summary["cloud"]["alive_at_exit"], false, "{summary}");
    assert!(summary["cloud"]["gone_s"].as_f64().is_some_and(|s| s >= 0.5), "{summary}");
    router.terminate();
}

#[test]
fn an_oversized_sample_is_counted_too_large_and_the_genuine_stream_is_unharmed() {
    let (router, locator) = start_router();
    let mut cloud = cloud(&locator);
    let mut edge = vehicle("veh-o", &locator, &["--count", "200", "--rate-hz", "100"]);
    edge.wait_line(STEP, |l| l == "edge veh-o: publishing");
    // A raw publisher on the vehicle's state key, tagged as a state: 64 KiB + 1, and 100 MB
    // (below Zenoh's bound, `risktwin_transport::session::MAX_MESSAGE_BYTES`).
    let sizes = [64 * 1024 + 1, 100_000_000];
    let rt = runtime();
    // Kept open until the cloud has printed its summary: the puts return once queued.
    let session = rt.block_on(async {
        let session = session(&locator).await;
        let publisher = session
            .declare_publisher("risktwin/v1/track/veh-o/state")
            .encoding(protobuf("risktwin.v1.VehicleState"))
            .congestion_control(CongestionControl::Block)
            .await
            .expect("a raw publisher");
        for size in sizes {
            publisher.put(vec![0x5a_u8; size]).await.expect("the put is queued");
        }
        session
    });
    cloud.wait_line(STEP, |l| l.contains("veh-o/state") && l.contains("counted too-large"));
    let summary = edge.exit_json(STEP);
    cloud.terminate();
    let ingest = cloud.exit_json(STEP);
    assert_eq!(ingest["dropped"]["too-large"], sizes.len(), "{ingest}");
    assert_eq!(ingest["total_dropped"], sizes.len(), "nothing else dropped: {ingest}");
    assert_eq!(ingest["received"]["veh-o"], summary["sent"], "the vehicle's own stream is whole: {ingest}");
    assert_eq!(summary["acknowledged"], summary["sent"], "{summary}");
    rt.block_on(async { session.close().await }).expect("the session closes");
    router.terminate();
}
