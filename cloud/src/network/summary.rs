//! The cloud's JSON summary of what the ingest saw: per source and stream received, dropped,
//! lost, recovered and presumed lost, and how far the twin lagged the cloud's clock.

use crate::ingest::{IngestStats, SnapshotDigest};
use crate::twin::fidelity::distribution::Distribution;
use risktwin_transport::EdgeStream;
use serde::Serialize;
use std::collections::{BTreeMap, HashMap};

/// How many edge streams a per-stream count array holds.
pub(super) const STREAMS: usize = EdgeStream::ALL.len();

/// What the ingest saw, as printed in the cloud's JSON summary.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Default)]
pub struct IngestSummary {
    /// Accepted messages per source, per stream (streams with none are left out).
    pub received: BTreeMap<String, BTreeMap<String, u64>>,
    /// Dropped messages per [`DropReason`] code.
    pub dropped: BTreeMap<String, u64>,
    /// All accepted messages.
    pub total_received: u64,
    /// All dropped messages.
    pub total_dropped: u64,
    /// Messages written to the recording (equals `total_received` when recording).
    pub recorded: u64,
    /// Snapshots the aligner emitted.
    pub snapshots: u64,
    /// Accepted messages that arrived after the snapshot of their time was emitted (beyond the
    /// allowed lateness); `late_dropped` of them were of no use to any later snapshot either.
    pub late: u64,
    /// Late messages the twin never saw (still received and recorded).
    pub late_dropped: u64,
    /// FNV-1a digest of every emitted snapshot (tick, statuses, pose bits), 16 hex digits.
    pub snapshot_digest: String,
    /// How far each snapshot's tick (what the twin shows) lay behind the cloud's clock when it
    /// was emitted: the alignment's wait for late samples and the streams' delay beyond their
    /// least (the clock mapping absorbs a source's constant delay: edge clocks are not trusted).
    pub twin_lag: LagSummary,
    /// Samples lost for good on the way, per source, per stream: neither received nor
    /// recoverable from the edge's cache (an outage longer than it). Per stream,
    /// `received + lost = sent` while the edge and the cloud outlive the recovery (the exceptions:
    /// docs/keyexpr.md, "Surviving faults").
    pub lost: BTreeMap<String, BTreeMap<String, u64>>,
    /// All lost samples.
    pub total_lost: u64,
    /// Accepted samples that came from an edge's cache (recovered after a gap: a partition, a
    /// router restart, a sample the link dropped), per source, per stream; counted in `received`
    /// too.
    pub recovered: BTreeMap<String, BTreeMap<String, u64>>,
    /// All recovered samples.
    pub total_recovered: u64,
    /// Sequence numbers each source skipped on a stream and never sent again, per source, per
    /// stream: the deduplicator's own count of what never arrived (it sees an edge's numbers,
    /// where `lost` sees the transport's: the same gaps for a live edge, plus what was numbered
    /// before the first sample the cloud got; for a replay, the recording's own gaps too).
    pub presumed_lost: BTreeMap<String, BTreeMap<String, u64>>,
    /// All presumed-lost sequence numbers.
    pub total_presumed_lost: u64,
    /// Per source, how often its samples switched between two publishing sessions both alive
    /// (two processes under one id; see `id_conflicts.rs`). Empty when every id is one process.
    pub id_conflicts: BTreeMap<String, u64>,
    /// Overload: the shedding level, how long the ingest shed, and its load measure
    /// (docs/keyexpr.md, "Overload").
    pub overload: LoadSummary,
    /// The segments of a rotating recording (`--record-dir`), when recording so.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub segments: Option<risktwin_store::recordings::SegmentsSummary>,
}

/// A lag's distribution, µs (the 95th percentile to 1 ms, exact up to 2 s).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Default)]
pub struct LagSummary {
    pub n: u64,
    pub mean_us: u64,
    pub p95_us: u64,
    pub max_us: u64,
}

impl LagSummary {
    pub(super) fn of(d: &Distribution) -> LagSummary {
        let s = d.stats();
        let us = |x: f64| (x * 1e6).round() as u64;
        LagSummary { n: s.n, mean_us: us(s.mean), p95_us: us(s.p95), max_us: us(s.max) }
    }
}

pub(super) fn summarize(
    stats: &IngestStats,
    received: &HashMap<String, [u64; STREAMS]>,
    digest: &SnapshotDigest,
) -> IngestSummary {
    let mut summary = IngestSummary {
        dropped: stats.dropped.clone(),
        total_received: stats.accepted,
        total_dropped: stats.dropped_total(),
        recorded: stats.recorded,
        snapshots: stats.snapshots,
        late: stats.late,
        late_dropped: stats.late_dropped,
        snapshot_digest: digest.hex(),
        ..IngestSummary::default()
    };
    summary.received = per_stream_names(received);
    summary
}

/// Counts per source and stream index as counts per source and stream name (streams with none
/// left out).
pub(super) fn per_stream_names(counts: &HashMap<String, [u64; STREAMS]>) -> BTreeMap<String, BTreeMap<String, u64>> {
    let named = |counts: &[u64; STREAMS]| {
        EdgeStream::ALL.iter().zip(counts).filter(|(_, n)| **n > 0).map(|(s, n)| (s.as_str().to_owned(), *n)).collect()
    };
    counts.iter().map(|(source, counts)| (source.clone(), named(counts))).collect()
}

/// The overload part of the ingest's summary.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct LoadSummary {
    /// The shedding level at the end (0 none, 1 CAN, 2 all but states).
    pub shed_level: u8,
    /// The highest level reached.
    pub shed_level_max: u8,
    /// Seconds spent shedding (whole windows).
    pub shedding_s: u64,
    /// The least delay of live states over the last full window, ms (the load measure).
    pub queue_delay_ms: Option<u64>,
}

/// What the loop role did, for the cloud's summary.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LoopRoleSummary {
    #[serde(flatten)]
    pub fleet: crate::fleet_loop::LoopSummary,
    /// Results received on the wire.
    pub results_received: u64,
    /// Results that did not decode (or were tagged with another schema), dropped.
    pub results_malformed: u64,
    /// Results whose header named another edge than their key, dropped.
    pub results_source_mismatch: u64,
    /// The twin's watch: episodes with ticks, results it had not watched, ticks dropped.
    pub watch: crate::twin::watch::WatchCounts,
}
