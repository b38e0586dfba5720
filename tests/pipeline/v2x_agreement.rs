//! The V2X scene and the agreement its real-time runs must show with virtual time, shared by
//! the run over a router (`tests/pipeline/scene_v2x.rs`) and the emulated deployment
//! (`tests/deploy/v2x.rs`).
//!
//! A lockstep run (`--speed 1`) is the embedded episode (its truth digest), so the copies decided
//! and passed agree exactly. Each copy's latency is imposed from the same seeded draw virtual
//! time records, so the p50s agree by construction (up to the excess); what real time adds is
//! the excess, arrival − (sent + drawn latency), and the copies that came after their draw
//! (`late`).

use serde_json::Value;
use std::collections::BTreeMap;

/// An emergency braking with the ego, two connected vehicles and four RSUs 150 m apart in urban
/// NLOS: the RSUs 300 and 450 m along the route hear about 80 % and 30 % of the CAMs. The RSUs
/// warn (rsu0 and rsu1 of the braked cars standing in their view) and send CPMs of what they
/// perceive.
pub const SCENE: [&str; 14] = [
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
    "--v2x-warnings",
    "--v2x-cpm",
];

/// V2X counts per participant.
pub type PerParticipant = BTreeMap<String, Value>;

fn count(v2x: &Value, key: &str) -> u64 {
    v2x[key].as_u64().unwrap_or_else(|| panic!("{key} in {v2x}"))
}

/// Copies and passed equal per participant, pooled PDR within 2 points, each participant's
/// latency p50 within 2 ms and its excess p50 within 2 ms, late copies at most 2 % of the passed
/// ones, nothing undecided, stale, ahead, malformed or foreign, and the warnings agreeing
/// ([`assert_warnings_agree`]); figures printed under `what`.
pub fn assert_agrees(what: &str, real_time: &PerParticipant, virtual_time: &PerParticipant) {
    assert_eq!(real_time.keys().collect::<Vec<_>>(), virtual_time.keys().collect::<Vec<_>>(), "participants");
    let total = |side: &PerParticipant, key: &str| side.values().map(|v| count(v, key)).sum::<u64>();
    let pdr = |side: &PerParticipant| total(side, "passed") as f64 / total(side, "copies") as f64;
    let (real_pdr, virtual_pdr) = (pdr(real_time), pdr(virtual_time));
    let (late, passed) = (total(real_time, "late"), total(real_time, "passed"));
    eprintln!("{what}: V2X PDR {real_pdr:.4}, virtual time {virtual_pdr:.4}; late {late} of {passed} passed");
    assert!(virtual_pdr < 0.9 && total(virtual_time, "copies") > 500, "a loss to measure: {virtual_time:?}");
    assert!((real_pdr - virtual_pdr).abs() <= 0.02, "PDR {real_pdr} against {virtual_pdr}");
    // The hold ends at sent + the drawn latency, so a copy is late only where the transport
    // (or the receiver's own step) took longer than its draw: rare on one host.
    assert!(late * 50 <= passed, "{late} of {passed} passed copies late (more than 2 %): {real_time:?}");
    for (id, virt) in virtual_time {
        let real = &real_time[id];
        assert_eq!(count(real, "cams_sent"), count(virt, "cams_sent"), "{id}: CAMs sent");
        assert_eq!(count(real, "copies"), count(virt, "copies"), "{id}: copies decided: {real}");
        assert_eq!(count(real, "passed"), count(virt, "passed"), "{id}: copies passed: {real}");
        for dropped in ["undecided", "stale", "ahead", "malformed", "foreign"] {
            assert_eq!(count(real, dropped), 0, "{id}: {dropped}: {real}");
        }
        let ms = |v: &Value, key: &str| v[key].as_f64().unwrap_or_else(|| panic!("{id}: no {key} in {v}"));
        let (real_ms, virtual_ms) = (ms(real, "latency_p50_ms"), ms(virt, "latency_p50_ms"));
        let (excess_p50, excess_p99) = (ms(real, "excess_p50_ms"), ms(real, "excess_p99_ms"));
        eprintln!(
            "{id}: copies {}, passed {}, late {}, p50 {real_ms:.2}/{virtual_ms:.2} ms (real/virtual), \
             excess p50 {excess_p50:.3} ms, p99 {excess_p99:.3} ms",
            count(real, "copies"),
            count(real, "passed"),
            count(real, "late")
        );
        assert!((real_ms - virtual_ms).abs() <= 2.0, "{id}: latency p50 {real_ms} ms against {virtual_ms} ms");
        assert!(excess_p50 <= 2.0, "{id}: excess p50 {excess_p50} ms over the drawn latency: {real}");
    }
    assert_warnings_agree(real_time, virtual_time);
}

/// The RSUs' warnings and CPMs decided alike in real and virtual time: per participant, made,
/// copies, passed, heard and warned steps equal; in real time no RSU batch came after the step
/// that needed it, and late copies (batch after the drawn latency) at most 2 % of the passed
/// ones.
pub fn assert_warnings_agree(real_time: &PerParticipant, virtual_time: &PerParticipant) {
    assert_eq!(real_time.keys().collect::<Vec<_>>(), virtual_time.keys().collect::<Vec<_>>(), "participants");
    for (id, virt) in virtual_time {
        let real = &real_time[id];
        let keys = ["warnings_made", "warning_copies", "warnings_passed", "warnings_heard", "warned_steps"];
        let cpm_keys = ["cpms_made", "cpm_objects_sent", "cpm_copies", "cpms_passed", "cpm_objects_heard"];
        for key in keys.into_iter().chain(cpm_keys) {
            assert_eq!(count(real, key), count(virt, key), "{id}: {key}: {real}");
        }
        assert_eq!(count(real, "warning_batches_late"), 0, "{id}: {real}");
        assert_eq!(count(real, "warning_batches_lost"), 0, "{id}: {real}");
        let (late, passed) = (count(real, "warnings_late"), count(real, "warnings_passed"));
        let (made, copies, heard) =
            (count(real, "warnings_made"), count(real, "warning_copies"), count(real, "warnings_heard"));
        eprintln!("{id}: warnings made {made}, copies {copies}, passed {passed}, heard {heard}, late {late}");
        assert!(late * 50 <= passed, "{id}: {late} of {passed} passed warnings late: {real}");
        let (cpms, cpm_copies) = (count(real, "cpms_made"), count(real, "cpm_copies"));
        let (cpms_passed, cpms_late) = (count(real, "cpms_passed"), count(real, "cpms_late"));
        eprintln!("{id}: CPMs made {cpms}, copies {cpm_copies}, passed {cpms_passed}, late {cpms_late}");
        assert!(cpms_late * 50 <= cpms_passed, "{id}: {cpms_late} of {cpms_passed} passed CPMs late: {real}");
    }
}
