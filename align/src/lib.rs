//! The cloud ingest core: exactly-once, clock offsets, timestamp checks and multi-rate alignment.
//!
//! Pure and deterministic like `common`: receive times are passed in, nothing reads
//! a clock, and the same messages with the same receive times give the same snapshots bit for
//! bit — which is what lets a recording replay into the same twin. Generic over the payload, so
//! the wire types stay in `protos/` and the transport in `cloud/`.
//!
//! - [`source`]: source names → dense [`SourceIndex`].
//! - [`dedupe`]: exactly-once by (source, sequence) in a bounded reorder window; loss counting.
//! - [`clock`]: per-source clock offset and drift from one-way messages (minimum filter).
//! - [`reason`]: why a message was dropped, with stable codes for counters.
//! - [`interp`], [`snapshot`], [`aligner`]: interpolation, as-of and late-data policy at a tick.
//! - [`ingest`]: all of the above in the order a worker applies them.

pub mod aligner;
pub mod clock;
pub mod dedupe;
pub mod ingest;
pub mod interp;
pub mod reason;
pub mod snapshot;
pub mod source;

pub use aligner::{AlignConfig, AlignCounts, Aligner, DEFAULT_LATENESS_NS, PushOutcome, StreamMode, StreamSpec};
pub use clock::{ClockConfig, ClockEstimator};
pub use dedupe::{DedupConfig, Deduper, SeqCounts, SeqProgress, Verdict};
pub use ingest::{Accepted, Incoming, IngestConfig, IngestCore, SequenceScope};
pub use interp::{Interpolate, lerp_angle};
pub use reason::{DropCounts, DropReason, MAX_EDGE_PAYLOAD_BYTES};
pub use snapshot::{Aligned, Snapshot, StreamIndex, ValueStatus};
pub use source::{SourceIndex, SourceTable, TooManySources};

#[cfg(test)]
mod bench_tests;
#[cfg(test)]
mod test_fleet;
