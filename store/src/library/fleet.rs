//! The closed loop's state in the library (schema version 3): scenarios pushed to fleet edges,
//! the episodes the fleet played (the edge's own outcome beside the twin's view of it) and the
//! policy versions the trainer produced. Every change is one transaction, so a cloud killed
//! at any point leaves a file whose pushes, episodes and outcomes agree.

use super::connection::ScenarioLibrary;
use super::error::LibraryError;
use super::rank::RankedScenario;
use super::record::{DEFAULT_POLICY, Outcome, validate_outcome};
use super::store::{insert_outcome, outcome_insert_sql};
use super::stored::{OUTCOME_COLUMN_COUNT, OUTCOME_COLUMNS, OutcomeRow};
use risktwin_common::telemetry::PolicyRef;
use rusqlite::{OptionalExtension, TransactionBehavior, params};
use std::path::Path;

/// The `policy` column of an outcome an edge reported: the reference driver's name, or
/// `<policy_id>/v<version>` for a pushed policy.
pub fn policy_label(policy: Option<&PolicyRef>) -> String {
    policy.map_or_else(|| DEFAULT_POLICY.to_owned(), |p| format!("{}/v{}", p.policy_id, p.version))
}

/// A scenario pushed to an edge whose result has not come back.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Push {
    pub seq: i64,
    pub scenario_id: String,
    pub site: String,
    pub edge: String,
    /// Times it was sent (1 + retries).
    pub attempts: u32,
}

/// One episode the fleet played, as the loop stores it.
#[derive(Debug, Clone, PartialEq)]
pub struct FleetEpisode {
    pub scenario_id: String,
    pub site: String,
    pub edge: String,
    /// The pushed policy that drove; `None`: the reference driver.
    pub policy: Option<PolicyRef>,
    /// The distributed scene the episode belonged to, if any.
    pub scene: Option<String>,
    /// The push it answers, when the loop sent it.
    pub push_seq: Option<i64>,
    /// What the edge reported (its `policy` is [`policy_label`] of `policy`).
    pub edge_outcome: Outcome,
    /// The twin's view of the same episode, when the twin watched it.
    pub twin_outcome: Option<Outcome>,
    /// Twin ticks the twin's view was scored from.
    pub twin_ticks: u64,
    /// Where the edge and the twin disagree, in words; `None` when they agree.
    pub disagreement: Option<String>,
}

/// A `fleet_episodes` row joined with its outcome rows, before the outcomes are checked.
struct EpisodeRow {
    seq: i64,
    scenario_id: String,
    site: String,
    edge: String,
    policy: Option<PolicyRef>,
    scene: Option<String>,
    push_seq: Option<i64>,
    twin_ticks: u64,
    disagreement: Option<String>,
    edge_outcome: OutcomeRow,
    twin_outcome: Option<OutcomeRow>,
}

/// A stored fleet episode.
#[derive(Debug, Clone, PartialEq)]
pub struct StoredFleetEpisode {
    pub seq: i64,
    pub episode: FleetEpisode,
}

/// What the library holds of the loop, for summaries and reports.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct FleetCounts {
    /// Generated scenarios in the library.
    pub scenarios: u64,
    /// Episodes the fleet played.
    pub episodes: u64,
    /// Of those, the ones the edge reported a collision or leaving the road in.
    pub failures: u64,
    /// Of those, the ones whose row says the twin disagrees.
    pub disagreements: u64,
    /// Pushes waiting for their result.
    pub outstanding: u64,
    /// Pushes given up.
    pub abandoned: u64,
}

impl ScenarioLibrary {
    /// Picks the riskiest scenario never pushed and notes it pushed to `site/edge`, in one
    /// transaction: two processes on one file cannot push the same scenario. `None` when every
    /// scenario has been pushed, or another process has a push outstanding at that edge.
    pub fn start_riskiest_push(
        &mut self,
        site: &str,
        edge: &str,
    ) -> Result<Option<(Push, RankedScenario)>, LibraryError> {
        let tx = self.conn.transaction_with_behavior(TransactionBehavior::Immediate)?;
        let Some(next) = ScenarioLibrary::riskiest_unpushed_in(&tx)? else { return Ok(None) };
        let inserted = tx.execute(
            "INSERT INTO pushes (scenario_id, site, edge, attempts, state) VALUES (?1, ?2, ?3, 1, 'outstanding')",
            params![next.id, site, edge],
        );
        match inserted {
            // Another process on this file has a push outstanding at that edge.
            Err(e) if e.sqlite_error_code() == Some(rusqlite::ErrorCode::ConstraintViolation) => return Ok(None),
            other => other?,
        };
        let seq = tx.last_insert_rowid();
        tx.commit()?;
        let push =
            Push { seq, scenario_id: next.id.clone(), site: site.to_owned(), edge: edge.to_owned(), attempts: 1 };
        Ok(Some((push, next)))
    }

    /// Counts one more attempt of outstanding push `seq`; its attempts so far.
    pub fn retry_push(&mut self, seq: i64) -> Result<u32, LibraryError> {
        let attempts: i64 = self.conn.query_row(
            "UPDATE pushes SET attempts = attempts + 1 WHERE seq = ?1 AND state = 'outstanding' RETURNING attempts",
            [seq],
            |r| r.get(0),
        )?;
        Ok(u32::try_from(attempts).unwrap_or(u32::MAX))
    }

    /// Gives outstanding push `seq` up: no result came after its attempts.
    pub fn abandon_push(&mut self, seq: i64) -> Result<(), LibraryError> {
        self.conn.execute("UPDATE pushes SET state = 'abandoned' WHERE seq = ?1 AND state = 'outstanding'", [seq])?;
        Ok(())
    }

    /// The pushes waiting for a result, oldest first.
    pub fn outstanding_pushes(&self) -> Result<Vec<Push>, LibraryError> {
        let mut stmt = self.conn.prepare_cached(
            "SELECT seq, scenario_id, site, edge, attempts FROM pushes WHERE state = 'outstanding' ORDER BY seq",
        )?;
        let rows = stmt.query_map([], |r| {
            Ok(Push {
                seq: r.get(0)?,
                scenario_id: r.get(1)?,
                site: r.get(2)?,
                edge: r.get(3)?,
                attempts: u32::try_from(r.get::<_, i64>(4)?).unwrap_or(u32::MAX),
            })
        })?;
        Ok(rows.collect::<Result<_, _>>()?)
    }

    /// Stores one fleet episode in one transaction: the edge's outcome (which ranks the
    /// scenario from now on and, on a collision, puts it in the regression set), the twin's, the
    /// episode row, and the end of the push it answers. The scenario must be in the library.
    pub fn record_fleet_episode(&mut self, e: &FleetEpisode) -> Result<i64, LibraryError> {
        let invalid = |source| LibraryError::InvalidRecord { id: e.scenario_id.clone(), source };
        validate_outcome(&e.edge_outcome).map_err(invalid)?;
        if let Some(twin) = &e.twin_outcome {
            validate_outcome(twin).map_err(invalid)?;
        }
        let tx = self.conn.transaction_with_behavior(TransactionBehavior::Immediate)?;
        let exists: bool =
            tx.query_row("SELECT EXISTS (SELECT 1 FROM scenarios WHERE id = ?1)", [&e.scenario_id], |r| r.get(0))?;
        if !exists {
            return Err(LibraryError::UnknownScenario(e.scenario_id.clone()));
        }
        let mut edge_stmt = tx.prepare_cached(&outcome_insert_sql("outcomes", "scenario_id"))?;
        insert_outcome(&mut edge_stmt, &e.scenario_id, &e.edge_outcome)?;
        drop(edge_stmt);
        let edge_seq = tx.last_insert_rowid();
        let twin_seq = match &e.twin_outcome {
            Some(twin) => {
                let mut twin_stmt = tx.prepare_cached(&outcome_insert_sql("twin_outcomes", "scenario_id"))?;
                insert_outcome(&mut twin_stmt, &e.scenario_id, twin)?;
                Some(tx.last_insert_rowid())
            }
            None => None,
        };
        if e.edge_outcome.metrics.collision {
            tx.execute(
                "INSERT INTO regression (scenario_id, reason, marked_seq) \
                 VALUES (?1, 'collision', (SELECT COALESCE(MAX(marked_seq), 0) + 1 FROM regression)) \
                 ON CONFLICT (scenario_id) DO NOTHING",
                [&e.scenario_id],
            )?;
        }
        tx.execute(
            "INSERT INTO fleet_episodes (scenario_id, site, edge, policy_id, policy_version, scene, push_seq, \
             edge_outcome_seq, twin_outcome_seq, twin_ticks, disagreement) \
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11)",
            params![
                e.scenario_id,
                e.site,
                e.edge,
                e.policy.as_ref().map(|p| &p.policy_id),
                e.policy.as_ref().map(|p| p.version),
                e.scene,
                e.push_seq,
                edge_seq,
                twin_seq,
                i64::try_from(e.twin_ticks).unwrap_or(i64::MAX),
                e.disagreement,
            ],
        )?;
        let seq = tx.last_insert_rowid();
        if let Some(push) = e.push_seq {
            tx.execute("UPDATE pushes SET state = 'done' WHERE seq = ?1", [push])?;
        }
        tx.commit()?;
        Ok(seq)
    }

    /// Every fleet episode, oldest first.
    pub fn fleet_episodes(&self) -> Result<Vec<StoredFleetEpisode>, LibraryError> {
        let columns_of = |table: &str| {
            std::iter::once("seq")
                .chain(OUTCOME_COLUMNS.split(", "))
                .map(|c| format!("{table}.{c}"))
                .collect::<Vec<_>>()
        };
        let (edge_columns, twin_columns) = (columns_of("o").join(", "), columns_of("t").join(", "));
        let mut stmt = self.conn.prepare_cached(&format!(
            "SELECT f.seq, f.scenario_id, f.site, f.edge, f.policy_id, f.policy_version, f.scene, f.push_seq, \
                    f.twin_ticks, f.disagreement, f.twin_outcome_seq IS NOT NULL, {edge_columns}, {twin_columns} \
             FROM fleet_episodes f JOIN outcomes o ON o.seq = f.edge_outcome_seq \
             LEFT JOIN twin_outcomes t ON t.seq = f.twin_outcome_seq ORDER BY f.seq"
        ))?;
        let columns = OUTCOME_COLUMN_COUNT + 1;
        let rows = stmt.query_map([], |r| {
            let policy = match (r.get::<_, Option<String>>(4)?, r.get::<_, Option<i64>>(5)?) {
                (Some(policy_id), Some(version)) => {
                    Some(PolicyRef { policy_id, version: u32::try_from(version).unwrap_or(u32::MAX) })
                }
                _ => None,
            };
            let watched: bool = r.get(10)?;
            Ok(EpisodeRow {
                seq: r.get(0)?,
                scenario_id: r.get(1)?,
                site: r.get(2)?,
                edge: r.get(3)?,
                policy,
                scene: r.get(6)?,
                push_seq: r.get(7)?,
                twin_ticks: r.get::<_, i64>(8)?.max(0) as u64,
                disagreement: r.get(9)?,
                edge_outcome: OutcomeRow::read_at(r, 11)?,
                twin_outcome: if watched { Some(OutcomeRow::read_at(r, 11 + columns)?) } else { None },
            })
        })?;
        rows.map(|row| {
            let row = row?;
            let episode = FleetEpisode {
                scenario_id: row.scenario_id,
                site: row.site,
                edge: row.edge,
                policy: row.policy,
                scene: row.scene,
                push_seq: row.push_seq,
                edge_outcome: row.edge_outcome.checked(&self.path, "outcomes")?,
                twin_outcome: row.twin_outcome.map(|t| t.checked(&self.path, "twin_outcomes")).transpose()?,
                twin_ticks: row.twin_ticks,
                disagreement: row.disagreement,
            };
            Ok(StoredFleetEpisode { seq: row.seq, episode })
        })
        .collect()
    }

    /// Counts of the loop's state.
    pub fn fleet_counts(&self) -> Result<FleetCounts, LibraryError> {
        let count = |sql: &str| -> Result<u64, LibraryError> {
            Ok(self.conn.query_row(sql, [], |r| r.get::<_, i64>(0))?.max(0) as u64)
        };
        Ok(FleetCounts {
            scenarios: count("SELECT COUNT(*) FROM scenarios")?,
            episodes: count("SELECT COUNT(*) FROM fleet_episodes")?,
            failures: count(
                "SELECT COUNT(*) FROM fleet_episodes f JOIN outcomes o ON o.seq = f.edge_outcome_seq \
                 WHERE o.collision = 1 OR o.offroad = 1",
            )?,
            disagreements: count("SELECT COUNT(*) FROM fleet_episodes WHERE disagreement IS NOT NULL")?,
            outstanding: count("SELECT COUNT(*) FROM pushes WHERE state = 'outstanding'")?,
            abandoned: count("SELECT COUNT(*) FROM pushes WHERE state = 'abandoned'")?,
        })
    }
}

/// A policy version the trainer produced, with the gate's decision.
#[derive(Debug, Clone, PartialEq)]
pub struct PolicyVersion {
    pub version: u32,
    pub policy_id: String,
    pub algo: String,
    /// The safetensors file, as pushed to the edges.
    pub weights: Vec<u8>,
    /// Whether the gate let it through (it is then the deployed version until a later one is).
    pub pushed: bool,
    /// Why the gate held it back (empty when pushed).
    pub reasons: Vec<String>,
    /// Fleet failures in the library when it was trained (the next one waits for more).
    pub failures: u64,
}

impl ScenarioLibrary {
    /// Stores a policy version and the gate's decision on it.
    pub fn record_policy(&mut self, p: &PolicyVersion) -> Result<(), LibraryError> {
        let reasons = serde_json::to_string(&p.reasons).expect("strings serialise");
        self.conn.execute(
            "INSERT INTO policies (version, policy_id, algo, weights, decision, reasons, failures) \
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)",
            params![
                p.version,
                p.policy_id,
                p.algo,
                p.weights,
                if p.pushed { "pushed" } else { "held-back" },
                reasons,
                i64::try_from(p.failures).unwrap_or(i64::MAX)
            ],
        )?;
        Ok(())
    }

    /// Every policy version, oldest first.
    pub fn policy_versions(&self) -> Result<Vec<PolicyVersion>, LibraryError> {
        self.policy_versions_where("1 ORDER BY version")
    }

    fn policy_versions_where(&self, filter: &str) -> Result<Vec<PolicyVersion>, LibraryError> {
        let mut stmt = self.conn.prepare_cached(&format!(
            "SELECT version, policy_id, algo, weights, decision, reasons, failures FROM policies WHERE {filter}"
        ))?;
        let rows = stmt.query_map([], |r| {
            Ok((
                r.get::<_, i64>(0)?,
                r.get::<_, String>(1)?,
                r.get::<_, String>(2)?,
                r.get::<_, Vec<u8>>(3)?,
                r.get::<_, String>(4)?,
                r.get::<_, String>(5)?,
                r.get::<_, i64>(6)?,
            ))
        })?;
        let mut out = Vec::new();
        for row in rows {
            let (version, policy_id, algo, weights, decision, reasons, failures) = row?;
            let corrupt = |reason: String| LibraryError::Corrupt { id: format!("policy version {version}"), reason };
            let reasons: Vec<String> =
                serde_json::from_str(&reasons).map_err(|e| corrupt(format!("reasons are not a JSON list: {e}")))?;
            out.push(PolicyVersion {
                version: u32::try_from(version).map_err(|_| corrupt("version out of range".into()))?,
                policy_id,
                algo,
                weights,
                pushed: decision == "pushed",
                reasons,
                failures: failures.max(0) as u64,
            });
        }
        Ok(out)
    }

    /// The latest policy version and the fleet failures it was trained at, if any.
    pub fn latest_policy(&self) -> Result<Option<(u32, u64)>, LibraryError> {
        let row: Option<(i64, i64)> = self
            .conn
            .query_row("SELECT version, failures FROM policies ORDER BY version DESC LIMIT 1", [], |r| {
                Ok((r.get(0)?, r.get(1)?))
            })
            .optional()?;
        Ok(row.map(|(v, f)| (u32::try_from(v).unwrap_or(u32::MAX), f.max(0) as u64)))
    }

    /// The version the fleet is driven by: the latest the gate let through.
    pub fn deployed_policy(&self) -> Result<Option<PolicyVersion>, LibraryError> {
        Ok(self.policy_versions_where("decision = 'pushed' ORDER BY version DESC LIMIT 1")?.pop())
    }

    /// A consistent copy of the whole library in a new file at `path` (`VACUUM INTO`): what a
    /// training run reads, as it was when the run was decided on.
    pub fn snapshot(&self, path: &Path) -> Result<(), LibraryError> {
        let path = path.to_str().ok_or_else(|| LibraryError::Corrupt {
            id: path.display().to_string(),
            reason: "a snapshot path must be UTF-8".into(),
        })?;
        self.conn.execute("VACUUM INTO ?1", [path])?;
        Ok(())
    }

    /// Forgets that policy `version` went to `site/edge` (the vehicle drove without it since:
    /// it restarted), so that it is sent again.
    pub fn forget_policy_delivery(&mut self, version: u32, site: &str, edge: &str) -> Result<(), LibraryError> {
        self.conn.execute(
            "DELETE FROM policy_pushes WHERE version = ?1 AND site = ?2 AND edge = ?3",
            params![version, site, edge],
        )?;
        Ok(())
    }

    /// Notes that policy `version` went to `site/edge`.
    pub fn note_policy_delivered(&mut self, version: u32, site: &str, edge: &str) -> Result<(), LibraryError> {
        self.conn.execute(
            "INSERT INTO policy_pushes (version, site, edge) VALUES (?1, ?2, ?3) ON CONFLICT DO NOTHING",
            params![version, site, edge],
        )?;
        Ok(())
    }

    /// Whether policy `version` went to `site/edge`.
    pub fn policy_delivered(&self, version: u32, site: &str, edge: &str) -> Result<bool, LibraryError> {
        Ok(self.conn.query_row(
            "SELECT EXISTS (SELECT 1 FROM policy_pushes WHERE version = ?1 AND site = ?2 AND edge = ?3)",
            params![version, site, edge],
            |r| r.get(0),
        )?)
    }
}

#[cfg(test)]
mod tests {
    use super::super::fixtures::{file_library, outcome, sampled};
    use super::super::{LibraryError, content_id};
    use super::*;
    use risktwin_common::scenario::ScenarioKind;

    fn episode(id: &str, push_seq: Option<i64>, collision: bool) -> FleetEpisode {
        let edge_outcome = outcome(0.5, collision, Some(1.5));
        let twin_outcome =
            Some(Outcome { risk: RiskTerms { score: 0.25, ..edge_outcome.risk }, ..edge_outcome.clone() });
        FleetEpisode {
            scenario_id: id.to_owned(),
            site: "s".into(),
            edge: "v1".into(),
            policy: None,
            scene: None,
            push_seq,
            edge_outcome,
            twin_outcome,
            twin_ticks: 120,
            disagreement: Some("S_risk: edge 0.500, twin 0.250".into()),
        }
    }
    use risktwin_common::risk::RiskTerms;

    #[test]
    fn pushes_go_riskiest_first_one_outstanding_per_edge_and_end_with_their_episode() {
        let (_dir, mut lib) = file_library();
        let records = [sampled(ScenarioKind::CutIn, 0, 0.2, false), sampled(ScenarioKind::CutIn, 1, 0.9, false)];
        lib.insert_batch(&records).expect("stored");
        let (low, high) = (content_id(&records[0].spec), content_id(&records[1].spec));
        assert_eq!(lib.riskiest_unpushed().expect("ranked").map(|r| r.id), Some(high.clone()));
        let (push, first) = lib.start_riskiest_push("s", "v1").expect("pushed").expect("a scenario");
        assert_eq!(first.id, high);
        assert_eq!(lib.riskiest_unpushed().expect("ranked").map(|r| r.id), Some(low.clone()), "pushed once only");
        // A second outstanding push to the same edge is refused by the schema; another edge is fine.
        assert_eq!(lib.start_riskiest_push("s", "v1").expect("checked"), None, "one outstanding per edge");
        let (other, second) = lib.start_riskiest_push("s", "v2").expect("another edge").expect("a scenario");
        assert_eq!(second.id, low);
        assert_eq!(lib.riskiest_unpushed().expect("ranked"), None);
        assert_eq!(lib.retry_push(push.seq).expect("retried"), 2);
        assert_eq!(
            lib.outstanding_pushes().expect("read").iter().find(|p| p.edge == "v1").map(|p| p.attempts),
            Some(2)
        );

        lib.record_fleet_episode(&episode(&high, Some(push.seq), true)).expect("stored");
        lib.abandon_push(other.seq).expect("given up");
        assert_eq!(lib.outstanding_pushes().expect("read"), []);
        let counts = lib.fleet_counts().expect("counts");
        assert_eq!(
            counts,
            FleetCounts { scenarios: 2, episodes: 1, failures: 1, disagreements: 1, outstanding: 0, abandoned: 1 }
        );
        // The edge's collision put the scenario in the regression set, and ranks it now.
        assert_eq!(lib.regression_set().expect("read").len(), 1);
        let stored = lib.fleet_episodes().expect("read");
        assert_eq!(stored.len(), 1);
        assert_eq!(stored[0].episode, episode(&high, Some(push.seq), true));
        assert!(lib.get(&high).expect("read").expect("held").outcomes.iter().any(|o| o.metrics.collision));
    }

    #[test]
    fn an_episode_of_an_unknown_scenario_or_with_a_bad_outcome_writes_nothing() {
        let (_dir, mut lib) = file_library();
        let rec = sampled(ScenarioKind::LowFriction, 0, 0.3, false);
        lib.insert_batch(std::slice::from_ref(&rec)).expect("stored");
        let id = content_id(&rec.spec);
        let (push, _) = lib.start_riskiest_push("s", "v1").expect("pushed").expect("the one scenario");
        assert!(matches!(
            lib.record_fleet_episode(&episode("feedfacefeedface", Some(push.seq), false)),
            Err(LibraryError::UnknownScenario(_))
        ));
        let mut bad = episode(&id, Some(push.seq), false);
        if let Some(twin) = bad.twin_outcome.as_mut() {
            twin.risk.score = 2.0;
        }
        assert!(matches!(lib.record_fleet_episode(&bad), Err(LibraryError::InvalidRecord { .. })));
        assert_eq!(lib.fleet_counts().expect("counts").episodes, 0);
        assert_eq!(lib.outstanding_pushes().expect("read").len(), 1, "the push is still outstanding");
        assert_eq!(lib.get(&id).expect("read").expect("held").outcomes.len(), 1, "no outcome added");
        // A policy's episode names its version, and its outcome the policy's label.
        let mut driven = episode(&id, Some(push.seq), false);
        driven.policy = Some(PolicyRef { policy_id: "ppo".into(), version: 3 });
        driven.edge_outcome.policy = policy_label(driven.policy.as_ref());
        lib.record_fleet_episode(&driven).expect("stored");
        assert_eq!(lib.fleet_episodes().expect("read")[0].episode.policy, driven.policy);
        assert_eq!(
            lib.get(&id).expect("read").expect("held").latest_outcome("ppo/v3").map(|o| o.risk.score),
            Some(0.5)
        );
    }

    #[test]
    fn policy_versions_keep_the_gate_decision_and_where_each_went() {
        let (_dir, mut lib) = file_library();
        let held = PolicyVersion {
            version: 1,
            policy_id: "risktwin-full".into(),
            algo: "ppo".into(),
            weights: vec![1, 2, 3],
            pushed: false,
            reasons: vec!["held-out set: 3 collisions against 1 of the deployed version".into()],
            failures: 5,
        };
        let pushed = PolicyVersion { version: 2, pushed: true, reasons: Vec::new(), failures: 9, ..held.clone() };
        assert_eq!(lib.latest_policy().expect("read"), None);
        lib.record_policy(&held).expect("stored");
        assert_eq!(lib.deployed_policy().expect("read"), None, "held back: not deployed");
        lib.record_policy(&pushed).expect("stored");
        assert!(lib.record_policy(&pushed).is_err(), "a version is stored once");
        assert_eq!(lib.policy_versions().expect("read"), [held, pushed]);
        assert!(!lib.policy_delivered(2, "s", "v1").expect("read"));
        lib.note_policy_delivered(2, "s", "v1").expect("noted");
        lib.note_policy_delivered(2, "s", "v1").expect("noted twice is once");
        assert!(lib.policy_delivered(2, "s", "v1").expect("read"));
        assert!(!lib.policy_delivered(2, "s", "v2").expect("read"));
        assert!(lib.note_policy_delivered(7, "s", "v1").is_err(), "an unknown version");
        lib.forget_policy_delivery(2, "s", "v1").expect("forgotten");
        assert!(!lib.policy_delivered(2, "s", "v1").expect("read"));
        assert_eq!(lib.latest_policy().expect("read"), Some((2, 9)));
        assert_eq!(lib.deployed_policy().expect("read").map(|p| p.version), Some(2));
        let dir = tempfile::tempdir().expect("tempdir");
        let copy = dir.path().join("snapshot.db");
        lib.snapshot(&copy).expect("copied");
        let copy = ScenarioLibrary::open(&copy).expect("a library");
        assert_eq!(copy.policy_versions().expect("read"), lib.policy_versions().expect("read"));
    }
}
