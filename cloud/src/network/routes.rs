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
//!
//! The cloud's own periodic puts to many keys (one delivery acknowledgement per edge every
//! 500 ms) go through [`DeclaredKeys`] for the same reason: undeclared, 2,000 vehicles' acks
//! cost the ingest about 10 µs of CPU per received message (14.3–15.1 µs against 5.3).

use risktwin_transport::zenoh::Session;
use risktwin_transport::zenoh::key_expr::KeyExpr;
use std::collections::{HashMap, HashSet};
use std::time::{Duration, Instant};
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

/// Keys this session puts to again and again, declared once each so that Zenoh routes their
/// puts from cache; a key unused for [`DeclaredKeys::IDLE`] is undeclared (an edge that left).
#[derive(Default)]
pub struct DeclaredKeys {
    keys: HashMap<String, (KeyExpr<'static>, Instant)>,
}

impl DeclaredKeys {
    /// How long a declared key may go unused before it is undeclared.
    pub const IDLE: Duration = Duration::from_secs(30);

    /// `key`, declared on `session` at its first use; `None` if it cannot be declared (put it
    /// by name: routed the slow way).
    pub async fn get(&mut self, session: &Session, key: &str, now: Instant) -> Option<KeyExpr<'static>> {
        if let Some((declared, used)) = self.keys.get_mut(key) {
            *used = now;
            return Some(declared.clone());
        }
        match session.declare_keyexpr(key.to_owned()).await {
            Ok(declared) => {
                self.keys.insert(key.to_owned(), (declared.clone(), now));
                Some(declared)
            }
            Err(e) => {
                tracing::warn!("cloud: declaring {key}: {e}");
                None
            }
        }
    }

    /// Undeclares every key unused for [`Self::IDLE`] at `now`.
    pub async fn forget_idle(&mut self, session: &Session, now: Instant) {
        let idle: Vec<String> = self
            .keys
            .iter()
            .filter(|(_, (_, used))| now.duration_since(*used) > Self::IDLE)
            .map(|(k, _)| k.clone())
            .collect();
        for key in idle {
            if let Some((declared, _)) = self.keys.remove(&key)
                && let Err(e) = session.undeclare(declared).await
            {
                tracing::warn!("cloud: undeclaring {key}: {e}");
            }
        }
    }

    /// How many keys are declared.
    pub fn len(&self) -> usize {
        self.keys.len()
    }

    /// Whether none is.
    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_harness::{Router, STEP};
    use super::*;
    use risktwin_transport::connect;
    use tokio::time::timeout;

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_key_is_declared_once_carries_puts_and_is_undeclared_when_idle() {
        let router = Router::start().await;
        let sender = connect(&router.client).await.unwrap();
        let receiver = connect(&router.client).await.unwrap();
        let key = "risktwin/v1/site/veh-1/ack";
        let subscriber = receiver.declare_subscriber(key).await.unwrap();
        let mut keys = DeclaredKeys::default();
        let t0 = Instant::now();
        let first = keys.get(&sender, key, t0).await.unwrap();
        let again = keys.get(&sender, key, t0 + Duration::from_secs(20)).await.unwrap();
        assert_eq!((first.as_str(), again.as_str(), keys.len()), (key, key, 1));
        // A put on the declared key reaches a subscriber of the name (once it is matched).
        let received = timeout(STEP, async {
            loop {
                sender.put(&again, "x").await.unwrap();
                if let Ok(Ok(sample)) = timeout(Duration::from_millis(100), subscriber.recv_async()).await {
                    break sample;
                }
            }
        })
        .await
        .unwrap();
        assert_eq!(received.key_expr().as_str(), key);
        keys.forget_idle(&sender, t0 + DeclaredKeys::IDLE).await;
        assert_eq!(keys.len(), 1, "used 20 s after t0: not idle yet");
        keys.forget_idle(&sender, t0 + Duration::from_secs(21) + DeclaredKeys::IDLE).await;
        assert_eq!(keys.len(), 0, "idle: undeclared");
        drop((subscriber, sender, receiver));
        router.stop().await;
    }
}
