//! `risktwin risk-field --commonroad` and `risktwin simulate --commonroad`: the risk field over a
//! real lanelet map, S_risk of the recorded ego, and the recorded scenario re-run in the twin.

use crate::support::{SIMULATE_KEYS, assert_input_error, ok_json, ok_stdout};
use std::path::PathBuf;
use tempfile::tempdir;

fn fixture(name: &str) -> String {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/crime").join(name);
    p.to_str().expect("fixture path is UTF-8").to_string()
}

#[test]
fn risk_field_on_a_real_map_writes_json_and_png() {
    let dir = tempdir().unwrap();
    let xml = fixture("OSC_CutIn-1_2_T-1.xml");
    let png = dir.path().join("field.png");
    let png_s = png.to_str().unwrap();
    let v = ok_json(
        dir.path(),
        &["risk-field", "--commonroad", &xml, "--ego", "3", "--time", "3.0", "--png", png_s, "--format", "json"],
    );
    for key in ["cols", "rows", "resolution_m", "origin_m", "max", "mean", "argmax_m", "risk_score"] {
        assert!(v.get(key).is_some(), "missing {key} in {v}");
    }
    assert_eq!(v["cols"], 160);
    assert_eq!(v["ego_id"], 3);
    let (max, mean) = (v["max"].as_f64().unwrap(), v["mean"].as_f64().unwrap());
    assert!(max > mean && mean > 0.0, "{v}");
    let score = v["risk_score"].as_f64().unwrap();
    assert!((0.0..=10.0).contains(&score), "{v}");
    let bytes = std::fs::read(&png).expect("png written");
    assert_eq!(&bytes[1..4], b"PNG");
    // The default ego is the planning problem's (or the first obstacle): same answer here.
    let d = ok_json(dir.path(), &["risk-field", "--commonroad", &xml, "--time", "3.0", "--format", "json"]);
    assert_eq!(d["ego_id"], 3);
}

#[test]
fn risk_field_rejects_times_beyond_the_recording_and_unknown_egos() {
    let dir = tempdir().unwrap();
    let xml = fixture("OSC_CutIn-1_2_T-1.xml");
    assert_input_error(
        dir.path(),
        &["risk-field", "--commonroad", &xml, "--time", "9999"],
        "outside the ego's recording",
    );
    assert_input_error(dir.path(), &["risk-field", "--commonroad", &xml, "--ego", "424242"], "424242");
    assert_input_error(
        dir.path(),
        &["risk-field", "--commonroad", "/nonexistent/scenario.xml"],
        "cannot read /nonexistent/scenario.xml",
    );
}

#[test]
fn simulate_replays_or_drives_a_recorded_scenario() {
    let dir = tempdir().unwrap();
    for (name, ego) in
        [("OSC_CutIn-1_2_T-1.xml", "3"), ("BEL_Putte-8_2_T-1.xml", "33"), ("HRV_Pula-27_3_T-1.xml", "34")]
    {
        let xml = fixture(name);
        for policy in ["replay", "idm"] {
            let v = ok_json(
                dir.path(),
                &["simulate", "--commonroad", &xml, "--ego", ego, "--policy", policy, "--format", "json"],
            );
            // docs/cli.md's simulate document, every key.
            for key in SIMULATE_KEYS {
                assert!(v.get(key).is_some(), "{name} {policy}: missing {key} in {v}");
            }
            assert!(v["steps"].as_u64().unwrap() > 0, "{name} {policy}: {v}");
            assert!(v["avg_speed_mps"].as_f64().unwrap() > 0.0, "{name} {policy}: {v}");
            if policy == "replay" && v["avg_speed_mps"].as_f64().unwrap() > 1.0 {
                // A moving recorded ego follows its own path to the end and hits nothing (the
                // Putte ego stands: its route is a 1 m stub it never covers).
                assert_eq!(v["collision"], false, "{name}: {v}");
                let completion = v["route_completion"].as_f64().unwrap();
                assert!(completion > 0.95, "{name}: the replay covers the recorded route: {v}");
            }
        }
    }
    let xml = fixture("OSC_CutIn-1_2_T-1.xml");
    assert_input_error(
        dir.path(),
        &["simulate", "--commonroad", &xml, "--policy", "ppo.bin"],
        "unknown driver 'ppo.bin'",
    );
}

#[test]
fn an_imported_recording_gives_the_offline_criticality() {
    let dir = tempdir().unwrap();
    for (name, ego) in
        [("OSC_CutIn-1_2_T-1.xml", "3"), ("BEL_Putte-8_2_T-1.xml", "33"), ("HRV_Pula-27_3_T-1.xml", "34")]
    {
        let xml = fixture(name);
        let mcap = dir.path().join(format!("{name}.mcap"));
        let mcap_s = mcap.to_str().unwrap();
        let summary = ok_json(dir.path(), &["import", "commonroad", &xml, "--out", mcap_s, "--format", "json"]);
        assert!(summary["messages"].as_u64().unwrap() > 10, "{name}: {summary}");
        assert!(summary["lanelets"].as_u64().unwrap() > 0, "{name}: {summary}");
        for format in ["csv", "json"] {
            let offline =
                ok_stdout(dir.path(), &["criticality", "--commonroad", &xml, "--ego", ego, "--format", format]);
            let replayed = ok_stdout(dir.path(), &["criticality", "--mcap", mcap_s, "--ego", ego, "--format", format]);
            assert!(offline.lines().count() > 5, "{name}: too little output to compare:\n{offline}");
            assert_eq!(replayed, offline, "{name} {format}: the recording's criticality differs from the XML's");
        }
    }
}

#[test]
fn import_and_criticality_mcap_reject_bad_input() {
    let dir = tempdir().unwrap();
    let out = dir.path().join("x.mcap");
    let out_s = out.to_str().unwrap();
    assert_input_error(dir.path(), &["import", "commonroad", "/nonexistent/s.xml", "--out", out_s], "cannot read");
    let not_mcap = crate::support::write_file(dir.path(), "not.mcap", "hello");
    assert_input_error(dir.path(), &["criticality", "--mcap", not_mcap.to_str().unwrap()], "not.mcap");
    // A valid recording, an ego it does not hold.
    let xml = fixture("OSC_CutIn-1_2_T-1.xml");
    ok_json(dir.path(), &["import", "commonroad", &xml, "--out", out_s, "--format", "json"]);
    assert_input_error(dir.path(), &["criticality", "--mcap", out_s, "--ego", "424242"], "424242");
}
