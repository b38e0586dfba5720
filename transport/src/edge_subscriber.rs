//! The cloud's one subscription to every edge→cloud stream: a zenoh-ext `AdvancedSubscriber`
//! that recovers what an outage lost from the publishers' caches ([`crate::recovery`]) and
//! reports every sample it could not recover.
//!
//! - `recovery(heartbeat)`: a gap in a publisher's numbers, or a heartbeat announcing numbers
//!   never received, makes the subscriber query the publisher's cache for the missing range;
//!   samples of that publisher are held back until the answer is in, then delivered in order;
//! - the miss listener: a gap still open when zenoh-ext's recovery ends is asked for once more
//!   ([`requery`]), and what that does not bring is reported as a [`StreamLoss`].
//!
//! Why ask again: zenoh-ext 1.10.2 reports as missed every gap still open when its recovery
//! query ends, without a second query: live samples dropped on a congested link while it was
//! recovering an earlier gap (its query asked for the cache up to then), and every gap whose
//! query went out on a session that had just lost its router (answered by nobody, at once: a
//! cloud continued after a stall longer than the lease). 100 vehicles after a 30 s stall lost
//! 54–865 of about 1,000,000 samples that way, all of them still in the edges' caches.
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

use crate::keyexpr::{self, EdgeStream, SiteId, SourceId};
use crate::recovery::RECOVERY_PRIORITY;
use crate::session::TransportError;
use crate::sync::LockExt;
use std::collections::{HashMap, HashSet};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use zenoh::Session;
use zenoh::query::{ConsolidationMode, ReplyKeyExpr};
use zenoh::sample::{Locality, Sample};
use zenoh::session::EntityGlobalId;
use zenoh_ext::{AdvancedSubscriber, AdvancedSubscriberBuilderExt, Miss, RecoveryConfig, SampleMissListener};

/// Publishers whose key is remembered; beyond, the table starts over (a later miss of a
/// forgotten publisher is still reported, without its key).
const MAX_PUBLISHERS: usize = 100_000;

/// How often a missed range is asked for, at most: again after [`REQUERY_DELAY`] while no
/// answer brought anything (a session still reconnecting); an answer that brings part of the
/// range ends it (the cache no longer holds the rest).
pub const REQUERY_ATTEMPTS: u32 = 3;

/// The wait between two asks for a missed range: a client session finds its router again within
/// this (its reconnection is immediate once it sees the link gone).
pub const REQUERY_DELAY: Duration = Duration::from_secs(1);

/// How long one ask waits for its answers.
const REQUERY_TIMEOUT: Duration = Duration::from_secs(5);

/// How long [`fetch_cached`] waits for the caches' answers.
pub const FETCH_TIMEOUT: Duration = Duration::from_secs(2);

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
/// subscriber's lock, one at a time), so they must be quick; samples a second ask brought
/// ([`requery`]) come from a task of the calling runtime, beside them.
///
/// One subscriber on `risktwin/v1/<site>/*/*` rather than one per stream: Zenoh matches every
/// sample against every wildcard subscription of the session, and five of them measured at
/// about 0.3 M msg/s where one reached 0.46 M (1 KiB, TCP loopback). The price is that keys of
/// the same shape that are not edge streams (another cloud's outputs, pushes to edges) also
/// arrive; they are recognised by the key parser and skipped. Samples published by this same
/// session are not received at all.
pub async fn subscribe_edge_streams(
    session: &Session,
    site: Option<&SiteId>,
    on_sample: impl Fn(EdgeStream, &Sample) + Send + Sync + 'static,
    on_loss: impl Fn(StreamLoss) + Send + Sync + 'static,
) -> Result<EdgeStreamSubscriber, TransportError> {
    subscribe(session, keyexpr::edge_streams_all(site), on_sample, on_loss).await
}

/// Subscribes to the edge streams of one shard group of `site` ([`keyexpr::shard_group_streams`]),
/// or of the whole site if `group` is `None`: [`subscribe_edge_streams`] for a sharded worker's
/// share, so that the other workers' samples are not sent to this one at all.
pub async fn subscribe_shard_group(
    session: &Session,
    site: &SiteId,
    group: Option<&str>,
    on_sample: impl Fn(EdgeStream, &Sample) + Send + Sync + 'static,
    on_loss: impl Fn(StreamLoss) + Send + Sync + 'static,
) -> Result<EdgeStreamSubscriber, TransportError> {
    let key = group.map_or_else(|| keyexpr::edge_streams_all(Some(site)), |g| keyexpr::shard_group_streams(site, g));
    subscribe(session, key, on_sample, on_loss).await
}

/// Asks the caches of `source`'s stream publishers for their last `per_publisher` samples each
/// (a sharded worker that starts owning a source: what reached it before it owned the source,
/// or before its first sample of it arrived). Returns what came within [`FETCH_TIMEOUT`], in
/// each publisher's order; a source without a live publisher brings nothing.
pub async fn fetch_cached(session: &Session, site: &SiteId, source: &SourceId, per_publisher: usize) -> Vec<Sample> {
    let selector = format!("{}/@adv/**?_max={}", keyexpr::source_streams(site, source), per_publisher.max(1));
    let mut samples = Vec::new();
    let replies = session
        .get(&selector)
        .consolidation(ConsolidationMode::None)
        .accept_replies(ReplyKeyExpr::Any)
        .priority(RECOVERY_PRIORITY)
        .timeout(FETCH_TIMEOUT)
        .await;
    match replies {
        Ok(replies) => {
            while let Ok(reply) = replies.recv_async().await {
                if let Ok(sample) = reply.into_result()
                    && keyexpr::parse_edge_key(sample.key_expr().as_str()).is_some()
                {
                    samples.push(sample);
                }
            }
        }
        Err(e) => tracing::debug!("edge streams: asking {selector}: {e}"),
    }
    samples.sort_by_key(|s| s.source_info().map(|i| (i.source_id().zid(), i.source_id().eid(), i.source_sn())));
    samples
}

async fn subscribe<F, L>(
    session: &Session,
    key: String,
    on_sample: F,
    on_loss: L,
) -> Result<EdgeStreamSubscriber, TransportError>
where
    F: Fn(EdgeStream, &Sample) + Send + Sync + 'static,
    L: Fn(StreamLoss) + Send + Sync + 'static,
{
    let declare_err =
        |what: &'static str, e: zenoh::Error| TransportError::Declare { what, key: key.clone(), reason: e.to_string() };
    let keys = Arc::new(Mutex::new(PublisherKeys::default()));
    let (on_sample, on_loss) = (Arc::new(on_sample), Arc::new(on_loss));
    let (sample_keys, deliver) = (Arc::clone(&keys), Arc::clone(&on_sample));
    let subscriber = session
        .declare_subscriber(key.clone())
        .allowed_origin(Locality::Remote)
        .callback(move |sample| {
            if let Some(info) = sample.source_info() {
                sample_keys.locked().remember(info.source_id(), &sample);
            }
            if let Some(parsed) = keyexpr::parse_edge_key(sample.key_expr().as_str()) {
                deliver(parsed.stream, &sample);
            }
        })
        .recovery(RecoveryConfig::default().heartbeat())
        .await
        .map_err(|e| declare_err("advanced subscriber", e))?;
    let (requery_session, runtime) = (session.clone(), tokio::runtime::Handle::current());
    let misses = subscriber
        .sample_miss_listener()
        .callback(move |miss: Miss| {
            let publisher = keys.locked().get(&miss.source());
            let Some((key, last_sn)) = publisher else {
                on_loss(StreamLoss { key: None, samples: miss.nb() });
                return;
            };
            // Called just before the sample after the gap is delivered: the gap follows `last_sn`.
            let missed =
                Missed { key, publisher: miss.source(), first_sn: last_sn.wrapping_add(1), samples: miss.nb() };
            let (session, on_sample, on_loss) = (requery_session.clone(), Arc::clone(&on_sample), Arc::clone(&on_loss));
            runtime.spawn(async move {
                let lost = requery(&session, &missed, |sample| {
                    if let Some(parsed) = keyexpr::parse_edge_key(sample.key_expr().as_str()) {
                        on_sample(parsed.stream, sample);
                    }
                })
                .await;
                if lost > 0 {
                    on_loss(StreamLoss { key: Some(missed.key), samples: lost });
                }
            });
        })
        .await
        .map_err(|e| declare_err("sample-miss listener", e))?;
    Ok(EdgeStreamSubscriber { subscriber, misses })
}

/// A range of one publisher's samples that zenoh-ext reported missed.
#[derive(Debug, Clone)]
pub struct Missed {
    /// The key the publisher's samples come on.
    pub key: String,
    pub publisher: EntityGlobalId,
    /// The first missed sequence number (zenoh-ext's numbering, not the header's).
    pub first_sn: u32,
    pub samples: u32,
}

/// Asks `missed.publisher`'s cache for the range (up to [`REQUERY_ATTEMPTS`] times, see there),
/// hands each sample of the range that comes back to `deliver` once (recovered: it arrives at
/// [`RECOVERY_PRIORITY`]), and returns how many it did not bring.
pub async fn requery(session: &Session, missed: &Missed, mut deliver: impl FnMut(&Sample)) -> u32 {
    let last_sn = missed.first_sn.wrapping_add(missed.samples.saturating_sub(1));
    if missed.samples == 0 || last_sn < missed.first_sn {
        // Nothing to ask, or a range across the wrap of the numbers (2³² samples): not asked.
        return missed.samples;
    }
    let (zid, eid) = (missed.publisher.zid().into_keyexpr(), missed.publisher.eid());
    let selector = format!("{}/@adv/*/{zid}/{eid}/**?_sn={}..{last_sn}", missed.key, missed.first_sn);
    let mut brought: HashSet<u32> = HashSet::new();
    for attempt in 0..REQUERY_ATTEMPTS {
        if attempt > 0 {
            tokio::time::sleep(REQUERY_DELAY).await;
        }
        if session.is_closed() {
            // Shutting down: nobody to ask, and the caller's callbacks should be let go.
            break;
        }
        let replies = match session
            .get(&selector)
            .consolidation(ConsolidationMode::None)
            .accept_replies(ReplyKeyExpr::Any)
            .priority(RECOVERY_PRIORITY)
            .timeout(REQUERY_TIMEOUT)
            .await
        {
            Ok(replies) => replies,
            Err(e) => {
                tracing::debug!("edge streams: asking again for {selector}: {e}");
                continue;
            }
        };
        while let Ok(reply) = replies.recv_async().await {
            let Ok(sample) = reply.result() else { continue };
            let in_range = sample.source_info().and_then(|info| {
                let sn = info.source_sn();
                (info.source_id() == &missed.publisher && (missed.first_sn..=last_sn).contains(&sn)).then_some(sn)
            });
            if let Some(sn) = in_range
                && sample.key_expr().as_str() == missed.key
                && brought.insert(sn)
            {
                deliver(sample);
            }
        }
        if !brought.is_empty() {
            break;
        }
    }
    missed.samples - brought.len() as u32
}

/// The key each publisher entity's samples came on, and the number of its last one.
#[derive(Default)]
struct PublisherKeys {
    keys: HashMap<EntityGlobalId, (String, u32)>,
}

impl PublisherKeys {
    fn remember(&mut self, publisher: &EntityGlobalId, sample: &Sample) {
        let sn = sample.source_info().map_or(0, |info| info.source_sn());
        if let Some((_, last)) = self.keys.get_mut(publisher) {
            *last = sn;
            return;
        }
        if self.keys.len() >= MAX_PUBLISHERS {
            tracing::warn!("edge streams: over {MAX_PUBLISHERS} publishers seen, their keys are forgotten");
            self.keys.clear();
        }
        self.keys.insert(*publisher, (sample.key_expr().as_str().to_owned(), sn));
    }

    fn get(&self, publisher: &EntityGlobalId) -> Option<(String, u32)> {
        self.keys.get(publisher).cloned()
    }
}
