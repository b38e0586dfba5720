//! `risktwin risk-field --commonroad` and `risktwin simulate --commonroad`: the risk field over a
//! real lanelet map, S_risk of the recorded ego, and the recorded scenario re-run in the twin.

use crate::support::{assert_input_error, ok_json};
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
            for key in ["collision", "offroad", "min_ttc_s", "min_distance_m", "risk_score", "steps"] {
                assert!(v.get(key).is_some(), "{name} {policy}: missing {key} in {v}");
            }
            assert!(v["steps"].as_u64().unwrap() > 0, "{name} {policy}: {v}");
        }
    }
    let xml = fixture("OSC_CutIn-1_2_T-1.xml");
    assert_input_error(dir.path(), &["simulate", "--commonroad", &xml, "--policy", "ppo.bin"], "unknown policy");
}
