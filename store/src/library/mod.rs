//! The high-risk scenario library (docs/method.md §8): every evaluated scenario with its spec, its
//! outcomes and risk terms, and its lineage, in one SQLite file; ranked by risk and used to pick
//! scenarios for replay, mutation and regression.
//!
//! # File
//! A SQLite database in WAL journal mode (`synchronous = NORMAL`, foreign keys on), marked as
//! ours by `PRAGMA application_id = 0x5254574C` ("RTWL") and versioned by `PRAGMA user_version`
//! ([`SCHEMA_VERSION`]). Opening a file that is not SQLite, a SQLite database of something else,
//! or a newer schema fails with a typed [`LibraryError`] naming the path; such files are never
//! written to. Every batch is one transaction.
//!
//! # Schema (version 3; all tables `STRICT`)
//! - `scenarios(id TEXT PK, kind TEXT, seed INTEGER, params TEXT, parent_id TEXT NULL → scenarios,
//!   generation INTEGER, origin TEXT, created_seq INTEGER UNIQUE)`:
//!   `id` is the content id ([`content_id`]: FNV-1a 64 of kind, seed and parameter bits, 16 hex
//!   digits), so a scenario stored twice is one row. `seed` is the u64 seed stored bit for bit as
//!   a signed integer. `params` is a JSON object with sorted keys and round-trip-exact numbers.
//!   `generation` is 0 for roots and parent + 1 for mutations; `origin` is one of `sampled`,
//!   `mutated`, `imported`, `regression`; `created_seq` counts insertions from 1.
//! - `outcomes(seq INTEGER PK, scenario_id → scenarios, policy TEXT, collision, offroad, success
//!   (0/1), route_completion, avg_speed_mps, steering_smoothness, longitudinal_smoothness,
//!   min_ttc_s REAL NULL, min_distance_m, episode_risk_score, reward, steps, risk_score, risk_ttc,
//!   risk_dist, risk_lane, risk_jerk, risk_collision)`: every field of `EpisodeMetrics` and
//!   `RiskTerms`. A scenario may have many outcomes; the one with the highest `seq` for a policy
//!   is its latest. `min_ttc_s` is NULL when no pair closed in (an infinite or NaN TTC is stored
//!   as NULL too, as docs/cli.md writes both as null). Risk terms carry a `CHECK` for [0, 1].
//! - `rejected(kind, reason, count)`, primary key (kind, reason): infeasible candidates by
//!   `Infeasible::code`, for reports.
//! - `regression(scenario_id PK → scenarios, reason 'collision'|'manual', marked_seq)`: the
//!   regression set. Any outcome with a collision adds its scenario automatically.
//! - `recorded(id TEXT PK, kind 'commonroad', source_name, benchmark_id, ego_id INTEGER, xml TEXT,
//!   created_seq INTEGER UNIQUE)` (version 2): recorded validation cases. `id` is
//!   [`recorded_id`] (FNV-1a 64 of kind, XML bytes and ego id), so importing a file twice is
//!   one row; the XML is stored whole, so the file needs nothing else to replay it; `ego_id` is
//!   the u64 obstacle id stored bit for bit.
//! - `recorded_outcomes(seq INTEGER PK, case_id → recorded, <the outcome columns>)` (version 2):
//!   as `outcomes`, for recorded cases; policy `replay` ([`REPLAY_POLICY`]) is the reference
//!   outcome. An outcome equal to its policy's latest is not written again. Collisions here do
//!   not enter `regression` (that set holds generated scenarios).
//!
//! - `pushes(seq INTEGER PK, scenario_id → scenarios, site, edge, attempts ≥ 1, state
//!   'outstanding'|'done'|'abandoned')` (version 3): scenarios the loop pushed to fleet edges;
//!   at most one outstanding per `(site, edge)` (a partial unique index).
//! - `twin_outcomes(seq INTEGER PK, scenario_id → scenarios, <the outcome columns>)` (version 3):
//!   the twin's score of a fleet episode.
//! - `fleet_episodes(seq INTEGER PK, scenario_id → scenarios, site, edge, policy_id NULL,
//!   policy_version NULL, scene NULL, push_seq NULL → pushes, edge_outcome_seq → outcomes,
//!   twin_outcome_seq NULL → twin_outcomes, twin_ticks, disagreement NULL)` (version 3): one
//!   episode played by the fleet; the edge's own outcome is an ordinary row of `outcomes`.
//! - `policies(version INTEGER PK, policy_id, algo, weights BLOB, decision 'pushed'|'held-back',
//!   reasons, failures)` and `policy_pushes(version → policies, site, edge)` (version 3): the
//!   policy versions the trainer produced, the gate's decision, and where each went.
//!
//! # Reading back
//! A file is input: every outcome read back is checked as a write is (risk terms and route
//! completion in [0, 1], `min_ttc_s` NULL or ≥ 0, distances and speeds ≥ 0, every number finite,
//! flags 0/1, `steps` ≥ 0), and at open the schema must be that of the file's version to the
//! letter, whitespace aside (a table rebuilt without its CHECKs is refused), checked before any
//! migration or pragma writes to the file. A row that fails is [`LibraryError::BadRow`]
//! (`library FILE: row id SEQ: TABLE: …`), a damaged page SQLite's "malformed" error; both are
//! the file's fault ([`LibraryError::blames_the_file`]), which the CLI reports as bad input.
//!
//! # Versions
//! `schema::MIGRATIONS[v]` takes a file from version `v` to `v + 1` inside one IMMEDIATE
//! transaction at open; a new file runs them all, so new and upgraded files are the same.
//! Migrations only add tables: a version-1 or version-2 file opens, keeps every row, and gains
//! the later tables (after which builds that read the older version only refuse it).

mod connection;
mod error;
mod fleet;
mod query;
mod rank;
mod record;
mod recorded;
mod regression;
mod schema;
mod store;
mod stored;

#[cfg(test)]
mod fixtures;

pub use connection::ScenarioLibrary;
pub use error::{LibraryError, RecordError};
pub use fleet::{FleetCounts, FleetEpisode, PolicyVersion, Push, StoredFleetEpisode, policy_label};
pub use rank::{RankOutcome, RankedScenario};
pub use record::{
    DEFAULT_POLICY, InsertSummary, KindCounts, Origin, Outcome, Rejection, ScenarioRecord, StoredScenario, content_id,
};
pub use recorded::{COMMONROAD_KIND, REPLAY_POLICY, RankedCase, RecordedCase, RecordedInsert, StoredCase, recorded_id};
pub use regression::{RegressionCase, RegressionReason};
pub use schema::{APPLICATION_ID, SCHEMA_VERSION};
