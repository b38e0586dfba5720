//! The files of a rotating recording: the segment being written, when the next one is due, and
//! the catalogue and retention around them. The [`Recorder`](risktwin_protos::recording::Recorder)
//! does the writing; this opens its files and books them.
//!
//! A segment is catalogued when it is opened (unfinished) and updated when it is closed, so a
//! killed recorder leaves a row that says so. Rotation is looked at by the recorder's flush
//! timer (not per message): a segment closes at the first look after it reached its size or
//! age, and only once it holds a message (a quiet recorder makes no empty segments).

use super::catalogue::{Catalogue, Provenance};
use super::error::{CatalogueError, SegmentError};
use risktwin_protos::recording::SegmentStats;
use serde::Serialize;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// How a rotating recording is kept.
#[derive(Debug, Clone, PartialEq)]
pub struct RotationConfig {
    pub dir: PathBuf,
    /// A segment closes once its file reaches this size...
    pub segment_bytes: u64,
    /// ...or this age.
    pub segment_age: Duration,
    /// Closed segments closed longer ago than this are deleted.
    pub retain_age: Option<Duration>,
    /// The oldest closed segments are deleted while the folder's segments hold more than this.
    pub retain_bytes: Option<u64>,
    pub provenance: Provenance,
}

/// What a rotating recording did, as the cloud's summary reports it.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct SegmentsSummary {
    pub dir: String,
    pub recording_id: i64,
    pub segments_opened: u64,
    pub segments_closed: u64,
    /// Segments deleted by retention (of this recording or older ones in the folder).
    pub segments_deleted: u64,
    /// Messages in the segments this recording closed.
    pub messages: u64,
    /// Bytes of the segments this recording closed.
    pub bytes_written: u64,
    pub bytes_deleted: u64,
}

/// The segment being written.
#[derive(Debug)]
struct OpenSegment {
    seq: u64,
    path: PathBuf,
    /// Another handle on its file: its size, without touching the writer.
    file: File,
    opened: Instant,
}

/// The segments of a rotating recording.
#[derive(Debug)]
pub struct Segments {
    config: RotationConfig,
    catalogue: Catalogue,
    open: OpenSegment,
    summary: SegmentsSummary,
}

/// Nanoseconds since the Unix epoch, now.
fn unix_ns() -> i64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.as_nanos() as i64)
}

impl Segments {
    /// Opens (or creates) the catalogue of `config.dir`, adds this recording to it and opens its
    /// first segment: the segments and the file to record into.
    pub fn start(config: RotationConfig) -> Result<(Self, BufWriter<File>), SegmentError> {
        let catalogue = Catalogue::create(&config.dir)?;
        let recording_id = catalogue.add_recording(unix_ns(), &config.provenance)?;
        let (open, file) = open_segment(&catalogue, &config.dir, recording_id, catalogue.next_seq()?)?;
        let summary = SegmentsSummary {
            dir: config.dir.display().to_string(),
            recording_id,
            segments_opened: 1,
            ..SegmentsSummary::default()
        };
        Ok((Self { config, catalogue, open, summary }, file))
    }

    /// Whether the segment holding `segment_messages` messages is due to close.
    pub fn due(&self, segment_messages: u64) -> bool {
        segment_messages > 0
            && (self.open.opened.elapsed() >= self.config.segment_age
                || self.open.file.metadata().is_ok_and(|m| m.len() >= self.config.segment_bytes))
    }

    /// Opens the next segment and hands it to `swap`, which finishes the current one into it
    /// (`Recorder::rotate`); then books the closed one and applies retention.
    pub fn rotate(
        &mut self,
        swap: impl FnOnce(BufWriter<File>) -> Result<(BufWriter<File>, SegmentStats), SegmentError>,
    ) -> Result<(), SegmentError> {
        let next_seq = self.open.seq + 1;
        let (next, file) = open_segment(&self.catalogue, &self.config.dir, self.summary.recording_id, next_seq)?;
        self.summary.segments_opened += 1;
        let closing = std::mem::replace(&mut self.open, next);
        let (written, stats) = swap(file)?;
        self.close(closing.seq, &closing.path, written, &stats)
    }

    /// What the recording did so far.
    pub fn summary(&self) -> &SegmentsSummary {
        &self.summary
    }

    /// Books the last segment, closed by the recorder into `written` with `stats`: the summary.
    pub fn finish(mut self, written: BufWriter<File>, stats: &SegmentStats) -> Result<SegmentsSummary, SegmentError> {
        // The last segment stays the "open" one: retention keeps it.
        let (seq, path) = (self.open.seq, self.open.path.clone());
        self.close(seq, &path, written, stats)?;
        Ok(self.summary)
    }

    /// Flushes segment `seq`'s file to disk, books it closed and applies retention.
    fn close(
        &mut self,
        seq: u64,
        path: &Path,
        written: BufWriter<File>,
        stats: &SegmentStats,
    ) -> Result<(), SegmentError> {
        let file =
            written.into_inner().map_err(|e| SegmentError::Io { path: path.to_path_buf(), source: e.into_error() })?;
        file.sync_data().map_err(io(path))?;
        let bytes = file.metadata().map_err(io(path))?.len();
        self.catalogue.close_segment(seq, stats, bytes, unix_ns())?;
        self.summary.segments_closed += 1;
        self.summary.messages += stats.messages;
        self.summary.bytes_written += bytes;
        self.retain()
    }

    /// Deletes the oldest closed segments beyond the age and size bounds (never the open one).
    fn retain(&mut self) -> Result<(), SegmentError> {
        if self.config.retain_age.is_none() && self.config.retain_bytes.is_none() {
            return Ok(());
        }
        let segments = self.catalogue.all_segments()?;
        let open_bytes = self.open.file.metadata().map_or(0, |m| m.len());
        let mut total: u64 = segments.iter().filter_map(|s| s.bytes).sum::<u64>() + open_bytes;
        let oldest_kept = self.config.retain_age.map(|age| unix_ns().saturating_sub(age.as_nanos() as i64));
        for segment in segments.iter().filter(|s| s.closed && s.seq != self.open.seq) {
            let too_old = oldest_kept.is_some_and(|t| segment.closed_unix_ns.is_some_and(|c| c < t));
            let too_much = self.config.retain_bytes.is_some_and(|max| total > max);
            if !(too_old || too_much) {
                continue;
            }
            let path = self.config.dir.join(&segment.file);
            match std::fs::remove_file(&path) {
                Ok(()) => {}
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                Err(e) => return Err(SegmentError::Io { path, source: e }),
            }
            self.catalogue.delete_segment(segment.seq)?;
            let bytes = segment.bytes.unwrap_or(0);
            total = total.saturating_sub(bytes);
            self.summary.segments_deleted += 1;
            self.summary.bytes_deleted += bytes;
            tracing::info!("recordings: retention deleted {} ({bytes} bytes)", segment.file);
        }
        Ok(())
    }
}

fn io(path: impl AsRef<Path>) -> impl Fn(std::io::Error) -> SegmentError {
    let path = path.as_ref().to_path_buf();
    move |source| SegmentError::Io { path: path.clone(), source }
}

/// Creates segment `seq`'s file in `dir` and catalogues it (unfinished).
fn open_segment(
    catalogue: &Catalogue,
    dir: &Path,
    recording_id: i64,
    seq: u64,
) -> Result<(OpenSegment, BufWriter<File>), SegmentError> {
    if catalogue.has_segment(seq)? {
        let reason = format!("segment {seq} is already catalogued (another recorder in this folder?)");
        return Err(CatalogueError::BadRow { path: catalogue.path().to_path_buf(), seq: seq as i64, reason }.into());
    }
    let now = SystemTime::now();
    let name = segment_name(seq, now);
    let path = dir.join(&name);
    // `create_new`: an existing file (another recorder's) is never truncated.
    let file = File::options().write(true).create_new(true).open(&path).map_err(io(&path))?;
    let size_handle = file.try_clone().map_err(io(&path))?;
    catalogue.open_segment(recording_id, seq, &name, unix_ns())?;
    let open = OpenSegment { seq, path, file: size_handle, opened: Instant::now() };
    Ok((open, BufWriter::new(file)))
}

/// `seg-000042-20260501T120000Z.mcap`: sorted by name, sorted by number and by time (UTC).
pub fn segment_name(seq: u64, at: SystemTime) -> String {
    format!("seg-{seq:06}-{}.mcap", utc_stamp(at))
}

/// `20260501T120000Z`: the UTC second of `at`, sortable as text (clamped to 1970–9999, the
/// years RFC 3339 spells with four digits).
pub fn utc_stamp(at: SystemTime) -> String {
    const LAST_SECOND_OF_9999: u64 = 253_402_300_799;
    let at = at.clamp(UNIX_EPOCH, UNIX_EPOCH + Duration::from_secs(LAST_SECOND_OF_9999));
    let rfc3339 = humantime::format_rfc3339_seconds(at).to_string();
    rfc3339.chars().filter(char::is_ascii_alphanumeric).collect()
}
