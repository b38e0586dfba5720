//! `scenarios regress`: the regression gate holds back a policy that drives worse than the
//! deployed version and lets through one that drives no worse.

use crate::support::{assert_input_error, generate, ok_json, ok_stdout, uint};
use serde_json::Value;
use tempfile::tempdir;

fn regress(dir: &std::path::Path, extra: &[&str]) -> Value {
    let args = ["scenarios", "regress", "--db", "lib.db", "--policy", "weak/policy.safetensors", "--per-kind", "4"];
    ok_json(dir, &[&args[..], extra, &["--format", "json"]].concat())
}

#[test]
fn a_barely_trained_policy_is_held_back_and_one_no_worse_is_pushed() {
    let dir = tempdir().unwrap();
    generate(dir.path(), "lib.db", 6, 5);
    // 4,096 steps of PPO: a policy that has not learnt to drive the route.
    ok_json(dir.path(), &["train", "--steps", "4096", "--variant", "base", "--out", "weak", "--format", "json"]);

    let held = regress(dir.path(), &[]);
    assert_eq!(held["decision"], "hold", "{held}");
    let reasons: Vec<&str> = held["reasons"].as_array().expect("reasons").iter().filter_map(Value::as_str).collect();
    assert!(reasons.iter().any(|r| r.starts_with("held-out set: ")), "{reasons:?}");
    let held_out = &held["held_out"];
    assert_eq!(uint(held_out, "scenarios"), 20, "4 per kind");
    let completion = |who: &str| held_out[who]["mean_route_completion"].as_f64().expect("completion");
    assert!(completion("candidate") < completion("deployed") - 0.02, "{held_out}");
    // The regression set is the library's: every scenario some driver collided in.
    let db = rusqlite::Connection::open(dir.path().join("lib.db")).expect("the library opens");
    let marked: i64 = db.query_row("SELECT COUNT(*) FROM regression", [], |r| r.get(0)).expect("a count");
    assert!(marked > 0, "the reference driver collides in one of these 30 generated scenarios");
    assert_eq!(uint(&held["regression"], "scenarios"), marked as u64);

    let same = regress(dir.path(), &["--against", "weak/policy.safetensors"]);
    assert_eq!(same["decision"], "push", "{same}");
    assert_eq!(same["reasons"], Value::Array(Vec::new()));
    for set in ["regression", "held_out"] {
        assert_eq!(same[set]["candidate"], same[set]["deployed"], "the same policy drives the same: {same}");
        assert_eq!(same[set]["newly_colliding"], Value::Array(Vec::new()));
    }
    // Any driver against any other: the policy's ONNX model (train writes it beside the file)
    // drives as the file, so the gate lets it through against it.
    let onnx = regress(dir.path(), &["--against", "weak/policy.onnx"]);
    assert_eq!(onnx["decision"], "push", "{onnx}");
    assert!(onnx["deployed"].as_str().is_some_and(|l| l.starts_with("weak/policy.onnx@")), "{onnx}");
    // The document's keys in the order docs/cli.md gives them.
    let args = ["scenarios", "regress", "--db", "lib.db", "--driver", "weak/policy.onnx", "--per-kind", "1"];
    let raw = ok_stdout(dir.path(), &[&args[..], &["--format", "json"]].concat());
    let top: Vec<&str> =
        raw.lines().filter_map(|l| l.strip_prefix("  \"")).filter_map(|l| l.split('"').next()).collect();
    let documented = ["decision", "reasons", "regression", "held_out", "completion_tolerance", "candidate", "deployed"];
    assert_eq!(top, documented, "{raw}");
}

#[test]
fn bad_gate_input_is_refused_by_name() {
    let dir = tempdir().unwrap();
    generate(dir.path(), "lib.db", 1, 5);
    let gate = |policy: &str, extra: &[&str], needle: &str| {
        let args = ["scenarios", "regress", "--db", "lib.db", "--policy", policy];
        assert_input_error(dir.path(), &[&args[..], extra].concat(), needle);
    };
    gate("missing.safetensors", &[], "driver missing.safetensors");
    gate("lib.db", &[], "unknown driver 'lib.db'");
    gate("missing.onnx", &[], "driver missing.onnx");
    gate("idm", &["--against", "replay"], "--against replay plays a recording's ego");
    gate("idm", &["--per-kind", "0"], "--per-kind 0 is out of range");
    let missing_db = ["scenarios", "regress", "--db", "missing.db", "--policy", "idm"];
    assert_input_error(dir.path(), &missing_db, "missing.db");
}
