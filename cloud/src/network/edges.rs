//! Watching the edges: liveliness tokens tell which edges are alive (logged, summarised), and
//! each edge seen joining gets its stream keys declared on the cloud's session so that Zenoh
//! routes its samples from cache instead of matching each one against the wildcard
//! subscription.

use super::liveliness::LivenessLog;
use super::receive::LiveIngest;
use risktwin_transport::zenoh::Session;
use risktwin_transport::zenoh::pubsub::Subscriber;
use risktwin_transport::{SiteId, SourceId, TransportError, declare_edge_keys, watch_liveliness};
use std::sync::{Arc, Mutex, PoisonError};
use tokio::sync::{mpsc, watch};
use tokio::task::JoinHandle;

/// The running watch: drop `subscriber` (or undeclare it) and `declarer` ends by itself.
pub struct EdgeWatch {
    pub subscriber: Subscriber<()>,
    pub declarer: JoinHandle<()>,
    /// How many edges have had their keys declared so far.
    pub declared: watch::Receiver<usize>,
}

/// Starts watching the edges at `site` (every site if `None`), recording joins and leaves; an
/// edge that left is a new incarnation for `ingest` when it comes back (a restarted process
/// numbers its messages from 0 again, which would otherwise be refused as duplicates).
pub async fn watch_edges(
    session: &Session,
    site: Option<&SiteId>,
    log: Arc<Mutex<LivenessLog>>,
    ingest: Arc<Mutex<LiveIngest>>,
) -> Result<EdgeWatch, TransportError> {
    let (joined_tx, mut joined) = mpsc::unbounded_channel();
    let subscriber = watch_liveliness(session, site, move |change| {
        log.lock().unwrap_or_else(PoisonError::into_inner).record(&change);
        if !change.alive {
            ingest.lock().unwrap_or_else(PoisonError::into_inner).edge_left(&change.site, &change.source);
        }
        if change.alive {
            // The receiver lives as long as the subscriber; a closed one means shutdown.
            let _ = joined_tx.send((change.site, change.source));
        }
    })
    .await?;
    let (declared_tx, declared) = watch::channel(0);
    let session = session.clone();
    // Declaring from inside the liveliness callback would re-enter Zenoh; a task does it.
    let declarer = tokio::spawn(async move {
        let mut keys = Vec::new();
        while let Some((site, source)) = joined.recv().await {
            let (Ok(site), Ok(source)) = (SiteId::new(site), SourceId::new(source)) else { continue };
            match declare_edge_keys(&session, &site, &source).await {
                Ok(declared) => keys.extend(declared),
                // Only an optimisation: samples still arrive through the wildcard subscription.
                Err(e) => tracing::warn!("cloud: {e}"),
            }
            declared_tx.send_modify(|n| *n += 1);
        }
    });
    Ok(EdgeWatch { subscriber, declarer, declared })
}
