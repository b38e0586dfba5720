//! Signed policy updates between real processes around a real router: a vehicle that trusts
//! the cloud's key drives with an update signed by it for this vehicle, and refuses — counted by
//! reason in its JSON summary — one whose weights or metadata changed after signing, one signed
//! with another key, an unsigned one; a vehicle with no trusted key refuses them all.

use crate::support::{Proc, keys, session, start_router};
use risktwin_common::telemetry::{Frame, Header, PolicyUpdate};
use risktwin_policy::signature::PolicySigningKey;
use risktwin_transport::keyexpr::{CloudToEdge, cloud_to_edge};
use risktwin_transport::{SiteId, SourceId, protobuf};
use serde_json::json;
use std::time::Duration;

const STEP: Duration = Duration::from_secs(60);
const SITE: &str = "sig";

fn vehicle(id: &str, locator: &str, trust: Option<&str>) -> Proc {
    let mut args = vec!["edge", "vehicle", "--id", id, "--site", SITE, "--connect", locator, "--rate-hz", "500"];
    // No cloud: pushes come from the test, nobody acknowledges (--no-ack).
    args.extend(["--wait-for-cloud-s", "0", "--no-ack"]);
    if let Some(key) = trust {
        args.extend(["--trust-key", key]);
    }
    let mut v = Proc::spawn(id, &args);
    v.wait_line(STEP, |l| l == format!("edge {id}: publishing"));
    v
}

/// `risktwin push policy` of `weights` (version 1) to `to`, signed with `key`.
fn push(locator: &str, to: &str, weights: &str, key: &str) {
    let mut args = vec!["push", "policy", "--weights", weights, "--policy-id", "ppo-s", "--version", "1"];
    args.extend(["--algo", "ppo", "--to", to, "--site", SITE, "--signing-key", key, "--connect", locator]);
    assert_eq!(crate::support::run_json(&args)["delivered"], true);
}

/// Publishes `update` on `to`'s policy key as the cloud would, once the vehicle's subscriber
/// matches (so that it cannot be lost before the vehicle hears of it).
fn put_raw(locator: &str, to: &str, update: &PolicyUpdate) {
    let runtime = tokio::runtime::Runtime::new().expect("a tokio runtime");
    runtime.block_on(async {
        let s = session(locator).await;
        let key =
            cloud_to_edge(&SiteId::new(SITE).expect("site"), &SourceId::new(to).expect("id"), CloudToEdge::Policy);
        let publisher =
            s.declare_publisher(key).encoding(protobuf("risktwin.v1.PolicyUpdate")).await.expect("publisher");
        let listener = publisher.matching_listener().await.expect("a matching listener");
        let matched = async {
            if publisher.matching_status().await.expect("status").matching() {
                return;
            }
            while let Ok(status) = listener.recv_async().await {
                if status.matching() {
                    return;
                }
            }
        };
        tokio::time::timeout(STEP, matched).await.expect("the vehicle subscribes");
        publisher.put(risktwin_protos::encode(update)).await.expect("put");
        drop(listener);
        publisher.undeclare().await.expect("undeclare");
        risktwin_transport::close(s).await.expect("close");
    });
}

fn refused(v: &mut Proc, reason: &str, n: usize) {
    v.wait_count(STEP, n, |l| l.starts_with(&format!("edge: refused policy update: {reason}: ")));
}

#[test]
fn only_updates_signed_by_the_trusted_key_for_the_vehicle_are_driven_with() {
    let (router, locator) = start_router();
    let dir = tempfile::tempdir().expect("a temporary directory");
    let (cloud_key, cloud_public) = keys(dir.path(), "cloud");
    let (stranger_key, _) = keys(dir.path(), "stranger");
    let out = dir.path().join("train");
    let mut trained = Proc::spawn(
        "train",
        &[
            "train",
            "--algo",
            "ppo",
            "--variant",
            "base",
            "--steps",
            "4096",
            "--format",
            "json",
            "--out",
            out.to_str().expect("UTF-8"),
        ],
    );
    let mut trusting = vehicle("veh-t", &locator, Some(&cloud_public));
    let mut untrusting = vehicle("veh-u", &locator, None);
    trained.exit_json(STEP);
    let weights_file = out.join("policy.safetensors");
    let weights = weights_file.to_str().expect("UTF-8");

    // Signed by the cloud for veh-t, then changed: one byte of the weights, or the version.
    let signer = PolicySigningKey::from_text(&std::fs::read_to_string(&cloud_key).expect("key")).expect("a key");
    let mut update = PolicyUpdate {
        header: Header { source: "cloud".into(), seq: 1, capture_time_ns: 1, publish_time_ns: 1, frame: Frame::World },
        policy_id: "ppo-s".into(),
        version: 1,
        algo: "ppo".into(),
        weights: std::fs::read(&weights_file).expect("weights"),
        target: format!("{SITE}/veh-t"),
        signature: Vec::new(),
    };
    signer.sign(&mut update);
    let mut flipped = update.clone();
    let middle = flipped.weights.len() / 2;
    flipped.weights[middle] ^= 0x01;
    put_raw(&locator, "veh-t", &flipped);
    refused(&mut trusting, "bad-signature", 1);
    let mut bumped = update.clone();
    bumped.version = 2;
    put_raw(&locator, "veh-t", &bumped);
    refused(&mut trusting, "bad-signature", 2);
    // The copy signed for veh-t, sent to veh-u: refused there for want of a trusted key.
    put_raw(&locator, "veh-u", &update);
    refused(&mut untrusting, "unverifiable", 1);

    push(&locator, "veh-t", weights, &stranger_key);
    refused(&mut trusting, "bad-signature", 3);
    // `push policy` signs always (it requires --signing-key); an unsigned update on the wire:
    let mut bare = update.clone();
    bare.signature.clear();
    put_raw(&locator, "veh-t", &bare);
    refused(&mut trusting, "unsigned", 1);
    push(&locator, "veh-u", weights, &cloud_key);
    refused(&mut untrusting, "unverifiable", 2);
    push(&locator, "veh-t", weights, &cloud_key);
    trusting.wait_line(STEP, |l| l.starts_with("edge: driving with policy ppo-s version 1"));

    let summaries: Vec<serde_json::Value> = [trusting, untrusting]
        .into_iter()
        .map(|mut v| {
            v.terminate();
            v.exit_json(STEP)
        })
        .collect();
    router.terminate();
    let t = &summaries[0]["pushes"];
    assert_eq!(t["policies_refused"], json!({"bad-signature": 3, "unsigned": 1}), "{t}");
    assert_eq!((&t["policy"]["policy_id"], &t["policy"]["version"]), (&json!("ppo-s"), &json!(1)), "{t}");
    let u = &summaries[1]["pushes"];
    assert_eq!(u["policies_refused"], json!({"unverifiable": 2}), "{u}");
    assert!(u["policy"].is_null(), "a vehicle without a trusted key drives with no network policy: {u}");
}
