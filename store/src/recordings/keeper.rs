//! The keeper of a rotating recording: a thread that books what the recorder did — a segment
//! opened, a segment finished — in the catalogue, flushes and syncs each finished file to disk
//! and applies retention. These take milliseconds to seconds (an `fsync` of a 256 MiB segment);
//! on the keeper's thread they never hold up the ingest, which only creates files and swaps
//! the recorder into them.
//!
//! The bookings arrive in order over a channel. The first failure ends the keeper: later
//! bookings are refused, and the recorder learns of it at its next rotation or flush tick
//! ([`Keeper::check`]) or at the end.

use super::catalogue::Catalogue;
use super::config::{RotationConfig, SegmentsSummary};
use super::error::SegmentError;
use risktwin_protos::recording::SegmentStats;
use risktwin_transport::sync::LockExt;
use risktwin_transport::wall_clock::unix_ns;
use std::fs::File;
use std::io::BufWriter;
use std::path::PathBuf;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

/// A segment's file was created.
#[derive(Debug)]
pub(super) struct Opened {
    pub seq: u64,
    /// Its name in the folder.
    pub file: String,
    pub unix_ns: i64,
}

/// A segment was finished (summary and footer written) into `written`, not yet flushed.
#[derive(Debug)]
pub(super) struct Closed {
    pub seq: u64,
    pub path: PathBuf,
    pub written: BufWriter<File>,
    pub stats: SegmentStats,
}

#[derive(Debug)]
pub(super) enum Booking {
    Opened(Opened),
    Closed(Closed),
}

/// The keeper thread and the way to it.
#[derive(Debug)]
pub(super) struct Keeper {
    /// `None` once finishing.
    to: Option<Sender<Booking>>,
    /// `None` once joined.
    thread: Option<JoinHandle<Result<SegmentsSummary, SegmentError>>>,
    /// The books so far (for live metrics).
    summary: Arc<Mutex<SegmentsSummary>>,
}

impl Keeper {
    /// Starts keeping `config.dir`'s recording `recording_id`, whose first segment, `first`, the
    /// catalogue already holds.
    pub fn start(
        config: RotationConfig,
        catalogue: Catalogue,
        recording_id: i64,
        first: Opened,
    ) -> Result<Self, SegmentError> {
        let (to, from) = channel();
        let summary = Arc::new(Mutex::new(SegmentsSummary {
            dir: config.dir.display().to_string(),
            recording_id,
            segments_opened: 1,
            ..SegmentsSummary::default()
        }));
        let books = Books {
            summary: Arc::clone(&summary),
            recording_id,
            open: (first.seq, config.dir.join(&first.file)),
            config,
            catalogue,
        };
        let thread = std::thread::Builder::new()
            .name("segment-keeper".into())
            .spawn(move || books.keep(&from))
            .map_err(|source| SegmentError::Io { path: PathBuf::from("(segment keeper thread)"), source })?;
        Ok(Keeper { to: Some(to), thread: Some(thread), summary })
    }

    /// What is booked so far.
    pub fn summary(&self) -> SegmentsSummary {
        self.summary.locked().clone()
    }

    /// Hands `booking` to the keeper: its error instead when it has failed.
    pub fn book(&mut self, booking: Booking) -> Result<(), SegmentError> {
        self.check()?;
        let sent = self.to.as_ref().is_some_and(|to| to.send(booking).is_ok());
        if sent { Ok(()) } else { self.failure() }
    }

    /// The keeper's error once it has stopped on one.
    pub fn check(&mut self) -> Result<(), SegmentError> {
        if self.thread.as_ref().is_some_and(JoinHandle::is_finished) { self.failure() } else { Ok(()) }
    }

    /// Waits until everything booked is done: the summary, or the first failure.
    pub fn finish(mut self) -> Result<SegmentsSummary, SegmentError> {
        self.to = None;
        self.join()
    }

    /// The error of a keeper that stopped early.
    fn failure(&mut self) -> Result<(), SegmentError> {
        self.join()?;
        Err(SegmentError::KeeperGone)
    }

    fn join(&mut self) -> Result<SegmentsSummary, SegmentError> {
        let Some(thread) = self.thread.take() else { return Err(SegmentError::KeeperGone) };
        thread.join().unwrap_or_else(|_| Err(SegmentError::KeeperGone))
    }
}

/// What the keeper thread owns.
struct Books {
    config: RotationConfig,
    catalogue: Catalogue,
    /// The segment being written (its number and path): retention never deletes it.
    open: (u64, PathBuf),
    recording_id: i64,
    /// Shared with the [`Keeper`], which reads it for live metrics.
    summary: Arc<Mutex<SegmentsSummary>>,
}

impl Books {
    /// Books what arrives until the recorder is done with it (the channel closes) or a booking
    /// fails.
    fn keep(mut self, bookings: &Receiver<Booking>) -> Result<SegmentsSummary, SegmentError> {
        for booking in bookings {
            match booking {
                Booking::Opened(opened) => self.open(opened)?,
                Booking::Closed(closed) => self.close(closed)?,
            }
        }
        Ok(self.books().clone())
    }

    fn books(&self) -> std::sync::MutexGuard<'_, SegmentsSummary> {
        self.summary.locked()
    }

    fn open(&mut self, opened: Opened) -> Result<(), SegmentError> {
        if self.catalogue.has_segment(opened.seq)? {
            return Err(super::error::CatalogueError::already_catalogued(self.catalogue.path(), opened.seq).into());
        }
        self.catalogue.open_segment(self.recording_id, opened.seq, &opened.file, opened.unix_ns)?;
        self.open = (opened.seq, self.config.dir.join(&opened.file));
        self.books().segments_opened += 1;
        Ok(())
    }

    /// Flushes a finished segment's file to disk, books it closed and applies retention.
    fn close(&mut self, Closed { seq, path, written, stats }: Closed) -> Result<(), SegmentError> {
        let io = |source| SegmentError::Io { path: path.clone(), source };
        let file = written.into_inner().map_err(|e| io(e.into_error()))?;
        file.sync_data().map_err(io)?;
        let bytes = file.metadata().map_err(io)?.len();
        self.catalogue.close_segment(seq, &stats, bytes, unix_ns())?;
        let mut books = self.books();
        books.segments_closed += 1;
        books.messages += stats.messages;
        books.bytes_written += bytes;
        drop(books);
        self.retain()
    }

    /// Deletes the oldest closed segments beyond the age and size bounds (never the open one).
    fn retain(&mut self) -> Result<(), SegmentError> {
        if self.config.retain_age.is_none() && self.config.retain_bytes.is_none() {
            return Ok(());
        }
        let segments = self.catalogue.all_segments()?;
        let open_bytes = std::fs::metadata(&self.open.1).map_or(0, |m| m.len());
        let mut total: u64 = segments.iter().filter_map(|s| s.bytes).sum::<u64>() + open_bytes;
        let oldest_kept = self.config.retain_age.map(|age| unix_ns().saturating_sub(age.as_nanos() as i64));
        for segment in segments.iter().filter(|s| s.closed && s.seq != self.open.0) {
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
            let mut books = self.books();
            books.segments_deleted += 1;
            books.bytes_deleted += bytes;
            tracing::info!("recordings: retention deleted {} ({bytes} bytes)", segment.file);
        }
        Ok(())
    }
}
