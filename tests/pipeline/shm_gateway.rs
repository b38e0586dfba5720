//! A vehicle's sensor producer and its edge gateway as separate processes on one host: samples
//! cross iceoryx2 shared memory zero-copy, the gateway forwards them through a real router to a
//! cloud, and every message the producer sent arrives.
//!
//! Vehicle ids carry the test process's pid, so concurrent runs never share an iceoryx2 service.

use crate::support::{Proc, start_router};
use serde_json::{Value, json};
use std::time::Duration;

const STEP: Duration = Duration::from_secs(60);

fn vehicle_id(tag: &str) -> String {
    format!("shm-{tag}-{}", std::process::id())
}

fn start_cloud(router: &str) -> Proc {
    let mut cloud = Proc::spawn("cloud", &["cloud", "--roles", "ingest", "--connect", router]);
    cloud.wait_line(STEP, |l| l == "ready");
    cloud
}

#[test]
fn sensor_through_gateway_to_cloud_loses_nothing() {
    let (mut router, locator) = start_router();
    let mut cloud = start_cloud(&locator);
    let id = vehicle_id("fwd");
    let vehicle = ["--id", &id, "--site", "track", "--seed", "3"];
    let mut gateway = Proc::spawn("gateway", &[&["edge", "gateway", "--connect", &locator][..], &vehicle].concat());
    // Started at once: the producer's handshake, not the test, waits for the gateway's subscribers.
    let producer_args =
        ["--rate-hz", "200", "--count", "40", "--clock-offset-ns", "5000000", "--clock-jitter-ns", "100000"];
    let mut sensor = Proc::spawn("sensor", &[&["edge", "sensor"][..], &vehicle, &producer_args].concat());

    let sent = sensor.exit_json(STEP);
    // 40 steps: 40 states, 2 CAN frames every tick (160), perception every 5th step (8).
    assert_eq!(sent["sent"], json!({"state": 40, "can": 160, "perception": 8}), "{sent}");
    assert_eq!(sent["source"], id.as_str());
    let forwarded = gateway.exit_json(STEP);
    assert_eq!(forwarded["forwarded"], sent["sent"], "gateway: {forwarded}");
    assert_eq!(forwarded["rejected"], json!({"state": 0, "can": 0, "perception": 0}));
    assert_eq!(forwarded["end_of_stream"], true, "the gateway stopped at the producer's end");

    let left = format!("edge left: track/{id}");
    cloud.wait_line(STEP, |l| l == left);
    cloud.terminate();
    let summary = cloud.exit_json(STEP);
    assert_eq!(summary["total_dropped"], 0, "drops: {}", summary["dropped"]);
    let streams = sent["sent"].as_object().expect("sent per stream");
    for (stream, n) in streams {
        assert_eq!(summary["received"][id.as_str()][stream], *n, "{stream}: cloud {summary}");
    }
    assert_eq!(summary["total_received"], 208, "{summary}");
    let joined = summary["liveliness"]["joined"].as_array().expect("liveliness");
    assert!(joined.iter().any(|v| *v == Value::from(format!("track/{id}"))), "{joined:?}");

    router.terminate();
    let (status, _) = router.wait_exit(STEP);
    assert_eq!(status.code(), Some(0));
}

#[test]
fn a_sensor_without_gateway_fails_clearly_and_publishes_nothing() {
    let id = vehicle_id("alone");
    let mut sensor =
        Proc::spawn("sensor", &["edge", "sensor", "--id", &id, "--count", "5", "--wait-for-cloud-s", "0.3"]);
    let line = sensor.wait_line(STEP, |l| l.contains("no gateway subscribed"));
    assert!(line.contains(&format!("risktwin/{id}/")), "{line}");
    let (status, stdout) = sensor.wait_exit(STEP);
    assert_ne!(status.code(), Some(0), "stdout: {stdout}");
    assert!(stdout.is_empty(), "{stdout}");
}

#[test]
fn sigterm_stops_an_idle_gateway_cleanly() {
    let (_router, locator) = start_router();
    let id = vehicle_id("idle");
    let mut gateway =
        Proc::spawn("gateway", &["edge", "gateway", "--id", &id, "--connect", &locator, "--wait-for-cloud-s", "0"]);
    gateway.wait_line(STEP, |l| l == format!("gateway {id}: ready"));
    gateway.terminate();
    let summary = gateway.exit_json(STEP);
    assert_eq!(summary["forwarded"], json!({"state": 0, "can": 0, "perception": 0}));
    assert_eq!(summary["end_of_stream"], false);
}
