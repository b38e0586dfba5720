//! Why the ingest turned a message away, with stable codes for counters, logs and the cloud's
//! JSON summary (all kebab-case; docs/keyexpr.md lists them next to the keys).
//!
//! One list for the whole ingest path: the transport side (`bad-key`, `no-replay-time`,
//! `wrong-schema`), the decoder (`malformed`, `missing-field`, `invalid-field`), the payload
//! check (`source-mismatch`) and the ingest core itself (the rest; [`crate::IngestCore`]
//! only ever returns those).

/// Why a message was not taken into the twin; [`DropReason::code`] is stable across releases.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum DropReason {
    /// The (source, sequence) pair was already accepted inside the reorder window.
    Duplicate,
    /// The sequence number is older than the reorder window: it can no longer be told apart
    /// from a duplicate, so it is refused.
    TooOld,
    /// The sequence number lies more than the reorder window ahead of the source's highest one
    /// and the source's next number did not confirm it (a forged or runaway number; see
    /// [`crate::Deduper`]).
    SeqJump,
    /// The capture time, mapped onto the cloud clock, lies after the receive time plus the
    /// allowed tolerance (network delay cannot be negative).
    FutureTimestamp,
    /// The source table is full; a new source name was refused.
    TooManySources,
    /// The stream index is not one the aligner was built with.
    UnknownStream,
    /// The key is not an edge stream of the scheme (`risktwin/v1/<site>/<source>/<stream>`).
    BadKey,
    /// Replay-ingest mode, and the message carries no replay-time attachment.
    NoReplayTime,
    /// The payload is not a protobuf message of the stream's type.
    Malformed,
    /// The message lacks a field it must carry.
    MissingField,
    /// A field holds a value outside its domain (NaN, out of range, unknown enum).
    InvalidField,
    /// The payload's header names another source than its key.
    SourceMismatch,
    /// The sample's encoding names another schema than the stream's (another message type or
    /// schema version), or none: it is not read as the stream's type.
    WrongSchema,
    /// The payload is larger than an edge stream's maximum ([`MAX_EDGE_PAYLOAD_BYTES`]): refused
    /// before it is decoded.
    TooLarge,
    /// The ingest is overloaded and sheds the message's stream (lower priority than states):
    /// counted as received by the deduplicator, then not used.
    Shed,
}

/// The largest payload an edge stream may carry, bytes. The real messages are far smaller
/// (docs/keyexpr.md: a state ≈ 112 B, a perception list ≈ 161 B, an RSU object list ≈ 260 B),
/// so the cap only refuses a broken or hostile publisher, long before Zenoh's own limit.
pub const MAX_EDGE_PAYLOAD_BYTES: usize = 64 * 1024;

impl DropReason {
    /// Every reason, in code order; `DropCounts` is indexed by position in this list.
    pub const ALL: [DropReason; 15] = [
        DropReason::Duplicate,
        DropReason::TooOld,
        DropReason::SeqJump,
        DropReason::FutureTimestamp,
        DropReason::TooManySources,
        DropReason::UnknownStream,
        DropReason::BadKey,
        DropReason::NoReplayTime,
        DropReason::Malformed,
        DropReason::MissingField,
        DropReason::InvalidField,
        DropReason::SourceMismatch,
        DropReason::WrongSchema,
        DropReason::TooLarge,
        DropReason::Shed,
    ];

    /// The stable, kebab-case code used in counters, logs and reports.
    pub const fn code(self) -> &'static str {
        match self {
            DropReason::Duplicate => "duplicate",
            DropReason::TooOld => "too-old",
            DropReason::SeqJump => "seq-jump",
            DropReason::FutureTimestamp => "future-timestamp",
            DropReason::TooManySources => "too-many-sources",
            DropReason::UnknownStream => "unknown-stream",
            DropReason::BadKey => "bad-key",
            DropReason::NoReplayTime => "no-replay-time",
            DropReason::Malformed => "malformed",
            DropReason::MissingField => "missing-field",
            DropReason::InvalidField => "invalid-field",
            DropReason::SourceMismatch => "source-mismatch",
            DropReason::WrongSchema => "wrong-schema",
            DropReason::TooLarge => "too-large",
            DropReason::Shed => "shed",
        }
    }

    /// The reason with this code, if any.
    pub fn from_code(code: &str) -> Option<DropReason> {
        DropReason::ALL.into_iter().find(|r| r.code() == code)
    }

    const fn slot(self) -> usize {
        self as usize
    }
}

impl std::fmt::Display for DropReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.code())
    }
}

/// A counter per [`DropReason`]; fixed size, no allocation.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DropCounts {
    counts: [u64; DropReason::ALL.len()],
}

impl DropCounts {
    /// Counts one more drop for `reason`.
    pub fn add(&mut self, reason: DropReason) {
        self.counts[reason.slot()] += 1;
    }

    /// How many drops `reason` has counted.
    pub fn get(&self, reason: DropReason) -> u64 {
        self.counts[reason.slot()]
    }

    /// All drops, whatever the reason.
    pub fn total(&self) -> u64 {
        self.counts.iter().sum()
    }

    /// `(code, count)` for every reason, in code order (zeros included, so reports keep a shape).
    pub fn iter(&self) -> impl Iterator<Item = (&'static str, u64)> + '_ {
        DropReason::ALL.into_iter().map(|r| (r.code(), self.get(r)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_are_stable_unique_and_round_trip() {
        let codes: Vec<&str> = DropReason::ALL.iter().map(|r| r.code()).collect();
        assert_eq!(
            codes,
            [
                "duplicate",
                "too-old",
                "seq-jump",
                "future-timestamp",
                "too-many-sources",
                "unknown-stream",
                "bad-key",
                "no-replay-time",
                "malformed",
                "missing-field",
                "invalid-field",
                "source-mismatch",
                "wrong-schema",
                "too-large",
                "shed"
            ]
        );
        for r in DropReason::ALL {
            assert_eq!(DropReason::from_code(r.code()), Some(r));
            assert_eq!(DropReason::ALL[r.slot()], r, "ALL must be in slot order");
        }
        assert_eq!(DropReason::from_code("late"), None);
    }

    #[test]
    fn counts_by_reason() {
        let mut c = DropCounts::default();
        c.add(DropReason::Duplicate);
        c.add(DropReason::Duplicate);
        c.add(DropReason::FutureTimestamp);
        assert_eq!(c.get(DropReason::Duplicate), 2);
        assert_eq!(c.get(DropReason::TooOld), 0);
        assert_eq!(c.total(), 3);
        let v: Vec<_> = c.iter().filter(|(_, n)| *n > 0).collect();
        assert_eq!(v, [("duplicate", 2), ("future-timestamp", 1)]);
    }
}
