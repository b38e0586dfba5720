//! What became of an edge's messages: the cloud's delivery acknowledgements on the edge's own
//! `ack` key and the cloud's liveliness token, watched while the edge publishes; at its end the
//! edge waits (at most [`ACK_WAIT`]) for acknowledgements that cover what it sent, and reports
//! per stream what was acknowledged, what the cloud counts lost and what stayed undelivered,
//! and when the cloud was gone (docs/keyexpr.md, "Delivery acknowledgements").

use crate::summary::{CloudGone, CloudSeen, DeliverySummary};
use risktwin_common::delivery::{DeliveryAck, DeliveryLedger};
use risktwin_protos::decode_tagged;
use risktwin_transport::keyexpr::{CloudToEdge, cloud_liveliness, cloud_to_edge};
use risktwin_transport::sync::LockExt;
use risktwin_transport::zenoh::Session;
use risktwin_transport::zenoh::pubsub::Subscriber;
use risktwin_transport::zenoh::sample::SampleKind;
use risktwin_transport::{EdgeStream, SiteId, SourceId, TransportError};
use std::collections::BTreeMap;
use std::ops::Range;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::sync::Notify;

/// How long an ending edge waits for acknowledgements of what it sent: the cloud acknowledges
/// every 500 ms, so this leaves room for five of them and a recovery of the last samples.
pub const ACK_WAIT: Duration = Duration::from_secs(3);

/// How long an acknowledgement's word that the cloud sheds a stream holds: four of the cloud's
/// acknowledgement periods (it repeats the word with every one while it sheds).
pub const SHED_HOLD: Duration = Duration::from_secs(2);

/// The longest wait for the answer to the start's question whether a cloud is there.
const PRESENCE_QUERY: Duration = Duration::from_secs(2);

/// Gone-periods of the cloud kept in a summary; later ones are only summed.
const MAX_GONE_LISTED: usize = 32;

/// Ranges of numbers skipped that one [`Numbering`] remembers; beyond them a skipped number
/// counts as undelivered (conservative: a source that skips this often is broken anyway).
const MAX_SKIPPED_RANGES: usize = 4096;

/// One stream's numbers as the edge knows them.
#[derive(Debug, Clone, Default)]
pub struct StreamSent {
    /// Sequence numbers handed out (0..numbered).
    pub numbered: u64,
    /// Messages put.
    pub sent: u64,
    /// Numbers of the messages refused (too large), not put.
    pub refused: Vec<u64>,
    /// Numbers never put for another reason (ranges, disjoint and below `numbered`): samples
    /// a gateway rejected, numbers missing from a replayed recording.
    pub skipped: Vec<Range<u64>>,
}

/// The numbers of one stream an edge forwards rather than numbers itself (a gateway, a
/// replay): numbers arrive in increasing order, and one jumped over was not sent.
#[derive(Debug, Default)]
pub(crate) struct Numbering {
    next: u64,
    sent: u64,
    skipped: Vec<Range<u64>>,
}

impl Numbering {
    /// Counts number `seq` as sent (one below the last is sent but changes no range).
    pub(crate) fn sent(&mut self, seq: u64) {
        if seq > self.next && self.skipped.len() < MAX_SKIPPED_RANGES {
            self.skipped.push(self.next..seq);
        }
        self.next = self.next.max(seq.saturating_add(1));
        self.sent += 1;
    }

    pub(crate) fn count(&self) -> u64 {
        self.sent
    }

    pub(crate) fn stream_sent(&self) -> StreamSent {
        StreamSent { numbered: self.next, sent: self.sent, refused: Vec::new(), skipped: self.skipped.clone() }
    }
}

#[derive(Debug, Default)]
struct Presence {
    /// Tokens alive now, by key (a cloud serving every site has its own).
    alive: BTreeMap<String, bool>,
    seen: bool,
    gone_since: Option<Instant>,
    gone: Vec<CloudGone>,
    gone_total: Duration,
}

impl Presence {
    fn any_alive(&self) -> bool {
        self.alive.values().any(|a| *a)
    }

    fn update(&mut self, key: &str, alive: bool, start: Instant, now: Instant) {
        let was = self.any_alive();
        self.alive.insert(key.to_owned(), alive);
        let is = self.any_alive();
        if is {
            self.seen = true;
        }
        if was && !is {
            self.gone_since = Some(now);
            tracing::warn!("cloud gone ({:.1} s after the start)", now.duration_since(start).as_secs_f64());
        } else if !was
            && is
            && let Some(since) = self.gone_since.take()
        {
            let gone = now.duration_since(since);
            self.close(since, gone, start);
            tracing::info!("cloud back after {:.1} s", gone.as_secs_f64());
        }
    }

    fn close(&mut self, since: Instant, gone: Duration, start: Instant) {
        self.gone_total += gone;
        if self.gone.len() < MAX_GONE_LISTED {
            let at_s = since.duration_since(start).as_secs_f64();
            self.gone.push(CloudGone { at_s, for_s: gone.as_secs_f64() });
        }
    }
}

/// The edge's watch on acknowledgements and on the cloud's presence.
pub struct DeliveryWatch {
    start: Instant,
    ledger: Arc<Mutex<DeliveryLedger>>,
    /// What the latest acknowledgement said the cloud sheds, and when it came.
    shed: Arc<Mutex<(u64, Option<Instant>)>>,
    presence: Arc<Mutex<Presence>>,
    changed: Arc<Notify>,
    subscribers: [Subscriber<()>; 2],
}

impl DeliveryWatch {
    /// Subscribes to the acknowledgements of `source` at `site` and to the cloud's token.
    pub async fn start(session: &Session, site: &SiteId, source: &SourceId) -> Result<Self, TransportError> {
        let start = Instant::now();
        let ledger = Arc::new(Mutex::new(DeliveryLedger::new(session.zid().to_string())));
        let presence = Arc::new(Mutex::new(Presence::default()));
        let changed = Arc::new(Notify::new());
        let key = cloud_to_edge(site, source, CloudToEdge::Ack);
        let (acks, notify) = (Arc::clone(&ledger), Arc::clone(&changed));
        let shed: Arc<Mutex<(u64, Option<Instant>)>> = Arc::default();
        let ordered = Arc::clone(&shed);
        let ack_subscriber = session
            .declare_subscriber(key.clone())
            .callback(move |sample| {
                match decode_tagged::<DeliveryAck>(&sample.encoding().to_string(), &sample.payload().to_bytes()) {
                    Ok(ack) => {
                        // A stream name this edge does not know is no stream it sends.
                        let mask = ack
                            .shed
                            .iter()
                            .filter_map(|name| EdgeStream::from_chunk(name))
                            .fold(0u64, |mask, s| mask | 1 << s.index());
                        if acks.locked().apply(ack) {
                            *ordered.locked() = (mask, Some(Instant::now()));
                        }
                        notify.notify_one();
                    }
                    Err(e) => tracing::warn!("acknowledgement on {} refused: {e}", sample.key_expr()),
                }
            })
            .await
            .map_err(|e| TransportError::Declare { what: "subscriber", key, reason: e.to_string() })?;
        // The token of a cloud serving this site, or every site (`*`): both intersect this key.
        let key = cloud_liveliness(Some(site));
        let (seen, notify) = (Arc::clone(&presence), Arc::clone(&changed));
        let cloud_alive = crate::live_metrics::cloud_alive(site.as_str(), source.as_str());
        let queried_alive = cloud_alive.clone();
        let cloud_subscriber = session
            .liveliness()
            .declare_subscriber(key.clone())
            .history(true)
            .callback(move |sample| {
                let alive = sample.kind() == SampleKind::Put;
                let mut presence = seen.locked();
                presence.update(sample.key_expr().as_str(), alive, start, Instant::now());
                cloud_alive.set(f64::from(u8::from(presence.any_alive())));
                notify.notify_one();
            })
            .await
            .map_err(|e| TransportError::Declare {
                what: "liveliness subscriber",
                key: key.clone(),
                reason: e.to_string(),
            })?;
        // The cloud's tokens as they are now, asked and answered before the edge publishes: the
        // subscriber's history can arrive after a short-lived edge (a replay of a small file
        // takes milliseconds) has already settled, which would then see no cloud at all.
        let query = |e: String| TransportError::Declare { what: "liveliness query", key: key.clone(), reason: e };
        let replies = session.liveliness().get(&key).timeout(PRESENCE_QUERY).await.map_err(|e| query(e.to_string()))?;
        while let Ok(reply) = replies.recv_async().await {
            if let Ok(sample) = reply.result() {
                let mut presence = presence.locked();
                presence.update(sample.key_expr().as_str(), sample.kind() == SampleKind::Put, start, Instant::now());
                queried_alive.set(f64::from(u8::from(presence.any_alive())));
            }
        }
        Ok(DeliveryWatch { start, ledger, shed, presence, changed, subscribers: [ack_subscriber, cloud_subscriber] })
    }

    /// The streams the cloud sheds now (bit [`EdgeStream::index`]): those the latest
    /// acknowledgement named, while it is younger than [`SHED_HOLD`] (a cloud that stopped
    /// acknowledging does not hold the edge back for ever).
    pub fn shed_mask(&self, now: Instant) -> u64 {
        match *self.shed.locked() {
            (mask, Some(at)) if now.duration_since(at) < SHED_HOLD => mask,
            _ => 0,
        }
    }

    /// Waits until acknowledgements say every message of `sent` was received, no cloud's token
    /// is there, or [`ACK_WAIT`] has passed; then undeclares the watch and tells what became of
    /// `sent`. A count of lost ones is not final before the deadline: the cloud counts a gap
    /// lost when it sees it and takes it back when its recovery brings the gap's messages.
    pub async fn settle(self, sent: &[(EdgeStream, StreamSent)]) -> Result<DeliverySummary, TransportError> {
        let deadline = tokio::time::Instant::now() + ACK_WAIT;
        loop {
            // Registered before the state is read, so that no change falls between the two.
            let changed = self.changed.notified();
            let summary = self.summary(sent);
            let received = summary.total_undelivered() == 0 && summary.total_lost() == 0;
            let alive = self.presence.locked().any_alive();
            if received || !alive || tokio::time::Instant::now() >= deadline {
                for subscriber in self.subscribers {
                    subscriber.undeclare().await.map_err(|e| TransportError::Declare {
                        what: "undeclare",
                        key: "(delivery watch)".to_owned(),
                        reason: e.to_string(),
                    })?;
                }
                return Ok(summary);
            }
            let _ = tokio::time::timeout_at(deadline, changed).await;
        }
    }

    fn summary(&self, sent: &[(EdgeStream, StreamSent)]) -> DeliverySummary {
        let ledger = self.ledger.locked();
        let mut summary = DeliverySummary {
            acknowledged: BTreeMap::new(),
            lost: BTreeMap::new(),
            undelivered: BTreeMap::new(),
            too_large: BTreeMap::new(),
            cloud: self.cloud_seen(ledger.heard(), ledger.clouds()),
        };
        for (stream, s) in sent {
            let unsent: Vec<Range<u64>> =
                s.refused.iter().map(|n| *n..n.saturating_add(1)).chain(s.skipped.iter().cloned()).collect();
            let d = ledger.stream(stream.as_str(), s.numbered, s.sent, &unsent);
            let name = stream.as_str().to_owned();
            summary.acknowledged.insert(name.clone(), d.acknowledged);
            summary.lost.insert(name.clone(), d.lost);
            summary.undelivered.insert(name.clone(), d.undelivered);
            summary.too_large.insert(name, s.refused.len() as u64);
        }
        summary
    }

    fn cloud_seen(&self, acknowledged: bool, clouds: usize) -> CloudSeen {
        let presence = self.presence.locked();
        let now = Instant::now();
        let mut gone = presence.gone.clone();
        let mut gone_total = presence.gone_total;
        if let Some(since) = presence.gone_since {
            gone_total += now.duration_since(since);
            if gone.len() < MAX_GONE_LISTED {
                let at_s = since.duration_since(self.start).as_secs_f64();
                gone.push(CloudGone { at_s, for_s: now.duration_since(since).as_secs_f64() });
            }
        }
        CloudSeen {
            seen: presence.seen || acknowledged,
            alive_at_exit: presence.any_alive(),
            acknowledged_by: clouds,
            gone,
            gone_s: gone_total.as_secs_f64(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_number_jumped_over_is_not_sent() {
        let mut n = Numbering::default();
        for seq in [0, 1, 3, 4, 7] {
            n.sent(seq);
        }
        let sent = n.stream_sent();
        assert_eq!((sent.numbered, sent.sent, sent.skipped), (8, 5, vec![2..3, 5..7]));
    }

    #[test]
    fn a_stream_that_starts_late_and_runs_away_stays_bounded() {
        let mut n = Numbering::default();
        n.sent(1000);
        n.sent(u64::MAX - 1);
        n.sent(u64::MAX);
        let sent = n.stream_sent();
        assert_eq!(sent.skipped, vec![0..1000, 1001..u64::MAX - 1]);
        assert_eq!((sent.numbered, sent.sent), (u64::MAX, 3));
        let mut n = Numbering::default();
        for seq in (0..2 * MAX_SKIPPED_RANGES as u64).map(|i| 2 * i + 1) {
            n.sent(seq);
        }
        assert_eq!(n.stream_sent().skipped.len(), MAX_SKIPPED_RANGES);
    }
}
