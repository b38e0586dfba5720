//! The files of a rotating recording: the segment being written, when the next one is due, and
//! the catalogue and retention around them. The [`Recorder`](risktwin_protos::recording::Recorder)
//! does the writing; this opens its files and books them.
//!
//! A segment is catalogued when it is opened (unfinished; the keeper thread writes the row
//! within milliseconds of the file's creation) and updated when it is closed, so a killed
//! recorder leaves a row that says so. Rotation is looked at by the recorder's flush timer (not
//! per message): a segment closes at the first look after it reached its size or age, and only
//! once it holds a message (a quiet recorder makes no empty segments).

use super::catalogue::Catalogue;
use super::config::{RotationConfig, SegmentsSummary};
use super::error::{CatalogueError, SegmentError};
use super::keeper::{Booking, Closed, Keeper, Opened};
use risktwin_protos::recording::SegmentStats;
use risktwin_transport::wall_clock::unix_ns;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// The segment being written.
#[derive(Debug)]
struct OpenSegment {
    seq: u64,
    path: PathBuf,
    /// Another handle on its file: its size, without touching the writer.
    file: File,
    opened: Instant,
}

/// The segments of a rotating recording. The swap to a new file happens on the caller's thread
/// (under the ingest's lock); the slow rest of a rotation — flushing and syncing the closed file
/// to disk, the catalogue's rows, retention — on the [`Keeper`]'s, so a rotation holds the
/// ingest for a file creation and the MCAP summary only.
#[derive(Debug)]
pub struct Segments {
    dir: PathBuf,
    segment_bytes: u64,
    segment_age: Duration,
    open: OpenSegment,
    keeper: Keeper,
}

impl Segments {
    /// Opens (or creates) the catalogue of `config.dir`, adds this recording to it and opens its
    /// first segment: the segments and the file to record into.
    pub fn start(config: RotationConfig) -> Result<(Self, BufWriter<File>), SegmentError> {
        let catalogue = Catalogue::create(&config.dir)?;
        let recording_id = catalogue.add_recording(unix_ns(), &config.provenance)?;
        let seq = catalogue.next_seq()?;
        if catalogue.has_segment(seq)? {
            return Err(CatalogueError::already_catalogued(catalogue.path(), seq).into());
        }
        let (opened, file, writer) = create_segment(&config.dir, seq)?;
        catalogue.open_segment(recording_id, seq, &opened.file, opened.unix_ns)?;
        let open = OpenSegment { seq, path: config.dir.join(&opened.file), file, opened: Instant::now() };
        let segments = Segments {
            dir: config.dir.clone(),
            segment_bytes: config.segment_bytes,
            segment_age: config.segment_age,
            keeper: Keeper::start(config, catalogue, recording_id, opened)?,
            open,
        };
        Ok((segments, writer))
    }

    /// Whether the segment holding `segment_messages` messages is due to close.
    pub fn due(&self, segment_messages: u64) -> bool {
        segment_messages > 0
            && (self.open.opened.elapsed() >= self.segment_age
                || self.open.file.metadata().is_ok_and(|m| m.len() >= self.segment_bytes))
    }

    /// The keeper's error, once it failed (it books nothing after it).
    pub fn check(&mut self) -> Result<(), SegmentError> {
        self.keeper.check()
    }

    /// Opens the next segment and hands it to `swap`, which finishes the current one into it
    /// (`Recorder::rotate`); the keeper then books both and applies retention.
    pub fn rotate(
        &mut self,
        swap: impl FnOnce(BufWriter<File>) -> Result<(BufWriter<File>, SegmentStats), SegmentError>,
    ) -> Result<(), SegmentError> {
        self.keeper.check()?;
        let seq = self.open.seq + 1;
        let (opened, file, next) = create_segment(&self.dir, seq)?;
        let path = self.dir.join(&opened.file);
        let closing = std::mem::replace(&mut self.open, OpenSegment { seq, path, file, opened: Instant::now() });
        self.keeper.book(Booking::Opened(opened))?;
        let (written, stats) = swap(next)?;
        self.keeper.book(Booking::Closed(Closed { seq: closing.seq, path: closing.path, written, stats }))
    }

    /// What the recording did so far (the keeper's books).
    pub fn summary(&self) -> SegmentsSummary {
        self.keeper.summary()
    }

    /// Books the last segment, closed by the recorder into `written` with `stats`, waits for the
    /// keeper to finish its work: the summary.
    pub fn finish(mut self, written: BufWriter<File>, stats: SegmentStats) -> Result<SegmentsSummary, SegmentError> {
        let (seq, path) = (self.open.seq, self.open.path.clone());
        self.keeper.book(Booking::Closed(Closed { seq, path, written, stats }))?;
        self.keeper.finish()
    }
}

fn io(path: impl AsRef<Path>) -> impl Fn(std::io::Error) -> SegmentError {
    let path = path.as_ref().to_path_buf();
    move |source| SegmentError::Io { path: path.clone(), source }
}

/// Creates segment `seq`'s file in `dir`: what the catalogue is to say of it, a handle for its
/// size and the writer.
fn create_segment(dir: &Path, seq: u64) -> Result<(Opened, File, BufWriter<File>), SegmentError> {
    let now = SystemTime::now();
    let name = segment_name(seq, now);
    let path = dir.join(&name);
    // `create_new`: an existing file (another recorder's) is never truncated.
    let file = File::options().write(true).create_new(true).open(&path).map_err(io(&path))?;
    let size_handle = file.try_clone().map_err(io(&path))?;
    Ok((Opened { seq, file: name, unix_ns: unix_ns() }, size_handle, BufWriter::new(file)))
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
