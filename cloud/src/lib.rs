//! Cloud roles. The scenario library (SQLite) lives in `library`.

pub mod generate;
pub mod library;
pub mod transport;
