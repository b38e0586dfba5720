//! What a scene's authority publishes for the cloud (never mixed into the edge streams):
//! - its road map on `risktwin/v1/<site>/scene/map`, every second: the first one, and any that
//!   differs from the last, moves that site's risk assessment, the warning path's lane TTC and
//!   the viz role's road onto it (sites without a scene keep `--road`); every one tells the twin's watch that a scene runs there (its ego's
//!   episode is scored for the loop) and marks the site's edges as scene participants;
//! - its ground truth, every physics step: each connected vehicle's state on
//!   `risktwin/v1/<site>/scene/gt/<source>` and every other object on `…/scene/objects`. The
//!   twin's fidelity is measured against it, and a recording keeps it on those topics.
//!
//! A message that does not decode (or is tagged with another schema) is counted in the
//! summary's drops by reason.

use super::receive::{GroundTruth, LiveIngest};
use crate::twin::risk::RiskAssessor;
use risktwin_common::telemetry::{ObjectList, RoadMap, VehicleStateSample};
use risktwin_protos::decode_tagged;
use risktwin_transport::keyexpr::{self, SceneTopic, parse_scene_ground_truth_key, parse_scene_topic_key, scene_topic};
use risktwin_transport::sync::LockExt;
use risktwin_transport::zenoh::Session;
use risktwin_transport::zenoh::pubsub::Subscriber;
use risktwin_transport::{SiteId, TransportError};
use std::collections::HashMap;
use std::sync::{Arc, Mutex};

/// Subscribes to the scene maps of `site` (every site if `None`), feeding them to `ingest`.
pub(crate) async fn subscribe_maps(
    session: &Session,
    site: Option<&SiteId>,
    ingest: Arc<Mutex<LiveIngest>>,
) -> Result<Subscriber<()>, TransportError> {
    let key = scene_topic(site, SceneTopic::Map);
    // The last map bytes per site: a republished map is the same bytes, and costs nothing.
    let last: Mutex<HashMap<String, Vec<u8>>> = Mutex::new(HashMap::new());
    session
        .declare_subscriber(key.clone())
        .callback(move |sample| {
            let Some(site) = parse_scene_topic_key(sample.key_expr().as_str(), SceneTopic::Map) else { return };
            let payload = sample.payload().to_bytes();
            let mut last = last.locked();
            if last.get(site).is_some_and(|bytes| bytes[..] == payload[..]) {
                ingest.locked().scene_seen(site);
                return;
            }
            match decode_tagged::<RoadMap>(&sample.encoding().to_string(), &payload) {
                Ok(map) => {
                    last.insert(site.to_owned(), payload.into_owned());
                    let mut live = ingest.locked();
                    live.scene_seen(site);
                    live.set_warning_road(site, &map.road);
                    live.set_viz_road(site, &map.road);
                    let Some(config) = live.risk_config() else { return };
                    drop(live);
                    // Rasterising a road takes ~0.1 s: never on a callback that delivers
                    // samples (they would wait, and their receive times with them).
                    let (ingest, site) = (Arc::clone(&ingest), site.to_owned());
                    std::thread::spawn(move || match RiskAssessor::new(map.road, config) {
                        Ok(assessor) => ingest.locked().set_site_risk(&site, assessor),
                        Err(e) => {
                            tracing::warn!("risk: site {site}'s road map is unusable ({e}); it keeps the default road")
                        }
                    });
                }
                Err(e) => {
                    tracing::warn!("risk: dropped site {site}'s scene map: {e}");
                    ingest.locked().reject(e.drop_reason());
                }
            }
        })
        .await
        .map_err(|e| TransportError::Declare { what: "scene-map subscriber", key, reason: e.to_string() })
}

/// Subscribes to the ground truth of `site`'s scene (every site if `None`): the connected
/// vehicles' states and the other objects, fed to `ingest`. Returns both subscribers.
pub(crate) async fn subscribe_ground_truth(
    session: &Session,
    site: Option<&SiteId>,
    ingest: Arc<Mutex<LiveIngest>>,
) -> Result<[Subscriber<()>; 2], TransportError> {
    let vehicles_key = keyexpr::scene_ground_truth_all(site);
    let objects_key = scene_topic(site, SceneTopic::Objects);
    let declare_err = |key: &String| {
        let key = key.clone();
        move |e: Box<dyn std::error::Error + Send + Sync>| TransportError::Declare {
            what: "ground-truth subscriber",
            key,
            reason: e.to_string(),
        }
    };
    let sink = Arc::clone(&ingest);
    let vehicles = session
        .declare_subscriber(vehicles_key.clone())
        .callback(move |sample| {
            let key = sample.key_expr().as_str();
            let Some((site, source)) = parse_scene_ground_truth_key(key) else { return };
            let truth =
                decode_tagged::<VehicleStateSample>(&sample.encoding().to_string(), &sample.payload().to_bytes())
                    .map(|sample| GroundTruth::Vehicle { source: source.to_owned(), sample });
            hand_over(&sink, key, site, truth);
        })
        .await
        .map_err(declare_err(&vehicles_key))?;
    let objects = session
        .declare_subscriber(objects_key.clone())
        .callback(move |sample| {
            let key = sample.key_expr().as_str();
            let Some(site) = parse_scene_topic_key(key, SceneTopic::Objects) else { return };
            let truth = decode_tagged::<ObjectList>(&sample.encoding().to_string(), &sample.payload().to_bytes())
                .map(GroundTruth::Objects);
            hand_over(&ingest, key, site, truth);
        })
        .await
        .map_err(declare_err(&objects_key))?;
    Ok([vehicles, objects])
}

/// Hands a decoded truth message to the ingest; one that did not decode is counted by reason.
fn hand_over(
    ingest: &Mutex<LiveIngest>,
    key: &str,
    site: &str,
    truth: Result<GroundTruth, risktwin_protos::DecodeError>,
) {
    let mut ingest = ingest.locked();
    match truth {
        Ok(truth) => {
            if let Err(e) = ingest.observe_truth(key, site, truth) {
                tracing::warn!("twin: recording the ground truth of {site} failed: {e}");
            }
        }
        Err(e) => {
            tracing::warn!("twin: dropped a ground-truth message on {key}: {e}");
            ingest.reject(e.drop_reason());
        }
    }
}
