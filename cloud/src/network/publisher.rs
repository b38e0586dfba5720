//! The task that publishes the cloud's outputs (risk field, risk report, scene) on their keys.
//! Outputs are latest-value data: a slow subscriber makes Zenoh drop them rather than stall
//! the cloud (`CongestionControl::Drop`). Each key's publisher tags its samples with the
//! message it carries (`risktwin_transport::protobuf`). With the viz role, each output goes to
//! its feed as well (copied only while a Foxglove client is connected).

use super::receive::Publication;
use crate::viz::VizFeed;
use risktwin_transport::zenoh::Session;
use risktwin_transport::zenoh::pubsub::Publisher;
use risktwin_transport::zenoh::qos::CongestionControl;
use risktwin_transport::{TransportError, protobuf};
use std::collections::HashMap;
use tokio::sync::mpsc::UnboundedReceiver;

/// Publishes everything that arrives on `outputs` (and hands it to `viz`, when given) until the
/// channel closes; returns how many messages went out.
pub(crate) async fn publish_outputs(
    session: Session,
    mut outputs: UnboundedReceiver<Publication>,
    viz: Option<VizFeed>,
) -> Result<u64, TransportError> {
    let mut publishers: HashMap<String, Publisher<'static>> = HashMap::new();
    let mut sent = 0;
    while let Some(Publication { key, message, log_ns, payload }) = outputs.recv().await {
        if let Some(viz) = &viz {
            viz.offer(&key, message, log_ns, &payload);
        }
        let publisher = match publishers.get(&key) {
            Some(p) => p,
            None => {
                let declared = session
                    .declare_publisher(key.clone())
                    .encoding(protobuf(message))
                    .congestion_control(CongestionControl::Drop)
                    .await
                    .map_err(|e| TransportError::Declare {
                        what: "publisher",
                        key: key.clone(),
                        reason: e.to_string(),
                    })?;
                publishers.entry(key.clone()).or_insert(declared)
            }
        };
        publisher.put(payload).await.map_err(|e| TransportError::Put { key, reason: e.to_string() })?;
        sent += 1;
    }
    for (key, publisher) in publishers {
        publisher.undeclare().await.map_err(|e| TransportError::Declare {
            what: "undeclare",
            key,
            reason: e.to_string(),
        })?;
    }
    Ok(sent)
}
