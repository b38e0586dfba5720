//! Recorded validation cases: a real scenario (CommonRoad XML, stored whole so that the library
//! file is self-contained and portable) with the ego it validates, its reference outcome (the
//! recorded ego replayed) and the outcome of every policy run on it, ranked by S_risk as
//! generated scenarios are.

use super::connection::ScenarioLibrary;
use super::error::{LibraryError, RecordError};
use super::rank::RankOutcome;
use super::record::{Outcome, ttc_for_storage, validate_outcome};
use super::store::{insert_outcome, outcome_insert_sql};
use super::stored::{OUTCOME_COLUMNS, OutcomeRow, file_of};
use risktwin_common::digest::fnv1a64;
use risktwin_common::risk::RiskTerms;
use rusqlite::{OptionalExtension, Transaction, TransactionBehavior, params};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The `kind` of a recorded CommonRoad case (in the table and in ranked output).
pub const COMMONROAD_KIND: &str = "commonroad";

/// The policy label of the reference outcome: the recorded ego played back as it drove.
pub const REPLAY_POLICY: &str = risktwin_common::driver::REPLAY_LABEL;

/// A recorded scenario offered to the library.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RecordedCase {
    /// The file it came from, without its folder (for people; not part of the id).
    pub source_name: String,
    /// CommonRoad `benchmarkID` (empty when the file has none).
    pub benchmark_id: String,
    /// The dynamic obstacle validated as the ego.
    pub ego_id: u64,
    /// The CommonRoad XML, exactly as read.
    pub xml: String,
}

impl RecordedCase {
    /// This case's content id ([`recorded_id`]).
    pub fn id(&self) -> String {
        recorded_id(&self.xml, self.ego_id)
    }
}

/// A recorded case as stored, with every outcome (oldest first).
#[derive(Debug, Clone, PartialEq)]
pub struct StoredCase {
    pub id: String,
    pub case: RecordedCase,
    /// Insertion order among recorded cases, starting at 1.
    pub created_seq: u64,
    pub outcomes: Vec<Outcome>,
}

impl StoredCase {
    /// The most recent outcome of `policy`, if it was ever run.
    pub fn latest_outcome(&self, policy: &str) -> Option<&Outcome> {
        self.outcomes.iter().rev().find(|o| o.policy == policy)
    }
}

/// What storing a recorded case did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RecordedInsert {
    pub id: String,
    /// A new case row (false: the same XML and ego were stored before).
    pub inserted: bool,
    /// A new outcome row (false: it equals the latest outcome of its policy).
    pub outcome_added: bool,
}

/// One element of `scenarios rank --kind commonroad --format json`: docs/cli.md's rank item where it
/// applies (no seed; `params` is empty, a recording has no generator parameters) plus what
/// names the recording.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RankedCase {
    pub id: String,
    /// Always [`COMMONROAD_KIND`].
    pub kind: String,
    pub benchmark_id: String,
    pub ego_id: u64,
    /// The file the case was imported from.
    pub source: String,
    pub params: BTreeMap<String, f64>,
    pub risk: RiskTerms,
    pub outcome: RankOutcome,
}

/// The content id of a recorded case: FNV-1a 64 over the kind, the XML bytes and the ego id, in
/// 16 hex digits as [`super::content_id`]; the same file and ego give the same id everywhere.
pub fn recorded_id(xml: &str, ego_id: u64) -> String {
    let bytes = COMMONROAD_KIND.bytes().chain([0]).chain(xml.bytes()).chain([0]).chain(ego_id.to_le_bytes());
    format!("{:016x}", fnv1a64(bytes))
}

/// Adds `outcome` to case `id` unless it equals the latest outcome of its policy, so a rerun of a
/// deterministic episode adds nothing. Returns whether a row was written.
fn append_outcome(tx: &Transaction<'_>, id: &str, outcome: &Outcome) -> Result<bool, LibraryError> {
    validate_outcome(outcome).map_err(|source| LibraryError::InvalidRecord { id: id.to_string(), source })?;
    let latest = tx
        .prepare_cached(&format!(
            "SELECT seq, {OUTCOME_COLUMNS} FROM recorded_outcomes WHERE case_id = ?1 AND policy = ?2 \
             ORDER BY seq DESC LIMIT 1"
        ))?
        .query_row(params![id, outcome.policy], |r| OutcomeRow::read_at(r, 0))
        .optional()?
        .map(|row| row.checked(&file_of(tx), "recorded_outcomes"))
        .transpose()?;
    // Compare as stored: an infinite TTC comes back as None.
    let mut as_stored = outcome.clone();
    as_stored.metrics.min_ttc_s = ttc_for_storage(outcome.metrics.min_ttc_s)
        .map_err(|source| LibraryError::InvalidRecord { id: id.to_string(), source })?;
    if latest.as_ref() == Some(&as_stored) {
        return Ok(false);
    }
    let mut insert = tx.prepare_cached(&outcome_insert_sql("recorded_outcomes", "case_id"))?;
    insert_outcome(&mut insert, id, outcome)?;
    Ok(true)
}

type CaseRow = (String, String, String, i64, String, i64);
type RankedRow = (String, String, String, i64, String, OutcomeRow);

impl ScenarioLibrary {
    /// Stores a recorded case with an outcome (its reference: policy [`REPLAY_POLICY`]) in one
    /// transaction. Idempotent: the same XML and ego are one row, and an outcome equal to the
    /// latest of its policy is not written again.
    pub fn insert_recorded(&mut self, case: &RecordedCase, outcome: &Outcome) -> Result<RecordedInsert, LibraryError> {
        let id = case.id();
        if case.xml.is_empty() {
            return Err(LibraryError::InvalidRecord {
                id,
                source: RecordError::EmptyScenario(case.source_name.clone()),
            });
        }
        let tx = self.conn.transaction_with_behavior(TransactionBehavior::Immediate)?;
        let created_seq: i64 = tx.query_row("SELECT COALESCE(MAX(created_seq), 0) FROM recorded", [], |r| r.get(0))?;
        // Ids are u64 stored bit for bit in SQLite's signed integers, as seeds are.
        let inserted = tx.execute(
            "INSERT INTO recorded (id, kind, source_name, benchmark_id, ego_id, xml, created_seq) \
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7) ON CONFLICT (id) DO NOTHING",
            params![
                id,
                COMMONROAD_KIND,
                case.source_name,
                case.benchmark_id,
                case.ego_id as i64,
                case.xml,
                created_seq + 1
            ],
        )? == 1;
        let outcome_added = append_outcome(&tx, &id, outcome)?;
        tx.commit()?;
        Ok(RecordedInsert { id, inserted, outcome_added })
    }

    /// Adds the outcome of a policy run to recorded case `id` (nothing when it equals the latest
    /// outcome of that policy). Returns whether a row was written.
    pub fn add_recorded_outcome(&mut self, id: &str, outcome: &Outcome) -> Result<bool, LibraryError> {
        let tx = self.conn.transaction_with_behavior(TransactionBehavior::Immediate)?;
        let known: bool = tx.query_row("SELECT EXISTS (SELECT 1 FROM recorded WHERE id = ?1)", [id], |r| r.get(0))?;
        if !known {
            return Err(LibraryError::UnknownScenario(id.to_string()));
        }
        let added = append_outcome(&tx, id, outcome)?;
        tx.commit()?;
        Ok(added)
    }

    /// The recorded case stored under `id`, with all its outcomes (oldest first).
    pub fn recorded(&self, id: &str) -> Result<Option<StoredCase>, LibraryError> {
        let row: Option<CaseRow> = self
            .conn
            .prepare_cached(
                "SELECT kind, source_name, benchmark_id, ego_id, xml, created_seq FROM recorded WHERE id = ?1",
            )?
            .query_row([id], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?, r.get(4)?, r.get(5)?)))
            .optional()?;
        let Some((kind, source_name, benchmark_id, ego_id, xml, created_seq)) = row else {
            return Ok(None);
        };
        if kind != COMMONROAD_KIND {
            return Err(LibraryError::Corrupt {
                id: id.to_string(),
                reason: format!("unknown recorded kind '{kind}'"),
            });
        }
        let mut stmt = self.conn.prepare_cached(&format!(
            "SELECT seq, {OUTCOME_COLUMNS} FROM recorded_outcomes WHERE case_id = ?1 ORDER BY seq"
        ))?;
        let rows = stmt.query_map([id], |r| OutcomeRow::read_at(r, 0))?.collect::<Result<Vec<_>, _>>()?;
        let outcomes =
            rows.into_iter().map(|o| o.checked(&self.path, "recorded_outcomes")).collect::<Result<_, _>>()?;
        Ok(Some(StoredCase {
            id: id.to_string(),
            case: RecordedCase { source_name, benchmark_id, ego_id: ego_id as u64, xml },
            created_seq: created_seq.max(0) as u64,
            outcomes,
        }))
    }

    /// The `top` riskiest recorded cases (all when `None`) by the latest outcome of `policy`
    /// (the reference: [`REPLAY_POLICY`]): highest `risk.score` first, ties by id.
    pub fn rank_recorded(&self, policy: &str, top: Option<usize>) -> Result<Vec<RankedCase>, LibraryError> {
        // SQLite reads a negative LIMIT as "no limit".
        let limit = top.map_or(-1, |k| i64::try_from(k).unwrap_or(i64::MAX));
        let outcome_columns = OUTCOME_COLUMNS.split(", ").map(|c| format!("o.{c}")).collect::<Vec<_>>().join(", ");
        let mut stmt = self.conn.prepare_cached(&format!(
            "SELECT c.id, c.kind, c.benchmark_id, c.ego_id, c.source_name, o.seq, {outcome_columns} \
             FROM recorded_outcomes o JOIN recorded c ON c.id = o.case_id \
             WHERE o.policy = ?1 \
               AND o.seq = (SELECT MAX(seq) FROM recorded_outcomes WHERE case_id = c.id AND policy = ?1) \
             ORDER BY o.risk_score DESC, c.id ASC \
             LIMIT ?2"
        ))?;
        let rows = stmt.query_map(params![policy, limit], |r| {
            Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?, r.get(4)?, OutcomeRow::read_at(r, 5)?))
        })?;
        rows.map(|row| {
            let (id, kind, benchmark_id, ego_id, source, outcome): RankedRow = row?;
            let outcome = outcome.checked(&self.path, "recorded_outcomes")?;
            Ok(RankedCase {
                id,
                kind,
                benchmark_id,
                ego_id: ego_id as u64,
                source,
                params: BTreeMap::new(),
                risk: outcome.risk,
                outcome: RankOutcome::of(&outcome),
            })
        })
        .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::super::fixtures::{file_library, outcome, sampled};
    use super::*;
    use risktwin_common::scenario::ScenarioKind;

    fn case(xml: &str, ego_id: u64) -> RecordedCase {
        RecordedCase {
            source_name: "ZAM_Test-1_1_T-1.xml".into(),
            benchmark_id: "ZAM_Test-1_1_T-1".into(),
            ego_id,
            xml: xml.into(),
        }
    }

    fn replayed(score: f64) -> Outcome {
        Outcome { policy: REPLAY_POLICY.into(), ..outcome(score, false, Some(1.5)) }
    }

    fn count(lib: &ScenarioLibrary, table: &str) -> i64 {
        lib.conn.query_row(&format!("SELECT COUNT(*) FROM {table}"), [], |r| r.get(0)).expect("count")
    }

    #[test]
    fn the_id_depends_on_the_xml_and_the_ego_only() {
        let a = case("<commonRoad/>", 7);
        assert_eq!(a.id().len(), 16);
        assert_eq!(a.id(), RecordedCase { source_name: "renamed.xml".into(), ..a.clone() }.id());
        assert_ne!(a.id(), case("<commonRoad />", 7).id());
        assert_ne!(a.id(), case("<commonRoad/>", 8).id());
        // Not a prefix ambiguity: the kind and the XML are separated.
        assert_ne!(recorded_id("a", 1), recorded_id("", 1));
    }

    #[test]
    fn a_case_comes_back_exactly_and_importing_twice_is_one_row() {
        let (_dir, mut lib) = file_library();
        let c = case("<commonRoad benchmarkID=\"x\"/>", u64::MAX - 1); // does not fit i64
        let reference = Outcome { policy: REPLAY_POLICY.into(), ..outcome(0.4375, false, Some(f64::INFINITY)) };
        let first = lib.insert_recorded(&c, &reference).expect("insert");
        assert_eq!(first, RecordedInsert { id: c.id(), inserted: true, outcome_added: true });
        let again = lib.insert_recorded(&c, &reference).expect("insert again");
        assert_eq!(again, RecordedInsert { id: c.id(), inserted: false, outcome_added: false });
        assert_eq!((count(&lib, "recorded"), count(&lib, "recorded_outcomes")), (1, 1));
        let stored = lib.recorded(&c.id()).expect("get").expect("stored");
        assert_eq!(stored.case, c);
        assert_eq!(stored.created_seq, 1);
        // The infinite TTC is stored as NULL, as for generated scenarios.
        let expected = Outcome { policy: REPLAY_POLICY.into(), ..outcome(0.4375, false, None) };
        assert_eq!(stored.outcomes, vec![expected]);
        assert_eq!(lib.recorded("0123456789abcdef").expect("get"), None);
        // Recorded cases are not generated scenarios: the default rank does not see them.
        assert!(lib.rank(None, None).expect("rank").is_empty());
        assert_eq!(lib.get(&c.id()).expect("get"), None);
    }

    #[test]
    fn policy_runs_are_outcomes_under_their_label() {
        let (_dir, mut lib) = file_library();
        let c = case("<commonRoad/>", 3);
        lib.insert_recorded(&c, &replayed(0.25)).expect("insert");
        let idm = outcome(0.75, true, Some(0.5));
        assert!(lib.add_recorded_outcome(&c.id(), &idm).expect("add"));
        assert!(!lib.add_recorded_outcome(&c.id(), &idm).expect("same run again"));
        let changed = outcome(0.5, false, Some(0.5));
        assert!(lib.add_recorded_outcome(&c.id(), &changed).expect("add"));
        let stored = lib.recorded(&c.id()).expect("get").expect("stored");
        assert_eq!(stored.outcomes.len(), 3);
        assert_eq!(stored.latest_outcome("idm"), Some(&changed));
        assert_eq!(stored.latest_outcome(REPLAY_POLICY), Some(&replayed(0.25)));
        // A collision on a recorded case does not enter the generated regression set.
        assert_eq!(count(&lib, "regression"), 0);
        assert!(matches!(lib.add_recorded_outcome("feedfacefeedface", &idm), Err(LibraryError::UnknownScenario(_))));
        let mut bad = idm.clone();
        bad.risk.score = 2.0;
        assert!(matches!(
            lib.add_recorded_outcome(&c.id(), &bad),
            Err(LibraryError::InvalidRecord { source: RecordError::OutOfRange { field: "risk.score", .. }, .. })
        ));
        assert!(matches!(
            lib.insert_recorded(&case("", 3), &replayed(0.1)),
            Err(LibraryError::InvalidRecord { source: RecordError::EmptyScenario(_), .. })
        ));
        assert_eq!(count(&lib, "recorded_outcomes"), 3);
    }

    #[test]
    fn rank_orders_by_the_latest_outcome_of_a_policy() {
        let (_dir, mut lib) = file_library();
        let (low, high, other) = (case("<a/>", 1), case("<b/>", 1), case("<c/>", 1));
        lib.insert_recorded(&low, &replayed(0.125)).expect("insert");
        lib.insert_recorded(&high, &replayed(0.875)).expect("insert");
        lib.insert_recorded(&other, &replayed(0.5)).expect("insert");
        lib.insert_recorded(&low, &replayed(0.9375)).expect("a changed reference wins");
        lib.insert_batch(&[sampled(ScenarioKind::CutIn, 0, 0.99, false)]).expect("a generated one");
        let ranked = lib.rank_recorded(REPLAY_POLICY, None).expect("rank");
        let ids: Vec<&str> = ranked.iter().map(|r| r.id.as_str()).collect();
        assert_eq!(ids, [low.id(), high.id(), other.id()]);
        assert_eq!(ranked[0].risk.score, 0.9375);
        assert_eq!(ranked[1].kind, COMMONROAD_KIND);
        assert_eq!(ranked[1].outcome, RankOutcome { collision: false, min_ttc_s: Some(1.5), min_distance_m: 4.25 });
        assert_eq!(lib.rank_recorded(REPLAY_POLICY, Some(1)).expect("top 1").len(), 1);
        assert!(lib.rank_recorded("idm", None).expect("never driven").is_empty());
        let json = serde_json::to_value(&ranked[1]).expect("json");
        assert_eq!(json["params"], serde_json::json!({}));
        assert_eq!(json["ego_id"], 1);
        assert_eq!(json["benchmark_id"], "ZAM_Test-1_1_T-1");
        assert!(json.get("seed").is_none());
    }
}
