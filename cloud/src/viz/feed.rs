//! What the rest of the cloud hands the viz role: a [`VizFeed`] copies a message into a bounded
//! queue only while a Foxglove client is connected, and counts the messages the queue had no
//! room for instead of waiting. It never blocks, so the ingest may call it on its receive path.

use risktwin_common::road::Road;
use risktwin_transport::sync::LockExt;
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use tokio::sync::mpsc::error::TrySendError;
use tokio::sync::mpsc::{Sender, UnboundedSender};

/// Messages the queue to the relay holds; beyond, new ones are dropped and counted. About a
/// second of 80 vehicles' states (50 Hz each), a few hundred bytes each.
pub(crate) const QUEUE_MESSAGES: usize = 4096;

/// One encoded message on its way to the relay: the topic and the payload in one buffer, so a
/// relayed message costs one allocation.
#[derive(Debug)]
pub(crate) struct VizMessage {
    bytes: Vec<u8>,
    topic_len: usize,
    /// Full name of the protobuf message (the channel's schema).
    pub(crate) schema: &'static str,
    /// The cloud time the message stands for, ns since the Unix epoch (its log time in a
    /// recording).
    pub(crate) log_time_ns: u64,
}

impl VizMessage {
    pub(crate) fn new(topic: &str, schema: &'static str, log_time_ns: u64, payload: &[u8]) -> Self {
        let mut bytes = Vec::with_capacity(topic.len() + payload.len());
        bytes.extend_from_slice(topic.as_bytes());
        bytes.extend_from_slice(payload);
        VizMessage { bytes, topic_len: topic.len(), schema, log_time_ns }
    }

    pub(crate) fn topic(&self) -> &str {
        // The first `topic_len` bytes were a `&str`.
        std::str::from_utf8(&self.bytes[..self.topic_len]).unwrap_or_default()
    }

    pub(crate) fn payload(&self) -> &[u8] {
        &self.bytes[self.topic_len..]
    }
}

/// What the feed, the relay and the server's listener share.
#[derive(Debug, Default)]
pub(crate) struct VizShared {
    /// Clients connected now.
    pub(crate) clients: AtomicUsize,
    /// Clients that ever connected.
    pub(crate) clients_seen: AtomicU64,
    pub(crate) counts: Mutex<VizCounts>,
}

/// Messages per topic.
#[derive(Debug, Default)]
pub(crate) struct VizCounts {
    /// Handed to the server for at least one subscribed client.
    pub(crate) sent: BTreeMap<String, u64>,
    /// Not relayed: the queue to the relay was full.
    pub(crate) dropped: BTreeMap<String, u64>,
}

impl VizShared {
    pub(crate) fn counts(&self) -> std::sync::MutexGuard<'_, VizCounts> {
        self.counts.locked()
    }
}

/// Adds one to `topic`'s count, allocating its name only the first time.
pub(crate) fn count(counts: &mut BTreeMap<String, u64>, topic: &str) {
    match counts.get_mut(topic) {
        Some(n) => *n += 1,
        None => {
            counts.insert(topic.to_owned(), 1);
        }
    }
}

/// The viz role's input: cheap to clone, never blocks.
#[derive(Debug, Clone)]
pub struct VizFeed {
    pub(crate) messages: Sender<VizMessage>,
    pub(crate) roads: UnboundedSender<(String, Road)>,
    pub(crate) shared: Arc<VizShared>,
}

impl VizFeed {
    /// Whether a client is connected (else offered messages are not even copied).
    pub fn watched(&self) -> bool {
        self.shared.clients.load(Ordering::Relaxed) > 0
    }

    /// Relays `payload`, an encoded `schema` message, on `topic` stamped `log_time_ns`, when a
    /// client is connected and the queue has room (else counted dropped).
    pub fn offer(&self, topic: &str, schema: &'static str, log_time_ns: u64, payload: &[u8]) {
        if !self.watched() {
            return;
        }
        match self.messages.try_send(VizMessage::new(topic, schema, log_time_ns, payload)) {
            Ok(()) => {}
            Err(TrySendError::Full(message)) => count(&mut self.shared.counts().dropped, message.topic()),
            // The relay has stopped: the cloud is shutting down.
            Err(TrySendError::Closed(_)) => {}
        }
    }

    /// `site`'s twin runs on `road` from now on (a scene's road map): shown as its road.
    pub fn set_road(&self, site: &str, road: &Road) {
        // A closed channel means the relay has stopped: nothing left to show.
        let _ = self.roads.send((site.to_owned(), road.clone()));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn feed(capacity: usize) -> (VizFeed, tokio::sync::mpsc::Receiver<VizMessage>) {
        let (messages, rx) = tokio::sync::mpsc::channel(capacity);
        let (roads, _) = tokio::sync::mpsc::unbounded_channel();
        (VizFeed { messages, roads, shared: Arc::default() }, rx)
    }

    #[test]
    fn nothing_is_copied_while_nobody_watches_and_a_full_queue_counts_drops() {
        let (feed, mut rx) = feed(2);
        feed.offer("risktwin/v1/s/veh/state", "risktwin.v1.VehicleState", 7, b"abc");
        assert!(rx.try_recv().is_err(), "no client: nothing queued");
        feed.shared.clients.store(1, Ordering::Relaxed);
        for _ in 0..3 {
            feed.offer("risktwin/v1/s/veh/state", "risktwin.v1.VehicleState", 7, b"abc");
        }
        let first = rx.try_recv().expect("queued");
        assert_eq!((first.topic(), first.payload(), first.log_time_ns), ("risktwin/v1/s/veh/state", &b"abc"[..], 7));
        assert_eq!(feed.shared.counts().dropped.get("risktwin/v1/s/veh/state"), Some(&1), "the third had no room");
    }
}
