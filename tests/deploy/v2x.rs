//! V2X on an emulated deployment (issue 16): a scene with V2X on a road-side host of its own
//! site, its data going to a cloud site over a 20 ms link, run by `deploy run` in network
//! namespaces, against the same scene embedded in one process in virtual time.
//!
//! The scene's participants meet on the host's own router (the radio is local: the channel
//! lives in their V2X layers, never in the relays), paced at the wall clock in lockstep
//! (`--speed 1`), so the episode is the embedded one (its truth digest) and every copy is
//! decided as in virtual time (what must agree: `tests/pipeline/v2x_agreement.rs`).

use super::{Deployment, LIMIT, risktwin};
use serde_json::Value;

#[path = "../pipeline/v2x_agreement.rs"]
mod v2x_agreement;
use v2x_agreement::{PerParticipant, SCENE, assert_agrees};

fn topology() -> String {
    let args: Vec<String> = SCENE.iter().chain(&["--speed", "1"]).map(|a| format!("{a:?}")).collect();
    format!(
        r#"
[[site]]
name = "cloud"

[[site]]
name = "road"

[[host]]
name = "cloud-0"
site = "cloud"
run = [{{ role = "cloud", args = ["--roles", "ingest"] }}]

[[host]]
name = "road-0"
site = "road"
run = [{{ role = "scene", args = [{}] }}]

[[link]]
between = ["road", "cloud"]
latency_ms = 20
"#,
        args.join(", ")
    )
}

#[test]
fn a_deployed_scene_with_v2x_agrees_with_its_virtual_time_statistics() {
    let argv: Vec<&str> = ["scene", "run", "--embedded"].iter().chain(&SCENE).copied().collect();
    let o = risktwin(&argv, LIMIT);
    assert!(o.status.success(), "embedded: {}", String::from_utf8_lossy(&o.stderr));
    let embedded: Value = serde_json::from_slice(&o.stdout).expect("the embedded outcome");
    let virtual_time: PerParticipant =
        serde_json::from_value(embedded["v2x"].clone()).expect("the embedded scene's V2X counts per participant");

    let d = Deployment::new(&topology());
    let report = d.run("30s");
    let host = d.out().join("hosts/road-0");
    let out = std::fs::read_to_string(host.join("scene.out")).expect("the scene's outcome");
    let scene: Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}"));
    assert_eq!(scene["truth_digest"], embedded["truth_digest"], "the same episode, step for step: {report}");
    let lines = std::fs::read_to_string(host.join("scene.participants")).expect("the participants' summaries");
    let real_time: PerParticipant = lines
        .lines()
        .map(|l| serde_json::from_str::<Value>(l).unwrap_or_else(|e| panic!("{e}: {l}")))
        .map(|s| (s["participant"].as_str().expect("participant").to_owned(), s["v2x"].clone()))
        .collect();
    assert_agrees("an emulated deployment", &real_time, &virtual_time);
    assert_eq!(d.leftovers(), Vec::<String>::new());
}
