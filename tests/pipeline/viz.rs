//! The viz role as a Foxglove client sees it: a cloud with `ingest,twin,risk,viz` and two
//! vehicles around a real router; a Node client on the official `@foxglove/ws-protocol` package
//! (`tests/peers/foxglove_client.js`) connects, subscribes to the scene, the risk grid and
//! report, the road and both vehicles' states, and decodes them with the schemas the server
//! advertises. What it decoded must be what the edges sent, under the recording's topics and
//! schemas.

use crate::peer_node;
use crate::support::{Proc, start_router};
use risktwin_cloud::network::OUTPUT_SCHEMAS;
use risktwin_common::scenario::ScenarioKind;
use risktwin_protos::convert::foxglove::{FOXGLOVE_SCENE_UPDATE, ROAD_ENTITY_ID, WORLD_FRAME_ID};
use risktwin_transport::keyexpr::{CloudOutput, EdgeStream, SiteId, SourceId, cloud_output, edge_stream};
use serde_json::Value;
use std::collections::BTreeMap;
use std::time::Duration;

const STEP: Duration = Duration::from_secs(60);
/// The client's peers, pinned.
const PACKAGES: [&str; 3] = ["@foxglove/ws-protocol@0.8.0", "ws@8.23.0", "protobufjs@8.8.1"];
const SITE: &str = "viz";
const VEHICLES: [&str; 2] = ["veh-a", "veh-b"];

#[test]
fn a_foxglove_client_decodes_the_live_twin() {
    let mut node = peer_node::node(&PACKAGES);
    let site = SiteId::new(SITE).expect("a site id");
    let state_topic = |id: &str| edge_stream(&site, &SourceId::new(id).expect("an id"), EdgeStream::State);
    let output = |o| cloud_output(&site, o);
    let mut wanted: Vec<(String, u64)> = VEHICLES.iter().map(|id| (state_topic(id), 20)).collect();
    wanted.extend([
        (output(CloudOutput::Scene), 10),
        (output(CloudOutput::RiskField), 2),
        (output(CloudOutput::RiskReport), 2),
        (output(CloudOutput::Road), 1),
    ]);

    let (router, locator) = start_router();
    let mut cloud = Proc::spawn(
        "cloud",
        &["cloud", "--roles", "ingest,twin,risk,viz", "--viz-listen", "127.0.0.1:0", "--connect", &locator],
    );
    let url = cloud.wait_line(STEP, |l| l.starts_with("viz on ws://127.0.0.1:"))["viz on ".len()..].to_owned();
    cloud.wait_line(STEP, |l| l == "ready");
    node.arg(concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/peers/foxglove_client.js")).arg(&url).arg("60");
    node.args(wanted.iter().map(|(topic, n)| format!("{topic}={n}")));
    let mut client = Proc::spawn_command("foxglove client", node);
    client.wait_line(STEP, |l| l.contains(r#""connected":true"#));
    // The cloud copies nothing for the viz while no client is connected.
    cloud.wait_line(STEP, |l| l.starts_with("viz: a Foxglove client connected"));
    // 8 s of states at 50 Hz: the client has what it wants in about 1 s of them.
    let vehicles: Vec<Proc> = VEHICLES
        .iter()
        .map(|id| {
            let args = ["edge", "vehicle", "--id", id, "--site", SITE, "--connect", &locator, "--count", "400"];
            Proc::spawn(id, &args)
        })
        .collect();

    let (status, stdout) = client.wait_exit(STEP);
    let stderr = client.drain_stderr();
    assert!(status.success(), "the Foxglove client failed:\n{stdout}\n{stderr}");
    let lines: Vec<Value> =
        stdout.lines().map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}"))).collect();
    let (done, decoded) = lines.split_last().expect("the client's lines");
    assert_eq!(done["done"], true, "{done}");

    let mut sent = BTreeMap::new();
    for (id, mut vehicle) in VEHICLES.iter().zip(vehicles) {
        sent.insert(*id, vehicle.exit_json(STEP)["sent"].clone());
        cloud.wait_line(STEP, |l| l == format!("edge left: {SITE}/{id}"));
    }
    cloud.terminate();
    let summary = cloud.exit_json(STEP);
    router.terminate();

    // The schema of every topic, as the recording names it.
    let mut schemas: BTreeMap<String, &str> = OUTPUT_SCHEMAS.iter().map(|&(o, schema)| (output(o), schema)).collect();
    schemas.insert(output(CloudOutput::Road), FOXGLOVE_SCENE_UPDATE);
    for id in VEHICLES {
        schemas.insert(state_topic(id), EdgeStream::State.message());
    }
    let mut counts: BTreeMap<&str, u64> = BTreeMap::new();
    let mut last_seq: BTreeMap<&str, u64> = BTreeMap::new();
    let mut both_in_one_scene = false;
    for line in decoded {
        let topic = line["topic"].as_str().expect("a topic");
        *counts.entry(topic).or_default() += 1;
        assert_eq!(line["schema"].as_str(), schemas.get(topic).copied(), "{line}");
        assert_eq!((&line["encoding"], &line["schema_encoding"]), (&"protobuf".into(), &"protobuf".into()), "{line}");
        let message = &line["message"];
        if let Some(id) = VEHICLES.iter().find(|id| state_topic(id) == topic) {
            assert_eq!(message["header"]["source"], *id, "{line}");
            let seq: u64 = message["header"]["seq"].as_str().and_then(|s| s.parse().ok()).expect("a seq");
            assert!(last_seq.insert(topic, seq).is_none_or(|last| seq > last), "states in order: {line}");
        } else if topic == output(CloudOutput::Scene) {
            let entities = message["entities"].as_array().expect("entities");
            for e in entities {
                assert!(VEHICLES.iter().any(|id| e["id"] == *id), "a box of a vehicle: {line}");
                assert_eq!((e["cubes"].as_u64(), e["frame_id"].as_str()), (Some(1), Some(WORLD_FRAME_ID)), "{line}");
            }
            assert!(entities.len() <= VEHICLES.len(), "{line}");
            both_in_one_scene |= entities.len() == VEHICLES.len();
        } else if topic == output(CloudOutput::RiskField) {
            let n = |field: &str| message[field].as_u64().expect("a count");
            assert_eq!(message["fields"], serde_json::json!(["risk"]), "{line}");
            assert_eq!((n("cell_stride"), n("row_stride")), (4, 4 * n("column_count")), "{line}");
            assert!(n("column_count") > 0 && n("data_bytes") % n("row_stride") == 0, "whole rows: {line}");
            assert_eq!((n("cells"), n("finite_cells")), (n("data_bytes") / 4, n("data_bytes") / 4), "{line}");
            assert!(message["max_cell"].as_f64().is_some_and(|m| m > 0.0), "{line}");
        } else if topic == output(CloudOutput::RiskReport) {
            assert!(VEHICLES.iter().any(|id| message["egoSource"] == *id), "{line}");
        } else if topic == output(CloudOutput::Road) {
            // The road the risk role runs on (`--road cut-in`), line for line.
            let road = risktwin_cloud::twin::scenario_road(ScenarioKind::CutIn);
            let lines = road.lines();
            let strips = lines.edges.iter().chain(&lines.centrelines);
            let points = strips.clone().map(Vec::len).sum::<usize>() + 4 * road.crosswalks.len();
            let entity = &message["entities"][0];
            assert_eq!(
                (entity["id"].as_str(), entity["frame_id"].as_str()),
                (Some(ROAD_ENTITY_ID), Some(WORLD_FRAME_ID))
            );
            assert_eq!(entity["lines"].as_u64(), Some((strips.count() + road.crosswalks.len()) as u64), "{line}");
            assert_eq!(entity["points"].as_u64(), Some(points as u64), "{line}");
        } else {
            panic!("a topic the client did not subscribe to: {line}");
        }
    }
    assert!(both_in_one_scene, "no scene held both vehicles");
    for (topic, n) in &wanted {
        assert!(counts.get(topic.as_str()).is_some_and(|got| got >= n), "{topic}: {counts:?}");
    }

    // The cloud's account: one client, nothing dropped, at least what the client decoded sent;
    // the ingest took everything the vehicles sent.
    let viz = &summary["viz"];
    assert_eq!((viz["url"].as_str(), viz["clients_seen"].as_u64()), (Some(url.as_str()), Some(1)), "{viz}");
    assert_eq!(viz["total_dropped"], 0, "{viz}");
    for (topic, got) in &counts {
        assert!(viz["sent"][topic].as_u64().is_some_and(|n| n >= *got), "{topic}: {viz}");
    }
    assert_eq!(summary["total_dropped"], 0, "{summary}");
    for (id, sent) in &sent {
        assert_eq!(&summary["received"][id], sent, "{summary}");
    }
}
