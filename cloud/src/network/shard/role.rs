//! A sharded worker's life: joining (the workers and sources alive, this worker's groups, then
//! its token), following the comings and goings, and leaving.

use super::{Forwarder, HANDOVER_SAMPLES, MEMBERS_WAIT, Owners, Shard, ShardSummary};
use crate::network::receive::LiveIngest;
use crate::network::{ingest_sink_then, loss_sink};
use risktwin_transport::keyexpr;
use risktwin_transport::zenoh::Session;
use risktwin_transport::zenoh::sample::SampleKind;
use risktwin_transport::zenoh::{liveliness::LivelinessToken, pubsub::Subscriber};
use risktwin_transport::{Shutdown, SiteId, TransportError};
use std::collections::{BTreeSet, HashMap};
use std::sync::atomic::AtomicU64;
use std::sync::{Arc, Mutex, Weak};
use tokio::sync::mpsc;
use tokio::task::JoinHandle;

/// A change seen on a liveliness token.
enum Change {
    /// A worker's token came or went.
    Worker { id: String, alive: bool },
    /// An edge's token came: a source to know of (one that goes is remembered).
    Source(String),
}

/// A running sharded worker: its token, subscriptions and membership task.
pub struct ShardRole {
    token: LivelinessToken,
    workers: Subscriber<()>,
    edges: Subscriber<()>,
    task: JoinHandle<()>,
    shard: Arc<Shard>,
    forward: Arc<Forwarder>,
}

fn declare_err(what: &'static str, key: &str, e: risktwin_transport::zenoh::Error) -> TransportError {
    TransportError::Declare { what, key: key.to_owned(), reason: e.to_string() }
}

/// The tokens alive under `key` now (waiting [`MEMBERS_WAIT`] at most), each as `parse` names it.
async fn alive_now(
    session: &Session,
    key: &str,
    what: &'static str,
    parse: impl Fn(&str) -> Option<&str>,
) -> Result<BTreeSet<String>, TransportError> {
    let replies = session.liveliness().get(key).timeout(MEMBERS_WAIT).await.map_err(|e| declare_err(what, key, e))?;
    let mut alive = BTreeSet::new();
    while let Ok(reply) = replies.recv_async().await {
        if let Some(id) = reply.result().ok().and_then(|s| parse(s.key_expr().as_str()).map(str::to_owned)) {
            alive.insert(id);
        }
    }
    Ok(alive)
}

/// The source of an edge token's key.
fn edge_of(key: &str) -> Option<&str> {
    keyexpr::parse_liveliness_key(key).map(|(_, source)| source)
}

impl ShardRole {
    /// Joins the workers of `site` and starts owning sources; accepted messages go into
    /// `ingest` and on to the union.
    pub async fn start(
        session: &Session,
        site: &SiteId,
        ingest: Arc<Mutex<LiveIngest>>,
        shutdown: Shutdown,
    ) -> Result<ShardRole, TransportError> {
        let me = session.zid().to_string();
        let (workers_key, edges_key) = (keyexpr::worker_liveliness_all(site), keyexpr::liveliness_all(Some(site)));
        // The workers and sources alive now, before this one owns anything: otherwise it would
        // take (and ask the caches for) every source until the workers' tokens arrived.
        let (mut workers, sources) = tokio::try_join!(
            alive_now(session, &workers_key, "workers' liveliness query", keyexpr::parse_worker_liveliness_key),
            alive_now(session, &edges_key, "edges' liveliness query", edge_of),
        )?;
        workers.insert(me.clone());
        tracing::info!("shard: this worker is {me}");
        tracing::info!("shard: workers at start ({} alive), {} sources", workers.len(), sources.len());
        let forward = Arc::new(Forwarder::start(session));
        let summary = ShardSummary {
            worker: me.clone(),
            workers_max: workers.len(),
            workers_at_exit: workers.len(),
            ..ShardSummary::default()
        };
        let mut owners = Owners { me: me.clone(), workers, sources: HashMap::new() };
        for source in &sources {
            owners.learn(source);
        }
        let to_union = Arc::clone(&forward);
        let shard = Arc::new(Shard {
            owners: Mutex::new(owners),
            deliver: Box::new(ingest_sink_then(Arc::clone(&ingest), move |sample, handled| {
                if handled.forwarded() {
                    to_union.put(sample);
                }
            })),
            count_loss: Box::new(loss_sink(ingest)),
            forward: Arc::clone(&forward),
            subscriptions: tokio::sync::Mutex::default(),
            fetch_slots: tokio::sync::Semaphore::new(super::FETCHES_IN_FLIGHT),
            session: session.clone(),
            site: site.clone(),
            runtime: tokio::runtime::Handle::current(),
            skipped: AtomicU64::new(0),
            fetches: AtomicU64::new(0),
            fetched: AtomicU64::new(0),
            summary: Mutex::new(summary),
        });
        // This worker's groups before its token: a worker that hands a group over on seeing the
        // token finds this one already subscribed.
        shard.subscribe_groups().await;
        let (changes_tx, changes) = mpsc::unbounded_channel();
        let to_follow = changes_tx.clone();
        let edges = session
            .liveliness()
            .declare_subscriber(edges_key.clone())
            .history(true)
            .callback(move |sample| {
                if let (Some(id), SampleKind::Put) = (edge_of(sample.key_expr().as_str()), sample.kind()) {
                    let _ = to_follow.send(Change::Source(id.to_owned()));
                }
            })
            .await
            .map_err(|e| declare_err("edges' liveliness subscriber", &edges_key, e))?;
        let workers = session
            .liveliness()
            .declare_subscriber(workers_key.clone())
            .history(true)
            .callback(move |sample| {
                if let Some(id) = keyexpr::parse_worker_liveliness_key(sample.key_expr().as_str()) {
                    let alive = sample.kind() == SampleKind::Put;
                    let _ = changes_tx.send(Change::Worker { id: id.to_owned(), alive });
                }
            })
            .await
            .map_err(|e| declare_err("workers' liveliness subscriber", &workers_key, e))?;
        let key = keyexpr::worker_liveliness(site, &me);
        let token = session
            .liveliness()
            .declare_token(key.clone())
            .await
            .map_err(|e| declare_err("worker liveliness token", &key, e))?;
        if risktwin_transport::metrics::enabled() {
            export_metrics(Arc::downgrade(&shard), Arc::downgrade(&forward));
        }
        let task = tokio::spawn(follow(Arc::clone(&shard), changes, shutdown));
        Ok(ShardRole { token, workers, edges, task, shard, forward })
    }

    /// Stops taking part: leaves the workers and drops the subscriptions.
    pub async fn finish(self) -> Result<ShardSummary, TransportError> {
        let undeclare = |e: risktwin_transport::zenoh::Error| TransportError::Close { reason: e.to_string() };
        self.token.undeclare().await.map_err(undeclare)?;
        self.workers.undeclare().await.map_err(undeclare)?;
        self.edges.undeclare().await.map_err(undeclare)?;
        self.task.abort();
        let subscriptions = std::mem::take(&mut *self.shard.subscriptions.lock().await);
        for (_, subscription) in subscriptions {
            subscription.undeclare().await.map_err(undeclare)?;
        }
        let mut summary = self.shard.summary();
        self.forward.count(&mut summary);
        self.forward.task.abort();
        if risktwin_transport::metrics::enabled() {
            export(&summary);
        }
        Ok(summary)
    }
}

/// Applies the workers' and sources' comings and goings, a burst (a worker's whole view at
/// start) in one go: owners recomputed, groups subscribed to, then the caches of the sources
/// taken over asked (after the subscription, so that nothing falls between the two).
async fn follow(shard: Arc<Shard>, mut changes: mpsc::UnboundedReceiver<Change>, mut shutdown: Shutdown) {
    loop {
        let mut change = tokio::select! {
            change = changes.recv() => match change {
                Some(change) => Some(change),
                None => return,
            },
            () = shutdown.wait() => return,
        };
        let (mut moved, mut grew) = (false, false);
        while let Some(next) = change {
            let mut owners = shard.owners();
            match next {
                Change::Worker { id, alive } => {
                    // Never this worker itself: it leaves only by ending.
                    let changed = if alive {
                        owners.workers.insert(id.clone())
                    } else {
                        id != owners.me && owners.workers.remove(&id)
                    };
                    if changed {
                        let n = owners.workers.len();
                        tracing::info!("shard: worker {}: {id} ({n} alive)", if alive { "joined" } else { "left" });
                    }
                    moved |= changed;
                }
                Change::Source(id) => grew |= owners.learn(&id),
            }
            drop(owners);
            change = changes.try_recv().ok();
        }
        let taken = if moved { shard.rebalance() } else { Vec::new() };
        if moved || grew {
            shard.subscribe_groups().await;
        }
        for source in taken {
            shard.fetch(source, HANDOVER_SAMPLES);
        }
    }
}

/// Has every scrape copy the worker's counts (docs/metrics.md) while it runs.
fn export_metrics(shard: Weak<Shard>, forward: Weak<Forwarder>) {
    risktwin_transport::metrics::on_scrape(move || {
        let (Some(shard), Some(forward)) = (shard.upgrade(), forward.upgrade()) else { return false };
        let mut copy = shard.summary();
        forward.count(&mut copy);
        export(&copy);
        true
    });
}

/// The worker's counts as metrics.
fn export(s: &ShardSummary) {
    metrics::gauge!("risktwin_shard_workers").set(s.workers_at_exit as f64);
    metrics::gauge!("risktwin_shard_sources_owned").set(s.owned_at_exit as f64);
    metrics::gauge!("risktwin_shard_groups").set(s.groups_at_exit as f64);
    metrics::counter!("risktwin_shard_sources_taken_over_total").absolute(s.took_over.len() as u64);
    metrics::counter!("risktwin_shard_sources_handed_over_total").absolute(s.handed_over);
    metrics::counter!("risktwin_shard_forwarded_messages_total").absolute(s.forwarded);
    metrics::counter!("risktwin_shard_forward_failed_total").absolute(s.forward_failed);
    metrics::counter!("risktwin_shard_skipped_messages_total").absolute(s.skipped);
    metrics::counter!("risktwin_shard_fetched_messages_total").absolute(s.fetched);
}
