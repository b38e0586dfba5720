//! `risktwin evaluate`: any driver on the held-out set or a library's scenarios, with
//! intervals; `risktwin train`'s ONNX model drives as its policy file for every algorithm; bad
//! models exit 2 by name.

use crate::support::{assert_input_error, generate, ok_json, ok_stdout, write_file};
use serde_json::Value;
use std::path::Path;
use tempfile::tempdir;

/// Largest difference of a continuous metric between a policy file and its ONNX model over the
/// held-out episodes: tract's tanh and sigmoid round differently from the host's in the last
/// bits, and the difference grows along an episode (measured: below 1e-4 for these policies).
const METRIC_TOLERANCE: f64 = 1e-3;

fn train(dir: &Path, algo: &str, out: &str) {
    let args = ["train", "--algo", algo, "--steps", "2048", "--variant", "base", "--seed", "2", "--out", out];
    ok_json(dir, &[&args[..], &["--format", "json"]].concat());
}

fn evaluate(dir: &Path, driver: &str, extra: &[&str]) -> Value {
    let args = ["evaluate", "--driver", driver, "--held-out", "--seed", "5", "--per-kind", "3", "--format", "json"];
    ok_json(dir, &[&args[..], extra].concat())
}

#[test]
fn trains_onnx_model_drives_as_its_policy_file_for_every_algorithm() {
    let dir = tempdir().unwrap();
    for algo in ["ppo", "ppo-gru", "sac"] {
        train(dir.path(), algo, algo);
        let native = evaluate(dir.path(), &format!("{algo}/policy.safetensors"), &[]);
        let onnx = evaluate(dir.path(), &format!("{algo}/policy.onnx"), &[]);
        assert_eq!(onnx["model_faults"], 0);
        let (a, b) = (native["episodes"].as_array().unwrap(), onnx["episodes"].as_array().unwrap());
        assert_eq!(a.len(), 15, "3 per kind");
        let mut worst = 0.0f64;
        for (x, y) in a.iter().zip(b) {
            assert_eq!(x["id"], y["id"]);
            assert_eq!(x["ended"], y["ended"], "{algo}: the same outcome in {}", x["id"]);
            assert_eq!(x["metrics"]["steps"], y["metrics"]["steps"], "{algo}: {}", x["id"]);
            for (key, v) in x["metrics"].as_object().unwrap() {
                if let (Some(p), Some(q)) = (v.as_f64(), y["metrics"][key].as_f64()) {
                    worst = worst.max((p - q).abs() / p.abs().max(1.0));
                }
            }
        }
        assert!(worst < METRIC_TOLERANCE, "{algo}: metrics differ by up to {worst}");
        eprintln!("{algo}: largest metric difference, policy file against ONNX: {worst:.2e}");
    }
}

#[test]
fn the_document_has_per_kind_shares_with_intervals_the_reference_and_the_floor() {
    let dir = tempdir().unwrap();
    let v = evaluate(dir.path(), "idm", &["--floor"]);
    assert_eq!(v["driver"], "idm");
    assert_eq!(v["set"], serde_json::json!({"source": "held-out", "seed": 5, "per_kind": 3}));
    assert_eq!(v["confidence"], 0.95);
    let kinds = v["by_kind"].as_object().unwrap();
    assert_eq!(kinds.len(), 5);
    for (kind, c) in kinds.iter().chain([(&"all".to_owned(), &v["overall"])]) {
        assert_eq!(c["driver"], c["reference"], "{kind}: idm is the reference");
        for share in ["collision", "success", "offroad", "out_of_time"] {
            let s = &c["driver"][share];
            let (p, lo, hi) = (s["share"].as_f64().unwrap(), s["low"].as_f64().unwrap(), s["high"].as_f64().unwrap());
            assert!(lo <= p && p <= hi && 0.0 <= lo && hi <= 1.0 && hi > lo, "{kind} {share}: {s}");
        }
        let avoidable = &c["floor"]["avoidable"];
        assert!(avoidable["count"].as_u64().unwrap() <= avoidable["episodes"].as_u64().unwrap(), "{c}");
    }
    assert_eq!(v["overall"]["driver"]["episodes"], 15);
    // Same flags → same bytes; the thread count does not matter.
    let args = ["evaluate", "--driver", "idm", "--held-out", "--seed", "5", "--per-kind", "3", "--format", "json"];
    let once = ok_stdout(dir.path(), &args);
    assert_eq!(once, ok_stdout(dir.path(), &[&args[..], &["--threads", "1"]].concat()));
}

#[test]
fn a_library_evaluation_stores_outcomes_under_the_label_and_writes_a_report() {
    let dir = tempdir().unwrap();
    let stored = generate(dir.path(), "lib.db", 2, 3)["stored"].as_u64().expect("stored");
    train(dir.path(), "ppo", "p");
    let v = ok_json(
        dir.path(),
        &["evaluate", "--driver", "p/policy.onnx", "--db", "lib.db", "--out", "report", "--format", "json"],
    );
    let label = v["driver"].as_str().unwrap().to_owned();
    assert!(label.starts_with("p/policy.onnx@") && label.len() == "p/policy.onnx@".len() + 12, "{label}");
    assert_eq!(v["set"]["source"], "library");
    assert_eq!(v["overall"]["driver"]["episodes"], stored, "every scenario of the library");
    let db = rusqlite::Connection::open(dir.path().join("lib.db")).unwrap();
    let outcomes: i64 =
        db.query_row("SELECT COUNT(*) FROM outcomes WHERE policy = ?1", [&label], |r| r.get(0)).unwrap();
    assert_eq!(outcomes as u64, stored);
    // The library ranks by that driver's outcomes: every scenario, each with its episode's
    // collision (the reference driver's ranking stays its own).
    let ranked =
        ok_json(dir.path(), &["scenarios", "rank", "--db", "lib.db", "--driver", "p/policy.onnx", "--format", "json"]);
    let ranked = ranked.as_array().expect("an array");
    assert_eq!(ranked.len() as u64, stored);
    let episodes = v["episodes"].as_array().expect("episodes");
    for item in ranked {
        let episode = episodes.iter().find(|e| e["id"] == item["id"]).expect("ranked scenarios were driven");
        assert_eq!(item["outcome"]["collision"], episode["metrics"]["collision"], "{item}");
    }
    // The same file by another path is the same driver (its digest); replay is no generated
    // scenario's driver.
    let by_other_path = ["scenarios", "rank", "--db", "lib.db", "--driver", "./p/../p/policy.onnx", "--format", "json"];
    assert_eq!(&ok_json(dir.path(), &by_other_path), &Value::Array(ranked.clone()));
    let args = ["scenarios", "rank", "--db", "lib.db", "--driver", "replay"];
    assert_input_error(dir.path(), &args, "--kind commonroad");
    for file in ["report.md", "metrics.json", "collision.png", "success.png"] {
        assert!(dir.path().join("report").join(file).is_file(), "{file}");
    }
    let metrics: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("report/metrics.json")).unwrap()).unwrap();
    assert_eq!(metrics, v);
    let md = std::fs::read_to_string(dir.path().join("report/report.md")).unwrap();
    assert!(md.contains(&label) && md.contains(&format!("| all | {stored} |")), "{md}");
}

#[test]
fn bad_models_and_flags_exit_2_by_name() {
    let dir = tempdir().unwrap();
    train(dir.path(), "ppo", "p");
    let eval = |driver: &str, needle: &str| assert_input_error(dir.path(), &["evaluate", "--driver", driver], needle);
    let onnx = std::fs::read(dir.path().join("p/policy.onnx")).unwrap();
    std::fs::write(dir.path().join("half.onnx"), &onnx[..onnx.len() / 2]).unwrap();
    eval("half.onnx", "driver half.onnx: not an ONNX model");
    std::fs::copy(dir.path().join("p/policy.safetensors"), dir.path().join("st.onnx")).unwrap();
    eval("st.onnx", "driver st.onnx: not an ONNX model");
    write_file(dir.path(), "empty.onnx", "");
    eval("empty.onnx", "driver empty.onnx: not an ONNX model: no graph");
    eval("missing.onnx", "driver missing.onnx");
    eval("replay", "--driver replay plays a recording's ego");
    eval("model.pt", "unknown driver 'model.pt'");
    let args = ["evaluate", "--driver", "idm", "--per-kind", "0"];
    assert_input_error(dir.path(), &args, "--per-kind 0 is out of range");
    assert_input_error(
        dir.path(),
        &["evaluate", "--driver", "idm", "--db", "none.db"],
        "no scenario library at none.db",
    );
    // A held-out set's flags have nothing to choose among recordings.
    for (flag, value) in [("--seed", "3"), ("--per-kind", "2")] {
        for (set, of) in [("--commonroad", "x.xml"), ("--db", "lib.db")] {
            let args = ["evaluate", "--driver", "idm", set, of, flag, value];
            assert_input_error(dir.path(), &args, "cannot be used with");
        }
    }
    let args = ["evaluate", "--driver", "idm", "--per-kind", "1", "--format", "csv"];
    assert_input_error(dir.path(), &args, "not CSV");
}

#[test]
fn commonroad_recordings_are_evaluated_closed_loop_beside_the_reference_driver() {
    let dir = tempdir().unwrap();
    train(dir.path(), "ppo", "p");
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/crime");
    let files: Vec<String> = ["OSC_CutIn-1_2_T-1.xml", "BEL_Putte-8_2_T-1.xml"]
        .iter()
        .map(|f| fixtures.join(f).to_str().expect("UTF-8").to_owned())
        .collect();
    let files: Vec<&str> = files.iter().map(String::as_str).collect();
    let run = |driver: &str| {
        ok_json(
            dir.path(),
            &[&["evaluate", "--driver", driver, "--format", "json", "--commonroad"][..], &files].concat(),
        )
    };
    let v = run("p/policy.onnx");
    assert_eq!(v["set"]["source"], "commonroad");
    assert_eq!(v["by_kind"].as_object().unwrap().keys().collect::<Vec<_>>(), ["commonroad"]);
    assert_eq!(v["overall"]["driver"]["episodes"], 2);
    assert!(v["episodes"].as_array().unwrap().iter().all(|e| e["seed"].is_null() && e["kind"] == "commonroad"));
    let replay = run("replay");
    assert_eq!(replay["driver"], "replay");
    assert_ne!(replay["overall"]["driver"], replay["overall"]["reference"], "replay is not the reference driver");
    assert_eq!(v["overall"]["reference"], replay["overall"]["reference"]);
    let args = ["evaluate", "--driver", "idm", "--floor", "--commonroad", files[0]];
    assert_input_error(dir.path(), &args, "--floor");
}
