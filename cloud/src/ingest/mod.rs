//! The cloud's ingest role: edge messages in, aligned twin snapshots and a recording out.

mod digest;
mod sample;
mod stream;
mod worker;

pub use digest::SnapshotDigest;
pub use sample::{Kinematics, TwinSample};
pub use stream::Stream;
pub use worker::{IngestStats, IngestWorker};
#[cfg(test)]
mod tests;
