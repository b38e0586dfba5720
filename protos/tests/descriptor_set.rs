//! The embedded FileDescriptorSet decodes and holds every message a recording names.

use prost::Message;
use prost_types::FileDescriptorSet;
use risktwin_common::telemetry::{RiskReport, VehicleStateSample};
use risktwin_protos::{FILE_DESCRIPTOR_SET, WireMessage};

fn message_names(set: &FileDescriptorSet) -> Vec<String> {
    set.file.iter().flat_map(|f| f.message_type.iter().map(move |m| format!("{}.{}", f.package(), m.name()))).collect()
}

#[test]
fn descriptor_set_holds_our_and_the_foxglove_messages() {
    let set = FileDescriptorSet::decode(FILE_DESCRIPTOR_SET).expect("the embedded set decodes");
    let names = message_names(&set);
    for name in [
        "risktwin.v1.VehicleState",
        VehicleStateSample::PROTO_NAME,
        RiskReport::PROTO_NAME,
        "risktwin.v1.CanFrame",
        "risktwin.v1.RoadMap",
        "risktwin.v1.RiskGrid",
        "foxglove.Grid",
        "foxglove.SceneUpdate",
        "foxglove.SceneEntity",
        "google.protobuf.Timestamp",
    ] {
        assert!(names.iter().any(|n| n == name), "{name} missing from {names:?}");
    }
    // Imports come first so a reader can build the pool in order; no file is listed twice.
    let files: Vec<&str> = set.file.iter().map(|f| f.name()).collect();
    for (i, f) in set.file.iter().enumerate() {
        for dep in &f.dependency {
            let at = files
                .iter()
                .position(|n| n == dep)
                .unwrap_or_else(|| panic!("{dep} (imported by {}) missing", f.name()));
            assert!(at < i, "{dep} listed after its importer {}", f.name());
        }
    }
    let mut sorted = files.clone();
    sorted.sort();
    sorted.dedup();
    assert_eq!(sorted.len(), files.len());
    assert!(set.file.iter().all(|f| f.source_code_info.is_none()), "stored without comments");
}
