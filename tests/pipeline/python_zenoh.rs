//! Interop: a Python `eclipse-zenoh` subscriber (the reference binding, same Zenoh version as
//! ours) connects to our router and decodes our edge's stream with protobuf classes built from
//! the FileDescriptorSet our recordings store.

use crate::support::{Proc, start_router};
use std::process::{Command, Stdio};
use std::time::Duration;

#[path = "../interop/episode.rs"]
mod episode;
use crate::peer_python;

#[test]
fn a_python_zenoh_subscriber_decodes_our_stream() {
    let dir = tempfile::tempdir().expect("temp dir");
    // Any recording carries the schemas; a short episode makes one.
    let schemas = episode::record(dir.path(), 1, "schemas.mcap");

    let python = peer_python::python(&["eclipse-zenoh==1.10.2", "mcap==1.6.0", "mcap-protobuf-support==0.6.0"]);
    let (router, locator) = start_router();
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/pipeline/python_subscriber.py");
    // 20 states at 50 Hz bring 80 CAN frames (two ids at 100 Hz) and 4 object lists.
    let expected = 20 + 80 + 4;
    let subscriber = Command::new(python)
        .arg(script)
        .arg(&locator)
        .arg(&schemas)
        .arg(expected.to_string())
        .stdout(Stdio::piped())
        .spawn()
        .expect("python starts");
    // The edge waits for a matching subscriber before it publishes; no RiskTwin cloud
    // acknowledges it (--no-ack).
    let args = ["edge", "vehicle", "--id", "veh-py", "--connect", &locator, "--count", "20", "--no-ack"];
    let mut edge = Proc::spawn("edge", &args);
    let sent = edge.exit_json(Duration::from_secs(60));
    let out = subscriber.wait_with_output().expect("python ends (it waits at most 30 s)");
    router.terminate();
    assert!(out.status.success(), "python subscriber failed");
    let got: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON line from python");
    for stream in ["state", "can", "perception"] {
        assert_eq!(got["counts"][stream], sent["sent"][stream], "{stream}: python saw {got}, edge sent {sent}");
    }
    assert_eq!(got["source_mismatch"], 0);
    assert_eq!(got["wrong_tag"], serde_json::json!([]), "every sample tagged application/protobuf;<its message>");
}
