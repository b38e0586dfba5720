//! The cloud's ingest role: edge messages in, aligned twin snapshots and a recording out.

mod digest;
mod replay;
mod sample;
mod stream;
pub mod synth;
mod worker;

pub use digest::SnapshotDigest;
pub use replay::{ReplayCounts, replay_into};
pub use sample::{Kinematics, TwinSample};
pub use stream::Stream;
pub use worker::{IngestStats, IngestWorker};
#[cfg(test)]
mod tests;
