//! Cloud roles. The scenario library (SQLite) lives in `library`.

pub mod library;
