//! Sharded ingest (`risktwin cloud --roles ingest --shard --site S`, docs/sharding.md): several
//! ingest workers share a site, each source owned by exactly one live worker.
//!
//! - Membership: each worker holds a liveliness token `risktwin/v1/<site>/cloud/workers/<id>`
//!   (its Zenoh session id) and watches the others'. A killed worker's token goes as soon as the
//!   router sees its link close; a frozen one's when its lease ends.
//! - Ownership: rendezvous (highest-random-weight) hashing of (worker, source), Thaler and
//!   Ravishankar 1998: every worker computes the same owner from the same member set, with no
//!   coordinator, and a worker that joins or leaves moves only its own share (≈ 1/n). A source
//!   needs no token to be sharded: its owner follows from its name.
//! - Every worker subscribes to the whole site (the unsharded ingest's one wildcard
//!   subscription, with its recovery) and lets through only the sources it owns; the others'
//!   samples are counted `skipped` and cost only their receipt. One subscription per owned
//!   source was tried first and does not scale in Zenoh 1.10.2: every key a session declares
//!   is matched against every subscription of the session under the session's write lock, and
//!   every sample of an undeclared key against every subscription too; at 2,000 sources a
//!   worker's receive thread stood still for seconds and it received 1 sample in 250
//!   (docs/sharding.md).
//! - Starting to own a source (its first sample here, or a departed worker's source), a worker
//!   holds its live samples back while it asks the source's caches for the last
//!   [`JOIN_SAMPLES`] or [`HANDOVER_SAMPLES`] of each stream, then lets those through first:
//!   what the previous owner stopped taking, or what reached the edge's cache before this
//!   worker's first sample of it, is not lost.
//! - Each accepted message (and each refused only by this worker's clock estimate, see
//!   [`super::Handled::forwarded`]) is forwarded unchanged to `risktwin/v1/<site>/cloud/ingested/…`,
//!   where the `union` role ([`super::union`]) feeds the twin and removes the hand-over's
//!   duplicates by (source, sequence number).
//!
//! Zenoh has no queue groups (eclipse-zenoh/zenoh#2217), so the assignment is ours.

mod forward;

use super::receive::LiveIngest;
use crate::network::{ingest_sink_then, loss_sink};
use forward::Forwarder;
use risktwin_transport::keyexpr::{self, parse_edge_key};
use risktwin_transport::zenoh::Session;
use risktwin_transport::zenoh::sample::{Sample, SampleKind};
use risktwin_transport::zenoh::{liveliness::LivelinessToken, pubsub::Subscriber};
use risktwin_transport::{
    EdgeStream, EdgeStreamSubscriber, Shutdown, SiteId, SourceId, StreamLoss, TransportError, fetch_cached,
};
use serde::Serialize;
use std::collections::{BTreeSet, HashMap};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError, Weak};
use std::time::{Duration, SystemTime, UNIX_EPOCH};
use tokio::sync::mpsc;
use tokio::task::JoinHandle;

/// Samples per stream a worker asks a source's caches for when it takes the source from a
/// departed worker: 5 s of a 200/s CAN stream, 20 s of a 50 Hz state stream. Below the union's
/// reorder window (1,024 numbers), so that every one of them the previous owner forwarded is
/// still told a duplicate.
pub const HANDOVER_SAMPLES: usize = 1000;

/// Samples per stream a worker asks for when a source's first sample reaches it: a new edge's
/// first samples (published the moment it saw a subscriber, possibly before this worker's
/// subscription reached it), or what a worker that just joined missed while the previous
/// owner had not yet seen it join (0.3 s of CAN, 1.3 s of states).
pub const JOIN_SAMPLES: usize = 64;

/// Live samples of one source held back while its caches answer, at most; beyond, they go
/// through at once (the cached ones then arrive after them, and the deduplicator's window
/// decides).
const MAX_HELD: usize = 8192;

/// Asks to sources' caches in flight at once, at most.
const FETCHES_IN_FLIGHT: usize = 16;

/// How long a starting worker waits for the other workers' tokens before it owns anything.
const MEMBERS_WAIT: Duration = Duration::from_secs(2);

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
    /// When this worker started taking its samples, ms since the Unix epoch.
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
    /// Sources seen (owned or not).
    pub sources_seen: usize,
    /// Sources handed to another worker (a worker joined).
    pub handed_over: u64,
    /// Sources taken from another worker (it left), with when.
    pub took_over: Vec<TakeOver>,
    /// Asks to a source's caches (one per source this worker started owning).
    pub fetches: u64,
    /// Samples those asks brought.
    pub fetched: u64,
    /// Samples of sources other workers own: received and let go.
    pub skipped: u64,
    /// Accepted messages forwarded to the union.
    pub forwarded: u64,
    /// Forwards Zenoh refused (the session closing).
    pub forward_failed: u64,
}

/// What this worker does with a source's samples.
enum Held {
    Mine,
    /// Another worker's (named): skipped.
    Theirs(String),
    /// Becoming this worker's: live samples wait here while the caches answer.
    Fetching(Vec<(EdgeStream, Sample)>),
}

/// Who is alive and who owns what; locked by the receive path for each sample (a lookup) and
/// by membership changes.
struct Owners {
    me: String,
    workers: BTreeSet<String>,
    sources: HashMap<String, Held>,
}

impl Owners {
    fn owner(&self, source: &str) -> &str {
        owner(self.workers.iter().map(String::as_str), source).unwrap_or(&self.me)
    }
}

type Deliver = dyn Fn(EdgeStream, &Sample) + Send + Sync;

/// What the receive path, the fetches and the membership task share.
struct Shard {
    owners: Mutex<Owners>,
    deliver: Box<Deliver>,
    forward: Arc<Forwarder>,
    fetch_slots: tokio::sync::Semaphore,
    session: Session,
    site: SiteId,
    runtime: tokio::runtime::Handle,
    skipped: AtomicU64,
    fetches: AtomicU64,
    fetched: AtomicU64,
    summary: Mutex<ShardSummary>,
}

impl Shard {
    fn owners(&self) -> std::sync::MutexGuard<'_, Owners> {
        self.owners.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn count(&self, change: impl FnOnce(&mut ShardSummary)) {
        change(&mut self.summary.lock().unwrap_or_else(PoisonError::into_inner));
    }

    /// The receive path: lets through the samples of the sources this worker owns.
    fn on_sample(self: &Arc<Self>, stream: EdgeStream, sample: &Sample) {
        let Some(source) = parse_edge_key(sample.key_expr().as_str()).map(|k| k.source) else { return };
        let mut owners = self.owners();
        match owners.sources.get_mut(source) {
            Some(Held::Mine) => {
                drop(owners);
                (self.deliver)(stream, sample);
            }
            Some(Held::Theirs(_)) => {
                self.skipped.fetch_add(1, Ordering::Relaxed);
            }
            Some(Held::Fetching(held)) if held.len() < MAX_HELD => held.push((stream, sample.clone())),
            Some(Held::Fetching(_)) => {
                drop(owners);
                (self.deliver)(stream, sample);
            }
            None => {
                let owner = owners.owner(source);
                // A publisher's first sample (number 0) has nothing before it to ask for.
                let first = sample.source_info().is_none_or(|info| info.source_sn() == 0);
                let held = if owner == owners.me && first {
                    Held::Mine
                } else if owner == owners.me {
                    self.fetch(source.to_owned(), JOIN_SAMPLES);
                    Held::Fetching(vec![(stream, sample.clone())])
                } else {
                    self.skipped.fetch_add(1, Ordering::Relaxed);
                    Held::Theirs(owner.to_owned())
                };
                let mine = matches!(held, Held::Mine);
                owners.sources.insert(source.to_owned(), held);
                drop(owners);
                if mine {
                    tracing::info!("shard: owns {source}");
                    (self.deliver)(stream, sample);
                }
            }
        }
    }

    /// Loss reports of the sources this worker owns (another worker counts its own).
    fn on_loss(&self, loss: &StreamLoss) -> bool {
        let source = loss.key.as_deref().and_then(parse_edge_key).map(|k| k.source);
        source.is_none_or(|s| matches!(self.owners().sources.get(s), Some(Held::Mine | Held::Fetching(_))))
    }

    /// Asks `source`'s caches for the last `per_stream` samples of each stream, then lets them
    /// and the live samples held meanwhile through, and owns the source from then on (unless it
    /// moved away meanwhile: then all of it goes).
    fn fetch(self: &Arc<Self>, source: String, per_stream: usize) {
        let Ok(id) = SourceId::new(source.as_str()) else { return };
        let shard = Arc::clone(self);
        self.runtime.spawn(async move {
            // A worker joining a running site asks for every source at once otherwise, and an
            // edge process playing many sources answers them all on one link.
            let Ok(_slot) = shard.fetch_slots.acquire().await else { return };
            let cached = fetch_cached(&shard.session, &shard.site, &id, per_stream).await;
            shard.fetches.fetch_add(1, Ordering::Relaxed);
            shard.fetched.fetch_add(cached.len() as u64, Ordering::Relaxed);
            let keys: BTreeSet<String> = cached.iter().map(|s| s.key_expr().as_str().to_owned()).collect();
            for key in keys {
                shard.forward.prepare(&key).await;
            }
            let mut next = cached;
            // Live samples wait in `Fetching` until none is left: none passes an older one.
            loop {
                for sample in &next {
                    if let Some(key) = parse_edge_key(sample.key_expr().as_str()) {
                        (shard.deliver)(key.stream, sample);
                    }
                }
                let mut owners = shard.owners();
                let Some(Held::Fetching(live)) = owners.sources.get_mut(&source) else { return };
                if live.is_empty() {
                    tracing::info!("shard: owns {source}");
                    owners.sources.insert(source, Held::Mine);
                    return;
                }
                next = std::mem::take(live).into_iter().map(|(_, sample)| sample).collect();
            }
        });
    }

    /// Recomputes every known source's owner after the workers changed.
    fn rebalance(self: &Arc<Self>) {
        let mut guard = self.owners();
        let Owners { me, workers, sources } = &mut *guard;
        let (mut took, mut handed) = (Vec::new(), 0);
        for (source, held) in sources.iter_mut() {
            let owner = owner(workers.iter().map(String::as_str), source).unwrap_or(me);
            match (&*held, owner == me) {
                (Held::Theirs(from), true) => {
                    let at_unix_ms = SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.as_millis() as u64);
                    tracing::info!("shard: took over {source} from {from}");
                    took.push(TakeOver { source: source.clone(), from: from.clone(), at_unix_ms });
                    *held = Held::Fetching(Vec::new());
                    self.fetch(source.clone(), HANDOVER_SAMPLES);
                }
                (Held::Mine | Held::Fetching(_), false) => {
                    tracing::info!("shard: handed {source} to {owner}");
                    *held = Held::Theirs(owner.to_owned());
                    handed += 1;
                }
                (Held::Theirs(_), false) => *held = Held::Theirs(owner.to_owned()),
                (Held::Mine | Held::Fetching(_), true) => {}
            }
        }
        let alive = workers.len();
        drop(guard);
        self.count(|s| {
            s.took_over.extend(took);
            s.handed_over += handed;
            s.workers_at_exit = alive;
            s.workers_max = s.workers_max.max(alive);
        });
    }

    /// The summary with the receive path's counts.
    fn summary(&self) -> ShardSummary {
        let mut summary = self.summary.lock().unwrap_or_else(PoisonError::into_inner).clone();
        let owners = self.owners();
        summary.owned_at_exit = owners.sources.values().filter(|h| !matches!(h, Held::Theirs(_))).count();
        summary.sources_seen = owners.sources.len();
        drop(owners);
        summary.skipped = self.skipped.load(Ordering::Relaxed);
        summary.fetches = self.fetches.load(Ordering::Relaxed);
        summary.fetched = self.fetched.load(Ordering::Relaxed);
        summary
    }
}

/// A membership change seen on a worker's liveliness token.
struct Change {
    id: String,
    alive: bool,
}

/// A running sharded worker: its token, subscriptions and membership task.
pub struct ShardRole {
    token: LivelinessToken,
    workers: Subscriber<()>,
    streams: EdgeStreamSubscriber,
    task: JoinHandle<()>,
    shard: Arc<Shard>,
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
        let key = keyexpr::worker_liveliness_all(site);
        let declare_err = |what: &'static str, key: &str, e: risktwin_transport::zenoh::Error| {
            TransportError::Declare { what, key: key.to_owned(), reason: e.to_string() }
        };
        // The workers alive now, before this one owns anything: otherwise it would take (and
        // ask the caches for) every source until their tokens arrived.
        let mut workers = BTreeSet::from([me.clone()]);
        let replies = session.liveliness().get(key.clone()).timeout(MEMBERS_WAIT).await;
        let replies = replies.map_err(|e| declare_err("workers' liveliness query", &key, e))?;
        while let Ok(reply) = replies.recv_async().await {
            if let Some(id) =
                reply.result().ok().and_then(|s| keyexpr::parse_worker_liveliness_key(s.key_expr().as_str()))
            {
                workers.insert(id.to_owned());
            }
        }
        tracing::info!("shard: this worker is {me}");
        tracing::info!("shard: workers at start ({} alive)", workers.len());
        let forward = Arc::new(Forwarder::start(session));
        let summary = ShardSummary {
            worker: me.clone(),
            workers_max: workers.len(),
            workers_at_exit: workers.len(),
            ..ShardSummary::default()
        };
        let to_union = Arc::clone(&forward);
        let shard = Arc::new(Shard {
            owners: Mutex::new(Owners { me: me.clone(), workers, sources: HashMap::new() }),
            deliver: Box::new(ingest_sink_then(Arc::clone(&ingest), move |sample, handled| {
                if handled.forwarded() {
                    to_union.put(sample);
                }
            })),
            forward: Arc::clone(&forward),
            fetch_slots: tokio::sync::Semaphore::new(FETCHES_IN_FLIGHT),
            session: session.clone(),
            site: site.clone(),
            runtime: tokio::runtime::Handle::current(),
            skipped: AtomicU64::new(0),
            fetches: AtomicU64::new(0),
            fetched: AtomicU64::new(0),
            summary: Mutex::new(summary),
        });
        // The site's streams before this worker's token: a worker that hands a source over on
        // seeing the token finds this one already receiving it.
        let (on_sample, on_loss, count_loss) = (Arc::clone(&shard), Arc::clone(&shard), loss_sink(ingest));
        let streams = risktwin_transport::subscribe_edge_streams(
            session,
            Some(site),
            move |stream, sample| on_sample.on_sample(stream, sample),
            move |loss| {
                if on_loss.on_loss(&loss) {
                    count_loss(loss);
                }
            },
        )
        .await?;
        let (changes_tx, changes) = mpsc::unbounded_channel();
        let workers = session
            .liveliness()
            .declare_subscriber(key.clone())
            .history(true)
            .callback(move |sample| {
                if let Some(id) = keyexpr::parse_worker_liveliness_key(sample.key_expr().as_str()) {
                    let _ = changes_tx.send(Change { id: id.to_owned(), alive: sample.kind() == SampleKind::Put });
                }
            })
            .await
            .map_err(|e| declare_err("workers' liveliness subscriber", &key, e))?;
        let key = keyexpr::worker_liveliness(site, &me);
        let token = session
            .liveliness()
            .declare_token(key.clone())
            .await
            .map_err(|e| declare_err("worker liveliness token", &key, e))?;
        if risktwin_transport::metrics::enabled() {
            export_metrics(Arc::downgrade(&shard), Arc::downgrade(&forward));
        }
        let task = tokio::spawn(follow_members(Arc::clone(&shard), changes, shutdown));
        Ok(ShardRole { token, workers, streams, task, shard, forward })
    }

    /// Stops taking part: leaves the workers and drops the subscriptions.
    pub async fn finish(self) -> Result<ShardSummary, TransportError> {
        let undeclare = |e: risktwin_transport::zenoh::Error| TransportError::Close { reason: e.to_string() };
        self.token.undeclare().await.map_err(undeclare)?;
        self.workers.undeclare().await.map_err(undeclare)?;
        self.streams.undeclare().await.map_err(undeclare)?;
        self.task.abort();
        let mut summary = self.shard.summary();
        self.forward.count(&mut summary);
        self.forward.task.abort();
        if risktwin_transport::metrics::enabled() {
            export(&summary);
        }
        Ok(summary)
    }
}

/// Applies the workers' comings and goings: a burst (a worker's whole view at start) in one go.
async fn follow_members(shard: Arc<Shard>, mut changes: mpsc::UnboundedReceiver<Change>, mut shutdown: Shutdown) {
    loop {
        let mut change = tokio::select! {
            change = changes.recv() => match change {
                Some(change) => Some(change),
                None => return,
            },
            () = shutdown.wait() => return,
        };
        let mut moved = false;
        while let Some(Change { id, alive }) = change {
            let mut owners = shard.owners();
            // Never this worker itself: it leaves only by ending.
            let changed =
                if alive { owners.workers.insert(id.clone()) } else { id != owners.me && owners.workers.remove(&id) };
            if changed {
                let n = owners.workers.len();
                tracing::info!("shard: worker {}: {id} ({n} alive)", if alive { "joined" } else { "left" });
            }
            moved |= changed;
            change = changes.try_recv().ok();
        }
        if moved {
            shard.rebalance();
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
    metrics::counter!("risktwin_shard_sources_taken_over_total").absolute(s.took_over.len() as u64);
    metrics::counter!("risktwin_shard_sources_handed_over_total").absolute(s.handed_over);
    metrics::counter!("risktwin_shard_forwarded_messages_total").absolute(s.forwarded);
    metrics::counter!("risktwin_shard_forward_failed_total").absolute(s.forward_failed);
    metrics::counter!("risktwin_shard_skipped_messages_total").absolute(s.skipped);
    metrics::counter!("risktwin_shard_fetched_messages_total").absolute(s.fetched);
}

#[cfg(test)]
mod tests;
