//! N vehicles + M RSUs + one cloud around one router.

use crate::support::{Proc, start_router};
use risktwin_align::IngestConfig;
use risktwin_cloud::ingest::{IngestWorker, SnapshotDigest};
use risktwin_protos::recording::read_messages;
use risktwin_transport::EdgeStream;
use serde_json::Value;
use std::time::Duration;

const STEP: Duration = Duration::from_secs(60);

fn edge(kind: &str, id: &str, router: &str, extra: &[&str]) -> Proc {
    let mut args = vec!["edge", kind, "--id", id, "--site", "track", "--connect", router];
    args.extend_from_slice(extra);
    Proc::spawn(id, &args)
}

fn start_cloud(router: &str, extra: &[&str]) -> Proc {
    let mut args = vec!["cloud", "--roles", "ingest", "--connect", router];
    args.extend_from_slice(extra);
    let mut cloud = Proc::spawn("cloud", &args);
    cloud.wait_line(STEP, |l| l == "ready");
    cloud
}

/// Waits for the cloud to see each edge leave, SIGTERMs it and returns its summary.
fn stop_cloud(mut cloud: Proc, ids: &[&str]) -> Value {
    for id in ids {
        let left = format!("edge left: track/{id}");
        cloud.wait_line(STEP, |l| l == left);
    }
    cloud.terminate();
    cloud.exit_json(STEP)
}

/// Every stream of every edge: the cloud received exactly what the edge sent, nothing dropped.
fn assert_all_accounted(sent: &[Value], summary: &Value) {
    assert_eq!(summary["total_dropped"], 0, "drops: {}", summary["dropped"]);
    let mut total_sent = 0;
    for edge in sent {
        let source = edge["source"].as_str().expect("source in the edge summary");
        let streams = edge["sent"].as_object().expect("sent per stream");
        assert!(!streams.is_empty());
        for (stream, n) in streams {
            let n = n.as_u64().expect("a count");
            assert!(n > 0, "{source} sent nothing on {stream}");
            assert_eq!(
                summary["received"][source][stream].as_u64(),
                Some(n),
                "{source}/{stream}: sent {n}, cloud: {summary}"
            );
            total_sent += n;
        }
        let name = format!("track/{source}");
        for set in ["joined", "left"] {
            let seen = summary["liveliness"][set].as_array().expect("liveliness sets");
            assert!(seen.iter().any(|v| v == name.as_str()), "{name} not in liveliness {set}: {seen:?}");
        }
    }
    assert_eq!(summary["total_received"].as_u64(), Some(total_sent));
    assert_eq!(summary["snapshot_digest"].as_str().map(str::len), Some(16), "{summary}");
}

#[test]
fn vehicles_and_rsu_through_a_router_lose_nothing() {
    let (mut router, locator) = start_router();
    let dir = tempfile::tempdir().expect("a temporary directory");
    let recording = dir.path().join("live.mcap");
    let cloud = start_cloud(&locator, &["--record", recording.to_str().expect("a UTF-8 path")]);
    let vehicles: Vec<String> = (0..3).map(|i| format!("veh-{i}")).collect();
    let mut edges: Vec<Proc> = vehicles
        .iter()
        .enumerate()
        .map(|(i, id)| {
            let offset = format!("{}", (i as i64 - 1) * 5_000_000);
            edge(
                "vehicle",
                id,
                &locator,
                &[
                    "--rate-hz",
                    "200",
                    "--count",
                    "40",
                    "--clock-offset-ns",
                    &offset,
                    "--clock-drift-ppm",
                    "50",
                    "--clock-jitter-ns",
                    "100000",
                    "--seed",
                    &i.to_string(),
                ],
            )
        })
        .collect();
    edges.push(edge("rsu", "rsu-0", &locator, &["--rate-hz", "50", "--count", "30"]));

    let sent: Vec<Value> = edges.iter_mut().map(|e| e.exit_json(STEP)).collect();
    for (summary, id) in sent.iter().zip(vehicles.iter()) {
        // 40 steps: 40 states, 2 CAN frames every 10 ms (160), perception every 5th step (8).
        assert_eq!(summary["sent"], serde_json::json!({"state": 40, "can": 160, "perception": 8}), "{id}");
    }
    assert_eq!(sent[3]["sent"], serde_json::json!({"rsu": 30, "signal": 30}));

    let ids: Vec<&str> = sent.iter().map(|s| s["source"].as_str().expect("source")).collect();
    let summary = stop_cloud(cloud, &ids);
    assert_all_accounted(&sent, &summary);
    // 0.8 s of data from four edges: the aligner emitted twin snapshots.
    assert!(summary["snapshots"].as_u64().is_some_and(|n| n > 0), "no snapshots: {summary}");

    // The recording is a complete MCAP file holding exactly the accepted messages.
    let bytes = std::fs::read(&recording).expect("the cloud wrote its recording");
    let recorded = read_messages(&bytes).expect("a valid MCAP recording");
    assert_eq!(Some(recorded.len() as u64), summary["total_received"].as_u64());
    assert_eq!(summary["recorded"], summary["total_received"]);

    // Replayed offline through a fresh worker at the recorded receive times, the recording
    // yields the very snapshots the live cloud emitted.
    let mut replay: IngestWorker<std::io::Cursor<Vec<u8>>> = IngestWorker::new(IngestConfig::default(), None);
    let mut digest = SnapshotDigest::default();
    for m in &recorded {
        let mut parts = m.topic.rsplit('/');
        let stream = parts.next().and_then(EdgeStream::from_chunk).expect("a known stream");
        let source = parts.next().expect("a source segment");
        let receive_ns = i64::try_from(m.log_time_ns).expect("a log time in range");
        replay.handle(source, stream, &m.topic, &m.data, receive_ns, |s| digest.add(s)).expect("no recorder, no I/O");
    }
    assert_eq!(replay.stats().accepted, recorded.len() as u64, "{:?}", replay.stats());
    assert_eq!(summary["snapshots"].as_u64(), Some(digest.count()));
    assert_eq!(summary["snapshot_digest"].as_str(), Some(digest.hex().as_str()), "replay digest differs from live");

    router.terminate();
    let (status, _) = router.wait_exit(STEP);
    assert_eq!(status.code(), Some(0), "the router stops cleanly on SIGTERM");
}

#[test]
fn sigterm_stops_an_edge_cleanly_and_what_it_sent_arrives() {
    let (_router, locator) = start_router();
    let mut cloud = start_cloud(&locator, &[]);
    // No --count, no --duration: only the signal stops it.
    let mut vehicle = edge("vehicle", "veh-sig", &locator, &["--rate-hz", "100"]);
    cloud.wait_line(STEP, |l| l == "edge joined: track/veh-sig");
    vehicle.wait_line(STEP, |l| l == "edge veh-sig: publishing");
    vehicle.terminate();
    let sent = vehicle.exit_json(STEP);
    let summary = stop_cloud(cloud, &["veh-sig"]);
    assert_all_accounted(&[sent], &summary);
}

#[test]
fn bad_ids_and_endpoints_are_refused_with_exit_2() {
    for args in [
        &["edge", "vehicle", "--id", "a/b"][..],
        &["edge", "vehicle", "--id", "cloud"],
        &["edge", "rsu", "--id", "r", "--site", "*"],
        &["edge", "vehicle", "--id", "v", "--connect", "not-a-locator"],
        &["edge", "vehicle", "--id", "v", "--cache-s", "nan"],
        &["edge", "vehicle", "--id", "v", "--driver", "missing.onnx"],
        &["edge", "vehicle", "--id", "v", "--driver", "replay"],
        &["edge", "rsu", "--id", "r", "--driver", "idm"],
        &["cloud", "--roles", "ingest,nonsense"],
        &["cloud", "--roles", "ingest", "--fidelity-report", "rep"],
    ] {
        let mut p = Proc::spawn("bad", args);
        let (status, stdout) = p.wait_exit(STEP);
        assert_eq!(status.code(), Some(2), "{args:?}: stdout {stdout}");
        assert!(stdout.is_empty(), "{args:?} printed on stdout: {stdout}");
    }
}

/// Replay over the network: a live run's recording, republished unpaced by `edge replay` with
/// the recorded receive times attached, into a cloud in `--replay-time` mode (alone, or a
/// sharded worker and its union), yields the live cloud's snapshots (same count and digest) and
/// counts.
#[test]
fn edge_replay_into_a_second_cloud_rebuilds_the_live_snapshots() {
    let (router, locator) = start_router();
    let dir = tempfile::tempdir().expect("a temporary directory");
    let recording = dir.path().join("live.mcap");
    let cloud = start_cloud(&locator, &["--record", recording.to_str().expect("a UTF-8 path")]);
    let mut edges = vec![
        edge("vehicle", "veh-r", &locator, &["--rate-hz", "200", "--count", "120", "--clock-offset-ns", "7000000"]),
        edge("vehicle", "veh-s", &locator, &["--rate-hz", "200", "--count", "120", "--clock-drift-ppm", "80"]),
        edge("rsu", "rsu-r", &locator, &["--rate-hz", "50", "--count", "30"]),
    ];
    for e in &mut edges {
        e.exit_json(STEP);
    }
    let live = stop_cloud(cloud, &["veh-r", "veh-s", "rsu-r"]);
    assert_eq!(live["total_dropped"], 0, "{live}");
    assert!(live["snapshots"].as_u64().is_some_and(|n| n > 4), "{live}");

    // The recording streamed unpaced into a fresh cloud that ingests at the attached times.
    let mut replayed_cloud = start_cloud(&locator, &["--replay-time"]);
    let path = recording.to_str().expect("a UTF-8 path");
    let mut replay = Proc::spawn("replay", &["edge", "replay", path, "--speed", "0", "--connect", &locator]);
    let published = replay.exit_json(STEP);
    assert_eq!(published["published"], live["total_received"], "every recorded message is republished");
    assert_eq!(published["skipped"], 0);
    assert_eq!(published["unnumbered"], 0);
    // The replay's own account, per source: everything acknowledged by the replaying cloud.
    let delivery = published["delivery"].as_object().expect("delivery per source");
    assert_eq!(delivery.len(), 3, "{published}");
    for source in ["veh-r", "veh-s", "rsu-r"] {
        let d = &delivery[&format!("track/{source}")];
        assert_eq!(d["acknowledged"], live["received"][source], "{source}: {d}");
        assert!(d["undelivered"].as_object().expect("per stream").values().all(|n| n == 0), "{source}: {d}");
    }
    replayed_cloud.terminate();
    let replayed = replayed_cloud.exit_json(STEP);
    assert_eq!(replayed["total_dropped"], 0, "{replayed}");
    assert_eq!(replayed["received"], live["received"], "the replayed cloud sees what the live one accepted");
    assert_eq!(replayed["snapshots"], live["snapshots"], "live {live}\nreplayed {replayed}");
    assert_eq!(replayed["snapshot_digest"], live["snapshot_digest"], "replay rebuilds the live snapshots");

    // The same through a sharded worker and a union: the worker forwards each message with its
    // attachment, and the union ingests at the recorded times too.
    let client = ["--connect", locator.as_str()];
    let mut union = Proc::spawn(
        "union",
        &[&["cloud", "--roles", "union,twin", "--site", "track", "--replay-time"][..], &client].concat(),
    );
    union.wait_line(STEP, |l| l == "ready");
    let mut worker = Proc::spawn(
        "worker",
        &[&["cloud", "--roles", "ingest", "--shard", "--site", "track", "--replay-time"][..], &client].concat(),
    );
    worker.wait_line(STEP, |l| l == "ready");
    let mut replay = Proc::spawn("replay", &["edge", "replay", path, "--speed", "0", "--connect", &locator]);
    replay.exit_json(STEP);
    worker.terminate();
    worker.exit_json(STEP);
    union.terminate();
    let unioned = union.exit_json(STEP);
    assert_eq!(unioned["total_dropped"], 0, "{unioned}");
    assert_eq!(unioned["received"], live["received"], "{unioned}");
    assert_eq!(unioned["snapshot_digest"], live["snapshot_digest"], "live {live}\nunion {unioned}");

    // Without --replay-time the cloud stamps the replay with its own clock: the counts match
    // but the snapshots are not the live ones (what the attachment is for).
    let mut own_clock = start_cloud(&locator, &[]);
    let mut replay = Proc::spawn("replay", &["edge", "replay", path, "--speed", "0", "--connect", &locator]);
    replay.exit_json(STEP);
    own_clock.terminate();
    let own = own_clock.exit_json(STEP);
    assert_eq!(own["received"], live["received"]);
    assert_ne!(own["snapshot_digest"], live["snapshot_digest"], "own-clock replay: {own}");
    router.terminate();
}
