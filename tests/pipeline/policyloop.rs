//! One full cycle of the closed loop over the pipeline, as separate processes around a real
//! router: a risk-ranked library scenario is pushed to an edge vehicle, which executes it under
//! the reference driver while its streams go through cloud ingest into the recording; a policy
//! trained by `risktwin train` is pushed as a policy update; the same scenario pushed again is
//! driven by that policy version (the result says which), and its streams, found in the
//! recording by their sequence numbers, trace a different trajectory.

use crate::support::{Proc, cut_in_library, keys, run_json, start_router};
use risktwin_common::telemetry::VehicleStateSample;
use risktwin_common::world::STEP_S;
use risktwin_edge::vehicle::DEFAULT_STATE_RATE_HZ;
use risktwin_protos::decode;
use risktwin_protos::recording::read_messages;
use serde_json::Value;
use std::time::Duration;

const STEP: Duration = Duration::from_secs(60);

/// The ego trajectory (x, y) of the `state` messages numbered `first..=last`, in order.
fn trajectory(states: &[VehicleStateSample], seqs: &Value) -> Vec<(f64, f64)> {
    let first = seqs[0].as_u64().expect("a first seq");
    let last = seqs[1].as_u64().expect("a last seq");
    let out: Vec<(f64, f64)> =
        states.iter().filter(|s| (first..=last).contains(&s.header.seq)).map(|s| (s.pose.x_m, s.pose.y_m)).collect();
    assert_eq!(out.len() as u64, last - first + 1, "every state of the episode reached the recording");
    out
}

#[test]
fn a_trained_policy_pushed_to_the_edge_drives_the_next_pushed_scenario() {
    let (router, locator) = start_router();
    let dir = tempfile::tempdir().expect("a temporary directory");
    let (db, ranked) = cut_in_library(dir.path(), 4);
    let id = ranked[0]["id"].as_str().expect("a ranked id").to_owned();
    let out = dir.path().join("train");
    let out_dir = out.to_str().expect("a UTF-8 path");
    // Trained while the pipeline starts; a few thousand steps: a real, if weak, policy.
    let mut train = Proc::spawn(
        "train",
        &["train", "--algo", "ppo", "--variant", "base", "--steps", "4096", "--out", out_dir, "--format", "json"],
    );

    let recording = dir.path().join("loop.mcap");
    let path = recording.to_str().expect("a UTF-8 path");
    let mut cloud = Proc::spawn("cloud", &["cloud", "--roles", "ingest", "--record", path, "--connect", &locator]);
    cloud.wait_line(STEP, |l| l == "ready");
    // 10× real time: a 15 s episode plays in 1.5 s.
    // The cloud's key signs the update; the vehicle trusts its public half.
    let (signing_key, verifying_key) = keys(dir.path(), "keys");
    let mut vehicle = Proc::spawn(
        "veh",
        &[
            "edge",
            "vehicle",
            "--id",
            "veh-l",
            "--site",
            "loop",
            "--connect",
            &locator,
            "--rate-hz",
            "500",
            "--trust-key",
            &verifying_key,
        ],
    );
    vehicle.wait_line(STEP, |l| l == "edge veh-l: publishing");
    let to = ["--to", "veh-l", "--site", "loop", "--connect", &locator];
    let push_scenario = || {
        let mut args = vec!["push", "scenario", "--db", &db, "--id", &id];
        args.extend_from_slice(&to);
        run_json(&args)
    };

    let by_reference = push_scenario();
    assert_eq!(by_reference["spec_id"], id.as_str());
    assert_eq!(by_reference["policy"], Value::Null, "the reference driver drove: {by_reference}");

    let trained = train.exit_json(STEP);
    assert_eq!(trained["steps"].as_u64(), Some(4096), "{trained}");
    let weights = out.join("policy.safetensors");
    let mut args = vec!["push", "policy", "--weights", weights.to_str().expect("a UTF-8 path")];
    args.extend_from_slice(&["--policy-id", "ppo-loop", "--version", "1", "--algo", "ppo"]);
    args.extend_from_slice(&["--signing-key", &signing_key]);
    args.extend_from_slice(&to);
    assert_eq!(run_json(&args)["delivered"], true);
    vehicle.wait_line(STEP, |l| l.starts_with("edge: driving with policy ppo-loop version 1"));

    let by_policy = push_scenario();
    assert_eq!(by_policy["spec_id"], id.as_str());
    assert_eq!(by_policy["policy"], serde_json::json!({"policy_id": "ppo-loop", "version": 1}), "{by_policy}");

    vehicle.terminate();
    let summary = vehicle.exit_json(STEP);
    cloud.wait_line(STEP, |l| l == "edge left: loop/veh-l");
    cloud.terminate();
    let ingest = cloud.exit_json(STEP);
    router.terminate();

    // Everything the vehicle sent, the pushed episodes included, went through ingest.
    assert_eq!(ingest["total_dropped"], 0, "{ingest}");
    assert_eq!(ingest["received"]["veh-l"], summary["sent"], "{ingest}\n{summary}");
    let results = summary["pushes"]["results"].as_array().expect("results");
    assert_eq!(results.len(), 2, "{summary}");
    assert_eq!(results[0]["policy"], Value::Null);
    assert_eq!(results[1]["policy"]["version"], 1);
    for (r, pushed) in results.iter().zip([&by_reference, &by_policy]) {
        assert_eq!(r["steps"], pushed["metrics"]["steps"], "{r}");
    }

    let bytes = std::fs::read(&recording).expect("the recording");
    let states: Vec<VehicleStateSample> = read_messages(&bytes)
        .expect("a valid MCAP file")
        .iter()
        .filter(|m| m.topic == "risktwin/v1/loop/veh-l/state")
        .map(|m| decode(&m.data).expect("a recorded VehicleState"))
        .collect();
    let reference_path = trajectory(&states, &results[0]["state_seqs"]);
    let policy_path = trajectory(&states, &results[1]["state_seqs"]);
    // 50 Hz state samples of 20 Hz physics steps: 2.5 a step, the half on whichever tick parity
    // the episode started.
    for (path, outcome) in [(&reference_path, &by_reference), (&policy_path, &by_policy)] {
        let steps = outcome["metrics"]["steps"].as_u64().expect("steps") as f64;
        let per_step = STEP_S * DEFAULT_STATE_RATE_HZ;
        assert!((path.len() as f64 - steps * per_step).abs() <= 0.5, "{} states for {steps} steps", path.len());
    }
    // Same scenario, same start: the drivers part ways.
    let (a, b) = (reference_path[0], policy_path[0]);
    assert!((a.0 - b.0).hypot(a.1 - b.1) < 1.0, "both start where the scenario puts the ego: {a:?} {b:?}");
    let n = reference_path.len().min(policy_path.len());
    let apart = (0..n)
        .map(|i| (reference_path[i].0 - policy_path[i].0).hypot(reference_path[i].1 - policy_path[i].1))
        .fold(0.0f64, f64::max);
    assert!(apart > 1.0, "the policy drove differently from the reference driver: at most {apart} m apart");
}
