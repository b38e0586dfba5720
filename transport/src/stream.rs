//! Typed publishing and subscribing on the key scheme: the payload stays opaque bytes here,
//! tagged with the encoding of the message its key carries.
//!
//! **Schema tags.** Every protobuf sample of RiskTwin carries the Zenoh encoding
//! `application/protobuf;<full message name>` ([`protobuf`]), e.g.
//! `application/protobuf;risktwin.v1.VehicleState`; the package is the schema version. A
//! receiver reads a payload only under the tag of the type it expects
//! (`risktwin_protos::decode_tagged`, or an encoding compared with [`protobuf`]'s), and counts
//! anything else as `wrong-schema`: a process of another schema version, or a publisher that
//! does not say what it sends, is refused by name and never misread.

use crate::keyexpr::{self, EdgeStream, SiteId, SourceId};
use crate::recovery::{Delivery, EXIT_LINGER, HEARTBEAT_PERIOD, LIVE_PRIORITY, MAX_CACHE_SAMPLES};
use crate::session::TransportError;
use crate::shutdown::Shutdown;
use std::time::Duration;
use tokio::sync::watch;
use zenoh::bytes::{Encoding, ZBytes};
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Subscriber;
use zenoh::sample::SampleKind;
use zenoh::{Session, Wait};
use zenoh_ext::{AdvancedPublisher, AdvancedPublisherBuilderExt, CacheConfig, MissDetectionConfig};

/// The encoding that tags a protobuf payload of message `name` (its full name).
pub fn protobuf(name: &str) -> Encoding {
    Encoding::APPLICATION_PROTOBUF.with_schema(name)
}

/// A publisher bound to one edge→cloud stream of one source, or to its road map.
///
/// A zenoh-ext `AdvancedPublisher` (see [`crate::recovery`]): reliable, every sample numbered,
/// the last [`Delivery::cache_samples`] kept for the cloud to fetch after an outage, its last
/// number announced every [`HEARTBEAT_PERIOD`]. What a put does under congestion is the [`Delivery`]'s choice.
///
/// Declaring and putting are synchronous: Zenoh resolves them without waiting (its futures for
/// them are ready ones), so async producers and a physics callback call the same code.
pub struct StreamPublisher {
    /// `None` for the road map.
    stream: Option<EdgeStream>,
    publisher: AdvancedPublisher<'static>,
    _route: LivelinessToken,
}

impl StreamPublisher {
    /// Declares the publisher of `stream` for `source` at `site`.
    pub fn declare(
        session: &Session,
        site: &SiteId,
        source: &SourceId,
        stream: EdgeStream,
        delivery: Delivery,
    ) -> Result<Self, TransportError> {
        let key = keyexpr::edge_stream(site, source, stream);
        Self::declare_key(session, key, Some(stream), stream.message(), delivery)
    }

    /// Declares the publisher of the road map of `source` at `site` (`…/<source>/map`), with the
    /// same delivery guarantees as the streams.
    pub fn declare_map(
        session: &Session,
        site: &SiteId,
        source: &SourceId,
        delivery: Delivery,
    ) -> Result<Self, TransportError> {
        Self::declare_key(session, keyexpr::edge_map(site, source), None, keyexpr::EDGE_MAP_MESSAGE, delivery)
    }

    fn declare_key(
        session: &Session,
        key: String,
        stream: Option<EdgeStream>,
        message: &'static str,
        delivery: Delivery,
    ) -> Result<Self, TransportError> {
        // A declared key expression travels as a small numeric id and this end keeps its routes
        // cached; otherwise every sample is matched against the (wildcard) subscriptions again,
        // which measured at a third of raw Zenoh's throughput. The receiving cloud declares the
        // key on its side too (risktwin_cloud::network::routes).
        let declared = session.declare_keyexpr(key.clone()).wait().map_err(|e| TransportError::Declare {
            what: "key expression",
            key: key.clone(),
            reason: e.to_string(),
        })?;
        let cache = CacheConfig::default().max_samples(delivery.cache_samples.clamp(1, MAX_CACHE_SAMPLES));
        let publisher = session
            .declare_publisher(declared)
            .encoding(protobuf(message))
            .priority(LIVE_PRIORITY)
            .congestion_control(delivery.congestion)
            .cache(cache)
            .sample_miss_detection(MissDetectionConfig::default().heartbeat(HEARTBEAT_PERIOD))
            .wait()
            .map_err(|e| TransportError::Declare { what: "publisher", key: key.clone(), reason: e.to_string() })?;
        let route = session.liveliness().declare_token(&key).wait().map_err(|e| TransportError::Declare {
            what: "stream token",
            key,
            reason: e.to_string(),
        })?;
        Ok(StreamPublisher { stream, publisher, _route: route })
    }

    /// The stream this publishes; `None` for the road map.
    pub fn stream(&self) -> Option<EdgeStream> {
        self.stream
    }

    /// The key this publishes on.
    pub fn key(&self) -> &str {
        self.publisher.key_expr().as_str()
    }

    /// Publishes one payload.
    pub fn put(&self, payload: impl Into<ZBytes>) -> Result<(), TransportError> {
        self.publisher
            .put(payload)
            .wait()
            .map_err(|e| TransportError::Put { key: self.key().to_owned(), reason: e.to_string() })
    }

    /// Publishes one payload with an attachment (e.g. a replay's recorded receive time).
    pub fn put_with_attachment(
        &self,
        payload: impl Into<ZBytes>,
        attachment: impl Into<ZBytes>,
    ) -> Result<(), TransportError> {
        self.publisher
            .put(payload)
            .attachment(attachment)
            .wait()
            .map_err(|e| TransportError::Put { key: self.key().to_owned(), reason: e.to_string() })
    }

    /// Waits until some subscriber matches this stream: `Ok(true)` once one does, `Ok(false)` if
    /// `timeout` passes or `shutdown` fires first. Publishing before that point would be lost.
    pub async fn wait_for_subscriber(&self, timeout: Duration, mut shutdown: Shutdown) -> Result<bool, TransportError> {
        let declare_err = |e: zenoh::Error| TransportError::Declare {
            what: "matching listener",
            key: self.key().to_owned(),
            reason: e.to_string(),
        };
        let listener = self.publisher.matching_listener().await.map_err(declare_err)?;
        // Read the status after the listener exists so that no change falls between the two.
        if self.publisher.matching_status().await.map_err(declare_err)?.matching() {
            return Ok(true);
        }
        let wait = async {
            while let Ok(status) = listener.recv_async().await {
                if status.matching() {
                    return true;
                }
            }
            false
        };
        tokio::select! {
            matched = tokio::time::timeout(timeout, wait) => Ok(matched.unwrap_or(false)),
            _ = shutdown.wait() => Ok(false),
        }
    }

    /// Whether some subscriber matches this stream now.
    pub fn matched(&self) -> bool {
        self.publisher.matching_status().wait().is_ok_and(|s| s.matching())
    }

    /// Undeclares the publisher (its cache goes with it: see [`retire`]).
    pub fn undeclare(self) -> Result<(), TransportError> {
        let key = self.key().to_owned();
        self.publisher.undeclare().wait().map_err(|e| TransportError::Declare {
            what: "undeclare",
            key,
            reason: e.to_string(),
        })
    }
}

/// Undeclares an edge's stream publishers once their caches have had [`EXIT_LINGER`] to answer
/// the cloud (see [`linger`]).
pub async fn retire(publishers: impl IntoIterator<Item = StreamPublisher>) -> Result<(), TransportError> {
    let publishers: Vec<StreamPublisher> = publishers.into_iter().collect();
    tokio::time::sleep(linger(&publishers)).await;
    for publisher in publishers {
        publisher.undeclare()?;
    }
    Ok(())
}

/// How long an ending edge keeps `publishers` (and their caches) after its last put:
/// [`EXIT_LINGER`] when some subscriber matches one of them, so that a sample lost just before
/// the edge stopped (a full link queue) is noticed by the cloud at the next heartbeat and
/// fetched; nothing when none does.
pub fn linger<'a>(publishers: impl IntoIterator<Item = &'a StreamPublisher>) -> Duration {
    if publishers.into_iter().any(StreamPublisher::matched) { EXIT_LINGER } else { Duration::ZERO }
}

/// How long an edge waits for another process's token under its own id to go before it refuses
/// to start: Zenoh's default lease (10 s, after which a crashed process's token goes) plus slack.
pub const DUPLICATE_ID_WAIT: Duration = Duration::from_secs(12);

/// How often an edge looks again for a token under its id while it waits.
const DUPLICATE_ID_POLL: Duration = Duration::from_millis(500);

/// Declares the liveliness token of `source`: the cloud sees the edge as alive while it exists.
///
/// Two processes under one id would interleave their sequence numbers, and the cloud would drop
/// one's messages as duplicates of the other's; so an edge first asks whether a token of its id
/// is alive. If one is, it waits up to [`DUPLICATE_ID_WAIT`] (a crashed predecessor's token
/// outlives it by the lease) and then refuses with [`TransportError::DuplicateId`].
pub async fn declare_alive(
    session: &Session,
    site: &SiteId,
    source: &SourceId,
) -> Result<LivelinessToken, TransportError> {
    declare_alive_within(session, site, source, DUPLICATE_ID_WAIT).await
}

/// [`declare_alive`] with another wait for a token under the same id to go.
pub async fn declare_alive_within(
    session: &Session,
    site: &SiteId,
    source: &SourceId,
    wait: Duration,
) -> Result<LivelinessToken, TransportError> {
    let key = keyexpr::liveliness_token(site, source);
    let deadline = tokio::time::Instant::now() + wait;
    let mut warned = false;
    while token_alive(session, &key).await? {
        if tokio::time::Instant::now() >= deadline {
            return Err(TransportError::DuplicateId { site: site.to_string(), id: source.to_string(), wait });
        }
        if !warned {
            tracing::warn!(
                "edge {source}: another process holds id {site}/{source}; waiting up to {wait:?} for it to go"
            );
            warned = true;
        }
        tokio::time::sleep(DUPLICATE_ID_POLL).await;
    }
    session.liveliness().declare_token(key.clone()).await.map_err(|e| TransportError::Declare {
        what: "liveliness token",
        key,
        reason: e.to_string(),
    })
}

/// Whether some session holds the liveliness token `key` now.
async fn token_alive(session: &Session, key: &str) -> Result<bool, TransportError> {
    let declare = |e: String| TransportError::Declare { what: "liveliness query", key: key.to_owned(), reason: e };
    let replies = session.liveliness().get(key).timeout(DUPLICATE_ID_POLL).await.map_err(|e| declare(e.to_string()))?;
    while let Ok(reply) = replies.recv_async().await {
        if reply.result().is_ok_and(|sample| sample.kind() == SampleKind::Put) {
            return Ok(true);
        }
    }
    Ok(false)
}

/// An edge appearing or disappearing, as told by its liveliness token.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Liveness {
    /// The site chunk of the token.
    pub site: String,
    /// The edge's source id.
    pub source: String,
    /// True when it joined, false when it left.
    pub alive: bool,
}

/// Watches every edge's liveliness token at `site` (every site if `None`), including the edges
/// already alive when the watch starts.
pub async fn watch_liveliness<F>(
    session: &Session,
    site: Option<&SiteId>,
    on_change: F,
) -> Result<Subscriber<()>, TransportError>
where
    F: Fn(Liveness) + Send + Sync + 'static,
{
    let key = keyexpr::liveliness_all(site);
    session
        .liveliness()
        .declare_subscriber(key.clone())
        .history(true)
        .callback(move |sample| {
            if let Some((site, source)) = keyexpr::parse_liveliness_key(sample.key_expr().as_str()) {
                let alive = sample.kind() == SampleKind::Put;
                on_change(Liveness { site: site.to_owned(), source: source.to_owned(), alive });
            }
        })
        .await
        .map_err(|e| TransportError::Declare { what: "liveliness subscriber", key, reason: e.to_string() })
}

/// Watches the liveliness token of one edge: the receiver holds whether the token exists, as
/// [`watch_liveliness`] reports it (tokens already alive included). Keep the returned
/// subscriber alive as long as the receiver is read.
pub async fn watch_edge_alive(
    session: &Session,
    site: &SiteId,
    source: &SourceId,
) -> Result<(Subscriber<()>, watch::Receiver<bool>), TransportError> {
    let (alive_tx, alive) = watch::channel(false);
    let source = source.to_string();
    let subscriber = watch_liveliness(session, Some(site), move |change| {
        if change.source == source {
            alive_tx.send_replace(change.alive);
        }
    })
    .await?;
    Ok((subscriber, alive))
}
