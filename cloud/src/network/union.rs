//! The `union` role: what the sharded ingest workers accepted ([`super::shard`]), taken from
//! `risktwin/v1/<site>/cloud/ingested/<source>/<stream>` into this process's ingest under the
//! edge key it came on, so that the twin, risk and warning roles see every source as if one
//! cloud had ingested them all.
//!
//! A hand-over brings some messages twice (the new owner asks the edge's caches for the last
//! ones, some of which the old owner had forwarded): the ingest's deduplicator takes each
//! (source, sequence number) once and counts the rest `duplicate`; what no worker forwarded
//! shows as `presumed_lost` (the union counts every source from number 0).

use super::receive::{LiveIngest, Origin};
use risktwin_protos::recording::decode_replay_time;
use risktwin_transport::keyexpr::{self, edge_key_of_ingested};
use risktwin_transport::sync::LockExt;
use risktwin_transport::zenoh::Session;
use risktwin_transport::zenoh::pubsub::Subscriber;
use risktwin_transport::zenoh::sample::Locality;
use risktwin_transport::{SiteId, TransportError};
use std::sync::{Arc, Mutex};

/// Forwarded keys declared at most (five streams of 100,000 sources, the ingest's source limit).
const MAX_DECLARED: usize = 500_000;

/// Subscribes to what the workers of `site` (every site if `None`) forward; drop or undeclare
/// the subscriber to stop.
pub async fn subscribe(
    session: &Session,
    site: Option<&SiteId>,
    ingest: Arc<Mutex<LiveIngest>>,
) -> Result<Subscriber<()>, TransportError> {
    let key = keyexpr::ingested_all(site);
    // The edge key is rebuilt into one buffer, reused under the ingest's lock.
    let buffer = Mutex::new(String::new());
    // Each forwarded key is declared at this session once (see `super::routes`: an undeclared
    // key is routed by walking the whole resource tree, ≈ 50 µs a sample here). The declarer
    // task ends with the subscriber's callback (its sender dropped).
    let (_declarer, keys) = super::routes::declare_route_keys(session);
    let seen = Mutex::new(std::collections::HashSet::<String>::new());
    session
        .declare_subscriber(key.clone())
        .allowed_origin(Locality::Remote)
        .callback(move |sample| {
            let payload = sample.payload().to_bytes();
            let replay_ns = sample.attachment().and_then(|a| decode_replay_time(&a.to_bytes()));
            {
                let mut seen = seen.locked();
                let forwarded = sample.key_expr().as_str();
                if !seen.contains(forwarded) && seen.len() < MAX_DECLARED {
                    seen.insert(forwarded.to_owned());
                    let _ = keys.send(forwarded.to_owned());
                }
            }
            let mut buffer = buffer.locked();
            let mut ingest = ingest.locked();
            let Some(edge_key) = edge_key_of_ingested(sample.key_expr().as_str(), &mut buffer) else {
                ingest.reject_bad_key();
                return;
            };
            // Neither recovered nor an edge's session: the worker accounted for both.
            let origin = Origin { recovered: false, publisher: None };
            if let Err(e) = ingest.handle(edge_key, sample.encoding(), &payload, replay_ns, origin) {
                tracing::error!("union: {e}");
            }
        })
        .await
        .map_err(|e| TransportError::Declare { what: "union subscriber", key, reason: e.to_string() })
}
