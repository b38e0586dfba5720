//! V2X on a scene's message paths in real time against virtual time (issue 16, item 5): the
//! authority and every participant as separate processes over a real router on this host, the
//! scene paced at the wall clock, CAMs held by real timers; against the embedded run of the same
//! configuration and seed, whose V2X layers decide the same messages in virtual time.

use crate::support::{Proc, start_router};
use serde_json::Value;
use std::collections::BTreeMap;
use std::time::Duration;

/// An emergency braking with the ego, two connected vehicles and four RSUs 150 m apart in urban
/// NLOS: the RSUs 300 and 450 m along the route hear about 80 % and 30 % of the CAMs.
const SCENE: [&str; 12] = [
    "--kind",
    "emergency-braking",
    "--seed",
    "3",
    "--connected",
    "3",
    "--rsus",
    "4",
    "--v2x-model",
    "3gpp-urban-nlos",
    "--v2x-latency",
    "sidelink:4:100",
];
const PARTICIPANTS: [&str; 7] = ["v0", "v1", "v2", "rsu0", "rsu1", "rsu2", "rsu3"];

fn args<'a>(head: &[&'a str], tail: &[&'a str]) -> Vec<&'a str> {
    head.iter().chain(tail).copied().collect()
}

fn count(v2x: &Value, key: &str) -> u64 {
    v2x[key].as_u64().unwrap_or_else(|| panic!("{key} in {v2x}"))
}

#[test]
fn a_realtime_scene_of_processes_agrees_with_the_virtual_time_v2x_statistics() {
    let embedded =
        Proc::spawn("embedded", &args(&["scene", "run", "--embedded"], &SCENE)).exit_json(Duration::from_secs(60));
    let virtual_time: BTreeMap<String, Value> =
        serde_json::from_value(embedded["v2x"].clone()).expect("an embedded scene's V2X counts per participant");

    let (_router, locator) = start_router();
    let net = ["--mode", "peer", "--listen", "tcp/127.0.0.1:0", "--connect", locator.as_str()];
    let mut participants: Vec<Proc> = PARTICIPANTS
        .iter()
        .map(|id| {
            let role = if id.starts_with("rsu") { "rsu" } else { "vehicle" };
            Proc::spawn(id, &args(&args(&["scene", role, "--participant", id], &SCENE), &net))
        })
        .collect();
    let authority_argv = args(&args(&["scene", "authority", "--speed", "1"], &SCENE), &net);
    let outcome = Proc::spawn("authority", &authority_argv).exit_json(Duration::from_secs(90));
    assert_eq!(outcome["truth_digest"], embedded["truth_digest"], "the same episode, step for step");
    let real_time: BTreeMap<String, Value> = participants
        .iter_mut()
        .map(|p| {
            let summary = p.exit_json(Duration::from_secs(20));
            (p.name.clone(), summary["v2x"].clone())
        })
        .collect();

    let total = |side: &BTreeMap<String, Value>, key: &str| side.values().map(|v| count(v, key)).sum::<u64>();
    let pdr = |side: &BTreeMap<String, Value>| total(side, "passed") as f64 / total(side, "copies") as f64;
    let (real_pdr, virtual_pdr) = (pdr(&real_time), pdr(&virtual_time));
    eprintln!("V2X PDR: real time {real_pdr:.4}, virtual time {virtual_pdr:.4}");
    assert!(virtual_pdr < 0.9 && total(&virtual_time, "copies") > 500, "a loss to measure: {virtual_time:?}");
    assert!((real_pdr - virtual_pdr).abs() <= 0.02, "PDR {real_pdr} against {virtual_pdr}");
    for id in PARTICIPANTS {
        let (real, virt) = (&real_time[id], &virtual_time[id]);
        assert_eq!(count(real, "cams_sent"), count(virt, "cams_sent"), "{id}: CAMs sent");
        let p50 = |v: &Value| v["latency_p50_ms"].as_f64().unwrap_or_else(|| panic!("{id}: no latency in {v}"));
        let (real_ms, virtual_ms) = (p50(real), p50(virt));
        eprintln!(
            "{id}: copies {}/{}, passed {}/{}, p50 {real_ms:.2}/{virtual_ms:.2} ms (real/virtual)",
            count(real, "copies"),
            count(virt, "copies"),
            count(real, "passed"),
            count(virt, "passed")
        );
        assert!((real_ms - virtual_ms).abs() <= 2.0, "{id}: latency p50 {real_ms} ms against {virtual_ms} ms");
    }
}
