//! A CommonRoad scenario as fleet data: `risktwin import commonroad` writes it as a recording,
//! `risktwin edge replay` streams it unpaced through a real router into a cloud running the
//! `criticality` role, and the report the cloud writes on SIGTERM equals `risktwin criticality
//! --commonroad` on the XML, byte for byte; with `--db` the replayed drive becomes a recorded case
//! of the library.

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
    let out = dir.path().join(format!("criticality.{ext}"));
    let summary = replayed(xml, dir.path(), &["--criticality-out", utf8(&out), "--ego", ego]);
    let report = std::fs::read_to_string(&out).expect("the cloud wrote its criticality report");
    (report, summary)
}

/// Imports `xml` as a recording in `dir`, replays it unpaced through a router into a cloud
/// running `ingest,criticality` with `cloud_args`, and returns the cloud's summary once it has
/// taken every message.
fn replayed(xml: &Path, dir: &Path, cloud_args: &[&str]) -> serde_json::Value {
    let recording = dir.join("scenario.mcap");
    let mut import =
        Proc::spawn("import", &["import", "commonroad", utf8(xml), "--out", utf8(&recording), "--format", "json"]);
    let imported = import.exit_json(STEP);
    let (router, locator) = start_router();
    let head = ["cloud", "--roles", "ingest,criticality", "--connect", locator.as_str()];
    let mut cloud = Proc::spawn("cloud", &[&head[..], cloud_args].concat());
    cloud.wait_line(STEP, |l| l == "ready");
    let mut replay =
        Proc::spawn("replay", &["edge", "replay", utf8(&recording), "--speed", "0", "--connect", &locator]);
    let published = replay.exit_json(STEP);
    assert_eq!(published["published"], imported["messages"], "the map and every state are republished");
    assert_eq!(published["skipped"], 0);
    cloud.terminate();
    let summary = cloud.exit_json(STEP);
    router.terminate();
    let crit = &summary["criticality"];
    assert_eq!(crit["maps"], 1, "{summary}");
    assert_eq!(crit["states"].as_u64(), imported["messages"].as_u64().map(|n| n - 1), "{summary}");
    assert_eq!(crit["dropped"], serde_json::json!({}), "{summary}");
    summary
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
fn a_replayed_drive_becomes_a_recorded_case_of_the_library_that_replays_as_the_file_does() {
    let xml = data("OSC_CutIn-1_2_T-1.xml");
    let dir = tempfile::tempdir().expect("a temporary directory");
    let db = dir.path().join("lib.db");
    let args = ["--db", utf8(&db), "--ego", "3"];
    let first = replayed(&xml, dir.path(), &args);
    let cases = first["criticality"]["cases"].as_array().expect("the stored cases").clone();
    assert_eq!(cases.len(), 1, "{first}");
    let case = &cases[0];
    assert_eq!((&case["ego_id"], &case["inserted"]), (&serde_json::json!(3), &serde_json::json!(true)), "{case}");
    let id = case["id"].as_str().expect("the case id");
    // The case holds the drive as it travelled: replayed from the library it gives what the
    // original file gives (the same route, obstacles and outcome).
    let run = |args: &[&str]| Proc::spawn("simulate", args).exit_json(STEP);
    let from_case = run(&["simulate", "--db", utf8(&db), "--id", id, "--policy", "replay", "--format", "json"]);
    let from_file =
        run(&["simulate", "--commonroad", utf8(&xml), "--ego", "3", "--policy", "replay", "--format", "json"]);
    for field in ["collision", "offroad", "route_completion", "min_distance_m", "min_ttc_s", "risk_score", "steps"] {
        assert!(!from_file[field].is_null(), "{field} in {from_file}");
        assert_eq!(from_case[field], from_file[field], "{field}: case {from_case}, file {from_file}");
    }
    assert_eq!(case["risk_score"], from_file["risk_score"], "the stored reference is the replay's");
    let ranked = run(&["scenarios", "rank", "--db", utf8(&db), "--kind", "commonroad", "--format", "json"]);
    assert!(ranked.to_string().contains(id), "the case ranks with the library's recorded cases: {ranked}");
    // The same drive replayed again is the same case.
    let again = replayed(&xml, dir.path(), &args);
    assert_eq!(again["criticality"]["cases"][0]["id"], case["id"], "{again}");
    assert_eq!(again["criticality"]["cases"][0]["inserted"], false, "{again}");
}

#[test]
fn the_criticality_role_without_an_output_file_or_a_library_is_refused_with_exit_2() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let junk = dir.path().join("junk.db");
    std::fs::write(&junk, b"not a database at all, just text that is long enough to fill a header").expect("written");
    let junk = utf8(&junk);
    for args in [
        &["cloud", "--roles", "ingest,criticality"][..],
        &["cloud", "--roles", "criticality", "--criticality-out", "report.txt"],
        &["cloud", "--roles", "ingest", "--ego", "3"],
        &["cloud", "--roles", "ingest,criticality", "--db", junk],
    ] {
        let mut p = Proc::spawn("bad", args);
        let (status, stdout) = p.wait_exit(STEP);
        let stderr = p.drain_stderr();
        assert_eq!(status.code(), Some(2), "{args:?}: stdout {stdout}, stderr {stderr}");
        assert!(stderr.contains("error: "), "{args:?}: {stderr}");
    }
}
