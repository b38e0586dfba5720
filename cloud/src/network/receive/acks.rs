//! The ingest's side of the delivery acknowledgements (`super::super::ack`): the acks due from
//! its accounting, and the task that puts them outside the ingest's lock.

use super::LiveIngest;
use crate::network::ack::{ACK_PERIOD, MAX_ACKS_PER_PERIOD};
use crate::network::routes::DeclaredKeys;
use risktwin_common::delivery::{DeliveryAck, StreamAck};
use risktwin_common::telemetry::{Frame, Header};
use risktwin_protos::{WireMessage, encode};
use risktwin_transport::keyexpr::{CloudToEdge, cloud_to_edge};
use risktwin_transport::sync::LockExt;
use risktwin_transport::wall_clock::unix_ns;
use risktwin_transport::zenoh::Session;
use risktwin_transport::zenoh::qos::CongestionControl;
use risktwin_transport::{SiteId, SourceId, protobuf};
use std::sync::{Arc, Mutex};
use std::time::Instant;
use tokio::task::JoinHandle;

impl LiveIngest {
    /// The acknowledgements due at `now` from the cloud session `cloud`: (key, payload).
    pub(crate) fn due_acks(&mut self, now: Instant, cloud: &str, max: usize) -> Vec<(String, Vec<u8>)> {
        let wall_ns = unix_ns();
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
            let acks = ingest.locked().due_acks(Instant::now(), &cloud, MAX_ACKS_PER_PERIOD);
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
