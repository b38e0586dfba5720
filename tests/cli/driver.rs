//! `--driver SPEC`: one way to name who drives (docs/driver-interface.md). `simulate` takes the
//! reference driver, a recording's ego, a policy file as `risktwin train` writes it, or its
//! ONNX model.

use crate::support::{assert_input_error, generate, ok_json, ok_stdout, rank, write_file};
use tempfile::tempdir;

#[test]
fn a_trained_policy_file_drives_simulate_and_a_bad_spec_or_file_is_refused_by_name() {
    let dir = tempdir().unwrap();
    generate(dir.path(), "lib.db", 1, 5);
    // 4,096 steps of PPO: a policy that drives, badly.
    ok_json(dir.path(), &["train", "--steps", "4096", "--variant", "base", "--out", "weak", "--format", "json"]);
    let ids: Vec<String> =
        rank(dir.path(), "lib.db").iter().map(|s| s["id"].as_str().expect("an id").to_owned()).collect();
    assert_eq!(ids.len(), 5, "one scenario of each kind");
    let simulate = |id: &str, flag: &str, driver: &str| {
        ok_stdout(dir.path(), &["simulate", "--db", "lib.db", "--id", id, flag, driver, "--format", "json"])
    };
    let mut differs = 0;
    for id in &ids {
        let by_policy = simulate(id, "--driver", "weak/policy.safetensors");
        let metrics: serde_json::Value = serde_json::from_str(&by_policy).expect("one JSON document");
        assert!(metrics["steps"].as_u64().is_some_and(|s| s > 0), "{metrics}");
        assert_eq!(by_policy, simulate(id, "--driver", "weak/policy.safetensors"), "the same bytes again");
        assert_eq!(by_policy, simulate(id, "--policy", "weak/policy.safetensors"), "--policy names the same driver");
        differs += usize::from(by_policy != simulate(id, "--driver", "idm"));
    }
    assert!(differs > 0, "the barely trained policy drives as the reference driver in every scenario");

    let id = ids[0].as_str();
    let sim = |driver: &str, needle: &str| {
        assert_input_error(dir.path(), &["simulate", "--db", "lib.db", "--id", id, "--driver", driver], needle);
    };
    for bad in ["ppo", "model.pt", "IDM"] {
        sim(bad, &format!("unknown driver '{bad}' (accepted: idm"));
    }
    sim("replay", "--driver replay plays a recording's ego");
    sim("missing.safetensors", "driver missing.safetensors");
    write_file(dir.path(), "junk.safetensors", "not a policy");
    sim("junk.safetensors", "driver junk.safetensors: not a safetensors file");
    // A policy file for another observation: its metadata is checked against this build first.
    let policy = std::fs::read(dir.path().join("weak/policy.safetensors")).expect("the policy file");
    let text = String::from_utf8_lossy(&policy[..200]).to_string();
    assert!(text.contains("\"obs_dim\":\"24\""), "metadata as written: {text}");
    let mut other = policy.clone();
    let at = other.windows(14).position(|w| w == b"\"obs_dim\":\"24\"").expect("obs_dim in the header");
    other[at + 11..at + 13].copy_from_slice(b"25");
    std::fs::write(dir.path().join("wide.safetensors"), other).expect("a file written");
    sim("wide.safetensors", "obs_dim = '25'");
    // A recording's ego is driven closed-loop by a model file too, from its recorded start.
    let xml = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/crime/OSC_CutIn-1_2_T-1.xml");
    let xml = xml.to_str().expect("a UTF-8 path");
    let on_recording =
        |driver: &str| ok_json(dir.path(), &["simulate", "--commonroad", xml, "--driver", driver, "--format", "json"]);
    let (learned, replayed) = (on_recording("weak/policy.safetensors"), on_recording("replay"));
    assert!(learned["steps"].as_u64().is_some_and(|s| s > 0), "{learned}");
    assert_ne!(learned, replayed, "the policy drives, it does not replay the recording");
    assert_eq!(learned["steps"], on_recording("weak/policy.onnx")["steps"], "its ONNX model drives the same");
    // train's ONNX model of the same policy drives too, and the same.
    let onnx = simulate(&ids[0], "--driver", "weak/policy.onnx");
    let native = simulate(&ids[0], "--driver", "weak/policy.safetensors");
    let steps = |text: &str| serde_json::from_str::<serde_json::Value>(text).expect("JSON")["steps"].clone();
    assert_eq!(steps(&onnx), steps(&native), "the same episode length");
}
