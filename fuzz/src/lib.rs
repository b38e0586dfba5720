//! What the fuzz targets share: the framing that splits one fuzz input into several messages,
//! so a target can feed a sequence (a stream of samples, of pushes) through the same state the
//! binary keeps between them, and so that seed inputs can be built from real messages
//! (`examples/seeds.rs`).
//!
//! A record is a tag byte followed by frames; a frame is a little-endian `u16` length and that
//! many bytes. A length past the end takes what is left, so every input reads as some records.

/// Reads records from a fuzz input.
pub struct Records<'a> {
    rest: &'a [u8],
}

impl<'a> Records<'a> {
    /// The records of `data`.
    pub fn new(data: &'a [u8]) -> Self {
        Self { rest: data }
    }

    /// The next record's tag, `None` at the end.
    pub fn tag(&mut self) -> Option<u8> {
        let (&tag, rest) = self.rest.split_first()?;
        self.rest = rest;
        Some(tag)
    }

    /// The next frame (empty at the end).
    pub fn frame(&mut self) -> &'a [u8] {
        let len = match self.rest {
            [a, b, rest @ ..] => {
                self.rest = rest;
                u16::from_le_bytes([*a, *b]) as usize
            }
            _ => {
                self.rest = &[];
                0
            }
        };
        let (frame, rest) = self.rest.split_at(len.min(self.rest.len()));
        self.rest = rest;
        frame
    }
}

/// Appends a record of `tag` and `frames` to `out` (what [`Records`] reads back).
pub fn write_record(out: &mut Vec<u8>, tag: u8, frames: &[&[u8]]) {
    out.push(tag);
    for frame in frames {
        let len = u16::try_from(frame.len()).expect("a seed frame fits in 64 KiB");
        out.extend_from_slice(&len.to_le_bytes());
        out.extend_from_slice(frame);
    }
}

/// Tag bits of an `ingest` record: which of [`INGEST_SOURCES`] sends it, on which site, which
/// stream's key it carries and which encoding tags it.
pub mod ingest_tag {
    /// Bits 0–2: the stream of `EdgeStream::ALL` (5: a key of no stream, 6–7: a key made of the
    /// attachment frame's bytes).
    pub const STREAM_MASK: u8 = 0b0000_0111;
    /// Bits 3–4: the source of [`super::INGEST_SOURCES`].
    pub const SOURCE_SHIFT: u8 = 3;
    /// Bit 5: the site of [`super::INGEST_SITES`].
    pub const SITE_SHIFT: u8 = 5;
    /// Bits 6–7: the encoding: 0 the stream's own, 1 the next stream's, 2 none (empty), 3 a
    /// protobuf encoding with the schema of another version.
    pub const ENCODING_SHIFT: u8 = 6;

    /// The tag of a message from source `source` of site `site` on stream `stream` with
    /// encoding choice `encoding`.
    pub fn of(stream: u8, source: u8, site: u8, encoding: u8) -> u8 {
        (stream & STREAM_MASK)
            | (source & 3) << SOURCE_SHIFT
            | (site & 1) << SITE_SHIFT
            | (encoding & 3) << ENCODING_SHIFT
    }
}

/// Sources the `ingest` target's keys name (two vehicles and an RSU, and one that is not a
/// valid id).
pub const INGEST_SOURCES: [&str; 4] = ["veh-1", "veh-2", "rsu-1", "veh 3"];
/// Sites the `ingest` target's keys name.
pub const INGEST_SITES: [&str; 2] = ["site0", "site1"];

/// What an `edge_push` record carries (its tag modulo 3); tag / 3 modulo 3 picks the encoding:
/// 0 the message's own, 1 another message's, 2 none.
pub mod push_tag {
    pub const SCENARIO: u8 = 0;
    pub const WARNING: u8 = 1;
    pub const POLICY: u8 = 2;
}

/// The vehicle the `edge_push` target plays: its id (a warning's addressee) and `SITE/ID` (a
/// signed policy update's target).
pub const PUSH_VEHICLE_ID: &str = "veh-1";
pub const PUSH_TARGET: &str = "site0/veh-1";
/// The seed of the key the `edge_push` vehicle trusts: a seed update is signed with it, so the
/// fuzzer starts past the signature check.
pub const PUSH_KEY_SEED: [u8; 32] = [7; 32];

/// What a `scene_wire` record carries (its tag modulo 5).
pub mod scene_tag {
    /// A scene authority's truth message (postcard), as a participant decodes it.
    pub const TRUTH: u8 = 0;
    /// A participant's reply (postcard), as the authority decodes it.
    pub const REPLY: u8 = 1;
    /// A scene's road map (protobuf), as the cloud decodes it and builds its risk raster on it.
    pub const ROAD_MAP: u8 = 2;
    /// A scene's ground-truth vehicle state (protobuf).
    pub const VEHICLE: u8 = 3;
    /// A scene's ground-truth object list (protobuf).
    pub const OBJECTS: u8 = 4;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_read_back_what_was_written() {
        let mut out = Vec::new();
        write_record(&mut out, 3, &[b"ab", b""]);
        write_record(&mut out, 9, &[b"xyz"]);
        let mut r = Records::new(&out);
        assert_eq!((r.tag(), r.frame(), r.frame()), (Some(3), &b"ab"[..], &b""[..]));
        assert_eq!((r.tag(), r.frame()), (Some(9), &b"xyz"[..]));
        assert_eq!(r.tag(), None);
    }

    #[test]
    fn a_length_past_the_end_takes_what_is_left() {
        let mut r = Records::new(&[1, 0xff, 0xff, b'a', b'b']);
        assert_eq!((r.tag(), r.frame()), (Some(1), &b"ab"[..]));
        assert_eq!((r.tag(), r.frame()), (None, &b""[..]));
    }
}
