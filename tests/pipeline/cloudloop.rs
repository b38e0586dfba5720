//! The cloud side of the loop as separate processes around a real router: the twin and risk
//! roles publish and record their outputs; a scenario and a policy pushed to a vehicle; the
//! library queryable answering a real Zenoh get. The test's own Zenoh session (a peer connected
//! to the router) subscribes, publishes bad pushes (garbage, untagged) and queries.

use crate::support::{Proc, cut_in_library, keys, run_json, runtime, session, start_router};
use prost::Message;
use risktwin_common::telemetry::RiskReport;
use risktwin_protos::foxglove::Grid;
use risktwin_protos::recording::read_messages;
use risktwin_protos::{decode, v1};
use serde_json::Value;
use std::time::{Duration, Instant};

const STEP: Duration = Duration::from_secs(60);

use crate::peer_python;

/// The JSON of a finished `risktwin …` run that must succeed.
#[test]
fn twin_and_risk_publish_and_record_grid_report_and_scene() {
    let (router, locator) = start_router();
    let dir = tempfile::tempdir().expect("a temporary directory");
    let recording = dir.path().join("twin.mcap");
    let rt = runtime();
    let test_session = rt.block_on(session(&locator));
    let (grids, reports) = rt.block_on(async {
        let grids = test_session.declare_subscriber("risktwin/v1/track/cloud/risk_field").await.expect("subscriber");
        let reports = test_session.declare_subscriber("risktwin/v1/track/cloud/risk_report").await.expect("subscriber");
        (grids, reports)
    });

    let path = recording.to_str().expect("a UTF-8 path");
    let mut cloud =
        Proc::spawn("cloud", &["cloud", "--roles", "ingest,twin,risk", "--record", path, "--connect", &locator]);
    cloud.wait_line(STEP, |l| l == "ready");
    // 3 s of a cut-in at 50 Hz: the risk role assesses at 2 Hz of twin time.
    let mut vehicle = Proc::spawn(
        "veh",
        &["edge", "vehicle", "--id", "veh-t", "--site", "track", "--connect", &locator, "--count", "150"],
    );

    let (grid, report) = rt.block_on(async {
        let grid = tokio::time::timeout(STEP, grids.recv_async()).await.expect("a grid within a minute").expect("open");
        let report =
            tokio::time::timeout(STEP, reports.recv_async()).await.expect("a report within a minute").expect("open");
        (grid, report)
    });
    let grid = Grid::decode(&*grid.payload().to_bytes()).expect("a foxglove.Grid");
    assert!(grid.column_count > 0 && grid.cell_stride == 4, "{} columns", grid.column_count);
    assert_eq!(grid.data.len() % (grid.row_stride as usize), 0);
    let cells: Vec<f32> = grid.data.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
    let max = cells.iter().copied().fold(f32::MIN, f32::max);
    assert!(max > 0.0 && max.is_finite(), "grid max {max}");
    let report: RiskReport = decode(&report.payload().to_bytes()).expect("a valid RiskReport");
    assert_eq!(report.ego_source, "veh-t");
    let t = &report.terms;
    for v in [t.score, t.ttc, t.dist, t.lane, t.jerk, t.collision] {
        assert!(v.is_finite() && (0.0..=1.0 + 1e-9).contains(&v.min(1.0)), "{t:?}");
    }
    assert!(report.min_distance_m >= 0.0 && !report.min_distance_m.is_nan());
    assert!(report.min_ttc_s.is_none_or(|s| s.is_finite() && s >= 0.0), "{:?}", report.min_ttc_s);

    let sent = vehicle.exit_json(STEP);
    cloud.wait_line(STEP, |l| l == "edge left: track/veh-t");
    cloud.terminate();
    let summary = cloud.exit_json(STEP);
    rt.block_on(async { test_session.close().await }).expect("the test session closes");
    router.terminate();

    assert_eq!(summary["total_dropped"], 0, "{summary}");
    assert_eq!(summary["received"]["veh-t"], sent["sent"], "{summary}");
    let twin = &summary["twin"];
    assert!(twin["risk_assessments"].as_u64().is_some_and(|n| n >= 2), "{twin}");
    assert!(twin["max_risk"].as_f64().is_some_and(|m| m > 0.0), "{twin}");
    assert_eq!(twin["vehicles"]["track"], 1, "{twin}");

    let bytes = std::fs::read(&recording).expect("the recording");
    let messages = read_messages(&bytes).expect("a valid MCAP file");
    let count = |topic: &str, schema: &str| {
        messages.iter().filter(|m| m.topic == topic && m.schema_name == schema).count() as u64
    };
    let assessments = twin["risk_assessments"].as_u64().expect("a count");
    assert_eq!(count("risktwin/v1/track/cloud/risk_field", "foxglove.Grid"), assessments);
    assert_eq!(count("risktwin/v1/track/cloud/risk_report", "risktwin.v1.RiskReport"), assessments);
    assert_eq!(count("risktwin/v1/track/cloud/scene", "foxglove.SceneUpdate"), twin["scenes"].as_u64().expect("n"));
    let edge_messages = messages.iter().filter(|m| m.topic.starts_with("risktwin/v1/track/veh-t/")).count() as u64;
    assert_eq!(Some(edge_messages), summary["total_received"].as_u64(), "every accepted message recorded");
    // Publish stamps of the edge messages are the edge's, not the cloud's receive times.
    assert!(
        messages
            .iter()
            .filter(|m| m.topic.ends_with("/state"))
            .all(|m| m.publish_time_ns <= m.log_time_ns + 1_000_000_000)
    );

    // The official Python reader decodes every message of the live recording.
    let python = peer_python::python(&["mcap==1.6.0", "mcap-protobuf-support==0.6.0"]);
    let script = r#"
import json, sys
from collections import Counter
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory
counts = Counter()
with open(sys.argv[1], "rb") as f:
    for schema, channel, message, proto in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
        counts[schema.name] += 1
print(json.dumps(counts))
"#;
    let out = std::process::Command::new(python).arg("-c").arg(script).arg(&recording).output().expect("python runs");
    assert!(out.status.success(), "python reader failed: {}", String::from_utf8_lossy(&out.stderr));
    let decoded: Value = serde_json::from_slice(&out.stdout).expect("JSON counts");
    let total: u64 = decoded.as_object().expect("counts").values().filter_map(Value::as_u64).sum();
    assert_eq!(total, messages.len() as u64, "python decoded {decoded}");
    assert_eq!(decoded["foxglove.Grid"].as_u64(), Some(assessments));
}

#[test]
fn a_pushed_scenario_runs_on_the_vehicle_and_bad_pushes_do_not_stop_it() {
    let (router, locator) = start_router();
    let dir = tempfile::tempdir().expect("a temporary directory");
    let (db, ranked) = cut_in_library(dir.path(), 6);
    let id = ranked[0]["id"].as_str().expect("a ranked id").to_owned();

    // 10× real time, so that a 15 s episode plays in 1.5 s; no cloud, so no waiting for one
    // and no acknowledgements (--no-ack).
    let (signing_key, verifying_key) = keys(dir.path(), "cloud");
    let mut vehicle = Proc::spawn(
        "veh",
        &[
            "edge",
            "vehicle",
            "--id",
            "veh-p",
            "--site",
            "track",
            "--connect",
            &locator,
            "--rate-hz",
            "500",
            "--wait-for-cloud-s",
            "0",
            "--no-ack",
            "--trust-key",
            &verifying_key,
        ],
    );
    vehicle.wait_line(STEP, |l| l == "edge veh-p: publishing");

    // Garbage on the vehicle's scenario key: counted, logged, the vehicle runs on.
    let rt = runtime();
    let test_session = rt.block_on(session(&locator));
    rt.block_on(async {
        let publisher = test_session.declare_publisher("risktwin/v1/track/veh-p/scenario").await.expect("a publisher");
        let deadline = Instant::now() + STEP;
        while !publisher.matching_status().await.expect("status").matching() {
            assert!(Instant::now() < deadline, "the vehicle never subscribed to its scenario key");
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        let tag = "application/protobuf;risktwin.v1.ScenarioPush";
        publisher.put(vec![0xff_u8, 0x01, 0x02]).encoding(tag).await.expect("put");
        // Untagged (or another schema version): refused by name before it is read.
        publisher.put(vec![0xff_u8, 0x01, 0x02]).await.expect("put");
    });
    vehicle.wait_line(STEP, |l| l.starts_with("edge: refused scenario push: malformed"));
    vehicle.wait_line(STEP, |l| l.starts_with("edge: refused scenario push: wrong-schema"));

    let pushed = run_json(&[
        "push",
        "scenario",
        "--db",
        &db,
        "--id",
        &id,
        "--to",
        "veh-p",
        "--site",
        "track",
        "--connect",
        &locator,
    ]);
    assert_eq!(pushed["spec_id"], id.as_str());
    assert_eq!(pushed["edge"], "veh-p");
    // The edge ran the episode to its end (at the library's step, so the figures are the
    // library's): a full outcome came back.
    let steps = pushed["metrics"]["steps"].as_u64().expect("steps");
    assert!(steps as f64 * risktwin_common::world::STEP_S > 2.0, "{pushed}");
    let score = pushed["risk"]["score"].as_f64().expect("a score");
    assert!((0.0..=1.0).contains(&score), "{pushed}");
    if pushed["metrics"]["collision"] == true {
        assert_eq!(pushed["risk"]["collision"], 1.0, "{pushed}");
    }

    // A policy update: accepted once, a repeat of its version refused.
    let weights = dir.path().join("w.safetensors");
    let mut rng = risktwin_common::rng::Rng::new(1);
    let net = risktwin_learn::PolicyNet::new(risktwin_learn::Algo::Ppo, &[16], &mut rng).expect("a policy");
    net.save(&weights).expect("weights written");
    let weights_bytes = std::fs::metadata(&weights).expect("the weights file").len();
    let w = weights.to_str().expect("a UTF-8 path");
    for _ in 0..2 {
        let policy = [
            "push",
            "policy",
            "--weights",
            w,
            "--policy-id",
            "ppo-1",
            "--version",
            "3",
            "--algo",
            "ppo",
            "--to",
            "veh-p",
            "--site",
            "track",
            "--signing-key",
            &signing_key,
            "--connect",
            &locator,
        ];
        assert_eq!(run_json(&policy)["delivered"], true);
    }
    vehicle.wait_line(STEP, |l| l.starts_with("edge: refused policy update: stale-version"));

    vehicle.terminate();
    let summary = vehicle.exit_json(STEP);
    rt.block_on(async { test_session.close().await }).expect("closes");
    router.terminate();
    let pushes = &summary["pushes"];
    assert_eq!(pushes["scenarios_accepted"], 1, "{summary}");
    assert_eq!(pushes["scenarios_refused"], serde_json::json!({"malformed": 1, "wrong-schema": 1}));
    assert_eq!(pushes["results"][0]["spec_id"], id.as_str());
    assert_eq!(
        pushes["policy"],
        serde_json::json!({"policy_id": "ppo-1", "version": 3, "algo": "ppo", "weights_bytes": weights_bytes})
    );
    assert_eq!(pushes["policies_refused"], serde_json::json!({"stale-version": 1}));
    assert!(summary["sent"]["state"].as_u64().is_some_and(|n| n > 100), "the vehicle kept publishing: {summary}");
}

#[test]
fn the_library_queryable_answers_a_zenoh_get() {
    let (router, locator) = start_router();
    let dir = tempfile::tempdir().expect("a temporary directory");
    let (db, ranked) = cut_in_library(dir.path(), 6);
    let mut cloud = Proc::spawn("cloud", &["cloud", "--roles", "library", "--db", &db, "--connect", &locator]);
    cloud.wait_line(STEP, |l| l == "ready");

    let rt = runtime();
    let test_session = rt.block_on(session(&locator));
    let get = |selector: &str| -> Vec<Result<Vec<u8>, String>> {
        rt.block_on(async {
            let replies = test_session.get(selector).await.expect("a get");
            let mut out = Vec::new();
            while let Ok(reply) = replies.recv_async().await {
                out.push(match reply.result() {
                    Ok(sample) => {
                        let encoding = sample.encoding().to_string();
                        assert_eq!(encoding, "application/protobuf;risktwin.v1.LibraryRanking", "the reply's tag");
                        Ok(sample.payload().to_bytes().to_vec())
                    }
                    Err(err) => Err(String::from_utf8_lossy(&err.payload().to_bytes()).into_owned()),
                });
            }
            out
        })
    };
    // A queryable declared by a peer reaches the router a moment after `ready`: ask until answered.
    let deadline = Instant::now() + STEP;
    let replies = loop {
        let replies = get("risktwin/v1/track/cloud/library/ranked?top=2;kind=cut-in");
        if !replies.is_empty() || Instant::now() > deadline {
            break replies;
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    assert_eq!(replies.len(), 1, "one answer");
    let bytes = replies[0].as_ref().expect("a ranking, not an error");
    let ranking = v1::LibraryRanking::decode(&**bytes).expect("a LibraryRanking");
    let ids: Vec<&str> = ranking.scenarios.iter().map(|s| s.id.as_str()).collect();
    let expected: Vec<&str> =
        ranked.as_array().expect("a list").iter().take(2).filter_map(|r| r["id"].as_str()).collect();
    assert_eq!(ids, expected, "the CLI's ranking, top 2");
    assert_eq!(ranking.scenarios[0].rank, 1);
    let score = ranking.scenarios[0].risk.as_ref().map(|r| r.score);
    assert_eq!(score, ranked[0]["risk"]["score"].as_f64());

    let refused = get("risktwin/v1/track/cloud/library/ranked?top=0");
    assert!(matches!(&refused[..], [Err(reason)] if reason.contains("top")), "{refused:?}");
    let again = get("risktwin/v1/track/cloud/library/ranked?top=1");
    assert!(matches!(&again[..], [Ok(_)]), "still serving after a refusal");

    rt.block_on(async { test_session.close().await }).expect("closes");
    cloud.terminate();
    let summary = cloud.exit_json(STEP);
    router.terminate();
    assert_eq!(summary["library"], serde_json::json!({"answered": 2, "refused": 1}), "{summary}");
}
