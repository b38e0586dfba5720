//! The ingest core in the order a cloud worker applies it to each decoded message.
//!
//! For a message `(source, stream, seq, capture_ns, receive_ns, payload)`:
//! 1. the aligner's clock moves to `receive_ns`, emitting every tick now due (so a tick holds
//!    exactly the messages received before `tick + lateness`, see [`super::aligner`]);
//! 2. an unknown stream or a source beyond the limit is refused (`unknown-stream`,
//!    `too-many-sources`), before any sequence accounting;
//! 3. exactly-once: a duplicate, a number older than the reorder window or an unconfirmed one
//!    beyond it is refused (`duplicate`, `too-old`, `seq-jump`; see [`super::dedupe`]);
//! 4. the capture time is mapped onto the cloud clock with the source's clock estimate (built
//!    from earlier messages only); a mapping later than `receive + future_tolerance` is not fed
//!    to the estimator, whose minimum filter one bad timestamp would otherwise wreck. Against a
//!    fitted estimate it is refused (`future-timestamp`), and a source that sends
//!    `clock_reset_after` of them in a row has had its clock stepped forward: its estimate is
//!    reset and re-anchored. While the estimate still warms up (a running minimum of a few
//!    samples), the estimate is the likelier error — its first samples came late, as a cache's
//!    burst of old samples does — so the message is taken at its receive time
//!    ([`IngestCore::warm_clamped`]), and `clock_reset_after_warming_up` in a row re-anchor it;
//! 5. the estimator takes the message in, and the payload goes to the aligner at its cloud time.
//!
//! Accounting: every message ends in exactly one of accepted or one drop reason, and per
//! sequence scope `fresh + presumed_lost = highest − first + 1` (see [`super::dedupe`]), where
//! `fresh = accepted + future-timestamp drops`. So, summed over sources,
//! `accepted + dropped(future-timestamp) + presumed_lost = sent (unique numbers)`.

use super::aligner::{AlignConfig, Aligner, PushOutcome, StreamSpec};
use super::clock::{ClockConfig, ClockEstimator};
use super::dedupe::{DedupConfig, Deduper, SeqCounts, SeqProgress};
use super::interp::Interpolate;
use super::reason::{DropCounts, DropReason};
use super::snapshot::{Snapshot, StreamIndex};
use super::source::SourceIndex;

/// What a sequence number counts: all messages of a source, or each stream separately.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SequenceScope {
    /// One counter per source across its streams.
    PerSource,
    /// One counter per (source, stream).
    PerStream,
}

/// How the ingest core is set up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct IngestConfig {
    pub dedup: DedupConfig,
    pub clock: ClockConfig,
    pub align: AlignConfig,
    pub sequence_scope: SequenceScope,
    /// How far after its receive time a mapped capture time may lie before it is "from the
    /// future"; covers the estimator's error while it warms up on a few samples.
    pub future_tolerance_ns: i64,
    /// Consecutive future timestamps after which a source's clock estimate is reset.
    pub clock_reset_after: u32,
    /// The same while the estimate warms up (no drift fitted yet: the running minimum of a few
    /// seconds): a run of future timestamps then most likely means the first samples arrived
    /// late (a cloud behind at start, a burst from a cache) and the anchor is off, not that the
    /// clock stepped. The run's messages are taken at their receive times, not refused.
    pub clock_reset_after_warming_up: u32,
}

impl Default for IngestConfig {
    fn default() -> Self {
        Self {
            dedup: DedupConfig::default(),
            clock: ClockConfig::default(),
            align: AlignConfig::default(),
            sequence_scope: SequenceScope::PerStream,
            future_tolerance_ns: 100_000_000,
            clock_reset_after: 50,
            clock_reset_after_warming_up: 5,
        }
    }
}

/// One decoded message as the ingest core needs it.
#[derive(Debug, Clone, PartialEq)]
pub struct Incoming<T> {
    pub source: SourceIndex,
    pub stream: StreamIndex,
    pub seq: u64,
    /// Capture time on the source's own clock.
    pub capture_ns: i64,
    /// Receive time on the cloud clock.
    pub receive_ns: i64,
    pub payload: T,
}

/// A message taken in: its time on the cloud clock and what the aligner made of it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Accepted {
    pub cloud_ns: i64,
    pub push: PushOutcome,
}

/// Validation, exactly-once, clock estimation and alignment for a fleet of sources.
#[derive(Debug, Clone)]
pub struct IngestCore<T> {
    cfg: IngestConfig,
    dedup: Deduper,
    clocks: Vec<ClockEstimator>,
    /// Per source: it left ([`IngestCore::restart_source`]) and its clock estimate goes at the
    /// first sign of a new incarnation (on any of its streams: once, not once per stream).
    clock_stale: Vec<bool>,
    future_streak: Vec<u32>,
    aligner: Aligner<T>,
    drops: DropCounts,
    accepted: u64,
    clock_resets: u64,
    /// Future timestamps taken at their receive time while the source's estimate warmed up.
    warm_clamped: u64,
    /// Streams shed now (bit `i`: stream index `i`), see [`IngestCore::set_shed`].
    shed: u64,
}

impl<T: Clone + Interpolate> IngestCore<T> {
    /// An ingest core for `streams` of an interpolable payload.
    pub fn new(cfg: IngestConfig, streams: &[StreamSpec]) -> Self {
        Self::with_aligner(cfg, Aligner::new(cfg.align, streams))
    }
}

impl<T: Clone> IngestCore<T> {
    /// An ingest core around an aligner built by the caller (e.g. [`Aligner::as_of`]).
    pub fn with_aligner(cfg: IngestConfig, aligner: Aligner<T>) -> Self {
        let cfg = IngestConfig { align: *aligner.config(), ..cfg };
        Self {
            cfg,
            dedup: Deduper::new(cfg.dedup),
            clocks: Vec::new(),
            clock_stale: Vec::new(),
            future_streak: Vec::new(),
            aligner,
            drops: DropCounts::default(),
            accepted: 0,
            clock_resets: 0,
            warm_clamped: 0,
            shed: 0,
        }
    }

    /// Takes in one message; emits due snapshots through `on_snapshot` first.
    pub fn ingest(&mut self, msg: Incoming<T>, on_snapshot: impl FnMut(&Snapshot<T>)) -> Result<Accepted, DropReason> {
        self.ingest_then(msg, |_| {}, on_snapshot)
    }

    /// [`IngestCore::ingest`], handing a message that passes steps 2–4 to `on_admitted` (with its
    /// cloud time) before any snapshot goes to `on_snapshot`: a caller that reacts to each
    /// message at once does so before the tick work it triggers. The core's state ends exactly
    /// as with `ingest` (steps 2–4 touch no aligner state, and the aligner still advances
    /// before the push), so the snapshots are the same; an admitted message is accepted (the
    /// aligner refuses only what step 2 refused already).
    pub fn ingest_then(
        &mut self,
        msg: Incoming<T>,
        on_admitted: impl FnOnce(i64),
        on_snapshot: impl FnMut(&Snapshot<T>),
    ) -> Result<Accepted, DropReason> {
        let admitted = self.admit(&msg);
        if let Ok(cloud_ns) = admitted {
            on_admitted(cloud_ns);
        }
        self.aligner.advance(msg.receive_ns, on_snapshot);
        let r = admitted.and_then(|cloud_ns| {
            let push = self.aligner.push(msg.source, msg.stream, cloud_ns, msg.payload)?;
            Ok(Accepted { cloud_ns, push })
        });
        match r {
            Ok(_) => self.accepted += 1,
            Err(reason) => self.drops.add(reason),
        }
        r
    }

    /// Steps 2–4 and the estimator's update of step 5: the message's cloud time, or why it is
    /// dropped. Touches no aligner state.
    fn admit(&mut self, msg: &Incoming<T>) -> Result<i64, DropReason> {
        let streams = self.aligner.streams();
        if msg.stream.as_usize() >= streams {
            return Err(DropReason::UnknownStream);
        }
        let s = msg.source.as_usize();
        if s >= self.cfg.align.max_sources {
            return Err(DropReason::TooManySources);
        }
        let key = match self.cfg.sequence_scope {
            SequenceScope::PerSource => msg.source,
            SequenceScope::PerStream => {
                let key = s.saturating_mul(streams).saturating_add(msg.stream.as_usize());
                SourceIndex(u32::try_from(key).map_err(|_| DropReason::TooManySources)?)
            }
        };
        let restarts = self.dedup.counts(key).restarts;
        if let Some(reason) = self.dedup.accept(key, msg.seq).drop_reason() {
            return Err(reason);
        }
        if s >= self.clocks.len() {
            self.clocks.resize_with(s + 1, || ClockEstimator::new(self.cfg.clock));
            self.future_streak.resize(s + 1, 0);
        }
        let clock = &mut self.clocks[s];
        if self.dedup.counts(key).restarts != restarts && self.clock_stale.get(s).copied().unwrap_or(false) {
            // A new process under the source's name: its clock is not the last one's.
            clock.reset();
            self.future_streak[s] = 0;
            self.clock_stale[s] = false;
        }
        clock.roll_to(msg.receive_ns);
        let mut mapped = clock.to_cloud_ns(msg.capture_ns);
        let mut teaches = true;
        if mapped.is_some_and(|m| m > msg.receive_ns.saturating_add(self.cfg.future_tolerance_ns)) {
            self.future_streak[s] += 1;
            let fitted = clock.is_fitted();
            let reset_after = if fitted { self.cfg.clock_reset_after } else { self.cfg.clock_reset_after_warming_up };
            if self.future_streak[s] < reset_after {
                if fitted {
                    return Err(DropReason::FutureTimestamp);
                }
                // Warming up, the estimate of a few samples is the likelier culprit (they came
                // late: a burst from a cache, a cloud behind): this one is taken at its receive
                // time, and kept out of the estimate until the run says the anchor was wrong.
                self.warm_clamped += 1;
                teaches = false;
            } else {
                clock.reset();
                self.clock_resets += 1;
                self.future_streak[s] = 0;
            }
            mapped = None;
        } else {
            self.future_streak[s] = 0;
        }
        if teaches {
            clock.observe(msg.capture_ns, msg.receive_ns);
        }
        // After the deduplicator and the clock: a shed message counts as received (its number
        // is no gap) and still teaches the estimator.
        if self.shed & (1 << msg.stream.as_usize().min(63)) != 0 {
            return Err(DropReason::Shed);
        }
        // The first message of a source (or after a reset) anchors it at its receive time.
        Ok(mapped.unwrap_or(msg.receive_ns))
    }

    /// Sheds the streams whose index has its bit set in `streams` (an overloaded ingest; see
    /// `docs/keyexpr.md`, "Overload"): their messages are dropped as [`DropReason::Shed`] once
    /// counted by the deduplicator. `0` sheds nothing.
    pub fn set_shed(&mut self, streams: u64) {
        self.shed = streams;
    }

    /// `source` may have started over (its process left, and a new one may come under the same
    /// name): the deduplicator decides on its next numbers ([`Deduper::restart`]), and the
    /// source's clock estimate is dropped once it does see a new incarnation. A source that only
    /// lost its link (a router restart) keeps its estimate: the samples it sends again from its
    /// cache arrive late, and an estimate anchored on them would map its live samples into the
    /// future.
    pub fn restart_source(&mut self, source: SourceIndex) {
        let s = source.as_usize();
        if s < self.cfg.align.max_sources {
            if s >= self.clock_stale.len() {
                self.clock_stale.resize(s + 1, false);
            }
            self.clock_stale[s] = true;
        }
        match self.cfg.sequence_scope {
            SequenceScope::PerSource => self.dedup.restart(source),
            SequenceScope::PerStream => {
                let streams = self.aligner.streams();
                for stream in 0..streams {
                    let key = source.as_usize().saturating_mul(streams).saturating_add(stream);
                    if let Ok(key) = u32::try_from(key) {
                        self.dedup.restart(SourceIndex(key));
                    }
                }
            }
        }
    }

    /// Moves the cloud clock without a message (a timer while idle), emitting due snapshots.
    pub fn advance(&mut self, now_ns: i64, on_snapshot: impl FnMut(&Snapshot<T>)) -> u64 {
        self.aligner.advance(now_ns, on_snapshot)
    }

    /// Drops so far, by reason.
    pub fn drops(&self) -> &DropCounts {
        &self.drops
    }

    /// Messages accepted so far.
    pub fn accepted(&self) -> u64 {
        self.accepted
    }

    /// Clock estimates reset after a run of future timestamps.
    pub fn clock_resets(&self) -> u64 {
        self.clock_resets
    }

    /// Messages that mapped into the future while their source's estimate warmed up, taken at
    /// their receive time rather than refused (see [`IngestConfig::clock_reset_after_warming_up`]).
    pub fn warm_clamped(&self) -> u64 {
        self.warm_clamped
    }

    /// The deduplicator (per-key sequence counters, presumed losses).
    pub fn dedup(&self) -> &Deduper {
        &self.dedup
    }

    /// The sequence counters of `stream` of `source`: that pair's own with
    /// [`SequenceScope::PerStream`], the source's (shared by its streams) with `PerSource`.
    pub fn seq_counts(&self, source: SourceIndex, stream: StreamIndex) -> SeqCounts {
        match self.cfg.sequence_scope {
            SequenceScope::PerSource => self.dedup.counts(source),
            SequenceScope::PerStream => {
                let key = source.as_usize().saturating_mul(self.aligner.streams()).saturating_add(stream.as_usize());
                u32::try_from(key).map(|k| self.dedup.counts(SourceIndex(k))).unwrap_or_default()
            }
        }
    }

    /// How far the current incarnation of `stream` of `source` is accounted for (the source's
    /// one sequence with [`SequenceScope::PerSource`]); `None` before its first accepted number.
    pub fn progress(&self, source: SourceIndex, stream: StreamIndex) -> Option<SeqProgress> {
        match self.cfg.sequence_scope {
            SequenceScope::PerSource => self.dedup.progress(source),
            SequenceScope::PerStream => {
                let key = source.as_usize().saturating_mul(self.aligner.streams()).saturating_add(stream.as_usize());
                u32::try_from(key).ok().and_then(|k| self.dedup.progress(SourceIndex(k)))
            }
        }
    }

    /// How sequence numbers are counted.
    pub fn sequence_scope(&self) -> SequenceScope {
        self.cfg.sequence_scope
    }

    /// The clock estimate of `source`, once it has sent an accepted message.
    pub fn clock(&self, source: SourceIndex) -> Option<&ClockEstimator> {
        self.clocks.get(source.as_usize())
    }

    /// The aligner (counts of late, stale, overflow; the last emitted tick).
    pub fn aligner(&self) -> &Aligner<T> {
        &self.aligner
    }
}

#[cfg(test)]
#[path = "ingest_tests.rs"]
mod tests;
