//! Rewriting what is readable of a damaged or unfinished recording as a finished MCAP file
//! (footer, summary, indexes), for `risktwin recover` and for tools that want only whole files.
//!
//! Schemas and channels keep their ids, messages their headers; metadata and attachments that
//! lie outside chunks are copied too. The first damage ends the read: what follows it is
//! reported as lost, never guessed at.

use super::RecordingError;
use super::scan::{RecordScanner, Tail};
use mcap::records::{Record, op};
use std::collections::HashSet;
use std::io::{Read, Seek, Write};

/// What a recovery kept and what it lost.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Recovery {
    pub schemas: u64,
    pub channels: u64,
    pub messages: u64,
    pub metadata: u64,
    pub attachments: u64,
    /// Messages on a channel that was never declared (or whose schema was lost): not written.
    pub orphan_messages: u64,
    /// First and last log time of the messages kept, ns.
    pub log_time_ns: Option<(u64, u64)>,
    /// Where reading stopped before the file's end, and why; `None` for a finished file.
    pub lost: Option<Tail>,
}

impl Recovery {
    /// Whether anything was kept.
    pub fn kept_anything(&self) -> bool {
        self.messages + self.metadata + self.attachments > 0
    }
}

/// Reads `scanner`'s file to its end or first damage and writes what it read to `out` as a
/// finished MCAP file. An error only for a file that is not MCAP, a failing read
/// ([`RecordingError::Io`]) or a failing write ([`RecordingError::Mcap`]); a file with nothing
/// readable gives an empty (but finished) file and a [`Recovery`] that kept nothing.
pub fn recover<R: Read, W: Write + Seek>(
    mut scanner: RecordScanner<R>,
    out: W,
) -> Result<(Recovery, W), RecordingError> {
    let mut recovery = Recovery::default();
    let mut writer: Option<mcap::Writer<W>> = None;
    let mut out = Some(out);
    let mut schemas = HashSet::new();
    let mut channels = HashSet::new();
    let options = |profile: &str| {
        mcap::WriteOptions::new()
            .profile(profile)
            .library(concat!("risktwin recover ", env!("CARGO_PKG_VERSION")))
            .chunk_size(Some(super::CHUNK_BYTES))
    };
    loop {
        let opcode = match scanner.next_record() {
            Ok(Some(opcode)) => opcode,
            Ok(None) => {
                recovery.lost = scanner.tail().cloned();
                break;
            }
            // Not a recording, or one that could not be read: not damage to report as lost
            // (a failing disk would otherwise pass for a file cut short).
            Err(e @ (RecordingError::NotMcap | RecordingError::Io(_))) => return Err(e),
            Err(e) => {
                let at_byte = scanner.record_at();
                let unreadable_bytes = scanner.source_len().map_or(0, |len| len.saturating_sub(at_byte));
                recovery.lost = Some(Tail { at_byte, unreadable_bytes, reason: e.to_string() });
                break;
            }
        };
        if opcode == op::HEADER && writer.is_none() {
            // The original's profile, when its header is readable.
            let profile = match mcap::parse_record(opcode, scanner.body()) {
                Ok(Record::Header(h)) => h.profile,
                _ => String::new(),
            };
            writer = Some(
                options(&profile)
                    .create(out.take().ok_or(RecordingError::Corrupt { reason: "two headers".into() })?)?,
            );
            continue;
        }
        let w = match writer.as_mut() {
            Some(w) => w,
            None => writer
                .insert(options("").create(out.take().ok_or(RecordingError::Corrupt { reason: "no writer".into() })?)?),
        };
        // A record that does not parse is lost alone: the framing around it was sound.
        let Ok(record) = mcap::parse_record(opcode, scanner.body()) else { continue };
        match record {
            Record::Schema { header, data } if header.id != 0 && schemas.insert(header.id) => {
                w.add_schema_with_id(header.id, &header.name, &header.encoding, &data)?;
                recovery.schemas += 1;
            }
            // A channel whose schema was lost is left out (its messages count as orphans).
            Record::Channel(c) if !channels.contains(&c.id) && (c.schema_id == 0 || schemas.contains(&c.schema_id)) => {
                w.add_channel_with_id(c.id, c.schema_id, &c.topic, &c.message_encoding, &c.metadata)?;
                channels.insert(c.id);
                recovery.channels += 1;
            }
            Record::Message { header, data } => {
                if !channels.contains(&header.channel_id) {
                    recovery.orphan_messages += 1;
                    continue;
                }
                w.write_to_known_channel(&header, &data)?;
                recovery.messages += 1;
                let (first, last) = recovery.log_time_ns.get_or_insert((header.log_time, header.log_time));
                (*first, *last) = ((*first).min(header.log_time), (*last).max(header.log_time));
            }
            Record::Metadata(m) => {
                w.write_metadata(&m)?;
                recovery.metadata += 1;
            }
            Record::Attachment { header, data, .. } => {
                let attachment = mcap::Attachment {
                    log_time: header.log_time,
                    create_time: header.create_time,
                    name: header.name,
                    media_type: header.media_type,
                    data,
                };
                w.attach(&attachment)?;
                recovery.attachments += 1;
            }
            _ => {}
        }
    }
    let mut writer = match writer {
        Some(w) => w,
        None => options("").create(out.take().ok_or(RecordingError::Corrupt { reason: "no writer".into() })?)?,
    };
    writer.finish()?;
    Ok((recovery, writer.into_inner()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recording::Recorder;

    /// A source that fails (as a failing disk does) after `ok` bytes.
    struct FailingAfter<'a> {
        bytes: &'a [u8],
        ok: usize,
    }

    impl Read for FailingAfter<'_> {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            if self.ok == 0 {
                return Err(std::io::Error::other("input/output error"));
            }
            let n = buf.len().min(self.ok).min(self.bytes.len());
            buf[..n].copy_from_slice(&self.bytes[..n]);
            (self.bytes, self.ok) = (&self.bytes[n..], self.ok - n);
            Ok(n)
        }
    }

    #[test]
    fn a_failing_read_is_an_error_not_damage() {
        let mut rec = Recorder::new(std::io::Cursor::new(Vec::new())).expect("recorder");
        let channel = rec.channel("risktwin/v1/s/veh-1/state", "risktwin.v1.VehicleState").expect("channel");
        for t in 0..50 {
            rec.write(channel, t, t, &[7; 100]).expect("write");
        }
        let bytes = rec.finish_into_inner().expect("finish").into_inner();
        let whole = recover(RecordScanner::new(bytes.as_slice()), std::io::Cursor::new(Vec::new()));
        assert!(whole.is_ok_and(|(r, _)| r.messages == 50 && r.lost.is_none()), "the whole file is read");
        let failing = RecordScanner::new(FailingAfter { bytes: &bytes, ok: bytes.len() / 2 });
        match recover(failing, std::io::Cursor::new(Vec::new())) {
            Err(RecordingError::Io(e)) => assert_eq!(e.to_string(), "input/output error"),
            Err(e) => panic!("another error: {e}"),
            Ok((r, _)) => panic!("a failing read passed for damage: {r:?}"),
        }
    }
}
