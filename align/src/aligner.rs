//! Multi-rate streams aligned into snapshots at a fixed tick.
//!
//! Each (source, stream) keeps a short, time-ordered ring of samples stamped in cloud time.
//! At tick `t` a continuous stream is interpolated between the samples bracketing `t`, a
//! discrete stream is taken as of the latest sample at or before `t`.
//!
//! **When a tick is emitted.** The watermark is the newest cloud receive time seen (from
//! [`Aligner::advance`]) minus the allowed lateness `L`. Tick `t` is emitted as soon as the
//! watermark reaches it, *before* the message that moved the watermark is pushed. Hence the
//! snapshot at `t` holds exactly the samples received before `t + L`: a definition that does not
//! depend on how messages sharing a receive time were ordered, nor on whether the worker also
//! advances from a timer, so a replay with the recorded receive times gives the same snapshots.
//!
//! **Late data.** A sample stamped at or before the last emitted tick is counted `late`.
//! Emitted snapshots are never revised. The late sample is kept only if it is newer than the
//! sample the next tick would interpolate from (it then serves the next snapshot); otherwise it
//! is dropped (counted `late_dropped`).
//!
//! **Staleness.** With `stale_periods · period` as the bound: a continuous stream is
//! interpolated only across a gap within the bound; past its newest sample it is held (not
//! extrapolated) while the sample's age is within the bound, and marked
//! [`ValueStatus::Stale`] beyond it.
//!
//! **Memory.** Rings have a fixed capacity, are pruned below each emitted tick (keeping the one
//! sample the next tick may interpolate from), and evict their oldest sample when full (counted
//! `overflow`); nothing is allocated per message once a source's rings exist.

use std::collections::VecDeque;

use super::interp::Interpolate;
use super::reason::DropReason;
use super::snapshot::{Aligned, Snapshot, StreamIndex, ValueStatus};
use super::source::SourceIndex;

/// How a stream's value at a tick is obtained.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StreamMode {
    /// Continuous signal: interpolated between bracketing samples.
    Interpolated,
    /// Discrete signal: the latest sample at or before the tick.
    AsOf,
}

/// One stream of every source: its mode and nominal sample period.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StreamSpec {
    pub mode: StreamMode,
    /// Nominal period between samples (e.g. 20 ms for 50 Hz); sets the staleness bound.
    pub period_ns: i64,
}

/// The allowed lateness unless configured otherwise: 30 ms, the late-data policy's default.
///
/// A snapshot at tick `t` is emitted once the watermark passes `t`, i.e. `L` after `t`; it then
/// holds what arrived before `t + L`. Capture times are mapped onto the cloud clock by the
/// per-source minimum-delay estimate, so a sample's `receive − mapped` is only its delay
/// *variation* plus up to twice the edge's capture jitter (the estimate anchors on the latest
/// stamp), not its absolute delay. `L` must cover, for the 50 Hz state streams, the sample
/// that brackets the tick from above (up to one 20 ms period after `t`, without which the
/// tick holds the previous value instead of interpolating) plus that variation; 10 ms of
/// margin covers LAN/loopback delay variation and millisecond-scale clock jitter. Larger `L`
/// only adds latency (edge publish → snapshot p50 measured 61 ms at 30 ms, 140 ms at 100 ms,
/// with a 50 ms tick), which matters to a live twin; links with more delay variation (cellular V2X) should raise it
/// (`risktwin bench latency --lateness-ms`, `IngestConfig::align`). A late sample is still
/// accepted and recorded, and counted; it serves the next tick when it is newer than what that
/// tick would use, else only the twin misses it (`late_dropped`).
pub const DEFAULT_LATENESS_NS: i64 = 30_000_000;

/// How the aligner is set up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AlignConfig {
    /// Snapshot period (50 ms = 20 Hz); ticks lie on multiples of it on the cloud clock.
    pub tick_ns: i64,
    /// How long after a tick samples for it are still waited for.
    pub lateness_ns: i64,
    /// A sample older than this many of its stream's periods is stale.
    pub stale_periods: u32,
    /// Samples per (source, stream) ring.
    pub capacity: usize,
    /// Most sources accepted; guards the per-source memory.
    pub max_sources: usize,
    /// After a long silence, at most this many ticks are emitted at once; older ones are skipped
    /// (counted) rather than flooding the consumer.
    pub max_catch_up_ticks: u32,
}

impl Default for AlignConfig {
    fn default() -> Self {
        Self {
            tick_ns: 50_000_000,
            lateness_ns: DEFAULT_LATENESS_NS,
            stale_periods: 3,
            capacity: 64,
            max_sources: 65_536,
            max_catch_up_ticks: 200,
        }
    }
}

/// What became of one pushed sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PushOutcome {
    /// Buffered for coming ticks.
    Buffered,
    /// Late (at or before the last emitted tick) but kept to serve the next tick.
    LateKept,
    /// Late and of no use to any coming tick: dropped.
    LateDropped,
    /// Another sample of the same stream has the same timestamp: the first one is kept.
    SameTime,
}

/// Counters of the aligner.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct AlignCounts {
    pub pushed: u64,
    /// Samples stamped at or before an already emitted tick (kept or dropped).
    pub late: u64,
    pub late_dropped: u64,
    pub same_time: u64,
    /// Oldest samples evicted from a full ring.
    pub overflow: u64,
    pub snapshots: u64,
    pub skipped_ticks: u64,
}

#[derive(Debug, Clone)]
struct Sample<T> {
    t_ns: i64,
    value: T,
}

type LerpFn<T> = fn(&T, &T, f64) -> T;

/// Aligns samples of many sources and streams into [`Snapshot`]s at a fixed tick.
#[derive(Debug, Clone)]
pub struct Aligner<T> {
    cfg: AlignConfig,
    streams: Vec<StreamSpec>,
    lerp: Option<LerpFn<T>>,
    rings: Vec<VecDeque<Sample<T>>>,
    now_ns: Option<i64>,
    next_tick_ns: Option<i64>,
    last_emitted_ns: Option<i64>,
    snapshot: Snapshot<T>,
    counts: AlignCounts,
}

impl<T: Clone + Interpolate> Aligner<T> {
    /// An aligner for `streams` (any mix of modes) of an interpolable payload.
    pub fn new(cfg: AlignConfig, streams: &[StreamSpec]) -> Self {
        Self::build(cfg, streams, Some(T::lerp))
    }
}

impl<T: Clone> Aligner<T> {
    /// An aligner whose streams are all [`StreamMode::AsOf`] (no interpolation needed).
    pub fn as_of(cfg: AlignConfig, periods_ns: &[i64]) -> Self {
        let streams: Vec<StreamSpec> =
            periods_ns.iter().map(|&period_ns| StreamSpec { mode: StreamMode::AsOf, period_ns }).collect();
        Self::build(cfg, &streams, None)
    }

    fn build(cfg: AlignConfig, streams: &[StreamSpec], lerp: Option<LerpFn<T>>) -> Self {
        let cfg = AlignConfig {
            tick_ns: cfg.tick_ns.max(1),
            lateness_ns: cfg.lateness_ns.max(0),
            capacity: cfg.capacity.max(2),
            max_catch_up_ticks: cfg.max_catch_up_ticks.max(1),
            ..cfg
        };
        Self {
            cfg,
            streams: streams.to_vec(),
            lerp,
            rings: Vec::new(),
            now_ns: None,
            next_tick_ns: None,
            last_emitted_ns: None,
            snapshot: Snapshot::new(streams.len()),
            counts: AlignCounts::default(),
        }
    }

    /// The configuration in use.
    pub fn config(&self) -> &AlignConfig {
        &self.cfg
    }

    /// The counters so far.
    pub fn counts(&self) -> AlignCounts {
        self.counts
    }

    /// Streams per source.
    pub fn streams(&self) -> usize {
        self.streams.len()
    }

    /// The last tick emitted, if any.
    pub fn last_emitted_ns(&self) -> Option<i64> {
        self.last_emitted_ns
    }

    /// The watermark: newest receive time seen minus the allowed lateness.
    pub fn watermark_ns(&self) -> Option<i64> {
        self.now_ns.map(|n| n.saturating_sub(self.cfg.lateness_ns))
    }

    /// Adds one sample stamped `t_ns` on the cloud clock. Refused (with the reason to count) if
    /// the stream is unknown or the source index is beyond the configured maximum.
    pub fn push(
        &mut self,
        source: SourceIndex,
        stream: StreamIndex,
        t_ns: i64,
        value: T,
    ) -> Result<PushOutcome, DropReason> {
        let n_streams = self.streams.len();
        if stream.as_usize() >= n_streams {
            return Err(DropReason::UnknownStream);
        }
        if source.as_usize() >= self.cfg.max_sources {
            return Err(DropReason::TooManySources);
        }
        let slot = source.as_usize() * n_streams + stream.as_usize();
        if slot >= self.rings.len() {
            let cap = self.cfg.capacity;
            self.rings.resize_with((source.as_usize() + 1) * n_streams, || VecDeque::with_capacity(cap));
        }
        self.counts.pushed += 1;
        let ring = &mut self.rings[slot];
        let mut outcome = PushOutcome::Buffered;
        let late_after = self.last_emitted_ns.filter(|&last| t_ns <= last);
        if let Some(last) = late_after {
            self.counts.late += 1;
            // After pruning, a front sample at or before `last` is what the next tick
            // interpolates from; a late sample is useful only if it is newer.
            match ring.front() {
                Some(f) if f.t_ns <= last && t_ns < f.t_ns => {
                    self.counts.late_dropped += 1;
                    return Ok(PushOutcome::LateDropped);
                }
                Some(f) if f.t_ns <= last && t_ns > f.t_ns => {
                    ring.pop_front();
                }
                _ => {}
            }
            outcome = PushOutcome::LateKept;
        }
        let idx = ring.partition_point(|s| s.t_ns <= t_ns);
        if idx > 0 && ring[idx - 1].t_ns == t_ns {
            self.counts.same_time += 1;
            return Ok(PushOutcome::SameTime);
        }
        if ring.len() >= self.cfg.capacity {
            if idx == 0 {
                // Older than everything in a full ring: it would be evicted at once.
                self.counts.overflow += 1;
                return Ok(outcome);
            }
            ring.pop_front();
            self.counts.overflow += 1;
            ring.insert(idx - 1, Sample { t_ns, value });
        } else {
            ring.insert(idx, Sample { t_ns, value });
        }
        Ok(outcome)
    }

    /// Moves the cloud clock to `now_ns` and emits, in order, every tick the watermark has
    /// reached; returns how many. Call it with a message's receive time *before* pushing that
    /// message (and from a timer when idle).
    pub fn advance(&mut self, now_ns: i64, mut on_snapshot: impl FnMut(&Snapshot<T>)) -> u64 {
        let now_ns = now_ns.clamp(-CLOCK_LIMIT_NS, CLOCK_LIMIT_NS);
        let now_ns = self.now_ns.map_or(now_ns, |n| n.max(now_ns));
        self.now_ns = Some(now_ns);
        let tick = self.cfg.tick_ns;
        let next = *self.next_tick_ns.get_or_insert_with(|| ceil_to(now_ns, tick));
        let watermark = now_ns.saturating_sub(self.cfg.lateness_ns);
        if watermark < next {
            return 0;
        }
        let due = (watermark - next) / tick + 1;
        let max = i64::from(self.cfg.max_catch_up_ticks);
        let mut t = next;
        if due > max {
            self.counts.skipped_ticks += (due - max) as u64;
            t = next + (due - max) * tick;
        }
        let mut emitted = 0;
        while t <= watermark {
            self.fill(t);
            on_snapshot(&self.snapshot);
            self.prune(t);
            self.last_emitted_ns = Some(t);
            self.counts.snapshots += 1;
            emitted += 1;
            t += tick;
        }
        self.next_tick_ns = Some(t);
        emitted
    }

    /// The snapshot at any time `t_ns` from what is buffered now (no side effect); the
    /// emitted snapshots come from [`advance`](Self::advance).
    pub fn snapshot_at(&self, t_ns: i64, out: &mut Snapshot<T>) {
        *out = Snapshot::new(self.streams.len());
        out.resize_for(self.rings.len());
        out.tick_ns = t_ns;
        for (slot, ring) in self.rings.iter().enumerate() {
            *out.slot_mut(slot) = self.value_at(slot, ring, t_ns);
        }
    }

    fn fill(&mut self, t_ns: i64) {
        self.snapshot.resize_for(self.rings.len());
        self.snapshot.tick_ns = t_ns;
        for slot in 0..self.rings.len() {
            let v = self.value_at(slot, &self.rings[slot], t_ns);
            *self.snapshot.slot_mut(slot) = v;
        }
    }

    fn value_at(&self, slot: usize, ring: &VecDeque<Sample<T>>, t_ns: i64) -> Aligned<T> {
        let spec = self.streams[slot % self.streams.len()];
        let idx = ring.partition_point(|s| s.t_ns <= t_ns);
        let Some(left) = idx.checked_sub(1).map(|i| &ring[i]) else {
            return Aligned::default();
        };
        // Saturating: a source may stamp anything, and an age past i64::MAX is just stale.
        let age_ns = t_ns.saturating_sub(left.t_ns);
        let bound_ns = spec.period_ns.saturating_mul(i64::from(self.cfg.stale_periods));
        if let (StreamMode::Interpolated, Some(lerp), Some(right)) = (spec.mode, self.lerp, ring.get(idx)) {
            let gap_ns = right.t_ns.saturating_sub(left.t_ns);
            if gap_ns <= bound_ns {
                let frac = age_ns as f64 / gap_ns as f64;
                return Aligned {
                    value: Some(lerp(&left.value, &right.value, frac)),
                    status: ValueStatus::Interpolated,
                    age_ns,
                };
            }
        }
        let status = if age_ns <= bound_ns { ValueStatus::AsOf } else { ValueStatus::Stale };
        Aligned { value: Some(left.value.clone()), status, age_ns }
    }

    /// Drops samples no tick after `t_ns` can use: all before the latest one at or before `t_ns`.
    fn prune(&mut self, t_ns: i64) {
        for ring in &mut self.rings {
            let idx = ring.partition_point(|s| s.t_ns <= t_ns);
            if idx > 1 {
                ring.drain(..idx - 1);
            }
        }
    }
}

/// The aligner's clock keeps within ±146 years of the epoch (ns): a receive time beyond (a
/// replay-time attachment may claim any) is clamped, so the tick arithmetic (the next tick, the
/// catch-up, the tick after) cannot overflow.
const CLOCK_LIMIT_NS: i64 = i64::MAX / 2;

/// The smallest multiple of `step` at or after `t`.
fn ceil_to(t: i64, step: i64) -> i64 {
    let r = t.rem_euclid(step);
    if r == 0 { t } else { t - r + step }
}

#[cfg(test)]
#[path = "aligner_tests.rs"]
mod tests;
