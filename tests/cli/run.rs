//! `risktwin run`: the report folder of a quick run (every file, PNGs that decode, per-variant
//! per-kind metrics with their spread over seeds, the computed verdict), byte-identical
//! metrics.json for the same seed, and SAC by flag.

use crate::support::{risktwin, shown, write_file};
use serde_json::Value;
use std::path::Path;
use tempfile::tempdir;

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
    assert_eq!(names, ["base", "risk-only", "full"]);
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
    for v in &variants[..2] {
        assert!(v["seeds"][0]["refreshes"].as_array().unwrap().is_empty());
    }
    assert_eq!(ab["held_out_episodes"].as_u64(), Some(10));
    let verdict = &m["verdict"];
    let sentence = verdict["sentences"][0].as_str().expect("a verdict sentence");
    assert!(sentence.starts_with("Target met") || sentence.starts_with("Target not met"), "{sentence}");
    assert_eq!(sentence.starts_with("Target met"), verdict["target_met"].as_bool().unwrap());
    let report = std::fs::read_to_string(folder.join("report.md")).unwrap();
    assert!(report.contains(sentence), "report.md lacks the computed verdict");
    assert!(report.contains("training_curves.png") && report.contains("ablation.png"));
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

    let bytes = |out: &str| std::fs::read(dir.path().join(out).join("metrics.json")).unwrap();
    run_ok(dir.path(), &["run", "--quick", "--seed", "7", "--out", "B"]);
    assert!(bytes("A") == bytes("B"), "metrics.json differs between two runs with --seed 7");
    run_ok(dir.path(), &["run", "--quick", "--seed", "8", "--out", "C"]);
    assert!(bytes("A") != bytes("C"), "--seed 7 and --seed 8 give the same metrics.json");
}

#[test]
fn sac_by_flag_with_a_tiny_config() {
    let dir = tempdir().unwrap();
    write_file(
        dir.path(),
        "tiny.json",
        r#"{"count_per_kind": 4, "iterations": 0, "train_steps": 256, "seeds": 1, "n_envs": 8, "phases": 2,
            "curve_points": 2, "replay_top": 4, "background": 2, "failure_mutations": 2, "eval_per_kind": 1,
            "top_k": 2, "heatmaps": 1}"#,
    );
    let m = run_ok(dir.path(), &["run", "--config", "tiny.json", "--algo", "sac", "--seed", "3", "--out", "S"]);
    assert_eq!(m["ablation"]["algo"], "sac");
    assert!(dir.path().join("S/policy_full.safetensors").is_file());
    let sentences = m["verdict"]["sentences"].as_array().unwrap();
    assert!(
        sentences.iter().any(|s| s.as_str().unwrap().contains("Only 1 seed")),
        "a one-seed run does not say it falls short of three seeds: {sentences:?}"
    );
    assert_eq!(m["verdict"]["target_met"], false);
}
