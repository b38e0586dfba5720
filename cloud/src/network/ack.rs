//! Delivery acknowledgements from the ingest to the edges (docs/keyexpr.md, "Delivery
//! acknowledgements"): every [`ACK_PERIOD`], each source whose accounting moved within the last
//! [`ACK_REPEAT`] gets one `DeliveryAck` on `risktwin/v1/<site>/<source>/ack` telling, per stream,
//! the next sequence number the cloud waits for, what it received and what it counts lost.
//!
//! One message per active source and period, never one per sample; a source quiet for longer
//! than [`ACK_REPEAT`] costs nothing (its last state went out four times), and at most
//! [`MAX_ACKS_PER_PERIOD`] go out per period, the longest-unacknowledged first. The acks are made
//! under the ingest's lock (a few hash lookups per source) and put outside it, by a task, never
//! from the receive callback.

use super::receive::LiveIngest;
use super::routes::DeclaredKeys;
use risktwin_common::delivery::{DeliveryAck, StreamAck};
use risktwin_common::telemetry::{Frame, Header};
use risktwin_protos::{WireMessage, encode};
use risktwin_transport::keyexpr::{CloudToEdge, cloud_to_edge};
use risktwin_transport::zenoh::Session;
use risktwin_transport::zenoh::qos::CongestionControl;
use risktwin_transport::zenoh::session::ZenohId;
use risktwin_transport::{SiteId, SourceId, protobuf};
use std::collections::HashMap;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};
use tokio::task::JoinHandle;

/// How often the ingest acknowledges.
pub const ACK_PERIOD: Duration = Duration::from_millis(500);

/// How long after its accounting last moved a source is still acknowledged (each period): a
/// lost acknowledgement is made good by the next ones, and an edge waiting at its exit hears
/// the final state more than once.
pub const ACK_REPEAT: Duration = Duration::from_secs(2);

/// The most acknowledgements per period (40 000 a second): a cloud facing more active sources
/// acknowledges each less often, never more.
pub const MAX_ACKS_PER_PERIOD: usize = 20_000;

/// One acknowledged source.
#[derive(Debug, Clone)]
struct AckSource {
    site: String,
    /// The session of the last sample accepted (its publisher's process).
    publisher: Option<ZenohId>,
    changed: Instant,
    acked: Option<Instant>,
}

/// The sources whose accounting moved lately (bounded by the ingest's source limit: only
/// accepted samples enter, and quiet ones leave).
#[derive(Debug, Default)]
pub struct AckSources {
    sources: HashMap<String, AckSource>,
    /// This cloud's acknowledgements so far (the header seq of the next one).
    seq: u64,
}

impl AckSources {
    /// A sample of `source` (at `site`, published by session `publisher`) was accepted at `now`.
    pub fn touch(&mut self, site: &str, source: &str, publisher: Option<ZenohId>, now: Instant) {
        // Look up by &str first so that a known source costs no allocation.
        match self.sources.get_mut(source) {
            Some(s) => {
                s.changed = now;
                if publisher.is_some() {
                    s.publisher = publisher;
                }
                if s.site != site {
                    site.clone_into(&mut s.site);
                }
            }
            None => {
                let entry = AckSource { site: site.to_owned(), publisher, changed: now, acked: None };
                self.sources.insert(source.to_owned(), entry);
            }
        }
    }

    /// The sources to acknowledge at `now` (site, source, publisher), at most `max`, the longest
    /// unacknowledged first; they count as acknowledged from now on. Sources quiet for longer
    /// than [`ACK_REPEAT`] are forgotten.
    fn due(&mut self, now: Instant, max: usize) -> Vec<(String, String, Option<ZenohId>)> {
        self.sources.retain(|_, s| now.duration_since(s.changed) <= ACK_REPEAT);
        let mut due: Vec<(&String, &mut AckSource)> = self.sources.iter_mut().collect();
        if due.len() > max {
            // `None` (never acknowledged) sorts first.
            due.select_nth_unstable_by_key(max, |(_, s)| s.acked);
            due.truncate(max);
        }
        due.into_iter()
            .map(|(source, s)| {
                s.acked = Some(now);
                (s.site.clone(), source.clone(), s.publisher)
            })
            .collect()
    }

    fn next_seq(&mut self) -> u64 {
        let seq = self.seq;
        self.seq += 1;
        seq
    }
}

impl LiveIngest {
    /// The acknowledgements due at `now` from the cloud session `cloud`: (key, payload).
    pub(crate) fn due_acks(&mut self, now: Instant, cloud: &str, max: usize) -> Vec<(String, Vec<u8>)> {
        let wall_ns = SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.as_nanos() as i64);
        let shed: Vec<String> = self.shed_streams().iter().map(|s| s.as_str().to_owned()).collect();
        let due = self.acks_mut().due(now, max);
        let mut out = Vec::with_capacity(due.len());
        for (site, source, publisher) in due {
            let (Ok(site_id), Ok(source_id), Some(publisher)) = (SiteId::new(&site), SourceId::new(&source), publisher)
            else {
                // A sample without its publisher's session (not an advanced publisher's) cannot be
                // acknowledged to one process; an invalid id has no key.
                continue;
            };
            let streams: Vec<StreamAck> = self
                .progress(&source)
                .into_iter()
                .map(|(stream, p)| StreamAck {
                    stream: stream.as_str().to_owned(),
                    next_seq: p.next_seq,
                    received: p.received,
                    lost: p.lost,
                })
                .collect();
            let header = Header {
                source: "cloud".to_owned(),
                seq: self.acks_mut().next_seq(),
                capture_time_ns: wall_ns,
                publish_time_ns: wall_ns,
                frame: Frame::World,
            };
            let ack = DeliveryAck {
                header,
                edge_source: source,
                edge_session: publisher.to_string(),
                cloud_session: cloud.to_owned(),
                streams,
                shed: shed.clone(),
            };
            out.push((cloud_to_edge(&site_id, &source_id, CloudToEdge::Ack), encode(&ack)));
        }
        out
    }
}

/// Publishes the ingest's acknowledgements every [`ACK_PERIOD`] until aborted.
pub(crate) fn spawn_acks(session: Session, ingest: Arc<Mutex<LiveIngest>>) -> JoinHandle<()> {
    tokio::spawn(async move {
        let cloud = session.zid().to_string();
        let encoding = protobuf(DeliveryAck::PROTO_NAME);
        let mut keys = DeclaredKeys::default();
        let mut every = tokio::time::interval(ACK_PERIOD);
        every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            every.tick().await;
            let acks = ingest.lock().unwrap_or_else(PoisonError::into_inner).due_acks(
                Instant::now(),
                &cloud,
                MAX_ACKS_PER_PERIOD,
            );
            let now = Instant::now();
            for (key, payload) in acks {
                let put = match keys.get(&session, &key, now).await {
                    Some(declared) => session.put(declared, payload),
                    None => session.put(&key, payload),
                };
                // Latest-value data: a full link drops it, and the next period's says the same or more.
                if let Err(e) = put.encoding(encoding.clone()).congestion_control(CongestionControl::Drop).await {
                    tracing::warn!("ingest: acknowledgement on {key} not sent: {e}");
                }
            }
            keys.forget_idle(&session, now).await;
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quiet_sources_are_forgotten_and_the_longest_unacknowledged_go_first() {
        let mut acks = AckSources::default();
        let t0 = Instant::now();
        for source in ["a", "b", "c"] {
            acks.touch("site", source, None, t0);
        }
        let first: Vec<String> = acks.due(t0, 2).into_iter().map(|(_, s, _)| s).collect();
        assert_eq!(first.len(), 2, "at most the budget");
        let second: Vec<String> = acks.due(t0 + ACK_PERIOD, 2).into_iter().map(|(_, s, _)| s).collect();
        let missed = ["a", "b", "c"].into_iter().find(|s| !first.iter().any(|f| f == s)).unwrap();
        assert!(second.iter().any(|s| s == missed), "the one left out goes next: {first:?} then {second:?}");
        acks.touch("site", "a", None, t0 + ACK_REPEAT);
        let later = acks.due(t0 + ACK_REPEAT + ACK_PERIOD, 10);
        assert_eq!(later.len(), 1, "only a is still moving: {later:?}");
        assert_eq!(acks.sources.len(), 1, "the quiet ones are forgotten");
    }
}
