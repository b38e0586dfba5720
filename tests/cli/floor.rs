//! `scenarios floor`: the fields docs/cli.md promises, counts that add up, the same document
//! whatever the thread count, and bad flags refused with exit 2.

use crate::support::{assert_input_error, keys, num, ok_json, uint};
use serde_json::Value;
use tempfile::tempdir;

const KINDS: [&str; 5] = ["cut-in", "emergency-braking", "pedestrian-crossing", "sensor-occlusion", "low-friction"];
const FLOOR_KEYS: [&str; 4] = ["avoidable", "planner", "reference", "scenarios"];
const CASE_KEYS: [&str; 11] = [
    "avg_speed_mps",
    "ended",
    "id",
    "kind",
    "min_distance_m",
    "min_ttc_s",
    "reference_ended",
    "route_completion",
    "seed",
    "sim_steps",
    "verdict",
];

fn floor(threads: &str) -> Value {
    let dir = tempdir().unwrap();
    let args = ["scenarios", "floor", "--kind", "all", "--count", "1", "--seed", "3", "--threads", threads];
    ok_json(dir.path(), &[&args[..], &["--format", "json"]].concat())
}

/// Every per-kind or overall block: its keys and its arithmetic.
fn assert_floor_block(f: &Value, what: &str) {
    assert_eq!(keys(f), FLOOR_KEYS, "{what}");
    let (n, avoidable) = (uint(f, "scenarios"), uint(f, "avoidable"));
    assert!(avoidable <= n, "{what}: {f}");
    let planner = &f["planner"];
    assert_eq!(uint(planner, "episodes"), n, "{what}");
    assert!((num(planner, "success_rate") - avoidable as f64 / n as f64).abs() < 1e-12, "{what}: {f}");
    // Every drive ends in one of the four ways (a collision may also leave the road).
    let ends: f64 =
        ["success_rate", "collision_rate", "offroad_rate", "timeout_rate"].iter().map(|k| num(planner, k)).sum();
    assert!(ends >= 1.0 - 1e-9 && ends <= 1.0 + num(planner, "collision_rate") + 1e-9, "{what}: {f}");
    assert_eq!(uint(&f["reference"], "episodes"), n, "{what}");
}

#[test]
fn floor_json_adds_up_and_does_not_depend_on_threads() {
    let doc = floor("2");
    let mut top = keys(&doc);
    top.sort_unstable();
    assert_eq!(top, ["by_kind", "cases", "overall", "per_kind", "seed", "wall_s"]);
    assert_eq!((uint(&doc, "seed"), uint(&doc, "per_kind")), (3, 1));
    assert!(num(&doc, "wall_s") > 0.0);
    assert_floor_block(&doc["overall"], "overall");
    let mut kinds = keys(&doc["by_kind"]);
    kinds.sort_unstable();
    let mut expected = KINDS.to_vec();
    expected.sort_unstable();
    assert_eq!(kinds, expected);
    let cases = doc["cases"].as_array().expect("cases");
    assert_eq!(cases.len(), 5, "one held-out scenario per kind");
    let mut avoidable = 0;
    for kind in KINDS {
        let block = &doc["by_kind"][kind];
        assert_floor_block(block, kind);
        assert_eq!(uint(block, "scenarios"), 1, "{kind}");
        avoidable += uint(block, "avoidable");
    }
    assert_eq!(avoidable, uint(&doc["overall"], "avoidable"));
    for c in cases {
        assert_eq!(keys(c), CASE_KEYS, "{c}");
        let verdict = c["verdict"].as_str().unwrap();
        assert!(["avoidable", "not-found"].contains(&verdict), "{c}");
        // An avoidable drive completed the route without touching anything (verdict and `ended`
        // both come from the replay's success, so check it against the other fields).
        if verdict == "avoidable" {
            assert!(num(c, "route_completion") >= 1.0 - 1e-9, "{c}");
            assert!(num(c, "min_distance_m") > 0.0, "{c}");
        }
        // Out of time means short of the route's end.
        if c["ended"] == "out-of-time" {
            assert!(num(c, "route_completion") < 1.0, "{c}");
        }
        assert!(uint(c, "sim_steps") > 0, "{c}");
        assert!((0.0..=1.0).contains(&num(c, "route_completion")), "{c}");
    }
    assert_eq!(cases.iter().filter(|c| c["verdict"] == "avoidable").count() as u64, avoidable);

    let mut again = floor("1");
    let mut first = doc.clone();
    for d in [&mut first, &mut again] {
        d.as_object_mut().unwrap().remove("wall_s");
    }
    assert_eq!(first, again, "the floor changed with the thread count");
}

#[test]
fn floor_refuses_bad_flags() {
    let dir = tempdir().unwrap();
    let d = dir.path();
    let line = assert_input_error(d, &["scenarios", "floor", "--kind", "cutin"], "'cutin'");
    assert!(line.contains("cut-in"), "{line}");
    let line = assert_input_error(d, &["scenarios", "floor", "--count", "0"], "--count 0");
    assert!(line.contains("out of range"), "{line}");
    assert_input_error(d, &["scenarios", "floor", "--count", "-2"], "-2");
    assert_input_error(d, &["scenarios", "floor", "--count", "many"], "'many'");
    let line = assert_input_error(d, &["scenarios", "floor", "--threads", "0"], "--threads 0");
    assert!(line.contains("out of range"), "{line}");
    assert_input_error(d, &["scenarios", "floor", "--seed", "x"], "'x'");
    assert_input_error(d, &["scenarios", "floor", "--format", "xml"], "'xml'");
    assert_input_error(d, &["scenarios", "floor", "--db", "lib.db"], "--db");
}
