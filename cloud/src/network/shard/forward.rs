//! The forward of a sharded worker's accepted samples to the union.

use super::ShardSummary;
use risktwin_transport::keyexpr::{self, parse_edge_key};
use risktwin_transport::recovery::LIVE_PRIORITY;
use risktwin_transport::sync::LockExt;
use risktwin_transport::zenoh::bytes::{Encoding, ZBytes};
use risktwin_transport::zenoh::pubsub::Publisher;
use risktwin_transport::zenoh::qos::CongestionControl;
use risktwin_transport::zenoh::{Session, Wait};
use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use tokio::sync::mpsc;
use tokio::task::JoinHandle;

/// Forwards accepted samples to the union, each edge key's forward key declared once (by a task:
/// declaring inside the receive callback would re-enter Zenoh's tables, see [`super::routes`]).
/// `CongestionControl::Block`: a union that cannot keep up slows this worker's receive path,
/// whose own link then drops, and those samples come back from the edges' caches; nothing is
/// dropped between worker and union unseen.
pub(super) struct Forwarder {
    session: Session,
    /// Publishers by edge key; `None` while being declared.
    declared: Arc<Mutex<HashMap<String, Option<Publisher<'static>>>>>,
    declare: mpsc::UnboundedSender<String>,
    pub(super) task: JoinHandle<()>,
    forwarded: AtomicU64,
    failed: AtomicU64,
}

impl Forwarder {
    pub(super) fn start(session: &Session) -> Self {
        let (declare, mut keys) = mpsc::unbounded_channel::<String>();
        let declared: Arc<Mutex<HashMap<String, Option<Publisher<'static>>>>> = Arc::default();
        let (held, on) = (Arc::clone(&declared), session.clone());
        // `put` sends each edge key once (it enters the map as `None` when sent).
        let task = tokio::spawn(async move {
            while let Some(edge_key) = keys.recv().await {
                declare_forward(&on, &held, edge_key).await;
            }
        });
        Forwarder {
            session: session.clone(),
            declared,
            declare,
            task,
            forwarded: AtomicU64::new(0),
            failed: AtomicU64::new(0),
        }
    }

    /// Declares the forward of `edge_key` now unless it is: a fetch's samples, put in a burst,
    /// would each be routed the slow way (about a millisecond) before the task declared it.
    pub(super) async fn prepare(&self, edge_key: &str) {
        let absent = !self.declared.locked().contains_key(edge_key);
        if absent {
            declare_forward(&self.session, &self.declared, edge_key.to_owned()).await;
        }
    }

    /// Its counts, into `summary`.
    pub(super) fn count(&self, summary: &mut ShardSummary) {
        summary.forwarded = self.forwarded.load(Ordering::Relaxed);
        summary.forward_failed = self.failed.load(Ordering::Relaxed);
    }

    /// Forwards `sample` (its payload shared, not copied) under its edge key's forward key, with
    /// its attachment (a replay's receive time, which a `--replay-time` union ingests at).
    pub(super) fn put(&self, sample: &risktwin_transport::zenoh::sample::Sample) {
        let edge_key = sample.key_expr().as_str();
        let (payload, encoding): (ZBytes, Encoding) = (sample.payload().clone(), sample.encoding().clone());
        let attachment = sample.attachment().cloned();
        let mut declared = self.declared.locked();
        let ok = match declared.get(edge_key) {
            Some(Some(publisher)) => publisher.put(payload).encoding(encoding).attachment(attachment).wait().is_ok(),
            known => {
                if known.is_none() {
                    declared.insert(edge_key.to_owned(), None);
                    let _ = self.declare.send(edge_key.to_owned());
                }
                drop(declared);
                let Some(forward_key) = parse_edge_key(edge_key).map(|k| keyexpr::ingested(&k)) else { return };
                self.session
                    .put(forward_key, payload)
                    .encoding(encoding)
                    .attachment(attachment)
                    .congestion_control(CongestionControl::Block)
                    .priority(LIVE_PRIORITY)
                    .wait()
                    .is_ok()
            }
        };
        let counter = if ok { &self.forwarded } else { &self.failed };
        counter.fetch_add(1, Ordering::Relaxed);
    }
}

/// Declares the publisher that forwards `edge_key`'s samples, into `declared`.
async fn declare_forward(
    session: &Session,
    declared: &Mutex<HashMap<String, Option<Publisher<'static>>>>,
    edge_key: String,
) {
    let Some(forward_key) = parse_edge_key(&edge_key).map(|k| keyexpr::ingested(&k)) else { return };
    let publisher = session
        .declare_publisher(forward_key)
        .congestion_control(CongestionControl::Block)
        .priority(LIVE_PRIORITY)
        .await;
    match publisher {
        Ok(p) => {
            declared.locked().insert(edge_key, Some(p));
        }
        Err(e) => tracing::warn!("shard: declaring the forward of {edge_key}: {e} (put one by one)"),
    }
}
