//! The warning role's puts: each hazard warning goes out on its vehicle's key
//! (`risktwin/v1/<site>/<vehicle>/warning`) from inside the ingest's Zenoh callback, so nothing
//! waits between the triggering message's receipt and the put (no channel, no task hop; the
//! twin's outputs, in contrast, go through the publisher task).
//!
//! One declared publisher per vehicle (its key travels as a numeric id). Declaring from inside
//! the callback would re-enter Zenoh's tables (see [`super::routes`]), so the warner's join and
//! leave of a vehicle (its first accepted state; forgotten, or its edge left) go over a channel
//! to a task that declares and undeclares. A warning whose publisher is not declared yet (the
//! first ones after a vehicle's first state) is put once on the session with the same QoS.
//! Both: express (not batched with other messages), at `InteractiveHigh` (above the edge
//! streams' `DataHigh`), `CongestionControl::Drop` (a stalled link never stalls the ingest; the
//! next critical message warns again).

use crate::warning::{WarningSink, WarningSummary};
use risktwin_common::telemetry::HazardWarning;
use risktwin_protos::{WireMessage, encode};
use risktwin_transport::protobuf;
use risktwin_transport::sync::LockExt;
use risktwin_transport::wall_clock::unix_ns;
use risktwin_transport::zenoh::pubsub::Publisher;
use risktwin_transport::zenoh::qos::{CongestionControl, Priority};
use risktwin_transport::zenoh::{Session, Wait};
use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use tokio::sync::{mpsc, watch};
use tokio::task::JoinHandle;

/// The QoS of every warning put (see the module doc).
pub const PRIORITY: Priority = Priority::InteractiveHigh;
pub const CONGESTION: CongestionControl = CongestionControl::Drop;
pub const EXPRESS: bool = true;

/// What the declaring task is asked to do.
enum Change {
    Declare(String),
    Undeclare(String),
}

/// The publishers declared so far, by key.
type Declared = Arc<Mutex<HashMap<String, Publisher<'static>>>>;

/// The running declarer: it ends once the sink is dropped (or abort `task`).
pub struct WarningPublishers {
    pub task: JoinHandle<()>,
    /// How many publishers are declared now.
    pub declared: watch::Receiver<usize>,
}

/// The sink that puts warnings on `session` (see the module doc), and its declaring task.
pub struct NetworkSink {
    session: Session,
    declared: Declared,
    changes: mpsc::UnboundedSender<Change>,
    via_publisher: u64,
    one_off: u64,
}

/// Starts the declaring task on `session` (needs a Tokio runtime) and returns the sink that
/// feeds it.
pub fn warning_sink(session: &Session) -> (NetworkSink, WarningPublishers) {
    let (changes, mut rx) = mpsc::unbounded_channel::<Change>();
    let (count_tx, count) = watch::channel(0);
    let declared: Declared = Arc::default();
    let held = Arc::clone(&declared);
    let on = session.clone();
    let task = tokio::spawn(async move {
        while let Some(change) = rx.recv().await {
            match change {
                Change::Declare(key) => {
                    if held.locked().contains_key(&key) {
                        continue;
                    }
                    let publisher = on
                        .declare_publisher(key.clone())
                        .encoding(protobuf(HazardWarning::PROTO_NAME))
                        .congestion_control(CONGESTION)
                        .priority(PRIORITY)
                        .express(EXPRESS)
                        .await;
                    match publisher {
                        Ok(p) => {
                            held.locked().insert(key, p);
                        }
                        // The warnings still go out, put one by one.
                        Err(e) => tracing::warn!("warning: declaring the publisher of {key} failed: {e}"),
                    }
                }
                Change::Undeclare(key) => {
                    let gone = held.locked().remove(&key);
                    if let Some(p) = gone
                        && let Err(e) = p.undeclare().await
                    {
                        tracing::debug!("warning: undeclaring the publisher of {key}: {e}");
                    }
                }
            }
            count_tx.send_replace(held.locked().len());
        }
    });
    let sink = NetworkSink { session: session.clone(), declared, changes, via_publisher: 0, one_off: 0 };
    (sink, WarningPublishers { task, declared: count })
}

impl WarningSink for NetworkSink {
    fn joined(&mut self, key: &str) {
        // A closed receiver means shutdown: the one-off puts still work.
        let _ = self.changes.send(Change::Declare(key.to_owned()));
    }

    fn left(&mut self, key: &str) {
        let _ = self.changes.send(Change::Undeclare(key.to_owned()));
    }

    fn put(&mut self, key: &str, warning: &HazardWarning) -> bool {
        // The header's publish time: now, as the put goes out (the warner, clock-free, leaves the
        // trigger's receive time there).
        let mut stamped = warning.clone();
        stamped.header.publish_time_ns = unix_ns();
        let payload = encode(&stamped);
        let declared = self.declared.locked();
        if let Some(publisher) = declared.get(key) {
            let ok = publisher.put(payload).wait().is_ok();
            self.via_publisher += u64::from(ok);
            return ok;
        }
        drop(declared);
        let ok = self
            .session
            .put(key, payload)
            .encoding(protobuf(HazardWarning::PROTO_NAME))
            .congestion_control(CONGESTION)
            .priority(PRIORITY)
            .express(EXPRESS)
            .wait()
            .is_ok();
        self.one_off += u64::from(ok);
        ok
    }

    fn count(&self, summary: &mut WarningSummary) {
        summary.via_publisher += self.via_publisher;
        summary.one_off += self.one_off;
    }
}
