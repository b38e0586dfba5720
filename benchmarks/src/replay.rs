//! Unpaced MCAP replay into ingest, in-process, against the raw `mcap` reader as the peer
//! (`risktwin bench replay`).
//!
//! One run times, alternating, per round: the `mcap` crate's own `MessageStream` over the
//! recording's bytes (the peer: it only reads), our [`MessageCursor`] alone, and our cursor
//! feeding every message through an [`IngestWorker`] (decode, validate, exactly-once, clock
//! estimation, alignment into snapshots) at its recorded receive time. Medians are compared.
//! Without a file (or with one that does not exist yet) a synthetic fleet recording is written
//! first: `vehicles` × `seconds` of state (50 Hz), CAN (100 Hz) and perception (10 Hz).

use crate::BenchError;
use crate::synth::{FleetConfig, SyntheticFleet};
use risktwin_align::IngestConfig;
use risktwin_cloud::ingest::{IngestWorker, SnapshotDigest, replay_into};
use risktwin_protos::recording::{MessageCursor, Recorder};
use serde::Serialize;
use std::io::{BufWriter, Cursor};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What to replay and how often.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReplayConfig {
    /// The recording to replay; written first (a synthetic fleet) if it does not exist, a
    /// temporary file (removed afterwards) if `None`.
    pub file: Option<PathBuf>,
    /// Vehicles of the synthetic fleet.
    pub vehicles: usize,
    /// Seconds of the synthetic fleet.
    pub seconds: u64,
    /// Measurements per side, alternating; medians are compared (at least 1).
    pub rounds: usize,
}

/// The figures, messages per second.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReplayReport {
    pub file: String,
    pub file_bytes: u64,
    pub messages: u64,
    pub raw_mcap_msgs_per_s: f64,
    pub cursor_msgs_per_s: f64,
    pub ingest_msgs_per_s: f64,
    /// Ingest over the raw reader alone (the raw reader does no ingest work).
    pub ratio_ingest_vs_raw_reader: f64,
    pub cursor_vs_raw_reader: f64,
    pub accepted: u64,
    pub dropped: u64,
    pub snapshots: u64,
    pub snapshot_digest: String,
}

/// Runs the benchmark (writing the synthetic recording first when needed).
pub fn replay(config: &ReplayConfig) -> Result<ReplayReport, BenchError> {
    let rounds = config.rounds.max(1);
    let temp;
    let path = match &config.file {
        Some(p) => p.clone(),
        None => {
            temp = TempFile(std::env::temp_dir().join(format!("risktwin-bench-replay-{}.mcap", std::process::id())));
            temp.0.clone()
        }
    };
    if !path.exists() {
        if config.vehicles == 0 || config.seconds == 0 {
            return Err(BenchError::Input("--vehicles and --seconds must be positive".into()));
        }
        let n = write_fleet(&path, config.vehicles, config.seconds)?;
        tracing::info!(
            "wrote {n} messages of {} vehicles × {} s to {}",
            config.vehicles,
            config.seconds,
            path.display()
        );
    }
    let bytes = std::fs::read(&path).map_err(|e| BenchError::Input(format!("cannot read {}: {e}", path.display())))?;

    let (mut raw, mut cursor, mut ingest) = (Vec::new(), Vec::new(), Vec::new());
    let mut last = None;
    for _ in 0..rounds {
        raw.push(time_raw(&bytes)?);
        cursor.push(time_cursor(&bytes)?);
        let (rate, outcome) = time_ingest(&bytes)?;
        ingest.push(rate);
        last = Some(outcome);
    }
    let outcome = last.expect("rounds ≥ 1");
    let (raw, cursor, ingest) = (median(&mut raw), median(&mut cursor), median(&mut ingest));
    Ok(ReplayReport {
        file: path.display().to_string(),
        file_bytes: bytes.len() as u64,
        messages: outcome.messages,
        raw_mcap_msgs_per_s: raw,
        cursor_msgs_per_s: cursor,
        ingest_msgs_per_s: ingest,
        ratio_ingest_vs_raw_reader: ingest / raw,
        cursor_vs_raw_reader: cursor / raw,
        accepted: outcome.accepted,
        dropped: outcome.dropped,
        snapshots: outcome.snapshots,
        snapshot_digest: outcome.digest,
    })
}

/// Removes the synthetic recording when the benchmark ends.
struct TempFile(PathBuf);

impl Drop for TempFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

fn write_fleet(path: &Path, vehicles: usize, seconds: u64) -> Result<u64, BenchError> {
    let file = std::fs::File::create(path).map_err(|e| BenchError::Input(format!("{}: {e}", path.display())))?;
    let mut recorder = Recorder::new(BufWriter::new(file)).map_err(BenchError::runtime)?;
    let config = FleetConfig { can: true, perception: true, ..FleetConfig::states_only(vehicles) };
    let mut fleet = SyntheticFleet::new(config, "bench");
    let mut written = 0u64;
    let mut failure = None;
    for tick in 0..seconds * 100 {
        fleet.tick(tick, |m| {
            let result = recorder
                .channel(m.key, risktwin_cloud::ingest::stream::proto_name(m.stream))
                .and_then(|channel| recorder.write(channel, m.receive_ns as u64, m.receive_ns as u64, m.payload));
            match result {
                Ok(()) => written += 1,
                Err(e) => failure = Some(e),
            }
        });
        if let Some(e) = failure.take() {
            return Err(BenchError::runtime(e));
        }
    }
    recorder.finish().map_err(BenchError::runtime)?;
    Ok(written)
}

fn time_raw(bytes: &[u8]) -> Result<f64, BenchError> {
    let start = Instant::now();
    let (mut n, mut total) = (0u64, 0usize);
    for m in mcap::MessageStream::new(bytes).map_err(BenchError::input)? {
        let m = m.map_err(BenchError::input)?;
        total += m.data.len();
        n += 1;
    }
    std::hint::black_box(total);
    Ok(n as f64 / start.elapsed().as_secs_f64())
}

fn time_cursor(bytes: &[u8]) -> Result<f64, BenchError> {
    let start = Instant::now();
    let (mut n, mut total) = (0u64, 0usize);
    let mut cursor = MessageCursor::new(bytes);
    while let Some(m) = cursor.next_message() {
        total += m.map_err(BenchError::input)?.data.len();
        n += 1;
    }
    std::hint::black_box(total);
    Ok(n as f64 / start.elapsed().as_secs_f64())
}

struct IngestOutcome {
    messages: u64,
    accepted: u64,
    dropped: u64,
    snapshots: u64,
    digest: String,
}

fn time_ingest(bytes: &[u8]) -> Result<(f64, IngestOutcome), BenchError> {
    let start = Instant::now();
    let mut worker: IngestWorker<Cursor<Vec<u8>>> = IngestWorker::new(IngestConfig::default(), None);
    let mut digest = SnapshotDigest::default();
    let counts =
        replay_into(&mut MessageCursor::new(bytes), &mut worker, |s| digest.add(s)).map_err(BenchError::input)?;
    let rate = (counts.fed + counts.skipped) as f64 / start.elapsed().as_secs_f64();
    let stats = worker.stats();
    let outcome = IngestOutcome {
        messages: counts.fed + counts.skipped,
        accepted: stats.accepted,
        dropped: stats.dropped_total(),
        snapshots: stats.snapshots,
        digest: digest.hex(),
    };
    Ok((rate, outcome))
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}
