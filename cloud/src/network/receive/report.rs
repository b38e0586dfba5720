//! What the ingest tells at its end and at each scrape: the summary, the closed recording, the
//! metrics snapshot.

use super::{LiveIngest, RecordError};
use crate::network::live_metrics::{self, Snapshot};
use crate::network::liveliness::LivenessLog;
use crate::network::summary::{IngestSummary, LagSummary, per_stream_names, summarize};
use crate::twin::outputs::{TwinOutputs, TwinSummary};
use risktwin_store::recordings::Segments;
use risktwin_transport::sync::LockExt;
use std::collections::BTreeMap;
use std::io::Write;
use std::sync::{Arc, Mutex, Weak};

impl LiveIngest {
    /// Closes the recording (so the file is a valid MCAP) and returns the summary, with the
    /// twin's when it ran.
    pub fn finish(self) -> Result<(IngestSummary, Option<TwinSummary>), RecordError> {
        let mut summary = self.summary();
        let (_, recording) = self.worker.finish()?;
        summary.segments = match (recording, self.segments) {
            (Some((file, closed)), Some(segments)) => Some(segments.finish(file, closed)?),
            (Some((mut file, _)), None) => {
                file.flush().map_err(RecordError::Flush)?;
                None
            }
            (None, _) => None,
        };
        if risktwin_transport::metrics::enabled() {
            let twin = self.outputs.as_ref().map(TwinOutputs::counts);
            live_metrics::export_ingest(&summary, &self.sites, twin.as_ref());
        }
        Ok((summary, self.outputs.as_ref().map(TwinOutputs::summary)))
    }

    /// The summary so far; a rotating recording's segments as they stand (closed ones counted).
    pub fn summary(&self) -> IngestSummary {
        let presumed_lost = self.worker.presumed_lost();
        let mut summary = summarize(self.worker.stats(), &self.received, &self.digest);
        summary.segments = self.segments.as_ref().map(Segments::summary);
        summary.recovered = per_stream_names(&self.recovered);
        summary.total_recovered = summary.recovered.values().flat_map(BTreeMap::values).sum();
        summary.twin_lag = LagSummary::of(&self.lag);
        summary.lost = self.losses.by_source().clone();
        summary.total_lost = self.losses.total();
        summary.total_presumed_lost = presumed_lost.values().flat_map(BTreeMap::values).sum();
        summary.presumed_lost = presumed_lost;
        summary.id_conflicts = self.conflicts.summary();
        summary.overload = self.load.summary();
        summary
    }

    /// What a scrape exports: copied while the receive path waits (a few ms for thousands of
    /// sources), exported after it has the lock back.
    pub(in crate::network) fn metrics_snapshot(&self) -> Snapshot {
        Snapshot {
            ingest: self.summary(),
            sites: self.sites.clone(),
            twin: self.outputs.as_ref().map(TwinOutputs::counts),
            warning: self.warning_summary(),
        }
    }
}

/// Has every scrape copy the counts of `ingest` and `liveness` while the cloud runs.
pub(in crate::network) fn watch_metrics(ingest: &Arc<Mutex<LiveIngest>>, liveness: &Arc<Mutex<LivenessLog>>) {
    // Weak: the cloud takes the ingest apart at shutdown, and exports the final counts itself.
    let (ingest, liveness): (Weak<_>, Weak<_>) = (Arc::downgrade(ingest), Arc::downgrade(liveness));
    risktwin_transport::metrics::on_scrape(move || {
        let (Some(ingest), Some(liveness)) = (ingest.upgrade(), liveness.upgrade()) else { return false };
        // Only the copy holds the ingest's lock: the receive path must not wait for the export
        // (a stall of a second would skew every source's clock estimate).
        let snapshot = ingest.locked().metrics_snapshot();
        live_metrics::export_ingest(&snapshot.ingest, &snapshot.sites, snapshot.twin.as_ref());
        snapshot.warning.iter().for_each(live_metrics::export_warning);
        live_metrics::export_liveliness(&liveness.locked().summary());
        true
    });
}
