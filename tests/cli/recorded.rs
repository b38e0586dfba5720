//! Recorded CommonRoad scenarios as validation cases in the library: `import commonroad --db`,
//! `scenarios rank --kind commonroad`, and `simulate`/`risk-field --db --id` giving byte for byte
//! what `--commonroad` gives on the original file.

use crate::support::{assert_input_error, generate, num, ok_json, ok_stdout, rank};
use serde_json::Value;
use std::path::{Path, PathBuf};
use tempfile::tempdir;

fn fixture(name: &str) -> String {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/crime").join(name);
    p.to_str().expect("fixture path is UTF-8").to_string()
}

/// `import commonroad XML --db DB [--ego ID] --format json`.
fn import(dir: &Path, xml: &str, db: &str, ego: Option<&str>) -> Value {
    let mut args = vec!["import", "commonroad", xml, "--db", db, "--format", "json"];
    if let Some(ego) = ego {
        args.extend(["--ego", ego]);
    }
    ok_json(dir, &args)
}

fn rank_recorded(dir: &Path, db: &str) -> Vec<Value> {
    match ok_json(dir, &["scenarios", "rank", "--db", db, "--kind", "commonroad", "--format", "json"]) {
        Value::Array(a) => a,
        other => panic!("rank output is not an array: {other}"),
    }
}

/// Rows of one table of the library file.
fn count_rows(db: &Path, sql: &str) -> i64 {
    let conn = rusqlite::Connection::open(db).expect("open the library file");
    conn.query_row(sql, [], |r| r.get(0)).expect("count")
}

#[test]
fn imported_cases_rank_by_risk_and_replay_byte_for_byte() {
    let dir = tempdir().unwrap();
    let (cutin, pula) = (fixture("OSC_CutIn-1_2_T-1.xml"), fixture("HRV_Pula-27_3_T-1.xml"));
    let a = import(dir.path(), &cutin, "lib.db", None);
    let b = import(dir.path(), &pula, "lib.db", Some("34"));
    assert_eq!((&a["ego_id"], &b["ego_id"]), (&Value::from(3), &Value::from(34)), "{a}\n{b}");
    assert_eq!(a["benchmark_id"], "ZAM_OpenDrive-1");
    assert_eq!(b["benchmark_id"], "HRV_Pula-27_3_T-1");
    assert_eq!((&a["inserted"], &b["inserted"]), (&Value::Bool(true), &Value::Bool(true)));
    // The reference outcome is the replayed ego: `simulate --policy replay`'s document, field
    // for field, inside the import report.
    for (report, xml, ego) in [(&a, &cutin, "3"), (&b, &pula, "34")] {
        let replay = ok_json(
            dir.path(),
            &["simulate", "--commonroad", xml, "--ego", ego, "--policy", "replay", "--format", "json"],
        );
        for (key, value) in replay.as_object().expect("simulate document") {
            assert_eq!(&report[key], value, "{key} of {xml}");
        }
        assert_eq!(report["risk"]["score"], report["risk_score"]);
    }

    let ranked = rank_recorded(dir.path(), "lib.db");
    assert_eq!(ranked.len(), 2, "{ranked:?}");
    let (first, second) = if num(&a, "risk_score") >= num(&b, "risk_score") { (&a, &b) } else { (&b, &a) };
    for (item, report) in ranked.iter().zip([first, second]) {
        assert_eq!(item["id"], report["id"]);
        assert_eq!(item["kind"], "commonroad");
        assert_eq!(item["ego_id"], report["ego_id"]);
        assert_eq!(item["benchmark_id"], report["benchmark_id"]);
        assert_eq!(item["params"], serde_json::json!({}));
        assert_eq!(item["risk"], report["risk"]);
        assert_eq!(item["outcome"]["min_ttc_s"], report["min_ttc_s"]);
        assert_eq!(item["outcome"]["min_distance_m"], report["min_distance_m"]);
        assert_eq!(item["outcome"]["collision"], report["collision"]);
    }
    assert!(num(&ranked[0]["risk"], "score") > num(&ranked[1]["risk"], "score"), "{ranked:?}");
    let top = ok_json(
        dir.path(),
        &["scenarios", "rank", "--db", "lib.db", "--kind", "commonroad", "--top", "1", "--format", "json"],
    );
    assert_eq!(top.as_array().map(Vec::len), Some(1), "{top}");

    // The stored case is the file: same bytes out, every format, both policies.
    for (report, xml, ego) in [(&a, &cutin, "3"), (&b, &pula, "34")] {
        let id = report["id"].as_str().expect("id");
        for policy in ["replay", "idm"] {
            for format in ["json", "table", "csv"] {
                let from_db = ok_stdout(
                    dir.path(),
                    &["simulate", "--db", "lib.db", "--id", id, "--policy", policy, "--format", format],
                );
                let from_file = ok_stdout(
                    dir.path(),
                    &["simulate", "--commonroad", xml, "--ego", ego, "--policy", policy, "--format", format],
                );
                assert_eq!(from_db, from_file, "{xml} {policy} {format}");
            }
        }
        let field = |source: &[&str]| {
            let mut args = vec!["risk-field"];
            args.extend_from_slice(source);
            args.extend(["--time", "1.5", "--cells", "64", "--format", "json"]);
            ok_stdout(dir.path(), &args)
        };
        assert_eq!(field(&["--db", "lib.db", "--id", id]), field(&["--commonroad", xml, "--ego", ego]), "{xml}");
    }
    // Without --ego the file's default ego is the one stored at import.
    let id = a["id"].as_str().expect("id");
    assert_eq!(
        ok_stdout(dir.path(), &["simulate", "--db", "lib.db", "--id", id, "--format", "json"]),
        ok_stdout(dir.path(), &["simulate", "--commonroad", &cutin, "--format", "json"])
    );

    // The idm runs above were stored on their cases under the policy label, once each (the
    // runs are deterministic, so repeating one adds nothing); the reference is untouched.
    let db = dir.path().join("lib.db");
    assert_eq!(count_rows(&db, "SELECT COUNT(*) FROM recorded_outcomes WHERE policy = 'idm'"), 2);
    assert_eq!(count_rows(&db, "SELECT COUNT(*) FROM recorded_outcomes WHERE policy = 'replay'"), 2);
    assert_eq!(rank_recorded(dir.path(), "lib.db"), ranked);
}

#[test]
fn importing_again_is_one_case_and_the_default_rank_does_not_change() {
    let dir = tempdir().unwrap();
    generate(dir.path(), "lib.db", 2, 5);
    let default_rank = ok_stdout(dir.path(), &["scenarios", "rank", "--db", "lib.db", "--format", "json"]);
    let all_table = ok_stdout(dir.path(), &["scenarios", "rank", "--db", "lib.db", "--kind", "all"]);
    let xml = fixture("BEL_Putte-8_2_T-1.xml");
    let first = import(dir.path(), &xml, "lib.db", Some("33"));
    let again = import(dir.path(), &xml, "lib.db", Some("33"));
    assert_eq!(first["id"], again["id"]);
    assert_eq!(again["inserted"], false);
    let db = dir.path().join("lib.db");
    assert_eq!(count_rows(&db, "SELECT COUNT(*) FROM recorded"), 1);
    assert_eq!(count_rows(&db, "SELECT COUNT(*) FROM recorded_outcomes"), 1);
    // Another ego of the same file is another case.
    let other_ego = import(dir.path(), &xml, "lib.db", Some("35"));
    assert_ne!(other_ego["id"], first["id"]);
    assert_eq!(count_rows(&db, "SELECT COUNT(*) FROM recorded"), 2);
    // Recorded cases stay out of the generated ranking: same bytes as before the imports.
    assert_eq!(ok_stdout(dir.path(), &["scenarios", "rank", "--db", "lib.db", "--format", "json"]), default_rank);
    assert_eq!(ok_stdout(dir.path(), &["scenarios", "rank", "--db", "lib.db", "--kind", "all"]), all_table);
    assert!(!rank(dir.path(), "lib.db").is_empty());
    assert_eq!(rank_recorded(dir.path(), "lib.db").len(), 2);
    // Both destinations at once: the recording and the case in one report.
    let both = ok_json(
        dir.path(),
        &["import", "commonroad", &xml, "--out", "putte.mcap", "--db", "lib.db", "--ego", "33", "--format", "json"],
    );
    assert!(both["messages"].as_u64().unwrap_or(0) > 10, "{both}");
    assert_eq!((&both["id"], &both["inserted"]), (&first["id"], &Value::Bool(false)));
    assert!(dir.path().join("putte.mcap").is_file());
}

#[test]
fn bad_ids_files_and_stored_xml_are_input_errors() {
    let dir = tempdir().unwrap();
    let xml = fixture("OSC_CutIn-1_2_T-1.xml");
    let id = import(dir.path(), &xml, "lib.db", None)["id"].as_str().expect("id").to_string();
    for command in ["simulate", "risk-field"] {
        assert_input_error(dir.path(), &[command, "--db", "lib.db", "--id", "0123456789abcdef"], "0123456789abcdef");
        assert_input_error(dir.path(), &[command, "--db", "missing.db", "--id", &id], "missing.db");
    }
    assert!(!dir.path().join("missing.db").exists());
    assert_input_error(dir.path(), &["simulate", "--db", "lib.db", "--id", &id, "--ego", "4"], "--ego 4");
    assert_input_error(
        dir.path(),
        &["simulate", "--db", "lib.db", "--id", &id, "--policy", "ppo"],
        "unknown driver 'ppo'",
    );
    assert_input_error(dir.path(), &["risk-field", "--db", "lib.db", "--id", &id, "--time", "9999"], "case");
    assert_input_error(dir.path(), &["import", "commonroad", &xml], "--out");
    // Nothing is created when the file or the ego is bad.
    assert_input_error(dir.path(), &["import", "commonroad", "/nonexistent/s.xml", "--db", "new.db"], "cannot read");
    assert_input_error(dir.path(), &["import", "commonroad", &xml, "--db", "new.db", "--ego", "424242"], "424242");
    assert!(!dir.path().join("new.db").exists());
    let not_xml = crate::support::write_file(dir.path(), "broken.xml", "<commonRoad><lanelet");
    assert_input_error(
        dir.path(),
        &["import", "commonroad", not_xml.to_str().unwrap(), "--db", "new.db"],
        "broken.xml",
    );
    assert!(!dir.path().join("new.db").exists());

    // A stored case whose XML was damaged in the file: a clear error, no panic.
    let conn = rusqlite::Connection::open(dir.path().join("lib.db")).expect("open");
    conn.execute("UPDATE recorded SET xml = '<commonRoad><lanelet' WHERE id = ?1", [&id]).expect("corrupt");
    drop(conn);
    for command in ["simulate", "risk-field"] {
        let line = assert_input_error(dir.path(), &[command, "--db", "lib.db", "--id", &id], "does not parse");
        assert!(line.contains(&id) && line.contains("lib.db"), "{line}");
    }
}
