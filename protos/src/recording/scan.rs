//! The records of an MCAP file, read so that a damaged or unfinished file cannot make the reader
//! allocate what its length fields claim, and so that an unfinished tail ends the read quietly.
//!
//! The file's top-level records are framed here, not by `mcap`'s `LinearReader`: a record's
//! byte offset is known (errors name it), its length is checked before anything is read, and a
//! record's bytes are read as they arrive, so a record never takes more memory than the file
//! holds. Only a complete chunk goes to a `LinearReader` (which decompresses it and checks its
//! CRC before yielding a record; a chunk whose CRC is 0, "not computed", is read through once
//! before its first record is yielded), so a chunk is read whole or not at all. The one length taken
//! on trust is a complete chunk's decompressed size, which the `LinearReader` allocates (zeroed)
//! before it decompresses: [`CHUNK_UNCOMPRESSED_CAP`] bounds it, so a small damaged file can
//! cost that much memory, no more.
//!
//! What counts as an unfinished tail ([`Tail`]) and what as damage (an error): a file that ends
//! inside a record or between records without its footer, the chunk that the `mcap` writer
//! leaves open with a placeholder length of `u64::MAX` (a recorder killed mid-chunk), and bytes
//! that do not start with an MCAP opcode (garbage after the last record) are a tail; a length
//! above [`RECORD_LENGTH_CAP`] (a chunk's decompressed size above [`CHUNK_UNCOMPRESSED_CAP`]), a
//! complete chunk that does not decompress or fails its CRC, and
//! a file without the MCAP magic are errors.

use super::RecordingError;
use mcap::records::op;
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};
use std::io::Read;

/// The largest record a reader takes: 256 MiB. A writer's chunks are about 1 MiB (ours: see
/// `CHUNK_BYTES`), so only a damaged length or an outsized attachment claims more; the cap
/// bounds the memory one record can take (it is held whole, but only as far as the file backs
/// it: its bytes are read as they arrive).
pub const RECORD_LENGTH_CAP: u64 = 256 << 20;

/// The largest decompressed size a chunk may claim: 64 MiB. Ours close at 1 MiB, other writers'
/// defaults are a few MiB (a chunk may outgrow its bound by its last message), so this leaves
/// room for large messages; unlike a record's length it is allocated up front when the chunk
/// is decompressed, so it is the memory a 100-byte damaged file can cost.
pub const CHUNK_UNCOMPRESSED_CAP: u64 = 64 << 20;

/// Bytes of a record before its body: opcode (1) and length (8).
pub(super) const RECORD_HEAD_LEN: usize = 9;
/// Read size while a record's body comes in: memory grows with the bytes that exist.
const READ_STEP: u64 = 1 << 20;
/// Offset of a chunk's uncompressed size in its body: after start and end time.
const CHUNK_UNCOMPRESSED_SIZE_AT: usize = 16;
/// Where a chunk's CRC of its uncompressed records lies in its body (after the size).
const CHUNK_CRC_AT: usize = 24;

/// Why a read ended before the file's footer and end magic.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Tail {
    /// Byte offset where the unreadable part begins.
    pub at_byte: u64,
    /// Bytes from `at_byte` to the end of the file.
    pub unreadable_bytes: u64,
    /// What was found there.
    pub reason: String,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Section {
    Start,
    Data,
    /// After the data end record: the summary repeats what the data section held.
    Summary,
    Done,
}

/// A complete chunk being read out by a `LinearReader`.
struct OpenChunk {
    reader: LinearReader,
    at_byte: u64,
    /// Bytes of the chunk record handed to the reader so far.
    fed: usize,
}

/// Yields the data-section records of an MCAP file (those inside chunks included) one at a time.
pub struct RecordScanner<R: Read> {
    source: R,
    /// The file's length, when known: an error then says how long the file is.
    source_len: Option<u64>,
    /// Offset of the next top-level record.
    offset: u64,
    /// Offset of the top-level record read last (the chunk being read out, if one is).
    record_at: u64,
    section: Section,
    /// The current top-level record, head included.
    record: Vec<u8>,
    chunk: Option<OpenChunk>,
    /// The body of the record last yielded.
    yielded: Vec<u8>,
    tail: Option<Tail>,
}

impl<R: Read> RecordScanner<R> {
    /// A scanner at the start of `source`.
    pub fn new(source: R) -> Self {
        Self {
            source,
            source_len: None,
            offset: 0,
            record_at: 0,
            section: Section::Start,
            record: Vec::new(),
            chunk: None,
            yielded: Vec::new(),
            tail: None,
        }
    }

    /// Tells the scanner the file's length (errors then name it).
    pub fn with_source_len(mut self, len: u64) -> Self {
        self.source_len = Some(len);
        self
    }

    /// Where the top-level record read last starts: after an error, where the damage is.
    pub fn record_at(&self) -> u64 {
        self.record_at
    }

    /// The file's length, when told.
    pub fn source_len(&self) -> Option<u64> {
        self.source_len
    }

    /// The body of the record last yielded by [`RecordScanner::next_record`].
    pub fn body(&self) -> &[u8] {
        &self.yielded
    }

    /// Why the read ended early, once [`RecordScanner::next_record`] returned `Ok(None)`; `None`
    /// for a file read to its end magic.
    pub fn tail(&self) -> Option<&Tail> {
        self.tail.as_ref()
    }

    /// The opcode of the next data-section record (its body: [`RecordScanner::body`]); `None`
    /// at the end of the file or of its readable part. After an error, `None` for ever.
    pub fn next_record(&mut self) -> Result<Option<u8>, RecordingError> {
        let result = self.advance();
        if !matches!(result, Ok(Some(_))) {
            self.section = Section::Done;
            self.chunk = None;
        }
        result
    }

    fn advance(&mut self) -> Result<Option<u8>, RecordingError> {
        loop {
            if let Some(opcode) = self.next_in_chunk()? {
                return Ok(Some(opcode));
            }
            match self.section {
                Section::Done => return Ok(None),
                Section::Start => {
                    let mut magic = [0u8; 8];
                    let n = read_some(&mut self.source, &mut magic)?;
                    if magic[..n] != mcap::MAGIC[..n] || n == 0 {
                        return Err(RecordingError::NotMcap);
                    }
                    if n < magic.len() {
                        return self.end_early(0, &magic[..n], "the file ends inside the MCAP magic");
                    }
                    self.offset = magic.len() as u64;
                    self.section = Section::Data;
                }
                Section::Data | Section::Summary => {
                    if let Some(opcode) = self.top_level_record()?
                        && self.section == Section::Data
                    {
                        return Ok(Some(opcode));
                    }
                }
            }
        }
    }

    /// Reads the next top-level record into `self.record`; yields it when it is a record
    /// outside a chunk, opens it when it is a chunk, ends the section at the footer.
    fn top_level_record(&mut self) -> Result<Option<u8>, RecordingError> {
        let at = self.offset;
        self.record_at = at;
        let mut head = [0u8; RECORD_HEAD_LEN];
        let n = read_some(&mut self.source, &mut head)?;
        if n < RECORD_HEAD_LEN {
            let reason = if n == 0 { "no footer" } else { "the file ends inside a record's opcode and length" };
            return self.end_early(at, &head[..n], reason).map(|_| None);
        }
        let opcode = head[0];
        let len = u64::from_le_bytes([head[1], head[2], head[3], head[4], head[5], head[6], head[7], head[8]]);
        // Opcode 0 and 0x10..0x7f are reserved: nothing writes them, so this is not a record.
        if opcode == 0 || (0x10..0x80).contains(&opcode) {
            let reason = format!("bytes that are no MCAP record (opcode {opcode:#04x})");
            return self.end_early(at, &head[..n], &reason).map(|_| None);
        }
        // The `mcap` writer's placeholder for a chunk it has not finished: the recorder stopped
        // inside this chunk.
        if opcode == op::CHUNK && len == u64::MAX {
            return self.end_early(at, &head[..n], "a chunk the writer never finished").map(|_| None);
        }
        let body_end = at.saturating_add(RECORD_HEAD_LEN as u64).saturating_add(len);
        if len > RECORD_LENGTH_CAP {
            return Err(RecordingError::RecordTooLong { at_byte: at, claimed: len, file_len: self.source_len });
        }
        if self.source_len.is_some_and(|file_len| body_end > file_len) {
            let reason = format!("the file ends inside a record of {len} bytes");
            return self.end_early(at, &head[..n], &reason).map(|_| None);
        }
        self.record.clear();
        self.record.extend_from_slice(&head);
        let got = read_up_to(&mut self.source, &mut self.record, len)?;
        if got < len {
            let reason = format!("the file ends inside a record of {len} bytes");
            let read = std::mem::take(&mut self.record);
            return self.end_early(at, &read, &reason).map(|_| None);
        }
        self.offset = body_end;
        match opcode {
            op::CHUNK if self.section == Section::Data => {
                self.open_chunk(at)?;
                Ok(None)
            }
            op::DATA_END => {
                self.section = Section::Summary;
                Ok(None)
            }
            op::FOOTER => {
                let mut magic = [0u8; 8];
                let n = read_some(&mut self.source, &mut magic)?;
                if n < magic.len() || magic != mcap::MAGIC {
                    return self.end_early(self.offset, &magic[..n], "no end magic after the footer").map(|_| None);
                }
                self.section = Section::Done;
                Ok(None)
            }
            _ => {
                self.yielded.clear();
                self.yielded.extend_from_slice(&self.record[RECORD_HEAD_LEN..]);
                Ok(Some(opcode))
            }
        }
    }

    /// Hands the complete chunk in `self.record` to a reader, once its claimed decompressed size
    /// is checked (the reader would allocate it).
    fn open_chunk(&mut self, at_byte: u64) -> Result<(), RecordingError> {
        let body = &self.record[RECORD_HEAD_LEN..];
        let uncompressed = body
            .get(CHUNK_UNCOMPRESSED_SIZE_AT..CHUNK_UNCOMPRESSED_SIZE_AT + 8)
            .and_then(|b| b.try_into().ok())
            .map(u64::from_le_bytes)
            .ok_or_else(|| RecordingError::Corrupt { reason: format!("chunk at byte {at_byte}: a short header") })?;
        if uncompressed > CHUNK_UNCOMPRESSED_CAP {
            return Err(RecordingError::ChunkTooLarge { at_byte, uncompressed });
        }
        // No record inside is longer than the chunk holds, decompressed or not.
        let limit = uncompressed.max(body.len() as u64).min(RECORD_LENGTH_CAP) as usize;
        let options = LinearReaderOptions::default()
            .with_skip_start_magic(true)
            .with_skip_end_magic(true)
            .with_prevalidate_chunk_crcs(true)
            .with_record_length_limit(limit);
        let crc = body.get(CHUNK_CRC_AT..CHUNK_CRC_AT + 4);
        if crc == Some(&[0; 4]) {
            // No CRC to check before the first record is yielded (0: "not computed"): read the
            // chunk through once first, so that one that does not parse yields nothing.
            let mut dry = OpenChunk { reader: LinearReader::new_with_options(options.clone()), at_byte, fed: 0 };
            while next_record_of(&mut dry, &self.record, &mut self.yielded)?.is_some() {}
        }
        self.chunk = Some(OpenChunk { reader: LinearReader::new_with_options(options), at_byte, fed: 0 });
        Ok(())
    }

    /// The next record of the open chunk, if any; closes the chunk at its end.
    fn next_in_chunk(&mut self) -> Result<Option<u8>, RecordingError> {
        let Some(chunk) = self.chunk.as_mut() else { return Ok(None) };
        match next_record_of(chunk, &self.record, &mut self.yielded)? {
            Some(opcode) => Ok(Some(opcode)),
            None => {
                self.chunk = None;
                Ok(None)
            }
        }
    }

    /// Ends the read at `at`, where `read` holds the bytes of the unreadable part read already:
    /// quietly, as an unfinished tail, unless the file ends with the MCAP magic. Only a writer
    /// that finished writes that (after the footer), so bytes it cannot read in such a file are
    /// damage, an error, not a recorder that stopped.
    fn end_early(&mut self, at: u64, read: &[u8], reason: &str) -> Result<Option<u8>, RecordingError> {
        let mut last = EndWindow::default();
        last.push(read);
        let rest = copy_rest(&mut self.source, &mut last)?;
        if last.is_magic() && read.len() as u64 + rest > mcap::MAGIC.len() as u64 {
            return Err(RecordingError::Corrupt {
                reason: format!("{reason} at byte {at}, in a file that ends with a footer: damaged, not unfinished"),
            });
        }
        let unreadable_bytes = match self.source_len {
            Some(len) => len.saturating_sub(at),
            None => read.len() as u64 + rest,
        };
        self.tail = Some(Tail { at_byte: at, unreadable_bytes, reason: reason.to_owned() });
        self.section = Section::Done;
        Ok(None)
    }
}

/// The last 8 bytes seen (as many as there were).
#[derive(Default)]
struct EndWindow {
    bytes: [u8; 8],
    len: usize,
}

impl EndWindow {
    fn push(&mut self, data: &[u8]) {
        let take = data.len().min(8);
        let keep = (8 - take).min(self.len);
        self.bytes.copy_within(self.len - keep..self.len, 0);
        self.bytes[keep..keep + take].copy_from_slice(&data[data.len() - take..]);
        self.len = keep + take;
    }

    fn is_magic(&self) -> bool {
        self.bytes[..self.len] == mcap::MAGIC[..]
    }
}

/// Reads into `buf` until it is full or the source ends; the count read (0: end of file).
pub(super) fn read_some<R: Read>(source: &mut R, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut filled = 0;
    while filled < buf.len() {
        match source.read(&mut buf[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(filled)
}

/// Appends up to `len` bytes of `source` to `buf`, growing it by at most [`READ_STEP`] at a
/// time, so a length that the file does not back costs no memory; the count read.
fn read_up_to<R: Read>(source: &mut R, buf: &mut Vec<u8>, len: u64) -> std::io::Result<u64> {
    let mut got = 0u64;
    while got < len {
        let step = (len - got).min(READ_STEP) as usize;
        let start = buf.len();
        buf.resize(start + step, 0);
        let n = read_some(source, &mut buf[start..])?;
        buf.truncate(start + n);
        got += n as u64;
        if n < step {
            break;
        }
    }
    Ok(got)
}

/// Counts the bytes left in `source`, reading them in small pieces.
/// Reads the rest of `source`, keeping its last bytes in `last`; the count read.
fn copy_rest<R: Read>(source: &mut R, last: &mut EndWindow) -> std::io::Result<u64> {
    let mut buf = [0u8; 64 << 10];
    let mut total = 0;
    loop {
        let n = read_some(source, &mut buf)?;
        if n == 0 {
            return Ok(total);
        }
        last.push(&buf[..n]);
        total += n as u64;
    }
}

/// The next record of `chunk`, whose whole record (head included) is `record`: its opcode, its
/// body copied into `out`.
fn next_record_of(chunk: &mut OpenChunk, record: &[u8], out: &mut Vec<u8>) -> Result<Option<u8>, RecordingError> {
    loop {
        match chunk.reader.next_event() {
            None => return Ok(None),
            Some(Err(e)) => {
                return Err(RecordingError::Corrupt { reason: format!("chunk at byte {}: {e}", chunk.at_byte) });
            }
            Some(Ok(LinearReadEvent::ReadRequest(need))) => {
                let rest = &record[chunk.fed..];
                let n = need.min(rest.len());
                chunk.reader.insert(n).copy_from_slice(&rest[..n]);
                chunk.reader.notify_read(n);
                chunk.fed += n;
            }
            Some(Ok(LinearReadEvent::Record { opcode, data })) => {
                out.clear();
                out.extend_from_slice(data);
                return Ok(Some(opcode));
            }
        }
    }
}
