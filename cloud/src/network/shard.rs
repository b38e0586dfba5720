//! Sharded ingest (`risktwin cloud --roles ingest --shard --site S`, docs/sharding.md): several
//! ingest workers share a site, each source owned by exactly one live worker.
//!
//! - Membership: each worker holds a liveliness token `risktwin/v1/<site>/cloud/workers/<id>`
//!   (its Zenoh session id) and watches the others' and the edges' tokens. A killed worker's
//!   token goes as soon as the router sees its link close; a frozen one's when its lease ends.
//! - Ownership: rendezvous (highest-random-weight) hashing of (worker, source), Thaler and
//!   Ravishankar 1998: every worker computes the same owner from the same member set, with no
//!   coordinator, and a worker that joins or leaves moves only its own share (≈ 1/n).
//! - A worker subscribes to each source it owns (one `AdvancedSubscriber` on
//!   `risktwin/v1/<site>/<source>/*`, so the router sends it its share only). Taking a source
//!   over from another worker, it first asks the source's caches for the last
//!   [`HANDOVER_SAMPLES`] of each stream: what was published while nobody owned the source comes
//!   back (edge caches keep 45 s), and part of what the previous owner took.
//! - Each accepted message (and each refused only by this worker's clock estimate, see
//!   [`super::Handled::forwarded`]) is forwarded unchanged to `risktwin/v1/<site>/cloud/ingested/…`,
//!   where the `union` role ([`super::union`]) feeds the twin and removes the hand-over's
//!   duplicates by (source, sequence number).
//!
//! Zenoh has no queue groups (eclipse-zenoh/zenoh#2217), so the assignment is ours. Sources
//! without a liveliness token (replays, fleet logs) are not sharded: one unsharded cloud takes
//! them.

use super::receive::LiveIngest;
use crate::network::{ingest_sink_then, loss_sink};
use risktwin_transport::keyexpr::{self, parse_edge_key};
use risktwin_transport::recovery::LIVE_PRIORITY;
use risktwin_transport::zenoh::Session;
use risktwin_transport::zenoh::bytes::{Encoding, ZBytes};
use risktwin_transport::zenoh::pubsub::Publisher;
use risktwin_transport::zenoh::qos::CongestionControl;
use risktwin_transport::zenoh::sample::SampleKind;
use risktwin_transport::zenoh::{Wait, liveliness::LivelinessToken, pubsub::Subscriber};
use risktwin_transport::{EdgeStreamSubscriber, Shutdown, SiteId, SourceId, TransportError, watch_liveliness};
use serde::Serialize;
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError, Weak};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};
use tokio::sync::mpsc;
use tokio::task::JoinHandle;

/// Samples per stream a worker asks a source's caches for when it starts owning the source: 5 s
/// of a 200/s CAN stream, 20 s of a 50 Hz state stream. Below the union's reorder window (1,024
/// numbers), so that every one of them the previous owner forwarded is still told a duplicate.
pub const HANDOVER_SAMPLES: usize = 1000;

/// How long a worker keeps the subscription of an edge whose token went: its last samples and
/// a recovery of its last gap still arrive.
const EDGE_LINGER: Duration = Duration::from_secs(10);

/// The weight of `worker` for `source`: FNV-1a (64 bit) over both, finished with the SplitMix64
/// mixer so that near-identical ids spread. Written out rather than `DefaultHasher` because every
/// worker must agree on it, whatever build or Rust version it runs.
fn weight(worker: &str, source: &str) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in worker.as_bytes().iter().chain(&[0xff]).chain(source.as_bytes()) {
        h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
    }
    h = (h ^ (h >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    h = (h ^ (h >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    h ^ (h >> 31)
}

/// The worker that owns `source` among `workers`: the one of highest weight (ties, which need
/// equal 64-bit hashes, go to the smaller id). `None` without workers.
pub fn owner<'w>(workers: impl IntoIterator<Item = &'w str>, source: &str) -> Option<&'w str> {
    workers.into_iter().max_by(|a, b| weight(a, source).cmp(&weight(b, source)).then_with(|| b.cmp(a)))
}

/// A source this worker started owning while another worker held it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct TakeOver {
    pub source: String,
    /// The worker that owned it before.
    pub from: String,
    /// When this worker's subscription was in place, ms since the Unix epoch.
    pub at_unix_ms: u64,
}

/// What a sharded worker reports on exit (`shard` in the cloud's JSON summary).
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct ShardSummary {
    /// This worker's id (its Zenoh session id).
    pub worker: String,
    /// The most workers seen alive at once, this one included.
    pub workers_max: usize,
    /// Workers alive at the end (while running: now), this one included.
    pub workers_at_exit: usize,
    /// Sources owned at the end (while running: now).
    pub owned_at_exit: usize,
    /// Subscriptions declared (a source owned, or owned again).
    pub subscribed: u64,
    /// Sources handed to another worker (a worker joined).
    pub handed_over: u64,
    /// Sources taken from another worker (it left, or this one joined), with when.
    pub took_over: Vec<TakeOver>,
    /// Subscriptions that could not be declared (logged; retried at the next change).
    pub subscribe_failed: u64,
    /// Accepted messages forwarded to the union.
    pub forwarded: u64,
    /// Forwards Zenoh refused (the session closing).
    pub forward_failed: u64,
}

/// A membership change seen on a liveliness token.
enum Change {
    Worker { id: String, alive: bool },
    Edge { source: String, alive: bool },
}

/// A running sharded worker: its token, watches and assignment task.
pub struct ShardRole {
    token: LivelinessToken,
    watches: [Subscriber<()>; 2],
    task: JoinHandle<Assignment>,
    forward: Arc<Forwarder>,
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
        let (changes_tx, changes) = mpsc::unbounded_channel();
        let workers_tx = changes_tx.clone();
        let key = keyexpr::worker_liveliness_all(site);
        let workers = session
            .liveliness()
            .declare_subscriber(key.clone())
            .history(true)
            .callback(move |sample| {
                if let Some(id) = keyexpr::parse_worker_liveliness_key(sample.key_expr().as_str()) {
                    let alive = sample.kind() == SampleKind::Put;
                    let _ = workers_tx.send(Change::Worker { id: id.to_owned(), alive });
                }
            })
            .await
            .map_err(|e| TransportError::Declare {
                what: "workers' liveliness subscriber",
                key,
                reason: e.to_string(),
            })?;
        let edges = watch_liveliness(session, Some(site), move |change| {
            let _ = changes_tx.send(Change::Edge { source: change.source, alive: change.alive });
        })
        .await?;
        let key = keyexpr::worker_liveliness(site, &me);
        let token = session.liveliness().declare_token(key.clone()).await.map_err(|e| TransportError::Declare {
            what: "worker liveliness token",
            key,
            reason: e.to_string(),
        })?;
        tracing::info!("shard: this worker is {me}");
        let forward = Arc::new(Forwarder::start(session));
        let summary =
            ShardSummary { worker: me.clone(), workers_max: 1, workers_at_exit: 1, ..ShardSummary::default() };
        let summary = Arc::new(Mutex::new(summary));
        if risktwin_transport::metrics::enabled() {
            export_metrics(Arc::downgrade(&summary), Arc::downgrade(&forward));
        }
        let assignment = Assignment::new(me, site.clone(), session.clone(), ingest, Arc::clone(&forward), summary);
        let task = tokio::spawn(assignment.run(changes, shutdown));
        Ok(ShardRole { token, watches: [workers, edges], task, forward })
    }

    /// Stops taking part: leaves the workers and drops every subscription.
    pub async fn finish(self) -> Result<ShardSummary, TransportError> {
        let undeclare = |e: risktwin_transport::zenoh::Error| TransportError::Close { reason: e.to_string() };
        self.token.undeclare().await.map_err(undeclare)?;
        for watch in self.watches {
            watch.undeclare().await.map_err(undeclare)?;
        }
        let assignment = self.task.await.map_err(|e| TransportError::Close { reason: format!("shard task: {e}") })?;
        let mut summary = assignment.finish().await;
        self.forward.count(&mut summary);
        self.forward.task.abort();
        if risktwin_transport::metrics::enabled() {
            export(&summary);
        }
        Ok(summary)
    }
}

/// The assignment task's state: who is alive, what this worker owns.
struct Assignment {
    me: String,
    site: SiteId,
    session: Session,
    ingest: Arc<Mutex<LiveIngest>>,
    forward: Arc<Forwarder>,
    workers: BTreeSet<String>,
    /// Edges seen, with when their token went (`None`: alive).
    edges: BTreeMap<String, Option<Instant>>,
    /// Each known source's owner as last computed.
    owners: HashMap<String, String>,
    subscribed: HashMap<String, EdgeStreamSubscriber>,
    /// Shared with the metrics' scrape ([`export_metrics`]); changed only on membership changes.
    summary: Arc<Mutex<ShardSummary>>,
}

impl Assignment {
    fn new(
        me: String,
        site: SiteId,
        session: Session,
        ingest: Arc<Mutex<LiveIngest>>,
        forward: Arc<Forwarder>,
        summary: Arc<Mutex<ShardSummary>>,
    ) -> Self {
        let workers = BTreeSet::from([me.clone()]);
        Assignment {
            me,
            site,
            session,
            ingest,
            forward,
            workers,
            edges: BTreeMap::new(),
            owners: HashMap::new(),
            subscribed: HashMap::new(),
            summary,
        }
    }

    async fn run(mut self, mut changes: mpsc::UnboundedReceiver<Change>, mut shutdown: Shutdown) -> Self {
        let mut sweep = tokio::time::interval(Duration::from_secs(1));
        loop {
            tokio::select! {
                change = changes.recv() => {
                    let Some(change) = change else { return self };
                    self.apply(change);
                    // A burst (a worker's whole view at start) is taken in one go.
                    while let Ok(change) = changes.try_recv() {
                        self.apply(change);
                    }
                }
                _ = sweep.tick() => {
                    let now = Instant::now();
                    self.edges.retain(|_, left| left.is_none_or(|at| now.duration_since(at) < EDGE_LINGER));
                }
                () = shutdown.wait() => return self,
            }
            self.rebalance().await;
        }
    }

    fn apply(&mut self, change: Change) {
        match change {
            Change::Worker { id, alive: true } => {
                if self.workers.insert(id.clone()) {
                    tracing::info!("shard: worker joined: {id} ({} alive)", self.workers.len());
                }
            }
            // Never this worker itself: it leaves only by ending.
            Change::Worker { id, alive: false } if id != self.me => {
                if self.workers.remove(&id) {
                    tracing::info!("shard: worker left: {id} ({} alive)", self.workers.len());
                }
            }
            Change::Worker { .. } => {}
            Change::Edge { source, alive } => {
                self.edges.insert(source, (!alive).then(Instant::now));
            }
        }
        let alive = self.workers.len();
        self.count(|s| {
            s.workers_at_exit = alive;
            s.workers_max = s.workers_max.max(alive);
        });
    }

    fn count(&self, change: impl FnOnce(&mut ShardSummary)) {
        change(&mut self.summary.lock().unwrap_or_else(PoisonError::into_inner));
    }

    /// Subscribes to the sources this worker owns now and lets go of the others.
    async fn rebalance(&mut self) {
        let gone: Vec<String> = self.subscribed.keys().filter(|s| !self.edges.contains_key(*s)).cloned().collect();
        for source in gone {
            self.unsubscribe(&source).await;
            self.owners.remove(&source);
        }
        let sources: Vec<String> = self.edges.keys().cloned().collect();
        for source in sources {
            let Some(owner) = owner(self.workers.iter().map(String::as_str), &source).map(str::to_owned) else {
                continue;
            };
            let before = self.owners.insert(source.clone(), owner.clone());
            let mine = owner == self.me;
            if mine && !self.subscribed.contains_key(&source) {
                let from = before.filter(|b| *b != self.me);
                if self.subscribe(&source, from.is_some()).await
                    && let Some(from) = from
                {
                    let at_unix_ms = SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.as_millis() as u64);
                    tracing::info!("shard: took over {source} from {from}");
                    self.count(|s| s.took_over.push(TakeOver { source, from, at_unix_ms }));
                }
            } else if !mine && self.subscribed.contains_key(&source) {
                self.unsubscribe(&source).await;
                self.count(|s| s.handed_over += 1);
            }
        }
    }

    /// Subscribes to `source`; with `take_over` (another worker owned it), first asking its
    /// caches for the last [`HANDOVER_SAMPLES`]. A new source is not asked: its edge publishes
    /// once it sees this subscription, and a history query racing with its first samples lost
    /// them in 2 of 7 runs (zenoh-ext 1.10.2; 0 of 6 without the query).
    async fn subscribe(&mut self, source: &str, take_over: bool) -> bool {
        let Ok(id) = SourceId::new(source) else { return false };
        let (ingest, forward) = (Arc::clone(&self.ingest), Arc::clone(&self.forward));
        let on_sample = ingest_sink_then(ingest, move |sample, handled| {
            if handled.forwarded() {
                forward.put(sample);
            }
        });
        let on_loss = loss_sink(Arc::clone(&self.ingest));
        let subscribed = risktwin_transport::subscribe_source_streams(
            &self.session,
            &self.site,
            &id,
            take_over.then_some(HANDOVER_SAMPLES),
            on_sample,
            on_loss,
        )
        .await;
        match subscribed {
            Ok(subscriber) => {
                tracing::info!("shard: owns {source}");
                self.subscribed.insert(source.to_owned(), subscriber);
                let owned = self.subscribed.len();
                self.count(|s| {
                    s.subscribed += 1;
                    s.owned_at_exit = owned;
                });
                true
            }
            Err(e) => {
                tracing::error!("shard: subscribing to {source}: {e}");
                self.count(|s| s.subscribe_failed += 1);
                // Asked again at the next change.
                self.owners.remove(source);
                false
            }
        }
    }

    async fn unsubscribe(&mut self, source: &str) {
        let removed = self.subscribed.remove(source);
        let owned = self.subscribed.len();
        self.count(|s| s.owned_at_exit = owned);
        if let Some(subscriber) = removed
            && let Err(e) = subscriber.undeclare().await
        {
            tracing::debug!("shard: undeclaring {source}: {e}");
        }
    }

    async fn finish(mut self) -> ShardSummary {
        let summary = self.summary.lock().unwrap_or_else(PoisonError::into_inner).clone();
        let sources: Vec<String> = self.subscribed.keys().cloned().collect();
        for source in sources {
            self.unsubscribe(&source).await;
        }
        summary
    }
}

/// Forwards accepted samples to the union, each edge key's forward key declared once (by a task:
/// declaring inside the receive callback would re-enter Zenoh's tables, see [`super::routes`]).
/// `CongestionControl::Block`: a union that cannot keep up slows this worker's receive path,
/// whose own link then drops, and those samples come back from the edges' caches; nothing is
/// dropped between worker and union unseen.
struct Forwarder {
    session: Session,
    /// Publishers by edge key; `None` while being declared.
    declared: Arc<Mutex<HashMap<String, Option<Publisher<'static>>>>>,
    declare: mpsc::UnboundedSender<String>,
    task: JoinHandle<()>,
    forwarded: AtomicU64,
    failed: AtomicU64,
}

impl Forwarder {
    fn start(session: &Session) -> Self {
        let (declare, mut keys) = mpsc::unbounded_channel::<String>();
        let declared: Arc<Mutex<HashMap<String, Option<Publisher<'static>>>>> = Arc::default();
        let (held, on) = (Arc::clone(&declared), session.clone());
        // `put` sends each edge key once (it enters the map as `None` when sent).
        let task = tokio::spawn(async move {
            while let Some(edge_key) = keys.recv().await {
                let Some(forward_key) = parse_edge_key(&edge_key).map(|k| keyexpr::ingested(&k)) else { continue };
                let publisher = on
                    .declare_publisher(forward_key)
                    .congestion_control(CongestionControl::Block)
                    .priority(LIVE_PRIORITY)
                    .await;
                match publisher {
                    Ok(p) => {
                        held.lock().unwrap_or_else(PoisonError::into_inner).insert(edge_key, Some(p));
                    }
                    Err(e) => tracing::warn!("shard: declaring the forward of {edge_key}: {e} (put one by one)"),
                }
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

    /// Its counts, into `summary`.
    fn count(&self, summary: &mut ShardSummary) {
        summary.forwarded = self.forwarded.load(Ordering::Relaxed);
        summary.forward_failed = self.failed.load(Ordering::Relaxed);
    }

    /// Forwards `sample` (its payload shared, not copied) under its edge key's forward key.
    fn put(&self, sample: &risktwin_transport::zenoh::sample::Sample) {
        let edge_key = sample.key_expr().as_str();
        let (payload, encoding): (ZBytes, Encoding) = (sample.payload().clone(), sample.encoding().clone());
        let mut declared = self.declared.lock().unwrap_or_else(PoisonError::into_inner);
        let ok = match declared.get(edge_key) {
            Some(Some(publisher)) => publisher.put(payload).encoding(encoding).wait().is_ok(),
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

/// Has every scrape copy the worker's counts (docs/metrics.md) while it runs.
fn export_metrics(summary: Weak<Mutex<ShardSummary>>, forward: Weak<Forwarder>) {
    risktwin_transport::metrics::on_scrape(move || {
        let (Some(summary), Some(forward)) = (summary.upgrade(), forward.upgrade()) else { return false };
        let mut copy = summary.lock().unwrap_or_else(PoisonError::into_inner).clone();
        forward.count(&mut copy);
        export(&copy);
        true
    });
}

/// The worker's counts as metrics.
fn export(s: &ShardSummary) {
    metrics::gauge!("risktwin_shard_workers").set(s.workers_at_exit as f64);
    metrics::gauge!("risktwin_shard_sources_owned").set(s.owned_at_exit as f64);
    metrics::counter!("risktwin_shard_sources_taken_over_total").absolute(s.took_over.len() as u64);
    metrics::counter!("risktwin_shard_sources_handed_over_total").absolute(s.handed_over);
    metrics::counter!("risktwin_shard_forwarded_messages_total").absolute(s.forwarded);
    metrics::counter!("risktwin_shard_forward_failed_total").absolute(s.forward_failed);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ids(n: usize) -> Vec<String> {
        (0..n).map(|i| format!("{:032x}", 0x9e37_79b9_7f4a_7c15_u128.wrapping_mul(i as u128 + 1))).collect()
    }

    #[test]
    fn each_source_has_one_owner_and_shares_are_even() {
        let workers = ids(3);
        let mut shares = HashMap::new();
        for v in 0..3000 {
            let owner = owner(workers.iter().map(String::as_str), &format!("veh-{v}")).unwrap();
            *shares.entry(owner.to_owned()).or_insert(0) += 1;
        }
        assert_eq!(shares.len(), 3);
        for (worker, n) in &shares {
            assert!((900..=1100).contains(n), "{worker} owns {n} of 3000");
        }
        assert_eq!(owner(std::iter::empty(), "veh-1"), None);
    }

    #[test]
    fn a_worker_leaving_moves_only_its_sources_and_one_joining_takes_only_its_share() {
        let all = ids(4);
        let three: Vec<&str> = all[..3].iter().map(String::as_str).collect();
        let two: Vec<&str> = all[..2].iter().map(String::as_str).collect();
        let four: Vec<&str> = all.iter().map(String::as_str).collect();
        let (mut moved, mut joined) = (0, 0);
        for v in 0..3000 {
            let source = format!("veh-{v}");
            let before = owner(three.iter().copied(), &source).unwrap();
            let after = owner(two.iter().copied(), &source).unwrap();
            if before != after {
                assert_eq!(before, three[2], "{source} moved though its owner stayed");
                moved += 1;
            }
            let grown = owner(four.iter().copied(), &source).unwrap();
            if grown != before {
                assert_eq!(grown, four[3], "{source} moved between two old workers");
                joined += 1;
            }
        }
        assert!((900..=1100).contains(&moved), "{moved}");
        assert!((600..=900).contains(&joined), "{joined}");
    }

    #[test]
    fn the_weight_is_fixed_across_builds() {
        // Every worker must compute the same owner: this value may never change (checked against
        // FNV-1a 64 and the SplitMix64 finaliser computed by hand in Python).
        assert_ne!(weight("a", "b"), weight("b", "a"));
        assert_ne!(weight("ab", "c"), weight("a", "bc"));
        assert_eq!(weight("w1", "veh-1"), 0x5c62_2a30_bc13_c620, "{:#x}", weight("w1", "veh-1"));
    }
}
