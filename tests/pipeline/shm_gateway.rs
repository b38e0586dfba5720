//! A vehicle's sensor producer and its edge gateway as separate processes on one host: samples
//! cross iceoryx2 shared memory zero-copy, the gateway forwards them through a real router to a
//! cloud, and every message the producer sent arrives — whichever process starts first, and
//! also when both are stopped by SIGTERM mid-run.
//!
//! Vehicle ids carry the test process's pid, so concurrent runs never share an iceoryx2 service.

use crate::support::{Proc, start_router};
use serde_json::{Value, json};
use std::time::Duration;

const STEP: Duration = Duration::from_secs(60);

/// Fast (4× real time) with a clock the cloud has to estimate.
const PRODUCER_ARGS: [&str; 6] = ["--rate-hz", "200", "--clock-offset-ns", "5000000", "--clock-jitter-ns", "100000"];

fn vehicle_id(tag: &str) -> String {
    format!("shm-{tag}-{}", std::process::id())
}

fn start_cloud(router: &str) -> Proc {
    let mut cloud = Proc::spawn("cloud", &["cloud", "--roles", "ingest", "--connect", router]);
    cloud.wait_line(STEP, |l| l == "ready");
    cloud
}

fn start_gateway(id: &str, router: &str) -> Proc {
    Proc::spawn("gateway", &["edge", "gateway", "--id", id, "--site", "track", "--seed", "3", "--connect", router])
}

fn start_sensor(id: &str, extra: &[&str]) -> Proc {
    let vehicle = ["edge", "sensor", "--id", id, "--site", "track", "--seed", "3"];
    Proc::spawn("sensor", &[&vehicle[..], &PRODUCER_ARGS, extra].concat())
}

/// Checks the gateway forwarded what the sensor sent, then stops the cloud once the vehicle
/// left and checks that it received exactly that, with no drop; returns the cloud's summary.
fn check_delivery(id: &str, sent: &Value, forwarded: &Value, mut cloud: Proc) -> Value {
    assert_eq!(sent["source"], id, "{sent}");
    assert_eq!(forwarded["forwarded"], sent["sent"], "gateway: {forwarded}\nsensor: {sent}");
    assert_eq!(forwarded["rejected"], json!({"state": 0, "can": 0, "perception": 0}));
    // The gateway's own account: every forwarded message acknowledged by the cloud.
    assert_eq!(forwarded["acknowledged"], sent["sent"], "gateway: {forwarded}");
    assert_eq!(forwarded["undelivered"], json!({"state": 0, "can": 0, "perception": 0}), "{forwarded}");
    let left = format!("edge left: track/{id}");
    cloud.wait_line(STEP, |l| l == left);
    cloud.terminate();
    let summary = cloud.exit_json(STEP);
    assert_eq!(summary["total_dropped"], 0, "drops: {}", summary["dropped"]);
    assert_eq!(summary["late_dropped"], 0, "{summary}");
    let streams = sent["sent"].as_object().expect("sent per stream");
    for (stream, n) in streams {
        assert_eq!(summary["received"][id][stream], *n, "{stream}: cloud {summary}");
    }
    let joined = summary["liveliness"]["joined"].as_array().expect("liveliness");
    let name = format!("track/{id}");
    assert!(joined.iter().any(|v| v.as_str() == Some(name.as_str())), "{joined:?}");
    summary
}

#[test]
fn sensor_through_gateway_to_cloud_loses_nothing() {
    let (mut router, locator) = start_router();
    let cloud = start_cloud(&locator);
    let id = vehicle_id("fwd");
    let mut gateway = start_gateway(&id, &locator);
    // Started at once: the producer's handshake, not the test, waits for the gateway's subscribers.
    let mut sensor = start_sensor(&id, &["--count", "40"]);

    let sent = sensor.exit_json(STEP);
    // 40 steps: 40 states, 2 CAN frames every tick (160), perception every 5th step (8).
    assert_eq!(sent["sent"], json!({"state": 40, "can": 160, "perception": 8}), "{sent}");
    let forwarded = gateway.exit_json(STEP);
    assert_eq!(forwarded["end_of_stream"], true, "the gateway stopped at the producer's end");
    let summary = check_delivery(&id, &sent, &forwarded, cloud);
    assert_eq!(summary["total_received"], 208, "{summary}");

    router.terminate();
    let (status, _) = router.wait_exit(STEP);
    assert_eq!(status.code(), Some(0));
}

#[test]
fn a_gateway_started_after_the_sensor_still_gets_everything() {
    let (_router, locator) = start_router();
    let cloud = start_cloud(&locator);
    let id = vehicle_id("late");
    let mut sensor = start_sensor(&id, &["--count", "30"]);
    sensor.wait_line(STEP, |l| l == format!("sensor {id}: waiting for the gateway"));
    let mut gateway = start_gateway(&id, &locator);

    let sent = sensor.exit_json(STEP);
    assert_eq!(sent["sent"], json!({"state": 30, "can": 120, "perception": 6}), "{sent}");
    let forwarded = gateway.exit_json(STEP);
    assert_eq!(forwarded["end_of_stream"], true);
    check_delivery(&id, &sent, &forwarded, cloud);
}

#[test]
fn sigterm_to_sensor_and_gateway_stops_both_cleanly_losing_nothing() {
    let (_router, locator) = start_router();
    let mut cloud = start_cloud(&locator);
    let id = vehicle_id("term");
    let mut gateway = start_gateway(&id, &locator);
    let mut sensor = start_sensor(&id, &[]);
    sensor.wait_line(STEP, |l| l == format!("sensor {id}: publishing"));
    // Something has crossed both hops before the signals.
    cloud.wait_line(STEP, |l| l == format!("edge joined: track/{id}"));
    // As a terminal's Ctrl-C reaches both: the sensor ends its stream, the gateway drains it.
    sensor.terminate();
    gateway.terminate();

    let sent = sensor.exit_json(STEP);
    let states = sent["sent"]["state"].as_u64().expect("state count");
    assert!(states > 0, "{sent}");
    let forwarded = gateway.exit_json(STEP);
    assert_eq!(forwarded["end_of_stream"], true, "the gateway waited for the producer's end: {forwarded}");
    check_delivery(&id, &sent, &forwarded, cloud);
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

#[test]
fn a_gateway_without_a_cloud_reports_everything_undelivered_and_fails() {
    let (_router, locator) = start_router();
    let id = vehicle_id("nocloud");
    let mut gateway =
        Proc::spawn("gateway", &["edge", "gateway", "--id", &id, "--connect", &locator, "--wait-for-cloud-s", "0"]);
    let mut sensor = start_sensor(&id, &["--count", "10"]);
    let sent = sensor.exit_json(STEP);
    let (status, stdout) = gateway.wait_exit(STEP);
    assert_eq!(status.code(), Some(1), "undelivered messages fail the gateway: {stdout}");
    let summary: Value = serde_json::from_str(&stdout).expect("the summary is printed before the error");
    assert_eq!(summary["forwarded"], sent["sent"], "{summary}");
    assert_eq!(summary["undelivered"], sent["sent"], "nothing acknowledged: {summary}");
    assert_eq!(summary["cloud"]["seen"], false, "{summary}");
    let error = gateway.wait_line(STEP, |l| l.starts_with("error: edge "));
    assert!(error.contains("no cloud seen"), "{error}");
}
