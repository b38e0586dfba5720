//! A CommonRoad scenario as fleet data: `risktwin import commonroad` writes it as a recording,
//! `risktwin edge replay` streams it unpaced through a real router into a cloud running the
//! `criticality` role, and the report the cloud writes on SIGTERM equals `risktwin criticality
//! --commonroad` on the XML, byte for byte.

use crate::support::{Proc, start_router};
use std::path::{Path, PathBuf};
use std::time::Duration;

const STEP: Duration = Duration::from_secs(60);

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/commonroad").join(name)
}

fn utf8(p: &Path) -> &str {
    p.to_str().expect("a UTF-8 path")
}

/// The offline report of `risktwin criticality --commonroad FILE --ego ID --format FORMAT`.
fn offline(xml: &Path, ego: &str, format: &str) -> String {
    let mut p = Proc::spawn("offline", &["criticality", "--commonroad", utf8(xml), "--ego", ego, "--format", format]);
    let (status, stdout) = p.wait_exit(STEP);
    assert!(status.success(), "offline criticality failed: {status}");
    stdout
}

fn replayed_criticality(xml: &Path, ego: &str, ext: &str) -> (String, serde_json::Value) {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let recording = dir.path().join("scenario.mcap");
    let mut import =
        Proc::spawn("import", &["import", "commonroad", utf8(xml), "--out", utf8(&recording), "--format", "json"]);
    let imported = import.exit_json(STEP);
    let (router, locator) = start_router();
    let out = dir.path().join(format!("criticality.{ext}"));
    let mut cloud = Proc::spawn(
        "cloud",
        &[
            "cloud",
            "--roles",
            "ingest,criticality",
            "--criticality-out",
            utf8(&out),
            "--ego",
            ego,
            "--connect",
            &locator,
        ],
    );
    cloud.wait_line(STEP, |l| l == "ready");
    let mut replay =
        Proc::spawn("replay", &["edge", "replay", utf8(&recording), "--speed", "0", "--connect", &locator]);
    let published = replay.exit_json(STEP);
    assert_eq!(published["published"], imported["messages"], "the map and every state are republished");
    assert_eq!(published["skipped"], 0);
    cloud.terminate();
    let summary = cloud.exit_json(STEP);
    router.terminate();
    let report = std::fs::read_to_string(&out).expect("the cloud wrote its criticality report");
    let crit = &summary["criticality"];
    assert_eq!(crit["maps"], 1, "{summary}");
    assert_eq!(crit["states"].as_u64(), imported["messages"].as_u64().map(|n| n - 1), "{summary}");
    assert_eq!(crit["dropped"], serde_json::json!({}), "{summary}");
    (report, summary)
}

#[test]
fn the_cloud_computes_the_offline_criticality_from_a_replayed_commonroad_scenario() {
    let xml = data("OSC_CutIn-1_2_T-1.xml");
    let (report, summary) = replayed_criticality(&xml, "3", "csv");
    let expected = offline(&xml, "3", "csv");
    assert!(expected.lines().count() > 10, "the offline report has cells: {expected}");
    assert_eq!(report, expected, "cloud summary: {summary}");
    assert_eq!(summary["criticality"]["ego_id"], 3);
    assert_eq!(summary["criticality"]["cells"].as_u64(), Some(expected.lines().count() as u64 - 1));
    // Every state also went through the ingest role, validated and accepted.
    assert_eq!(summary["total_dropped"], 0, "{summary}");
}

#[test]
fn the_cloud_writes_the_json_report_too_on_a_multi_vehicle_scenario() {
    let xml = data("ZAM_Tjunction-1_97_T-1.xml");
    let (report, _) = replayed_criticality(&xml, "1", "json");
    assert_eq!(report, offline(&xml, "1", "json"));
}

#[test]
fn the_criticality_role_without_an_output_file_is_refused_with_exit_2() {
    for args in [
        &["cloud", "--roles", "ingest,criticality"][..],
        &["cloud", "--roles", "criticality", "--criticality-out", "report.txt"],
    ] {
        let mut p = Proc::spawn("bad", args);
        let (status, stdout) = p.wait_exit(STEP);
        assert_eq!(status.code(), Some(2), "{args:?}: stdout {stdout}");
    }
}
