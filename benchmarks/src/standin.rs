//! The payload of the transport benchmark (`risktwin bench zenoh`): a hand-encoded, header-like
//! record of fixed layout, so the benchmark measures Zenoh and our wrapper without the protobuf
//! codec. The roles themselves send `risktwin-protos` messages.
//!
//! Layout, little-endian: magic `RTS1` (4 B), seq (u64), capture_time_ns (i64),
//! publish_time_ns (i64), source length (u8) and bytes (UTF-8), filler length (u32) and filler.

use thiserror::Error;

/// Leading bytes of every stand-in payload.
pub const MAGIC: [u8; 4] = *b"RTS1";
/// Size of the fixed part before the source bytes.
const FIXED_LEN: usize = 4 + 8 + 8 + 8 + 1;
/// Smallest possible payload (empty source, no filler).
pub const MIN_LEN: usize = FIXED_LEN + 4;

/// One decoded stand-in record, borrowing the source id from the payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StandIn<'a> {
    /// The publishing edge's id (must match the key's source chunk).
    pub source: &'a str,
    /// Per-stream sequence number, from 0.
    pub seq: u64,
    /// When the data was captured, on the edge's own clock, ns since the Unix epoch.
    pub capture_time_ns: i64,
    /// When it was handed to Zenoh, on the edge's own clock, ns since the Unix epoch.
    pub publish_time_ns: i64,
}

/// Why a payload is not a stand-in record.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum StandInError {
    #[error("payload of {len} bytes is shorter than the {need} bytes its header needs")]
    TooShort { len: usize, need: usize },
    #[error("payload starts with {found:02x?}, not the stand-in magic {MAGIC:02x?}")]
    BadMagic { found: [u8; 4] },
    #[error("payload is {actual} bytes but its header declares {declared}")]
    LengthMismatch { declared: usize, actual: usize },
    #[error("payload source id is not UTF-8")]
    SourceNotUtf8,
    #[error("source id of {len} bytes does not fit the one-byte length of the stand-in")]
    SourceTooLong { len: usize },
}

impl StandInError {
    /// A short, stable, kebab-case name for counting drops by reason.
    pub const fn reason(&self) -> &'static str {
        match self {
            StandInError::TooShort { .. } => "too-short",
            StandInError::BadMagic { .. } => "bad-magic",
            StandInError::LengthMismatch { .. } => "length-mismatch",
            StandInError::SourceNotUtf8 => "source-not-utf8",
            StandInError::SourceTooLong { .. } => "source-too-long",
        }
    }
}

impl StandIn<'_> {
    /// Appends the encoding, padded with filler up to `total_len` bytes if that is longer.
    pub fn encode_into(&self, total_len: usize, out: &mut Vec<u8>) -> Result<(), StandInError> {
        let source = self.source.as_bytes();
        let source_len = u8::try_from(source.len()).map_err(|_| StandInError::SourceTooLong { len: source.len() })?;
        let bare_len = MIN_LEN + source.len();
        let filler_len = total_len.saturating_sub(bare_len);
        let filler_len_u32 = u32::try_from(filler_len)
            .map_err(|_| StandInError::LengthMismatch { declared: total_len, actual: bare_len })?;
        out.reserve(bare_len + filler_len);
        out.extend_from_slice(&MAGIC);
        out.extend_from_slice(&self.seq.to_le_bytes());
        out.extend_from_slice(&self.capture_time_ns.to_le_bytes());
        out.extend_from_slice(&self.publish_time_ns.to_le_bytes());
        out.push(source_len);
        out.extend_from_slice(source);
        out.extend_from_slice(&filler_len_u32.to_le_bytes());
        out.resize(out.len() + filler_len, 0xA5);
        Ok(())
    }

    /// The encoding as a new buffer of at least `total_len` bytes.
    pub fn encode(&self, total_len: usize) -> Result<Vec<u8>, StandInError> {
        let mut out = Vec::new();
        self.encode_into(total_len, &mut out)?;
        Ok(out)
    }
}

/// Decodes `bytes` without allocating; every malformation is a typed error.
pub fn decode(bytes: &[u8]) -> Result<StandIn<'_>, StandInError> {
    if bytes.len() < MIN_LEN {
        return Err(StandInError::TooShort { len: bytes.len(), need: MIN_LEN });
    }
    let found: [u8; 4] = bytes[0..4].try_into().expect("length checked above");
    if found != MAGIC {
        return Err(StandInError::BadMagic { found });
    }
    let u64_at = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().expect("length checked above"));
    let seq = u64_at(4);
    let capture_time_ns = u64_at(12) as i64;
    let publish_time_ns = u64_at(20) as i64;
    let source_len = usize::from(bytes[28]);
    let source_end = FIXED_LEN + source_len;
    let need = source_end + 4;
    if bytes.len() < need {
        return Err(StandInError::TooShort { len: bytes.len(), need });
    }
    let filler_len = u32::from_le_bytes(bytes[source_end..need].try_into().expect("length checked above"));
    let declared = need + filler_len as usize;
    if declared != bytes.len() {
        return Err(StandInError::LengthMismatch { declared, actual: bytes.len() });
    }
    let source = std::str::from_utf8(&bytes[FIXED_LEN..source_end]).map_err(|_| StandInError::SourceNotUtf8)?;
    Ok(StandIn { source, seq, capture_time_ns, publish_time_ns })
}

#[cfg(test)]
mod tests {
    use super::*;

    const REC: StandIn<'static> =
        StandIn { source: "veh-1", seq: 42, capture_time_ns: -5, publish_time_ns: 1_700_000_000_000_000_000 };

    #[test]
    fn round_trips_with_and_without_filler() {
        let bare = REC.encode(0).unwrap();
        assert_eq!(bare.len(), MIN_LEN + 5);
        assert_eq!(decode(&bare).unwrap(), REC);
        let kib = REC.encode(1024).unwrap();
        assert_eq!(kib.len(), 1024);
        assert_eq!(decode(&kib).unwrap(), REC);
    }

    #[test]
    fn malformed_payloads_are_typed_errors() {
        let good = REC.encode(64).unwrap();
        assert_eq!(decode(&good[..10]), Err(StandInError::TooShort { len: 10, need: MIN_LEN }));
        let mut bad = good.clone();
        bad[0] = b'X';
        assert_eq!(decode(&bad), Err(StandInError::BadMagic { found: *b"XTS1" }));
        assert_eq!(decode(&good[..63]), Err(StandInError::LengthMismatch { declared: 64, actual: 63 }));
        let mut extra = good.clone();
        extra.push(0);
        assert_eq!(decode(&extra).map_err(|e| e.reason()), Err("length-mismatch"));
        let mut not_utf8 = good;
        not_utf8[FIXED_LEN] = 0xFF;
        assert_eq!(decode(&not_utf8), Err(StandInError::SourceNotUtf8));
        let long = "x".repeat(300);
        assert_eq!(StandIn { source: &long, ..REC }.encode(0), Err(StandInError::SourceTooLong { len: 300 }));
        // Garbage of any length never panics.
        for len in 0..80 {
            let junk: Vec<u8> = (0..len).map(|i| (i * 37 % 251) as u8).collect();
            let _ = decode(&junk);
        }
    }
}
