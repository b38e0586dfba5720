//! The cloud's live Prometheus metrics (docs/metrics.md). Every count is the JSON summary's own,
//! copied at each scrape (`receive::watch_metrics`) and once more at the end, so the two never disagree and the
//! receive path does no work for them; only the twin's snapshot lag is observed as it happens
//! (a histogram needs each value), once per snapshot.

use super::liveliness::LivenessSummary;
use super::summary::{IngestSummary, LoopRoleSummary};
use crate::fleet_loop::LoopSummary;
use crate::twin::outputs::TwinCounts;
use crate::warning::WarningSummary;
use std::collections::{BTreeMap, HashMap};

/// The histogram of how far each snapshot's tick lay behind the cloud's clock, s.
pub(super) const SNAPSHOT_LAG: &str = "risktwin_twin_snapshot_lag_seconds";

/// The counts a scrape exports, copied out of the ingest.
pub(super) struct Snapshot {
    pub(super) ingest: IngestSummary,
    /// Each source's site.
    pub(super) sites: HashMap<String, String>,
    pub(super) twin: Option<TwinCounts>,
    pub(super) warning: Option<WarningSummary>,
}

/// Per source and stream counts, labelled with the source's site.
fn per_stream(name: &'static str, counts: &BTreeMap<String, BTreeMap<String, u64>>, sites: &HashMap<String, String>) {
    for (source, streams) in counts {
        let site = sites.get(source).map_or("", String::as_str);
        for (stream, n) in streams {
            metrics::counter!(name, "site" => site.to_owned(), "source" => source.clone(), "stream" => stream.clone())
                .absolute(*n);
        }
    }
}

/// The ingest's summary (and the twin's counts, when it runs); `sites` names each source's site.
pub(super) fn export_ingest(s: &IngestSummary, sites: &HashMap<String, String>, twin: Option<&TwinCounts>) {
    per_stream("risktwin_ingest_messages_received_total", &s.received, sites);
    per_stream("risktwin_ingest_messages_lost_total", &s.lost, sites);
    per_stream("risktwin_ingest_messages_recovered_total", &s.recovered, sites);
    per_stream("risktwin_ingest_messages_presumed_lost_total", &s.presumed_lost, sites);
    for (reason, n) in &s.dropped {
        metrics::counter!("risktwin_ingest_messages_dropped_total", "reason" => reason.clone()).absolute(*n);
    }
    metrics::gauge!("risktwin_ingest_shed_level").set(f64::from(s.overload.shed_level));
    metrics::counter!("risktwin_ingest_shedding_seconds_total").absolute(s.overload.shedding_s);
    if let Some(ms) = s.overload.queue_delay_ms {
        metrics::gauge!("risktwin_ingest_queue_delay_seconds").set(ms as f64 * 1e-3);
    }
    metrics::counter!("risktwin_ingest_messages_late_total").absolute(s.late);
    metrics::counter!("risktwin_ingest_messages_late_unused_total").absolute(s.late_dropped);
    for (source, n) in &s.id_conflicts {
        metrics::counter!("risktwin_ingest_id_conflicts_total", "source" => source.clone()).absolute(*n);
    }
    metrics::counter!("risktwin_twin_snapshots_total").absolute(s.snapshots);
    metrics::counter!("risktwin_recording_messages_total").absolute(s.recorded);
    if let Some(seg) = &s.segments {
        for (state, n) in
            [("opened", seg.segments_opened), ("closed", seg.segments_closed), ("deleted", seg.segments_deleted)]
        {
            metrics::counter!("risktwin_recording_segments_total", "state" => state).absolute(n);
        }
        metrics::counter!("risktwin_recording_bytes_total").absolute(seg.bytes_written);
        metrics::counter!("risktwin_recording_deleted_bytes_total").absolute(seg.bytes_deleted);
    }
    if let Some(twin) = twin {
        metrics::counter!("risktwin_twin_ticks_total").absolute(twin.ticks);
        metrics::counter!("risktwin_twin_scenes_total").absolute(twin.scenes);
        metrics::counter!("risktwin_risk_assessments_total").absolute(twin.risk_assessments);
        for (site, n) in &twin.vehicles {
            metrics::gauge!("risktwin_twin_vehicles", "site" => site.clone()).set(*n as f64);
        }
        for (site, risk) in &twin.latest_max_risk {
            metrics::gauge!("risktwin_risk_field_max", "site" => site.clone()).set(*risk);
        }
    }
}

/// Edges that joined, left, and are alive.
pub(super) fn export_liveliness(s: &LivenessSummary) {
    metrics::counter!("risktwin_cloud_edges_joined_total").absolute(s.joined.len() as u64);
    metrics::counter!("risktwin_cloud_edges_left_total").absolute(s.left.len() as u64);
    metrics::gauge!("risktwin_cloud_edges_alive").set(s.alive.len() as f64);
}

/// The warning role's counts.
pub(super) fn export_warning(s: &WarningSummary) {
    set_counters([
        ("risktwin_warning_states_total", s.states),
        ("risktwin_warning_late_states_total", s.late_states),
        ("risktwin_warning_pairs_assessed_total", s.pairs_assessed),
        ("risktwin_warning_critical_total", s.critical),
        ("risktwin_warning_rate_limited_total", s.rate_limited),
        ("risktwin_warning_failed_total", s.failed),
    ]);
    for (vehicle, n) in &s.sent_to {
        let (site, vehicle) = vehicle.split_once('/').unwrap_or(("", vehicle));
        metrics::counter!("risktwin_warning_sent_total", "site" => site.to_owned(), "vehicle" => vehicle.to_owned())
            .absolute(*n);
    }
}

/// The loop role's counts of this run (the library's own totals are in its database).
pub(crate) fn export_loop(s: &LoopSummary) {
    set_counters([
        ("risktwin_loop_pushes_total", s.pushes),
        ("risktwin_loop_retries_total", s.retries),
        ("risktwin_loop_abandoned_total", s.abandoned),
        ("risktwin_loop_episodes_total", s.episodes),
        ("risktwin_loop_failures_total", s.failures),
        ("risktwin_loop_disagreements_total", s.disagreements),
        ("risktwin_loop_mutants_total", s.mutants),
    ]);
}

/// Sets each unlabelled counter to its count.
fn set_counters<const N: usize>(counts: [(&'static str, u64); N]) {
    for (name, n) in counts {
        metrics::counter!(name).absolute(n);
    }
}

/// The loop role's result counts, at the end.
pub(super) fn export_loop_results(s: &LoopRoleSummary) {
    export_loop(&s.fleet);
    metrics::counter!("risktwin_loop_results_received_total").absolute(s.results_received);
    metrics::counter!("risktwin_loop_results_dropped_total", "reason" => "malformed").absolute(s.results_malformed);
    metrics::counter!("risktwin_loop_results_dropped_total", "reason" => "source-mismatch")
        .absolute(s.results_source_mismatch);
}
