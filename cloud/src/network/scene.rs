//! What a scene's authority publishes for the cloud (never mixed into the edge streams):
//! - its road map on `risktwin/v1/<site>/scene/map`, every second: the first one, and any that
//!   differs from the last, moves that site's risk assessment onto it (sites without a scene
//!   keep `--road`);
//! - each connected vehicle's true state on `risktwin/v1/<site>/scene/gt/<source>`, every
//!   physics step: the twin's fidelity is measured against it.
//!
//! A message that does not decode is counted in the summary's drops by reason.

use super::receive::LiveIngest;
use risktwin_common::telemetry::{RoadMap, VehicleStateSample};
use risktwin_protos::decode;
use risktwin_transport::keyexpr::{self, parse_scene_ground_truth_key, parse_scene_map_key};
use risktwin_transport::zenoh::Session;
use risktwin_transport::zenoh::pubsub::Subscriber;
use risktwin_transport::{SiteId, TransportError};
use std::collections::HashMap;
use std::sync::{Arc, Mutex, PoisonError};

/// Subscribes to the scene maps of `site` (every site if `None`), feeding them to `ingest`.
pub(crate) async fn subscribe_maps(
    session: &Session,
    site: Option<&SiteId>,
    ingest: Arc<Mutex<LiveIngest>>,
) -> Result<Subscriber<()>, TransportError> {
    let key = keyexpr::scene_maps(site);
    // The last map bytes per site: a republished map is the same bytes, and costs nothing.
    let last: Mutex<HashMap<String, Vec<u8>>> = Mutex::new(HashMap::new());
    session
        .declare_subscriber(key.clone())
        .callback(move |sample| {
            let Some(site) = parse_scene_map_key(sample.key_expr().as_str()) else { return };
            let payload = sample.payload().to_bytes();
            let mut last = last.lock().unwrap_or_else(PoisonError::into_inner);
            if last.get(site).is_some_and(|bytes| bytes[..] == payload[..]) {
                return;
            }
            match decode::<RoadMap>(&payload) {
                Ok(map) => {
                    last.insert(site.to_owned(), payload.into_owned());
                    ingest.lock().unwrap_or_else(PoisonError::into_inner).set_site_road(site, map.road);
                }
                Err(e) => {
                    tracing::warn!("risk: dropped site {site}'s scene map: {e}");
                    ingest.lock().unwrap_or_else(PoisonError::into_inner).reject(e.drop_reason());
                }
            }
        })
        .await
        .map_err(|e| TransportError::Declare { what: "scene-map subscriber", key, reason: e.to_string() })
}

/// Subscribes to the ground truth of every connected vehicle of `site`'s scene (every site if
/// `None`), feeding it to `ingest`'s twin.
pub(crate) async fn subscribe_ground_truth(
    session: &Session,
    site: Option<&SiteId>,
    ingest: Arc<Mutex<LiveIngest>>,
) -> Result<Subscriber<()>, TransportError> {
    let key = keyexpr::scene_ground_truth_all(site);
    session
        .declare_subscriber(key.clone())
        .callback(move |sample| {
            let Some((site, source)) = parse_scene_ground_truth_key(sample.key_expr().as_str()) else { return };
            let mut ingest = ingest.lock().unwrap_or_else(PoisonError::into_inner);
            match decode::<VehicleStateSample>(&sample.payload().to_bytes()) {
                Ok(s) => ingest.observe_truth(site, source, s.header.capture_time_ns, s.pose.position()),
                Err(e) => {
                    tracing::warn!("twin: dropped a ground-truth sample of {site}/{source}: {e}");
                    ingest.reject(e.drop_reason());
                }
            }
        })
        .await
        .map_err(|e| TransportError::Declare { what: "ground-truth subscriber", key, reason: e.to_string() })
}
