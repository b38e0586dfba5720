//! RiskTwin's SQLite stores, each a real database file opened by path:
//!
//! - [`library`]: the scenario library — generated and recorded scenarios, their episodes, the
//!   risk ranking, the regression set and the fleet's policy versions and pushes;
//! - [`recordings`]: the catalogue of a rotating recording's MCAP segments.
//!
//! Both check a file's schema against the one this build writes before they touch it
//! (`sqlite_schema`), so an old or foreign file is refused by name instead of being altered.

pub mod library;
pub mod recordings;
mod sqlite_schema;
