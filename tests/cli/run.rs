//! `risktwin run`: the report folder of a quick run (every file, PNGs that decode, per-variant
//! per-kind metrics with their spread over seeds, the computed verdict, the achievable floor of
//! the held-out set, the closed loop over Zenoh with its edge results), byte-identical
//! metrics.json for the same seed, SAC by flag (its policy pushed to the edge too), and the
//! push phase switched off.

use crate::support::{assert_input_error, num, risktwin, shown, write_file};
use serde_json::Value;
use std::path::Path;
use tempfile::tempdir;

/// The metric keys of metrics.json. Spelled out here on purpose rather than taken from
/// `risktwin_cloud::trainer::stats::METRIC_NAMES`: the file's keys are the output contract
/// (docs/cli.md), and a test that read the list from the library would follow a rename instead
/// of catching it.
const METRICS: [&str; 8] = [
    "reward",
    "success_rate",
    "route_completion",
    "collision_rate",
    "avg_speed_mps",
    "steering_smoothness",
    "longitudinal_smoothness",
    "risk_score",
];
const KINDS: [&str; 5] = ["cut-in", "emergency-braking", "pedestrian-crossing", "sensor-occlusion", "low-friction"];

/// Decodes a PNG fully and returns its size.
fn decode_png(path: &Path) -> (u32, u32) {
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut reader = png::Decoder::new(std::io::BufReader::new(file)).read_info().expect("PNG header");
    let mut buf = vec![0; reader.output_buffer_size().expect("buffer size")];
    let info = reader.next_frame(&mut buf).expect("PNG data");
    (info.width, info.height)
}

fn run_ok(dir: &Path, args: &[&str]) -> Value {
    let res = risktwin(dir, args);
    assert_eq!(res.status.code(), Some(0), "{}", shown(&res));
    let out = dir.join(args[args.iter().position(|a| *a == "--out").expect("--out") + 1]);
    serde_json::from_slice(&std::fs::read(out.join("metrics.json")).expect("metrics.json")).expect("JSON")
}

fn assert_spread(v: &Value, what: &str) {
    for m in METRICS {
        let s = &v[m];
        for k in ["mean", "std", "min", "max"] {
            assert!(s[k].is_f64() || s[k].is_u64(), "{what}.{m}.{k} missing: {s}");
        }
        let (mean, min, max) = (s["mean"].as_f64().unwrap(), s["min"].as_f64().unwrap(), s["max"].as_f64().unwrap());
        assert!(min <= mean + 1e-12 && mean <= max + 1e-12, "{what}.{m}: {s}");
        assert!(s["std"].as_f64().unwrap() >= 0.0);
    }
}

#[test]
fn quick_run_writes_the_report_folder_and_repeats_byte_for_byte() {
    let dir = tempdir().unwrap();
    let m = run_ok(dir.path(), &["run", "--quick", "--seed", "7", "--out", "A"]);
    let folder = dir.path().join("A");
    for f in ["report.md", "metrics.json", "library.db", "training_curves.png", "ablation.png"] {
        assert!(folder.join(f).is_file(), "no {f} in the report folder");
    }
    assert!(std::fs::read(folder.join("library.db")).unwrap().starts_with(b"SQLite format 3\0"));
    let heatmaps: Vec<String> = std::fs::read_dir(&folder)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n.starts_with("risk_field_") && n.ends_with(".png"))
        .collect();
    assert!(!heatmaps.is_empty(), "no risk_field_*.png");
    for png in heatmaps.iter().map(String::as_str).chain(["training_curves.png", "ablation.png"]) {
        let (w, h) = decode_png(&folder.join(png));
        assert!(w >= 100 && h >= 100, "{png} is {w}×{h}");
    }

    let ab = &m["ablation"];
    let variants = ab["variants"].as_array().expect("variants");
    let names: Vec<&str> = variants.iter().map(|v| v["variant"].as_str().unwrap()).collect();
    assert_eq!(names, ["base", "risk-only", "full", "ttc"]);
    assert_eq!(m["training_seeds"].as_array().unwrap().len(), 3);
    for v in variants {
        let name = v["variant"].as_str().unwrap();
        assert_spread(&v["overall"], name);
        for k in KINDS {
            assert_spread(&v["by_kind"][k], &format!("{name}.{k}"));
        }
        assert_eq!(v["seeds"].as_array().unwrap().len(), 3, "{name}");
        assert!(!v["curve"].as_array().unwrap().is_empty(), "{name} has no training curve");
    }
    // full refreshed its training set from the library between its two phases, in every seed.
    for seed in variants[2]["seeds"].as_array().unwrap() {
        let refreshes = seed["refreshes"].as_array().unwrap();
        assert_eq!(refreshes.len(), 1, "{seed}");
        assert!(refreshes[0]["evaluated"].as_u64().unwrap() > 0);
    }
    for v in variants.iter().filter(|v| v["variant"] != "full") {
        assert!(v["seeds"][0]["refreshes"].as_array().unwrap().is_empty());
    }
    assert_eq!(ab["held_out_episodes"].as_u64(), Some(10));
    let verdict = &m["verdict"];
    let sentence = verdict["sentences"][0].as_str().expect("a verdict sentence");
    assert!(sentence.starts_with("Target met") || sentence.starts_with("Target not met"), "{sentence}");
    assert_eq!(sentence.starts_with("Target met"), verdict["target_met"].as_bool().unwrap());
    // Every learned variant against the reference driver, in a sentence of its own.
    let against = verdict["sentences"].as_array().unwrap().iter().filter_map(|s| s.as_str()).find(|s| {
        s.starts_with("Every learned variant collides at most") || s.starts_with("Against the reference driver")
    });
    let against = against.expect("a sentence on the variants against the reference driver");
    assert_eq!(against.starts_with("Every"), verdict["every_variant_beats_reference"].as_bool().unwrap(), "{against}");
    let report = std::fs::read_to_string(folder.join("report.md")).unwrap();
    assert!(report.contains(sentence), "report.md lacks the computed verdict");
    assert!(report.contains("training_curves.png") && report.contains("ablation.png"));
    // The achievable floor of the same held-out set, per kind, with the variants against it.
    let floor = &m["floor"];
    let cases = floor["cases"].as_array().expect("floor.cases");
    assert_eq!(cases.len(), 10);
    // The reference driver's result is `ablation.reference` alone; the cases' endings are its episodes.
    assert!(floor.get("reference").is_none(), "floor repeats the reference driver");
    for k in KINDS {
        let episodes = floor["planner"]["by_kind"][k]["episodes"].as_u64();
        assert_eq!(episodes, Some(2), "floor.planner.by_kind.{k}");
        let crashed = cases.iter().filter(|c| c["kind"] == k && c["reference_ended"] == "collision").count();
        assert_eq!(crashed as f64 / 2.0, num(&ab["reference"]["by_kind"][k], "collision_rate"), "{k}");
    }
    assert!(report.contains("### Against the achievable floor"), "report.md lacks the floor");
    // The recording opens with the official MCAP reader and holds the top scenario's episode.
    let mcap = std::fs::read(folder.join("recording.mcap")).expect("recording.mcap");
    let mut topics = std::collections::BTreeMap::<String, usize>::new();
    for message in mcap::MessageStream::new(&mcap).expect("an MCAP file") {
        *topics.entry(message.expect("a readable message").channel.topic.clone()).or_default() += 1;
    }
    assert!(topics.keys().any(|t| t.ends_with("/state")), "no state topic in {topics:?}");
    assert!(topics.values().all(|&n| n > 0) && topics.len() >= 2, "{topics:?}");
    let what = m["recording"].as_str().expect("metrics.json says what was recorded");
    assert!(what.contains("full policy") && report.contains(what), "{what}");

    assert_closed_loop(&m, &folder, "ppo", 1);

    let bytes = |out: &str| std::fs::read(dir.path().join(out).join("metrics.json")).unwrap();
    run_ok(dir.path(), &["run", "--quick", "--seed", "7", "--out", "B"]);
    assert!(bytes("A") == bytes("B"), "metrics.json differs between two runs with --seed 7");
    run_ok(dir.path(), &["run", "--quick", "--seed", "8", "--out", "C"]);
    assert!(bytes("A") != bytes("C"), "--seed 7 and --seed 8 give the same metrics.json");
}

/// One ranked scenario's outcome in the comparison, as metrics.json has it.
fn outcome_fields(o: &Value) -> (bool, bool, f64) {
    (o["collision"].as_bool().unwrap(), o["success"].as_bool().unwrap(), o["risk_score"].as_f64().unwrap())
}

/// The push phase: the top `n` scenarios went to the edge over Zenoh under the reference driver
/// and again under the pushed `full` policy; the edge's results are those of its own code run
/// in-process (exactly), the policy run's S_risk at the world step is the re-score's, and the
/// cloud recorded the vehicle's streams in loop.mcap.
fn assert_closed_loop(m: &Value, folder: &Path, algo: &str, n: usize) {
    let cl = &m["closed_loop"];
    let policy = serde_json::json!({"policy_id": format!("{algo}-full-final"), "version": 1});
    assert_eq!(cl["policy"], policy, "{cl}");
    assert_eq!(cl["edge"], "run/veh-1");
    let scenarios = cl["scenarios"].as_array().expect("closed_loop.scenarios");
    assert_eq!(scenarios.len(), n, "{cl}");
    let rescore = m["rescore"].as_array().unwrap();
    let full = rescore.iter().find(|r| r["policy"] == format!("{algo}-full-final").as_str()).expect("full re-scored");
    for (i, sc) in scenarios.iter().enumerate() {
        assert_eq!(sc["id"], m["top"][i]["id"], "pushed in ranking order");
        assert_eq!(sc["reference"]["driven_by"], Value::Null, "the edge's reference driver drove first: {sc}");
        assert_eq!(sc["policy"]["driven_by"], policy, "the pushed policy version drove second: {sc}");
        for c in [&sc["reference"], &sc["policy"]] {
            assert_eq!(c["edge_equals_here"], true, "{c}");
            assert_eq!(c["edge"], c["edge_code_here"], "{c}");
            assert!(c["edge"]["duration_s"].as_f64().unwrap() > 0.0, "{c}");
        }
        let (_, _, run_risk) = outcome_fields(&sc["policy"]["run"]);
        assert_eq!(run_risk, full["risk"][i].as_f64().unwrap(), "the 50 ms run is the re-score");
        let (collision, _, _) = outcome_fields(&sc["reference"]["run"]);
        assert_eq!(collision, m["top"][i]["outcome"]["collision"].as_bool().unwrap(), "the 50 ms run is the library's");
    }
    let report = std::fs::read_to_string(folder.join("report.md")).unwrap();
    assert!(report.contains("## Closed loop over Zenoh"), "no closed-loop section");
    assert!(report.contains(&format!("`{algo}-full-final` v1 | edge |")), "the report names the driving policy");
    assert!(report.contains("Every edge result equals the edge code run here, exactly."));
    assert!(!report.contains("shown by the pipeline tests; the embedded run"), "the old 'Not in this run' bullet");
    let mcap = std::fs::read(folder.join("loop.mcap")).expect("loop.mcap");
    let mut states = 0;
    for message in mcap::MessageStream::new(&mcap).expect("an MCAP file") {
        states += usize::from(message.expect("a readable message").channel.topic == "risktwin/v1/run/veh-1/state");
    }
    // At least every step of the pushed episodes went through ingest into the recording.
    let steps: f64 = scenarios
        .iter()
        .flat_map(|sc| [&sc["reference"], &sc["policy"]])
        .map(|c| c["edge"]["duration_s"].as_f64().unwrap() / 0.02)
        .sum();
    assert!(states as f64 >= steps.round(), "{states} recorded states for {steps} pushed steps");
}

#[test]
fn push_phase_switched_off_or_out_of_range() {
    let dir = tempdir().unwrap();
    write_file(dir.path(), "big.json", r#"{"push_scenarios": 101}"#);
    assert_input_error(dir.path(), &["run", "--config", "big.json", "--out", "X"], "push_scenarios 101");
    write_file(
        dir.path(),
        "off.json",
        r#"{"count_per_kind": 3, "iterations": 0, "train_steps": 64, "seeds": 1, "n_envs": 4, "phases": 1,
            "curve_points": 1, "replay_top": 2, "background": 1, "failure_mutations": 0, "eval_per_kind": 1,
            "top_k": 2, "heatmaps": 0, "push_scenarios": 0}"#,
    );
    let m = run_ok(dir.path(), &["run", "--config", "off.json", "--seed", "2", "--out", "O"]);
    assert_eq!(m["closed_loop"], Value::Null);
    assert!(!dir.path().join("O/loop.mcap").exists());
    let report = std::fs::read_to_string(dir.path().join("O/report.md")).unwrap();
    assert!(!report.contains("## Closed loop over Zenoh") && report.contains("`push_scenarios` is 0"));
}

/// The other learners by flag: SAC, and the recurrent baseline, whose policy the edge drives
/// with its GRU state carried from step to step (its results still equal the edge code run
/// here, exactly).
#[test]
fn sac_and_ppo_gru_by_flag_with_a_tiny_config() {
    let dir = tempdir().unwrap();
    write_file(
        dir.path(),
        "tiny.json",
        r#"{"count_per_kind": 4, "iterations": 0, "train_steps": 256, "seeds": 1, "n_envs": 8, "phases": 2,
            "curve_points": 2, "replay_top": 4, "background": 2, "failure_mutations": 2, "eval_per_kind": 1,
            "top_k": 2, "heatmaps": 1}"#,
    );
    for algo in ["sac", "ppo-gru"] {
        let m = run_ok(dir.path(), &["run", "--config", "tiny.json", "--algo", algo, "--seed", "3", "--out", algo]);
        assert_eq!(m["ablation"]["algo"], algo);
        let policy = std::fs::read(dir.path().join(algo).join("policy_full.safetensors")).expect("the policy file");
        assert_eq!(risktwin_policy::file::read_meta(&policy).expect("a policy file").algo, algo);
        // push_scenarios defaults to 3, capped by top_k 2; the edge drives with this policy.
        assert_closed_loop(&m, &dir.path().join(algo), algo, 2);
        let sentences = m["verdict"]["sentences"].as_array().unwrap();
        assert!(
            sentences.iter().any(|s| s.as_str().unwrap().contains("Only 1 seed")),
            "a one-seed run does not say it falls short of three seeds: {sentences:?}"
        );
        assert_eq!(m["verdict"]["target_met"], false);
    }
}
