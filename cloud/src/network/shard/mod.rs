//! Sharded ingest (`risktwin cloud --roles ingest --shard --site S`, docs/sharding.md): several
//! ingest workers share a site, each source owned by exactly one live worker.
//!
//! - Membership: each worker holds a liveliness token `risktwin/v1/<site>/cloud/workers/<id>`
//!   (its Zenoh session id) and watches the others'. A killed worker's token goes as soon as the
//!   router sees its link close; a frozen one's when its lease ends.
//! - Groups: the unit of ownership is a source's shard group, the last two characters of its id
//!   ([`keyexpr::shard_group`]), because a group is what a Zenoh key expression can select
//!   (`risktwin/v1/<site>/$*<group>/*`): a worker subscribes to its groups only, so the other
//!   workers' samples are never sent to it and its work follows its share. One subscription
//!   per source does not scale in Zenoh 1.10.2 (every key a session declares is matched against
//!   every subscription of the session under its write lock: at 2,000 sources a worker stood
//!   still for seconds), and one subscription to the whole site costs every worker about half
//!   an owned sample's CPU for each sample it lets go (docs/sharding.md).
//! - Ownership: rendezvous (highest-random-weight) hashing of (worker, group), Thaler and
//!   Ravishankar 1998: every worker computes the same owner from the same member set, with no
//!   coordinator, and a worker that joins or leaves moves only its own share (≈ 1/n).
//! - Discovery: a worker learns the sources from the edges' liveliness tokens
//!   (`risktwin/v1/<site>/alive/<source>`, which every RiskTwin edge holds) and subscribes to
//!   the group of each source it owns. A publisher without a token is ingested only while a
//!   source of its group has one (docs/sharding.md, limits).
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
mod role;

pub use role::ShardRole;

use forward::Forwarder;
use risktwin_transport::keyexpr::{parse_edge_key, shard_group};
use risktwin_transport::sync::LockExt;
use risktwin_transport::wall_clock::unix_ns;
use risktwin_transport::zenoh::Session;
use risktwin_transport::zenoh::sample::Sample;
use risktwin_transport::{EdgeStream, EdgeStreamSubscriber, SiteId, SourceId, StreamLoss, fetch_cached};
use serde::Serialize;
use std::collections::{BTreeSet, HashMap};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

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

/// How long a starting worker waits for the other workers' and the edges' tokens before it
/// owns anything.
const MEMBERS_WAIT: Duration = Duration::from_secs(2);

/// The weight of `worker` for `group`: FNV-1a (64 bit) over both, finished with the SplitMix64
/// mixer so that near-identical ids spread. Written out rather than `DefaultHasher` because every
/// worker must agree on it, whatever build or Rust version it runs.
fn weight(worker: &str, group: &str) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in worker.as_bytes().iter().chain(&[0xff]).chain(group.as_bytes()) {
        h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
    }
    h = (h ^ (h >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    h = (h ^ (h >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    h ^ (h >> 31)
}

/// The worker that owns the shard group `group` among `workers`: the one of highest weight
/// (ties, which need equal 64-bit hashes, go to the smaller id). `None` without workers.
pub fn owner<'w>(workers: impl IntoIterator<Item = &'w str>, group: &str) -> Option<&'w str> {
    workers.into_iter().max_by(|a, b| weight(a, group).cmp(&weight(b, group)).then_with(|| b.cmp(a)))
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
    /// Shard groups subscribed to at the end (while running: now).
    pub groups_at_exit: usize,
    /// Sources known (by their token or a sample), owned or not.
    pub sources_seen: usize,
    /// Sources handed to another worker (a worker joined).
    pub handed_over: u64,
    /// Sources taken from another worker (it left), with when.
    pub took_over: Vec<TakeOver>,
    /// Asks to a source's caches (one per source this worker started owning).
    pub fetches: u64,
    /// Samples those asks brought.
    pub fetched: u64,
    /// Samples of sources other workers own that reached this one (while a group moves) and were
    /// let go.
    pub skipped: u64,
    /// Accepted messages forwarded to the union.
    pub forwarded: u64,
    /// Forwards Zenoh refused (the session closing).
    pub forward_failed: u64,
}

/// What this worker does with a source's samples.
enum Held {
    /// This worker's, known by its token, no sample of it here yet.
    Unseen,
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
        owner(self.workers.iter().map(String::as_str), shard_group(source)).unwrap_or(&self.me)
    }

    /// Remembers `source` (its token was seen); whether it is new and this worker's.
    fn learn(&mut self, source: &str) -> bool {
        if self.sources.contains_key(source) {
            return false;
        }
        let owner = self.owner(source);
        let held = if owner == self.me { Held::Unseen } else { Held::Theirs(owner.to_owned()) };
        let mine = matches!(held, Held::Unseen);
        self.sources.insert(source.to_owned(), held);
        mine
    }

    /// The groups this worker subscribes to: those of the sources it owns, or, while it is the
    /// only worker, the whole site (`None`) in one subscription: each sample is matched against
    /// every subscription of the session, and a hundred groups cost a lone worker 24 % more
    /// CPU per message (docs/sharding.md).
    fn groups(&self) -> BTreeSet<Option<String>> {
        if self.workers.len() == 1 {
            return BTreeSet::from([None]);
        }
        let mine = self.sources.iter().filter(|(_, held)| !matches!(held, Held::Theirs(_)));
        mine.map(|(source, _)| Some(shard_group(source).to_owned())).collect()
    }
}

type Deliver = dyn Fn(EdgeStream, &Sample) + Send + Sync;
type CountLoss = dyn Fn(StreamLoss) + Send + Sync;

/// What the receive path, the fetches and the membership task share.
struct Shard {
    owners: Mutex<Owners>,
    deliver: Box<Deliver>,
    count_loss: Box<CountLoss>,
    forward: Arc<Forwarder>,
    /// This worker's subscriptions, by shard group (`None`: the whole site).
    subscriptions: tokio::sync::Mutex<HashMap<Option<String>, EdgeStreamSubscriber>>,
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
        self.owners.locked()
    }

    fn count(&self, change: impl FnOnce(&mut ShardSummary)) {
        change(&mut self.summary.locked());
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
            None | Some(Held::Unseen) => {
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

    /// Counts the loss reports of the sources this worker owns (another worker counts its own).
    fn on_loss(&self, loss: StreamLoss) {
        let source = loss.key.as_deref().and_then(parse_edge_key).map(|k| k.source);
        let mine = source.is_none_or(|s| matches!(self.owners().sources.get(s), Some(Held::Mine | Held::Fetching(_))));
        if mine {
            (self.count_loss)(loss);
        }
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

    /// Recomputes every known source's owner after the workers changed; returns the sources
    /// this worker takes over, to be fetched once their groups are subscribed to.
    fn rebalance(&self) -> Vec<String> {
        let mut guard = self.owners();
        let Owners { me, workers, sources } = &mut *guard;
        let (mut took, mut handed) = (Vec::new(), 0);
        for (source, held) in sources.iter_mut() {
            let owner = owner(workers.iter().map(String::as_str), shard_group(source)).unwrap_or(me);
            match (&*held, owner == me) {
                (Held::Theirs(from), true) => {
                    let at_unix_ms = (unix_ns() / 1_000_000) as u64;
                    tracing::info!("shard: took over {source} from {from}");
                    took.push(TakeOver { source: source.clone(), from: from.clone(), at_unix_ms });
                    *held = Held::Fetching(Vec::new());
                }
                (Held::Mine | Held::Fetching(_), false) => {
                    tracing::info!("shard: handed {source} to {owner}");
                    *held = Held::Theirs(owner.to_owned());
                    handed += 1;
                }
                (Held::Theirs(_) | Held::Unseen, false) => *held = Held::Theirs(owner.to_owned()),
                (Held::Mine | Held::Fetching(_) | Held::Unseen, true) => {}
            }
        }
        let alive = workers.len();
        drop(guard);
        let taken = took.iter().map(|t| t.source.clone()).collect();
        self.count(|s| {
            s.took_over.extend(took);
            s.handed_over += handed;
            s.workers_at_exit = alive;
            s.workers_max = s.workers_max.max(alive);
        });
        taken
    }

    /// Subscribes to the groups of the sources this worker owns and drops the others'; a new
    /// subscription is in place before this returns.
    async fn subscribe_groups(self: &Arc<Self>) {
        let mut subscriptions = self.subscriptions.lock().await;
        let wanted = self.owners().groups();
        let new: Vec<&Option<String>> = wanted.iter().filter(|g| !subscriptions.contains_key(*g)).collect();
        for group in new {
            let (on_sample, on_loss) = (Arc::clone(self), Arc::clone(self));
            let subscription = risktwin_transport::subscribe_shard_group(
                &self.session,
                &self.site,
                group.as_deref(),
                move |stream, sample| on_sample.on_sample(stream, sample),
                move |loss| on_loss.on_loss(loss),
            )
            .await;
            match subscription {
                Ok(s) => {
                    subscriptions.insert(group.clone(), s);
                }
                // Only a closing session refuses: the worker is ending.
                Err(e) => tracing::warn!("shard: subscribing to group {group:?}: {e}"),
            }
        }
        let gone: Vec<Option<String>> = subscriptions.keys().filter(|g| !wanted.contains(*g)).cloned().collect();
        for group in gone {
            if let Some(s) = subscriptions.remove(&group)
                && let Err(e) = s.undeclare().await
            {
                tracing::warn!("shard: leaving group {group:?}: {e}");
            }
        }
        let groups = subscriptions.len();
        self.count(|s| s.groups_at_exit = groups);
    }

    /// The summary with the receive path's counts.
    fn summary(&self) -> ShardSummary {
        let mut summary = self.summary.locked().clone();
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

#[cfg(test)]
mod tests;
