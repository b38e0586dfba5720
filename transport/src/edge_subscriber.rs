//! The cloud's one subscription to every edge→cloud stream: a zenoh-ext `AdvancedSubscriber`
//! that recovers what an outage lost from the publishers' caches ([`crate::recovery`]) and
//! reports every sample it could not recover.
//!
//! - `recovery(heartbeat)`: a gap in a publisher's numbers, or a heartbeat announcing numbers
//!   never received, makes the subscriber query the publisher's cache for the missing range;
//!   samples of that publisher are held back until the answer is in, then delivered in order;
//! - the miss listener: what the cache no longer held is reported as a [`StreamLoss`].
//!
//! No `history`: a publisher that appears is not asked for its cache (one exception: zenoh-ext
//! asks for everything up to a heartbeat that reaches a new subscriber before any sample of
//! its publisher; docs/keyexpr.md, "Surviving faults"). With
//! `history(detect_late_publishers)`, zenoh-ext 1.10.2 re-sends every reappearing publisher's
//! whole cache after each reconnection (no `_sn` range), and while its cache answers, the
//! publisher's puts wait on the cache lock (the edge's tick loop with them); a cloud that starts
//! late would also take 30 s of history for live data. An edge waits for the cloud's subscriber
//! before it publishes, so nothing is missed at the start, and a publisher's state (its last
//! delivered number) outlives a router restart, so the heartbeat asks for just the missing range.
//!
//! A miss names the publisher entity, not its key: the key is the one the entity's samples
//! came on (a miss always follows a sample delivered from the same publisher).

use crate::keyexpr::{self, EdgeStream, SiteId};
use crate::session::TransportError;
use std::collections::HashMap;
use std::sync::{Arc, Mutex, PoisonError};
use zenoh::Session;
use zenoh::sample::{Locality, Sample};
use zenoh::session::EntityGlobalId;
use zenoh_ext::{AdvancedSubscriber, AdvancedSubscriberBuilderExt, Miss, RecoveryConfig, SampleMissListener};

/// Publishers whose key is remembered; beyond, the table starts over (a later miss of a
/// forgotten publisher is still reported, without its key).
const MAX_PUBLISHERS: usize = 100_000;

/// Samples of one publisher that are lost for good: neither received nor recoverable.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StreamLoss {
    /// The key the publisher's samples came on; `None` if it was forgotten ([`MAX_PUBLISHERS`]).
    pub key: Option<String>,
    /// How many consecutive samples were lost.
    pub samples: u32,
}

/// The subscription of [`subscribe_edge_streams`]; undeclare it to stop receiving.
pub struct EdgeStreamSubscriber {
    subscriber: AdvancedSubscriber<()>,
    misses: SampleMissListener<()>,
}

impl EdgeStreamSubscriber {
    /// Stops receiving samples and loss reports (their callbacks are dropped).
    pub async fn undeclare(self) -> Result<(), zenoh::Error> {
        self.misses.undeclare().await?;
        self.subscriber.undeclare().await
    }
}

/// Subscribes to every edge→cloud stream of every source at `site` (every site if `None`).
/// `on_sample(stream, sample)` and `on_loss(loss)` run on Zenoh's receive path (under the
/// subscriber's lock, one at a time), so they must be quick.
///
/// One subscriber on `risktwin/v1/<site>/*/*` rather than one per stream: Zenoh matches every
/// sample against every wildcard subscription of the session, and five of them measured at
/// about 0.3 M msg/s where one reached 0.46 M (1 KiB, TCP loopback). The price is that keys of
/// the same shape that are not edge streams (another cloud's outputs, pushes to edges) also
/// arrive; they are recognised by the key parser and skipped. Samples published by this same
/// session are not received at all.
pub async fn subscribe_edge_streams<F, L>(
    session: &Session,
    site: Option<&SiteId>,
    on_sample: F,
    on_loss: L,
) -> Result<EdgeStreamSubscriber, TransportError>
where
    F: Fn(EdgeStream, &Sample) + Send + Sync + 'static,
    L: Fn(StreamLoss) + Send + Sync + 'static,
{
    let key = keyexpr::edge_streams_all(site);
    let declare_err =
        |what: &'static str, e: zenoh::Error| TransportError::Declare { what, key: key.clone(), reason: e.to_string() };
    let keys = Arc::new(Mutex::new(PublisherKeys::default()));
    let sample_keys = Arc::clone(&keys);
    let subscriber = session
        .declare_subscriber(key.clone())
        .allowed_origin(Locality::Remote)
        .callback(move |sample| {
            if let Some(info) = sample.source_info() {
                sample_keys.lock().unwrap_or_else(PoisonError::into_inner).remember(info.source_id(), &sample);
            }
            if let Some(parsed) = keyexpr::parse_edge_key(sample.key_expr().as_str()) {
                on_sample(parsed.stream, &sample);
            }
        })
        .recovery(RecoveryConfig::default().heartbeat())
        .await
        .map_err(|e| declare_err("advanced subscriber", e))?;
    let misses = subscriber
        .sample_miss_listener()
        .callback(move |miss: Miss| {
            let key = keys.lock().unwrap_or_else(PoisonError::into_inner).key_of(&miss.source());
            on_loss(StreamLoss { key, samples: miss.nb() });
        })
        .await
        .map_err(|e| declare_err("sample-miss listener", e))?;
    Ok(EdgeStreamSubscriber { subscriber, misses })
}

/// The key each publisher entity's samples came on.
#[derive(Default)]
struct PublisherKeys {
    keys: HashMap<EntityGlobalId, String>,
}

impl PublisherKeys {
    fn remember(&mut self, publisher: &EntityGlobalId, sample: &Sample) {
        if self.keys.contains_key(publisher) {
            return;
        }
        if self.keys.len() >= MAX_PUBLISHERS {
            tracing::warn!("edge streams: over {MAX_PUBLISHERS} publishers seen, their keys are forgotten");
            self.keys.clear();
        }
        self.keys.insert(*publisher, sample.key_expr().as_str().to_owned());
    }

    fn key_of(&self, publisher: &EntityGlobalId) -> Option<String> {
        self.keys.get(publisher).cloned()
    }
}
