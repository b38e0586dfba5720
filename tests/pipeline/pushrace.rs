//! A push that starts before its edge, with a cloud ingest role on the same site: the ingest's
//! wildcard subscription (`risktwin/v1/<site>/*/*`) matches the edge's push key, so a pusher
//! going by matching status alone publishes at once, to nobody, and then waits in vain for the
//! result. The pusher must wait for the edge itself (its liveliness token) and deliver when it
//! comes up.

use crate::support::{Proc, cut_in_library, start_router};
use serde_json::Value;
use std::time::Duration;

const STEP: Duration = Duration::from_secs(60);

/// A router, a cloud ingest role on site `track` (ready) and a library of two cut-ins.
struct Site {
    router: Proc,
    locator: String,
    cloud: Proc,
    db: String,
    /// The top-ranked scenario.
    id: String,
    _dir: tempfile::TempDir,
}

fn site_with_ingest() -> Site {
    let (router, locator) = start_router();
    let dir = tempfile::tempdir().expect("a temporary directory");
    let (db, ranked) = cut_in_library(dir.path(), 2);
    let id = ranked[0]["id"].as_str().expect("a ranked id").to_owned();
    let mut cloud = Proc::spawn("cloud", &["cloud", "--roles", "ingest", "--site", "track", "--connect", &locator]);
    cloud.wait_line(STEP, |l| l == "ready");
    Site { router, locator, cloud, db, id, _dir: dir }
}

#[test]
fn a_push_waits_for_an_edge_that_comes_up_after_it_despite_the_ingest_subscriber() {
    let Site { router, locator, mut cloud, db, id, _dir } = site_with_ingest();

    // Long enough for the edge to start; short enough that a lost push fails the test quickly
    // (the episode plays at 10× real time, in about 1.5 s).
    let push_args = [
        "push",
        "scenario",
        "--db",
        &db,
        "--id",
        &id,
        "--to",
        "veh-late",
        "--site",
        "track",
        "--connect",
        &locator,
        "--wait-for-edge-s",
        "60",
        "--wait-for-result-s",
        "30",
    ];
    let mut push = Proc::spawn("push", &push_args);
    // The push is past the point where it decides to send; only now does the edge start.
    push.wait_line(STEP, |l| l.starts_with("push: waiting up to 60 s for edge track/veh-late"));
    let mut vehicle = Proc::spawn(
        "veh",
        &["edge", "vehicle", "--id", "veh-late", "--site", "track", "--connect", &locator, "--rate-hz", "500"],
    );

    let pushed: Value = push.exit_json(STEP);
    assert_eq!(pushed["spec_id"], id.as_str(), "{pushed}");
    assert_eq!(pushed["edge"], "veh-late", "{pushed}");
    assert!(pushed["metrics"]["steps"].as_u64().is_some_and(|n| n > 100), "a whole episode ran: {pushed}");

    vehicle.terminate();
    let summary = vehicle.exit_json(STEP);
    assert_eq!(summary["pushes"]["scenarios_accepted"], 1, "{summary}");
    assert_eq!(summary["pushes"]["results"][0]["spec_id"], id.as_str(), "{summary}");
    cloud.wait_line(STEP, |l| l == "edge left: track/veh-late");
    cloud.terminate();
    let ingested = cloud.exit_json(STEP);
    assert_eq!(ingested["total_dropped"], 0, "{ingested}");
    assert_eq!(ingested["received"]["veh-late"], summary["sent"], "{ingested}");
    router.terminate();
}

#[test]
fn a_push_to_an_edge_that_never_comes_up_fails_as_no_edge_despite_the_ingest_subscriber() {
    let Site { router, locator, mut cloud, db, id, _dir } = site_with_ingest();
    let mut push = Proc::spawn(
        "push",
        &[
            "push",
            "scenario",
            "--db",
            &db,
            "--id",
            &id,
            "--to",
            "veh-absent",
            "--site",
            "track",
            "--connect",
            &locator,
            "--wait-for-edge-s",
            "1",
        ],
    );
    // The ingest's subscription matches the push key, yet nothing is sent to nobody: the push
    // ends as "no edge", not as a missing result a minute later.
    let line = push.wait_line(STEP, |l| l.starts_with("error:"));
    assert!(line.contains("edge veh-absent was not up") && line.contains("within 1 s"), "{line}");
    let (status, stdout) = push.wait_exit(STEP);
    assert_eq!(status.code(), Some(1), "a runtime failure: {stdout}");
    assert!(stdout.is_empty(), "{stdout}");
    cloud.terminate();
    cloud.exit_json(STEP);
    router.terminate();
}
