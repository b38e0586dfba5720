//! Interoperability with the reference implementations of our formats: recordings must decode
//! with the official Python `mcap` reader and `mcap-protobuf-support` decoder.

mod episode;
mod onnx_models;
mod peer_cache;
mod peer_python;
mod python_package;

use std::process::Command;

const DECODE_ALL: &str = r#"
import json, struct, sys
from collections import Counter
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory
counts = Counter()
grid_bytes = set()
with open(sys.argv[1], "rb") as f:
    reader = make_reader(f, decoder_factories=[DecoderFactory()])
    for schema, channel, message, proto in reader.iter_decoded_messages():
        counts[channel.topic + " " + schema.name] += 1
        if schema.name == "foxglove.Grid":
            # One little-endian float32 per cell, whole rows, and a positive risk somewhere.
            values = struct.unpack("<%df" % (len(proto.data) // 4), proto.data)
            grid_bytes.add(proto.cell_stride == 4 and proto.row_stride == proto.column_count * 4
                           and len(proto.data) % proto.row_stride == 0 and max(values) > 0.0)
print(json.dumps({"counts": counts, "grids_consistent": all(grid_bytes)}))
"#;

#[test]
fn python_mcap_reader_decodes_every_message_of_a_recording() {
    let dir = tempfile::tempdir().expect("temp dir");
    let recording = episode::record(dir.path(), 3, "ep.mcap");
    let python = peer_python::python(&["mcap==1.6.0", "mcap-protobuf-support==0.6.0"]);
    let out = Command::new(python).arg("-c").arg(DECODE_ALL).arg(&recording).output().expect("python runs");
    assert!(out.status.success(), "python reader failed: {}", String::from_utf8_lossy(&out.stderr));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON line");
    let counts = report["counts"].as_object().expect("counts");
    let n = |key: &str| counts.get(key).and_then(|v| v.as_u64()).unwrap_or(0);
    let ego = n("/twin/ego/state risktwin.v1.VehicleState");
    assert!(ego > 100, "ego states decoded: {counts:?}");
    assert_eq!(n("/twin/scene foxglove.SceneUpdate"), ego, "one scene per step");
    assert_eq!(n("/twin/veh-0/state risktwin.v1.VehicleState"), ego, "the lead on every step");
    assert_eq!(n("/twin/risk_field foxglove.Grid"), ego.div_ceil(10), "risk grid at 2 Hz");
    assert_eq!(report["grids_consistent"], true);
}
