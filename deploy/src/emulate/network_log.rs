//! The deployment's network as an MCAP file, `network.mcap` beside the report: every link's
//! condition (`risktwin.v1.LinkCondition` on `/deploy/link/<name>`) when an event changes it and
//! twice a second with what crossed it, and the timeline (`foxglove.Log` on `/deploy/timeline`).
//! Stamped with the wall clock, the clock of the cloud's recording: opened together with it,
//! Foxglove shows when the network degraded beside what the twin saw.

use super::relay::HopView;
use crate::topology::Jitter;
use risktwin_protos::convert::foxglove::timestamp;
use risktwin_protos::recording::{Recorder, RecordingError};
use risktwin_protos::v1::LinkCondition;
use risktwin_transport::wall_clock::unix_ns;
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;
use std::sync::atomic::Ordering;

/// Full protobuf name of a link's condition.
const LINK_CONDITION: &str = "risktwin.v1.LinkCondition";
/// The timeline's topic.
pub const TIMELINE_TOPIC: &str = "/deploy/timeline";
/// A link's topic prefix (the link's name follows).
pub const LINK_TOPIC: &str = "/deploy/link/";

/// The file being written. A write that fails stops the recording (logged once) and never the
/// deployment. Its writes are sparse (an event, twice a second the links), so each is flushed
/// as a chunk of its own: a killed deployment loses at most the write under way, well within
/// the live recorder's 1 s bound, which would otherwise wait for the next write.
pub struct NetworkLog {
    recorder: Option<Recorder<BufWriter<File>>>,
}

impl NetworkLog {
    /// Starts `path` (replaced if it exists).
    pub fn create(path: &Path) -> Result<NetworkLog, RecordingError> {
        let file = File::create(path)?;
        Ok(NetworkLog { recorder: Some(Recorder::live(BufWriter::new(file))?) })
    }

    fn with(&mut self, write: impl FnOnce(&mut Recorder<BufWriter<File>>) -> Result<(), RecordingError>) {
        if let Some(recorder) = self.recorder.as_mut()
            && let Err(e) = write(recorder).and_then(|()| recorder.flush())
        {
            tracing::warn!("network.mcap: {e}; no more is recorded");
            self.recorder = None;
        }
    }

    /// A line of the timeline.
    pub fn note(&mut self, what: &str) {
        self.with(|r| r.record_log(TIMELINE_TOPIC, unix_ns() as u64, "deploy", what));
    }

    /// Every hop's condition now.
    pub fn links(&mut self, hops: &[HopView]) {
        let t = unix_ns() as u64;
        self.with(|r| {
            for h in hops {
                r.record_proto(&format!("{LINK_TOPIC}{}", h.name), LINK_CONDITION, t, &condition(h, t))?;
            }
            Ok(())
        });
    }

    /// Writes the file's summary and footer.
    pub fn finish(mut self) {
        if let Some(recorder) = self.recorder.take()
            && let Err(e) = recorder.finish()
        {
            tracing::warn!("network.mcap: {e}");
        }
    }
}

fn condition(h: &HopView, t: u64) -> LinkCondition {
    let (jitter_ms, jitter_dist) = match h.shape.jitter {
        None => (0.0, ""),
        Some(Jitter::Normal { sd_ms }) => (sd_ms, "normal"),
        Some(Jitter::Uniform { max_ms }) => (max_ms, "uniform"),
    };
    LinkCondition {
        timestamp: Some(timestamp(t as i64)),
        link: h.name.clone(),
        partitioned: h.partitioned,
        latency_ms: h.shape.latency.as_secs_f64() * 1e3,
        jitter_ms,
        jitter_dist: jitter_dist.to_owned(),
        bandwidth_mbps: h.shape.bandwidth_bps.map_or(0.0, |b| b / 1e6),
        bytes_up: h.counts.bytes[0].load(Ordering::Relaxed),
        bytes_down: h.counts.bytes[1].load(Ordering::Relaxed),
        connections: h.counts.connections.load(Ordering::Relaxed),
        refused: h.counts.refused.load(Ordering::Relaxed),
    }
}
