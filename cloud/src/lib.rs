//! Cloud roles. The scenario library (SQLite) lives in `library`.

pub mod commonroad_recording;
pub mod criticality;
pub mod episode_recording;
pub mod generate;
pub mod ingest;
pub mod library;
#[cfg(test)]
mod test_fixtures;
pub mod trainer;
pub mod transport;
pub mod twin;
