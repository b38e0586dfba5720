//! A span of a recording kept in several files (the segments of a rotating recorder): their
//! messages in file order, those with a log time in `[from, to)` and on a topic the caller keeps,
//! streamed one file after the other; and [`export`], which writes them as one finished file.
//!
//! Channel ids are renumbered by topic and schema across the files (each file numbers its own):
//! a reader that keys on [`MessageRef::channel_id`] sees one id per topic for the whole span.
//! An unfinished file (a recorder killed) gives its complete chunks and is reported
//! ([`SpanCursor::unfinished`]), as the single-file readers do.

use super::read::{MessageCursor, MessageRef, UnfinishedRecording};
use super::{Recorder, RecordingError};
use std::collections::HashMap;
use std::fs::File;
use std::io::{BufReader, Seek, Write};
use std::ops::Range;
use std::path::PathBuf;

/// Read size of each file.
const READ_BUFFER_BYTES: usize = 1 << 20;

/// Which topics a span keeps (e.g. one source's edge streams).
pub type TopicFilter = Box<dyn FnMut(&str) -> bool + Send>;

/// Streams the messages of a span of files in order; see the module.
pub struct SpanCursor {
    paths: std::vec::IntoIter<PathBuf>,
    current: Option<(PathBuf, MessageCursor<BufReader<File>>)>,
    log_time_ns: Range<u64>,
    keep_topic: TopicFilter,
    /// Span-wide channel id (from 1) by topic and schema.
    ids: HashMap<(String, String), u16>,
    /// The current file's channel ids mapped to span-wide ones (0: not seen yet).
    local: Vec<u16>,
    /// Whether each span-wide channel (by id − 1) is kept.
    kept: Vec<bool>,
    unfinished: Vec<(PathBuf, UnfinishedRecording)>,
}

impl SpanCursor {
    /// The messages of `paths`, in that order, whose log time lies in `log_time_ns` and whose
    /// topic `keep_topic` takes.
    pub fn new(paths: Vec<PathBuf>, log_time_ns: Range<u64>, keep_topic: TopicFilter) -> Self {
        Self {
            paths: paths.into_iter(),
            current: None,
            log_time_ns,
            keep_topic,
            ids: HashMap::new(),
            local: Vec::new(),
            kept: Vec::new(),
            unfinished: Vec::new(),
        }
    }

    /// Every message of `paths`.
    pub fn all(paths: Vec<PathBuf>) -> Self {
        Self::new(paths, 0..u64::MAX, Box::new(|_| true))
    }

    /// The files read so far that were unfinished, and what each lost.
    pub fn unfinished(&self) -> &[(PathBuf, UnfinishedRecording)] {
        &self.unfinished
    }

    /// The next message of the span, its channel id the span-wide one; `None` after the last
    /// file. An error names the file; after one the cursor goes on with the next file.
    #[allow(clippy::should_implement_trait)] // a lending iterator: `Iterator` cannot lend
    pub fn next_message(&mut self) -> Option<Result<MessageRef<'_>, RecordingError>> {
        loop {
            let (path, cursor) = match self.current.as_mut() {
                Some(open) => open,
                None => {
                    let path = self.paths.next()?;
                    match open(&path) {
                        Ok(cursor) => {
                            self.local.clear();
                            self.current.insert((path, cursor))
                        }
                        Err(e) => return Some(Err(in_file(&path, e))),
                    }
                }
            };
            let (span, local, ids, kept, keep_topic) =
                (&self.log_time_ns, &mut self.local, &mut self.ids, &mut self.kept, &mut self.keep_topic);
            let found = cursor.seek_where(|m| {
                if !span.contains(&m.log_time_ns) {
                    return false;
                }
                let id = span_id(local, ids, kept, keep_topic, m);
                kept[usize::from(id) - 1]
            });
            match found {
                Some(Ok(())) => break,
                // A file with no complete message (a segment killed before its first chunk
                // closed) is an unfinished file with nothing in it, not the end of the span.
                Some(Err(RecordingError::NothingReadable(tail))) => {
                    let lost = UnfinishedRecording { messages: 0, last_log_time_ns: 0, tail };
                    self.unfinished.push((path.clone(), lost));
                    self.current = None;
                }
                Some(Err(e)) => {
                    let e = in_file(path, e);
                    self.current = None;
                    return Some(Err(e));
                }
                None => {
                    if let Some(lost) = cursor.unfinished() {
                        self.unfinished.push((path.clone(), lost));
                    }
                    self.current = None;
                }
            }
        }
        let (_, cursor) = self.current.as_ref()?;
        let m = cursor.message()?;
        let channel_id = self.local[usize::from(m.channel_id)];
        Some(Ok(MessageRef { channel_id, ..m }))
    }
}

/// `m`'s span-wide channel id, made (and its topic judged) on its file's first message on it.
fn span_id(
    local: &mut Vec<u16>,
    ids: &mut HashMap<(String, String), u16>,
    kept: &mut Vec<bool>,
    keep_topic: &mut TopicFilter,
    m: &MessageRef<'_>,
) -> u16 {
    let slot = usize::from(m.channel_id);
    if let Some(&id) = local.get(slot).filter(|id| **id != 0) {
        return id;
    }
    let key = (m.topic.to_owned(), m.schema_name.to_owned());
    let id = match ids.get(&key) {
        Some(&id) => id,
        None => {
            // More than 65535 topics in one span: the last ids are shared (never in practice).
            let id = u16::try_from(ids.len() + 1).unwrap_or(u16::MAX);
            ids.insert(key, id);
            kept.push(keep_topic(m.topic));
            id
        }
    };
    if local.len() <= slot {
        local.resize(slot + 1, 0);
    }
    local[slot] = id;
    id
}

fn open(path: &PathBuf) -> Result<MessageCursor<BufReader<File>>, RecordingError> {
    let file = File::open(path)?;
    let len = file.metadata()?.len();
    Ok(MessageCursor::new(BufReader::with_capacity(READ_BUFFER_BYTES, file)).with_source_len(len))
}

/// `e` with the file it came from.
fn in_file(path: &std::path::Path, e: RecordingError) -> RecordingError {
    RecordingError::Corrupt { reason: format!("{}: {e}", path.display()) }
}

/// What [`export`] wrote.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Exported {
    pub messages: u64,
    /// Least and greatest log time written, ns.
    pub log_time_ns: Option<(u64, u64)>,
}

/// Writes every message of `span` to `out` as one finished recording (offline [`Recorder`]:
/// the bytes follow the messages), each with its topic, schema name, log and publish time and
/// data; the schemas are this build's ([`crate::FILE_DESCRIPTOR_SET`]), as a recording of it
/// has them. Stops at the first error.
pub fn export<W: Write + Seek>(span: &mut SpanCursor, out: W) -> Result<(W, Exported), RecordingError> {
    let mut recorder = Recorder::new(out)?;
    let mut exported = Exported::default();
    while let Some(m) = span.next_message() {
        let m = m?;
        let channel = recorder.channel(m.topic, m.schema_name)?;
        recorder.write(channel, m.log_time_ns, m.publish_time_ns, m.data)?;
        exported.messages += 1;
        let (first, last) = exported.log_time_ns.get_or_insert((m.log_time_ns, m.log_time_ns));
        (*first, *last) = ((*first).min(m.log_time_ns), (*last).max(m.log_time_ns));
    }
    Ok((recorder.finish_into_inner()?, exported))
}
