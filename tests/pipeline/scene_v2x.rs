//! V2X on a scene's message paths in real time against virtual time (issue 16, item 5): the
//! authority and every participant as separate processes over a real router on this host, the
//! scene paced at the wall clock, CAMs held by real timers; against the embedded run of the same
//! configuration and seed, whose V2X layers decide the same messages in virtual time. What must
//! agree is in `v2x_agreement.rs`.

use crate::support::{Proc, start_router};
use crate::v2x_agreement::{PerParticipant, SCENE, assert_agrees, assert_warnings_agree};
use std::time::Duration;

const PARTICIPANTS: [&str; 7] = ["v0", "v1", "v2", "rsu0", "rsu1", "rsu2", "rsu3"];

fn args<'a>(head: &[&'a str], tail: &[&'a str]) -> Vec<&'a str> {
    head.iter().chain(tail).copied().collect()
}

#[test]
fn a_realtime_scene_of_processes_agrees_with_the_virtual_time_v2x_statistics() {
    let embedded =
        Proc::spawn("embedded", &args(&["scene", "run", "--embedded"], &SCENE)).exit_json(Duration::from_secs(60));
    let virtual_time: PerParticipant =
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
    let real_time: PerParticipant = participants
        .iter_mut()
        .map(|p| {
            let summary = p.exit_json(Duration::from_secs(20));
            (p.name.clone(), summary["v2x"].clone())
        })
        .collect();

    assert_agrees("processes over a router", &real_time, &virtual_time);
}

/// Every role of a scene must run the same V2X channel: the authority refuses a participant
/// started with another latency by name, as it refuses one of another seed.
#[test]
fn a_participant_with_other_v2x_flags_is_refused_by_name() {
    let (_router, locator) = start_router();
    let net = ["--mode", "client", "--connect", locator.as_str()];
    let scene = ["--kind", "cut-in", "--seed", "3", "--connected", "1", "--v2x-model", "3gpp-urban-nlos"];
    let mut authority = Proc::spawn("authority", &args(&args(&["scene", "authority"], &scene), &net));
    let other = args(&args(&["scene", "vehicle", "--participant", "v0"], &scene), &["--v2x-latency", "sidelink:4:50"]);
    let mut v0 = Proc::spawn("v0", &args(&other, &net));
    let (status, _) = authority.wait_exit(Duration::from_secs(40));
    let stderr = authority.drain_stderr();
    assert_eq!(status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("participant v0 runs") && stderr.contains("V2X 3gpp-urban-nlos sidelink:4:50"), "{stderr}");
    let (status, _) = v0.wait_exit(Duration::from_secs(10));
    assert!(!status.success(), "the refused participant is told: {}", v0.drain_stderr());
}

#[test]
fn bad_v2x_flags_are_refused_with_exit_2() {
    let cases: [(&[&str], &str); 7] = [
        (&["--v2x-bursts", "0:-5"], "--v2x-bursts \"0:-5\""),
        (&["--v2x-bursts", "0:nan"], "--v2x-bursts \"0:nan\""),
        (&["--v2x-bursts", "0.3"], "expected SHARE:MEAN_BURST"),
        (&["--v2x-latency", "sidelink:50:10"], "--v2x-latency"),
        (&["--v2x-model", "nowhere"], "--v2x-model \"nowhere\""),
        (&["--v2x-warnings"], "--v2x-warnings needs --v2x-model"),
        (&["--v2x-cpm"], "--v2x-cpm needs --v2x-model"),
    ];
    for (flags, expected) in cases {
        let without_model = ["--v2x-model", "--v2x-warnings", "--v2x-cpm"].contains(&flags[0]);
        let model = if without_model { &[][..] } else { &["--v2x-model", "3gpp-urban-nlos"][..] };
        let argv = args(&args(&["scene", "run", "--embedded", "--kind", "cut-in", "--seed", "3"], model), flags);
        let mut p = Proc::spawn("bad v2x", &argv);
        let (status, _) = p.wait_exit(Duration::from_secs(30));
        let stderr = p.drain_stderr();
        assert_eq!(status.code(), Some(2), "{argv:?}: {stderr}");
        assert!(stderr.contains("error: ") && stderr.contains(expected), "{argv:?}: {stderr}");
    }
}

/// RSU → vehicle warnings on a scene's V2X paths (issue 16, item 3): in a pedestrian crossing
/// where the unwarned ego hits the pedestrian, rsu0 warns it over a short latency and the ego
/// stops in time; the warnings are counted made, passed and heard. In virtual time embedded, and
/// in real time with every role its own process over a router (lockstep at the wall clock): the
/// same episode, step for step, and the same warnings decided and heard.
#[test]
fn rsu_warnings_prevent_the_crash_of_a_scene_embedded_and_over_a_router() {
    let scene = [
        "--kind",
        "pedestrian-crossing",
        "--seed",
        "23",
        "--rsus",
        "1",
        "--v2x-model",
        "3gpp-urban-los",
        "--v2x-latency",
        "sidelink:4:10",
    ];
    let run = |extra: &[&str]| {
        let argv = args(&args(&["scene", "run", "--embedded"], &scene), extra);
        Proc::spawn("embedded", &argv).exit_json(Duration::from_secs(60))
    };
    let unwarned = run(&[]);
    assert_eq!(unwarned["metrics"]["collision"], true, "the unwarned ego crashes: {unwarned}");
    assert_eq!(unwarned["v2x"]["rsu0"]["warnings_made"], 0);
    let warned = run(&["--v2x-warnings"]);
    assert_eq!(warned["metrics"]["collision"], false, "the warned ego does not: {warned}");
    assert_eq!(warned, run(&["--v2x-warnings"]), "deterministic");
    let (rsu, ego) = (&warned["v2x"]["rsu0"], &warned["v2x"]["v0"]);
    let made = rsu["warnings_made"].as_u64().expect("a count");
    assert!(made > 0, "{rsu}");
    assert_eq!(ego["warning_copies"].as_u64(), Some(made), "one copy per warning to the only vehicle");
    let (passed, heard) =
        (ego["warnings_passed"].as_u64().expect("a count"), ego["warnings_heard"].as_u64().expect("a count"));
    assert!(heard <= passed && passed <= made && heard > 0, "{ego}");
    assert!(ego["warned_steps"].as_u64().expect("a count") > 0, "{ego}");
    // CPMs alone (what the RSU perceives, by ETSI's inclusion rules) prevent it too.
    let cpm = run(&["--v2x-cpm"]);
    assert_eq!(cpm["metrics"]["collision"], false, "the ego that hears CPMs does not: {cpm}");
    let (rsu, ego) = (&cpm["v2x"]["rsu0"], &cpm["v2x"]["v0"]);
    let cpms = rsu["cpms_made"].as_u64().expect("a count");
    assert!(cpms > 0 && rsu["warnings_made"] == 0, "{rsu}");
    assert_eq!(ego["cpm_copies"].as_u64(), Some(cpms), "{ego}");
    assert!(ego["cpm_objects_heard"].as_u64().expect("a count") > 0, "{ego}");

    let (_router, locator) = start_router();
    let dir = tempfile::tempdir().expect("a temporary directory");
    let summaries = dir.path().join("participants.jsonl");
    let over_router = ["--router", locator.as_str(), "--speed", "1", "--v2x-warnings", "--participant-summaries"];
    let argv = args(&args(&args(&["scene", "run"], &scene), &over_router), &[summaries.to_str().expect("utf-8")]);
    let real = Proc::spawn("run", &argv).exit_json(Duration::from_secs(90));
    assert_eq!(real["truth_digest"], warned["truth_digest"], "the warned episode, step for step: {real}");
    assert_eq!(real["metrics"]["collision"], false, "{real}");
    let lines = std::fs::read_to_string(&summaries).expect("the participants' summaries");
    let real_time: PerParticipant = lines
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap_or_else(|e| panic!("{e}: {l}")))
        .map(|s| (s["participant"].as_str().expect("participant").to_owned(), s["v2x"].clone()))
        .collect();
    let virtual_time: PerParticipant = serde_json::from_value(warned["v2x"].clone()).expect("V2X counts");
    assert_warnings_agree(&real_time, &virtual_time);
}
