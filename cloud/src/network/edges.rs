//! Watching the edges: liveliness tokens tell which edges are alive (logged, summarised).

use super::liveliness::LivenessLog;
use super::receive::LiveIngest;
use risktwin_transport::sync::LockExt;
use risktwin_transport::zenoh::Session;
use risktwin_transport::zenoh::pubsub::Subscriber;
use risktwin_transport::{SiteId, TransportError, watch_liveliness};
use std::sync::{Arc, Mutex};

/// Starts watching the edges at `site` (every site if `None`), recording joins and leaves; an
/// edge that left is a new incarnation for `ingest` when it comes back (a restarted process
/// numbers its messages from 0 again, which would otherwise be refused as duplicates). Drop the
/// subscriber (or undeclare it) to stop.
pub async fn watch_edges(
    session: &Session,
    site: Option<&SiteId>,
    log: Arc<Mutex<LivenessLog>>,
    ingest: Arc<Mutex<LiveIngest>>,
) -> Result<Subscriber<()>, TransportError> {
    watch_liveliness(session, site, move |change| {
        log.locked().record(&change);
        if !change.alive {
            ingest.locked().edge_left(&change.site, &change.source);
        }
    })
    .await
}
