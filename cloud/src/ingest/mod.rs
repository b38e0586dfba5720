//! The cloud's ingest role: edge messages in, aligned twin snapshots and a recording out.

mod digest;
mod replay;
mod sample;
pub mod stream;
mod worker;

pub use digest::SnapshotDigest;
pub use replay::{ReplayCounts, replay_into};
pub use sample::{ObservedKinematics, TwinSample};
pub use worker::{AcceptedMessage, IngestStats, IngestWorker};
#[cfg(test)]
mod tests;
