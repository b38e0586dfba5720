//! Cached routes for the keys that carry data. Zenoh caches a sample's route only on a
//! resource its own tables know with a context (a declared key expression, subscriber, …);
//! any other sample is matched against the whole resource tree again, and that tree holds a
//! node for every publisher whose recovery cache (a zenoh-ext queryable) it learnt of: at 2,000
//! vehicles one uncached sample cost about 0.5 ms, against a few µs from cache.
//!
//! So the cloud declares on its own session the key of every stream it accepts a first sample
//! from (the ingest tells; see `LiveIngest::with_route_keys`). Declaring on the first accepted
//! sample rather than on an edge's liveliness token declares exactly the keys in use (a
//! vehicle sends 2 of the 5 edge streams) and covers sources without a token (replays, fleet
//! logs).

use risktwin_transport::zenoh::Session;
use risktwin_transport::zenoh::key_expr::KeyExpr;
use std::collections::HashSet;
use tokio::sync::{mpsc, watch};
use tokio::task::JoinHandle;

/// The running declarer: drop every sender (or abort `task`) and it ends.
pub struct RouteKeys {
    pub task: JoinHandle<()>,
    /// How many keys are declared so far.
    pub declared: watch::Receiver<usize>,
}

/// Starts declaring, on `session`, every key sent to the returned sender (each once).
pub fn declare_route_keys(session: &Session) -> (RouteKeys, mpsc::UnboundedSender<String>) {
    let (keys_tx, mut keys) = mpsc::unbounded_channel::<String>();
    let (declared_tx, declared) = watch::channel(0);
    let session = session.clone();
    // Declaring from inside a Zenoh callback (where the ingest runs) would re-enter Zenoh's
    // tables; a task does it.
    let task = tokio::spawn(async move {
        let mut seen = HashSet::new();
        let mut held: Vec<KeyExpr<'static>> = Vec::new();
        while let Some(key) = keys.recv().await {
            if !seen.insert(key.clone()) {
                continue;
            }
            match session.declare_keyexpr(key).await {
                Ok(declared) => held.push(declared),
                // Only an optimisation: the samples still arrive, routed the slow way.
                Err(e) => tracing::warn!("cloud: declaring a stream key: {e}"),
            }
            declared_tx.send_replace(held.len());
        }
    });
    (RouteKeys { task, declared }, keys_tx)
}
