//! Cloud roles. The scenario library (SQLite) lives in `library`.

pub mod episode_recording;
pub mod generate;
pub mod ingest;
pub mod library;
pub mod transport;
