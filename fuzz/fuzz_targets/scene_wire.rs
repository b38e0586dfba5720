//! The wire of a distributed scene: the physics-plane messages (postcard) a participant and the
//! authority decode (`Truth`, `Reply`), and the scene topics the cloud subscribes to (protobuf):
//! the road map, which the cloud builds its risk raster on, and the ground truth of vehicles and
//! objects. One message per record.
#![no_main]

use libfuzzer_sys::fuzz_target;
use risktwin_cloud::twin::risk::{RiskAssessor, RiskConfig};
use risktwin_common::telemetry::{ObjectList, RoadMap, VehicleStateSample};
use risktwin_edge::fleet::wire::{Reply, Truth};
use risktwin_fuzz::{Records, scene_tag};
use risktwin_protos::{WireMessage, decode_tagged, encoding_of};

fuzz_target!(|data: &[u8]| {
    let mut records = Records::new(data);
    while let Some(tag) = records.tag() {
        let payload = records.frame();
        match tag % 5 {
            scene_tag::TRUTH => {
                if let Ok(truth) = Truth::decode(payload) {
                    // What a participant derives from it before answering.
                    let _ = truth.ego_object(0);
                }
            }
            scene_tag::REPLY => drop(Reply::decode(payload)),
            scene_tag::ROAD_MAP => {
                if let Ok(map) = decode_tagged::<RoadMap>(&encoding_of(RoadMap::PROTO_NAME), payload) {
                    let _ = RiskAssessor::new(map.road, RiskConfig::default());
                }
            }
            scene_tag::VEHICLE => {
                drop(decode_tagged::<VehicleStateSample>(&encoding_of(VehicleStateSample::PROTO_NAME), payload))
            }
            _ => drop(decode_tagged::<ObjectList>(&encoding_of(ObjectList::PROTO_NAME), payload)),
        }
    }
});
