//! Reading the messages of a recording, finished or not: [`MessageCursor`] streams them,
//! [`read_messages`] collects those of a finished file, [`salvage_messages`] those of any file.
//!
//! An unfinished file (a recorder killed: no footer, a chunk left open, trailing garbage) gives
//! every message of its complete chunks, and its [`UnfinishedRecording`] says what was lost; a
//! file whose damage starts before its first complete message is an error, as is one that is not
//! MCAP at all or that claims impossible lengths ([`super::scan`]).

use super::RecordingError;
use super::scan::{RecordScanner, Tail};
use mcap::records::{Record, op};
use std::collections::HashMap;
use std::io::Read;

/// One recorded message.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedMessage {
    pub topic: String,
    pub schema_name: String,
    pub log_time_ns: u64,
    pub publish_time_ns: u64,
    pub data: Vec<u8>,
}

/// What a read of an unfinished recording kept and what it could not read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UnfinishedRecording {
    /// Messages read before the unreadable tail.
    pub messages: u64,
    /// Log time of the last message read (the largest, should the file not be in time order).
    pub last_log_time_ns: u64,
    /// Where the unreadable tail starts and why.
    pub tail: Tail,
}

impl std::fmt::Display for UnfinishedRecording {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "unfinished recording, read {} messages up to log time {:.3} s; {} trailing bytes unreadable from byte {} ({})",
            self.messages,
            self.last_log_time_ns as f64 * 1e-9,
            self.tail.unreadable_bytes,
            self.tail.at_byte,
            self.tail.reason
        )
    }
}

/// All messages of a finished recording in file order; an unfinished, truncated or corrupt file
/// is an error (what tests of a cleanly closed recording want). Collects them: for large
/// recordings iterate with a [`MessageCursor`] instead.
pub fn read_messages(bytes: &[u8]) -> Result<Vec<RecordedMessage>, RecordingError> {
    let (messages, unfinished) = salvage_messages(bytes)?;
    match unfinished {
        Some(u) => Err(RecordingError::Unfinished(Box::new(u))),
        None => Ok(messages),
    }
}

/// Every readable message of a recording, finished or not, and what was lost of an unfinished
/// one.
pub fn salvage_messages(bytes: &[u8]) -> Result<(Vec<RecordedMessage>, Option<UnfinishedRecording>), RecordingError> {
    let mut out = Vec::new();
    let mut cursor = MessageCursor::new(bytes).with_source_len(bytes.len() as u64);
    while let Some(m) = cursor.next_message() {
        let m = m?;
        out.push(RecordedMessage {
            topic: m.topic.to_owned(),
            schema_name: m.schema_name.to_owned(),
            log_time_ns: m.log_time_ns,
            publish_time_ns: m.publish_time_ns,
            data: m.data.to_vec(),
        });
    }
    Ok((out, cursor.unfinished()))
}

/// One message lent by a [`MessageCursor`]: valid until the cursor moves on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MessageRef<'a> {
    pub topic: &'a str,
    pub schema_name: &'a str,
    pub channel_id: u16,
    pub log_time_ns: u64,
    pub publish_time_ns: u64,
    pub data: &'a [u8],
}

/// A channel as the cursor keeps it: what a message needs to be named.
#[derive(Debug)]
struct ChannelName {
    topic: String,
    schema_name: String,
}

/// Bytes of a message record before its data: channel id (2), sequence (4), log time (8),
/// publish time (8).
const MESSAGE_HEADER_LEN: usize = 22;

/// Streams the messages of an MCAP recording from any reader (a file, a memory map, a byte
/// slice) in file order, without collecting them and without an allocation per message: each
/// message is copied once, out of the decompressed chunk, and lent out.
///
/// It reads to the end magic; an unfinished file ends after its last complete chunk, and
/// [`MessageCursor::unfinished`] then says what was lost. The summary section (which repeats
/// the channels) is skipped.
pub struct MessageCursor<R: Read> {
    scanner: RecordScanner<R>,
    schemas: HashMap<u16, String>,
    channels: HashMap<u16, ChannelName>,
    messages: u64,
    last_log_time_ns: u64,
    done: bool,
    /// The message the cursor stopped at: channel id, log and publish time.
    at: Option<(u16, u64, u64)>,
}

impl<R: Read> MessageCursor<R> {
    /// A cursor at the start of `source`.
    pub fn new(source: R) -> Self {
        Self {
            scanner: RecordScanner::new(source),
            schemas: HashMap::new(),
            channels: HashMap::new(),
            messages: 0,
            last_log_time_ns: 0,
            done: false,
            at: None,
        }
    }

    /// Tells the cursor the file's length: a length field past it is then named against it.
    pub fn with_source_len(mut self, len: u64) -> Self {
        self.scanner = self.scanner.with_source_len(len);
        self
    }

    /// What was lost of an unfinished recording, once [`MessageCursor::next_message`] returned
    /// `None`; `None` for a finished one.
    pub fn unfinished(&self) -> Option<UnfinishedRecording> {
        self.scanner.tail().map(|tail| UnfinishedRecording {
            messages: self.messages,
            last_log_time_ns: self.last_log_time_ns,
            tail: tail.clone(),
        })
    }

    /// The next message, `None` at the end of the file or of its readable part; after an error,
    /// `None` for ever.
    #[allow(clippy::should_implement_trait)] // a lending iterator: `Iterator` cannot lend
    pub fn next_message(&mut self) -> Option<Result<MessageRef<'_>, RecordingError>> {
        match self.seek_where(|_| true)? {
            Ok(()) => self.message().map(Ok),
            Err(e) => Some(Err(e)),
        }
    }

    /// Moves to the next message that `keep` takes (each message read counts as read, kept or
    /// not), then lent by [`MessageCursor::message`]; `None` as for
    /// [`MessageCursor::next_message`]. Lets a filtering reader return the message it stops at.
    pub fn seek_where(&mut self, mut keep: impl FnMut(&MessageRef<'_>) -> bool) -> Option<Result<(), RecordingError>> {
        self.at = None;
        if self.done {
            return None;
        }
        loop {
            match self.advance() {
                Ok(Some(at)) => {
                    let Some(message) = lend(&self.channels, self.scanner.body(), at) else {
                        self.done = true;
                        return Some(Err(RecordingError::Corrupt {
                            reason: format!("a message on unknown channel {}", at.0),
                        }));
                    };
                    let kept = keep(&message);
                    self.messages += 1;
                    self.last_log_time_ns = self.last_log_time_ns.max(at.1);
                    if kept {
                        self.at = Some(at);
                        return Some(Ok(()));
                    }
                }
                Ok(None) => {
                    self.done = true;
                    // Damage before the first complete message leaves nothing to salvage.
                    return match self.scanner.tail() {
                        Some(tail) if self.messages == 0 => Some(Err(RecordingError::NothingReadable(tail.clone()))),
                        _ => None,
                    };
                }
                Err(e) => {
                    self.done = true;
                    return Some(Err(e));
                }
            }
        }
    }

    /// The message [`MessageCursor::seek_where`] stopped at; `None` when it found none.
    pub fn message(&self) -> Option<MessageRef<'_>> {
        lend(&self.channels, self.scanner.body(), self.at?)
    }

    /// Reads up to the next message record, leaving it as the scanner's body.
    fn advance(&mut self) -> Result<Option<(u16, u64, u64)>, RecordingError> {
        while let Some(opcode) = self.scanner.next_record()? {
            let data = self.scanner.body();
            match opcode {
                op::MESSAGE => {
                    let Some(head) = data.get(..MESSAGE_HEADER_LEN) else {
                        return Err(RecordingError::Corrupt {
                            reason: format!("a message record of {} bytes (at least {MESSAGE_HEADER_LEN})", data.len()),
                        });
                    };
                    let channel_id = u16::from_le_bytes([head[0], head[1]]);
                    let word = |at: usize| {
                        let mut w = [0u8; 8];
                        w.copy_from_slice(&head[at..at + 8]);
                        u64::from_le_bytes(w)
                    };
                    return Ok(Some((channel_id, word(6), word(14))));
                }
                op::SCHEMA | op::CHANNEL => match mcap::parse_record(opcode, data)? {
                    Record::Schema { header, .. } => {
                        self.schemas.insert(header.id, header.name);
                    }
                    Record::Channel(channel) => {
                        // Schema id 0 means "no schema".
                        let schema_name = match channel.schema_id {
                            0 => String::new(),
                            id => self.schemas.get(&id).cloned().ok_or_else(|| RecordingError::Corrupt {
                                reason: format!("channel {} names unknown schema {id}", channel.id),
                            })?,
                        };
                        self.channels.insert(channel.id, ChannelName { topic: channel.topic, schema_name });
                    }
                    _ => {}
                },
                _ => {}
            }
        }
        Ok(None)
    }
}

/// The message record `body` (read at `(channel id, log time, publish time)`) as lent out;
/// `None` for a channel never declared.
fn lend<'a>(
    channels: &'a HashMap<u16, ChannelName>,
    body: &'a [u8],
    (channel_id, log_time_ns, publish_time_ns): (u16, u64, u64),
) -> Option<MessageRef<'a>> {
    let channel = channels.get(&channel_id)?;
    Some(MessageRef {
        topic: &channel.topic,
        schema_name: &channel.schema_name,
        channel_id,
        log_time_ns,
        publish_time_ns,
        data: &body[MESSAGE_HEADER_LEN..],
    })
}
