//! One scenario, two ways in: a library entry (`--db --id`) and the spec rebuilt from what `rank`
//! printed (`--spec`) must give the same episode and the same risk field; and the report of a run
//! agrees with its own library.

use crate::support::{generate, ok_json, ok_stdout, rank, risktwin, shown};
use serde_json::{Value, json};
use std::path::Path;
use tempfile::tempdir;

/// Writes the spec of a rank entry (kind, seed, params) as `name`.
fn spec_from_rank_entry(dir: &Path, name: &str, entry: &Value) {
    let spec = json!({"kind": entry["kind"], "seed": entry["seed"], "params": entry["params"]});
    std::fs::write(dir.join(name), serde_json::to_string_pretty(&spec).unwrap()).unwrap();
}

#[test]
fn library_entry_and_rebuilt_spec_simulate_alike() {
    let dir = tempdir().unwrap();
    generate(dir.path(), "lib.db", 10, 2);
    let ranked = rank(dir.path(), "lib.db");
    // The top entry of each kind, plus one that never closes in (min_ttc_s null).
    let mut picks: Vec<&Value> = Vec::new();
    for kind in ["cut-in", "emergency-braking", "pedestrian-crossing", "sensor-occlusion", "low-friction"] {
        picks.push(ranked.iter().find(|r| r["kind"] == kind).unwrap_or_else(|| panic!("no {kind} stored")));
    }
    picks.push(ranked.iter().find(|r| r["outcome"]["min_ttc_s"].is_null()).expect("seed 2 has a scenario without TTC"));
    for entry in picks {
        let id = entry["id"].as_str().unwrap();
        spec_from_rank_entry(dir.path(), "spec.json", entry);
        let by_id = ok_stdout(dir.path(), &["simulate", "--db", "lib.db", "--id", id, "--format", "json"]);
        let by_spec = ok_stdout(dir.path(), &["simulate", "--spec", "spec.json", "--format", "json"]);
        assert_eq!(by_id, by_spec, "scenario {id}: --db/--id and --spec disagree");
        // The episode is the one the library scored.
        let m: Value = serde_json::from_str(&by_id).unwrap();
        assert_eq!(m["collision"], entry["outcome"]["collision"], "{id}");
        assert_eq!(m["min_ttc_s"], entry["outcome"]["min_ttc_s"], "{id}");
        assert_eq!(m["min_distance_m"], entry["outcome"]["min_distance_m"], "{id}");
        assert_eq!(m["risk_score"], entry["risk"]["score"], "{id}");

        let field = |src: &[&str]| {
            let args = [src, &["--time", "1", "--cells", "24", "--format", "json"]].concat();
            ok_stdout(dir.path(), &args)
        };
        assert_eq!(
            field(&["risk-field", "--db", "lib.db", "--id", id]),
            field(&["risk-field", "--spec", "spec.json"]),
            "{id}: risk field"
        );
    }
}

#[test]
fn run_report_agrees_with_its_library() {
    let dir = tempdir().unwrap();
    let res = risktwin(dir.path(), &["run", "--quick", "--seed", "3", "--out", "R", "--format", "json"]);
    assert_eq!(res.status.code(), Some(0), "{}", shown(&res));
    // --format json: stdout is one document, the run's metrics.
    let printed: Value = serde_json::from_slice(&res.stdout).expect("run --format json prints one JSON document");
    let metrics: Value = serde_json::from_slice(&std::fs::read(dir.path().join("R/metrics.json")).unwrap()).unwrap();
    assert_eq!(printed, metrics);
    // The ranking in the report is the library's ranking.
    let top_k = metrics["config"]["top_k"].as_u64().expect("config.top_k").to_string();
    let top = ok_json(dir.path(), &["scenarios", "rank", "--db", "R/library.db", "--top", &top_k, "--format", "json"]);
    assert_eq!(metrics["top"], top);
    // Per-kind counts in the report add up to what the library holds.
    let stored: u64 = metrics["by_kind"].as_object().unwrap().values().map(|k| k["scenarios"].as_u64().unwrap()).sum();
    assert_eq!(stored, rank(dir.path(), "R/library.db").len() as u64);
}
