//! The warning role's puts: each hazard warning goes out on its vehicle's key
//! (`risktwin/v1/<site>/<vehicle>/warning`) from inside the ingest's Zenoh callback, so nothing
//! waits between the triggering message's receipt and the put (no channel, no task hop; the
//! twin's outputs, in contrast, go through the publisher task).
//!
//! One declared publisher per warned vehicle (its key travels as a numeric id), declared on the
//! first warning to it. Express (not batched with other messages), at `InteractiveHigh` (above
//! the edge streams' `DataHigh`), `CongestionControl::Drop` (a stalled link never stalls the
//! ingest; the next critical message warns again).

use crate::warning::WarningSink;
use risktwin_common::telemetry::HazardWarning;
use risktwin_protos::{WireMessage, encode};
use risktwin_transport::protobuf;
use risktwin_transport::zenoh::pubsub::Publisher;
use risktwin_transport::zenoh::qos::{CongestionControl, Priority};
use risktwin_transport::zenoh::{Session, Wait};
use std::collections::HashMap;

/// The sink that puts warnings on `session` (see the module doc); `false` for a warning whose
/// publisher could not be declared or whose put failed.
pub fn warning_sink(session: &Session) -> Box<WarningSink<'static>> {
    let session = session.clone();
    let mut publishers: HashMap<String, Publisher<'static>> = HashMap::new();
    Box::new(move |key: &str, warning: &HazardWarning| {
        let publisher = match publishers.get(key) {
            Some(p) => p,
            None => {
                let declared = session
                    .declare_publisher(key.to_owned())
                    .encoding(protobuf(HazardWarning::PROTO_NAME))
                    .congestion_control(CongestionControl::Drop)
                    .priority(Priority::InteractiveHigh)
                    .express(true)
                    .wait();
                match declared {
                    Ok(p) => publishers.entry(key.to_owned()).or_insert(p),
                    Err(e) => {
                        tracing::warn!("warning: declaring the publisher of {key} failed: {e}");
                        return false;
                    }
                }
            }
        };
        publisher.put(encode(warning)).wait().is_ok()
    })
}
