//! `scenarios mutate`: children of a stored scenario, feasibility-checked, simulated with the
//! reference driver and stored as its mutations; the same draw twice stores nothing new.

use crate::support::{assert_input_error, generate, keys, ok_json, rank, uint};
use serde_json::Value;
use tempfile::tempdir;

fn mutate(dir: &std::path::Path, id: &str, count: &str, seed: &str) -> Value {
    let args = ["scenarios", "mutate", "--db", "lib.db", "--id", id, "--count", count, "--seed", seed];
    ok_json(dir, &[&args[..], &["--format", "json"]].concat())
}

fn child_ids(report: &Value) -> Vec<String> {
    let children = report["children"].as_array().expect("children");
    children.iter().map(|c| c["id"].as_str().expect("an id").to_owned()).collect()
}

#[test]
fn children_are_stored_with_their_parent_and_the_same_draw_is_the_same() {
    let dir = tempdir().unwrap();
    generate(dir.path(), "lib.db", 4, 5);
    let before = rank(dir.path(), "lib.db");
    let parent = before[0]["id"].as_str().expect("an id").to_owned();

    let report = mutate(dir.path(), &parent, "6", "3");
    let expected = ["children", "collisions", "duplicates", "infeasible", "kind", "parent", "requested", "stored"];
    assert_eq!(keys(&report), expected);
    assert_eq!(
        (report["parent"].as_str(), report["kind"].as_str()),
        (Some(parent.as_str()), before[0]["kind"].as_str())
    );
    let children = report["children"].as_array().expect("children");
    let infeasible: u64 = report["infeasible"].as_object().expect("by reason").values().filter_map(Value::as_u64).sum();
    assert_eq!(children.len() as u64 + infeasible, 6, "every draw is a child or counted infeasible: {report}");
    assert_eq!(uint(&report, "stored") + uint(&report, "duplicates"), children.len() as u64);
    assert!(uint(&report, "stored") > 0, "{report}");
    let risks: Vec<f64> = children.iter().map(|c| c["risk"].as_f64().expect("risk")).collect();
    assert!(risks.windows(2).all(|w| w[0] >= w[1]), "highest risk first: {risks:?}");

    // Stored: rank lists every child with the risk the report gave, of the parent's kind.
    let after = rank(dir.path(), "lib.db");
    assert_eq!(after.len() as u64, before.len() as u64 + uint(&report, "stored"));
    for child in children {
        let stored = after.iter().find(|r| r["id"] == child["id"]).unwrap_or_else(|| panic!("{child} is ranked"));
        assert_eq!(stored["risk"]["score"], child["risk"]);
        assert_eq!(stored["kind"], report["kind"]);
    }
    // ... as mutations of the parent, in the file itself.
    let db = rusqlite::Connection::open(dir.path().join("lib.db")).expect("the library opens");
    for id in child_ids(&report) {
        let (origin, parent_id): (String, String) = db
            .query_row("SELECT origin, parent_id FROM scenarios WHERE id = ?1", [&id], |r| Ok((r.get(0)?, r.get(1)?)))
            .expect("the child's row");
        assert_eq!((origin.as_str(), parent_id.as_str()), ("mutated", parent.as_str()));
    }

    // The same draw gives the same children and stores nothing new; another seed, others.
    let again = mutate(dir.path(), &parent, "6", "3");
    assert_eq!(child_ids(&again), child_ids(&report));
    assert_eq!((uint(&again, "stored"), uint(&again, "duplicates")), (0, children.len() as u64));
    let other = mutate(dir.path(), &parent, "6", "4");
    assert_ne!(child_ids(&other), child_ids(&report));
}

#[test]
fn bad_mutations_are_refused_by_name() {
    let dir = tempdir().unwrap();
    generate(dir.path(), "lib.db", 1, 5);
    let id = rank(dir.path(), "lib.db")[0]["id"].as_str().expect("an id").to_owned();
    let base = ["scenarios", "mutate", "--db", "lib.db", "--id"];
    assert_input_error(dir.path(), &[&base[..], &["nope"]].concat(), "no generated scenario 'nope'");
    assert_input_error(dir.path(), &[&base[..], &[&id, "--radius", "2"]].concat(), "--radius 2: mutation radius 2");
    assert_input_error(dir.path(), &[&base[..], &[&id, "--count", "0"]].concat(), "--count 0 is out of range");
    let missing = ["scenarios", "mutate", "--db", "missing.db", "--id", &id];
    assert_input_error(dir.path(), &missing, "missing.db");
}
