//! Identity and authorisation between real processes around a real router under mutual TLS
//! with access rules (docs/security.md): a session without a certificate of the deployment's
//! CA gets nothing through; only a cloud identity's push reaches a vehicle; an edge that
//! publishes under another vehicle's keys is refused by the router while the genuine stream
//! arrives whole; and the cloud recovers from an edge's cache across a router restart.

use crate::faults::{Fault, TLS_IDENTITIES, assert_accounted, assert_held_back, per_stream, run_with_fault};
use crate::support::{Certs, Proc, runtime, session_as};
use risktwin_transport::keyexpr::{CloudToEdge, cloud_to_edge};
use risktwin_transport::{SiteId, SourceId, zenoh};
use serde_json::Value;
use std::time::Duration;

const STEP: Duration = Duration::from_secs(60);
const SITE: &str = "track";

/// A cloud ingest under `identity`, a client of the router, once ready.
fn cloud(certs: &Certs, locator: &str) -> Proc {
    let mut args = vec!["cloud", "--roles", "ingest", "--mode", "client", "--connect", locator];
    args.extend(certs.flags("cloud:c"));
    let mut cloud = Proc::spawn("cloud", &args);
    cloud.wait_line(STEP, |l| l == "ready");
    cloud
}

/// `edge vehicle --id id` with `tls` flags (none: plain) and `extra` arguments.
fn vehicle(name: &str, id: &str, connect: &str, tls: &[&str], extra: &[&str]) -> Proc {
    let mut args = vec!["edge", "vehicle", "--id", id, "--site", SITE, "--mode", "client", "--connect", connect];
    args.extend(tls);
    args.extend(extra);
    Proc::spawn(name, &args)
}

/// Waits for `p` to fail (it could not join), and returns its stderr.
fn refused_to_join(p: &mut Proc) -> String {
    let (status, _) = p.wait_exit(STEP);
    let stderr = p.drain_stderr();
    assert_eq!(status.code(), Some(1), "{} joined a TLS router it had no right to:\n{stderr}", p.name);
    assert!(stderr.contains("error:"), "{stderr}");
    stderr
}

/// The cloud's `received` of `source`, stream by stream, equals what the edge's summary sent.
fn assert_received_all(cloud: &Value, edge: &Value, source: &str) {
    let sent = edge["sent"].as_object().expect("sent per stream");
    assert!(sent.values().all(|n| n.as_u64() > Some(0)), "{edge}");
    for (stream, n) in sent {
        assert_eq!(&cloud["received"][source][stream], n, "{source}/{stream}: received = sent; {cloud}");
    }
}

#[test]
fn sessions_without_a_certificate_of_the_deployment_ca_get_nothing_through() {
    let certs = Certs::init(&["router:r", "cloud:c", "edge:track:veh-a"]);
    let other_ca = Certs::init(&["edge:track:veh-a"]);
    let (_router, locator) = certs.start_router("router:r");
    let mut cloud = cloud(&certs, &locator);
    let count = ["--count", "40", "--rate-hz", "100", "--wait-for-cloud-s", "5"];

    // Plain TCP to the TLS port: no TLS handshake, no Zenoh session.
    let plain = locator.replacen("tls/", "tcp/", 1);
    refused_to_join(&mut vehicle("anonymous", "veh-a", &plain, &[], &count));
    // The right name, the deployment's CA trusted, but a certificate another CA signed.
    let ca = certs.dir.path().join("ca.pem");
    let forged_cert = other_ca.dir.path().join("edge:track:veh-a.pem");
    let forged_key = other_ca.dir.path().join("edge:track:veh-a-key.pem");
    let forged_tls = [ca.to_str().unwrap(), forged_cert.to_str().unwrap(), forged_key.to_str().unwrap()];
    let forged = ["--tls-ca", forged_tls[0], "--tls-cert", forged_tls[1], "--tls-key", forged_tls[2]];
    refused_to_join(&mut vehicle("other-ca", "veh-a", &locator, &forged, &count));
    // TLS that trusts the router but shows no certificate of its own.
    runtime().block_on(async {
        let mut config = zenoh::Config::default();
        let endpoints = serde_json::json!([locator]).to_string();
        let ca_path = serde_json::json!(ca.to_str().unwrap()).to_string();
        for (key, value) in [
            ("mode", r#""client""#),
            ("connect/endpoints", endpoints.as_str()),
            ("connect/timeout_ms", "5000"),
            ("transport/link/tls/root_ca_certificate", ca_path.as_str()),
        ] {
            config.insert_json5(key, value).expect("a config value");
        }
        assert!(zenoh::open(config).await.is_err(), "a client without a certificate joined the TLS router");
    });

    // The genuine vehicle, meanwhile, gets every message through.
    let mut genuine = vehicle("genuine", "veh-a", &locator, &certs.flags("edge:track:veh-a"), &count);
    let sent = genuine.exit_json(STEP);
    cloud.wait_line(STEP, |l| l == "edge left: track/veh-a");
    cloud.terminate();
    let summary = cloud.exit_json(STEP);
    assert_received_all(&summary, &sent, "veh-a");
    assert_eq!(summary["total_dropped"], 0, "{summary}");
    assert_eq!(summary["received"].as_object().map(|r| r.len()), Some(1), "only the genuine vehicle: {summary}");
}

/// Puts one policy update on `to`'s policy key from a session as `identity`, once the key's
/// subscriber matches (so that the router, not timing, decides whether it arrives).
fn put_policy_as(certs: &Certs, identity: &str, locator: &str, to: &str) {
    runtime().block_on(async {
        let s = session_as(locator, certs.security(identity)).await.expect("the identity joins");
        let key = cloud_to_edge(&SiteId::new(SITE).unwrap(), &SourceId::new(to).unwrap(), CloudToEdge::Policy);
        let publisher = s
            .declare_publisher(key)
            .encoding(risktwin_transport::protobuf("risktwin.v1.PolicyUpdate"))
            .await
            .expect("a publisher");
        let matched = async {
            while !publisher.matching_status().await.expect("a status").matching() {
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
        };
        tokio::time::timeout(STEP, matched).await.expect("the vehicle's subscriber is seen");
        publisher.put(b"not a policy update".to_vec()).await.expect("a put");
        publisher.undeclare().await.expect("undeclare");
        risktwin_transport::close(s).await.expect("close");
    });
}

#[test]
fn only_a_cloud_identity_pushes_and_an_edge_publishes_only_under_its_own_keys() {
    let certs = Certs::init(&["router:r", "cloud:c", "edge:track:veh-a", "edge:track:veh-b"]);
    let (_router, locator) = certs.start_router("router:r");
    let mut cloud = cloud(&certs, &locator);
    let mut genuine = vehicle("veh-a", "veh-a", &locator, &certs.flags("edge:track:veh-a"), &["--rate-hz", "100"]);
    genuine.wait_line(STEP, |l| l == "edge veh-a: publishing");

    // veh-b's certificate publishing as veh-a: every sample refused by the router.
    let forger_args = ["--count", "60", "--rate-hz", "100", "--wait-for-cloud-s", "5"];
    let mut forger = vehicle("forger", "veh-a", &locator, &certs.flags("edge:track:veh-b"), &forger_args);
    // It is told: no acknowledgement reaches it (veh-a's ack key is not its own), so all it
    // sent is undelivered and it exits 1.
    let (status, stdout) = forger.wait_exit(STEP);
    assert_eq!(status.code(), Some(1), "the forger's undelivered samples fail it:\n{stdout}");
    let forged: serde_json::Value = serde_json::from_str(&stdout).expect("the forger's summary");
    assert!(forged["sent"]["state"].as_u64() > Some(0), "the forger did publish: {forged}");
    assert_eq!(forged["undelivered"]["state"], forged["sent"]["state"], "{forged}");

    // Pushes to veh-a: an edge identity's, through the CLI (it cannot even see veh-a) and raw
    // (it sees the subscriber, but its put is refused); an anonymous one (no link); the cloud's.
    let dir = tempfile::tempdir().expect("a temporary directory");
    let (signing_key, _) = crate::support::keys(dir.path(), "cloud");
    let weights = dir.path().join("w.safetensors");
    std::fs::write(&weights, b"weights").expect("a weights file");
    let push = |connect: &str, tls: &[&str]| {
        let mut args = vec!["push", "policy", "--weights", weights.to_str().unwrap(), "--policy-id", "p"];
        args.extend(["--version", "1", "--algo", "ppo", "--signing-key", &signing_key, "--to", "veh-a"]);
        args.extend(["--site", SITE, "--mode", "client", "--connect", connect, "--wait-for-edge-s", "3"]);
        args.extend(tls);
        Proc::spawn("push", &args)
    };
    let mut as_edge = push(&locator, &certs.flags("edge:track:veh-b"));
    let (status, _) = as_edge.wait_exit(STEP);
    assert_ne!(status.code(), Some(0), "an edge identity's push went out:\n{}", as_edge.drain_stderr());
    put_policy_as(&certs, "edge:track:veh-b", &locator, "veh-a");
    refused_to_join(&mut push(&locator.replacen("tls/", "tcp/", 1), &[]));
    let pushed = push(&locator, &certs.flags("cloud:c")).exit_json(STEP);
    assert_eq!(pushed["delivered"], true, "{pushed}");
    // veh-a holds no trust key: an update that reaches it is refused as unverifiable.
    genuine.wait_line(STEP, |l| l.starts_with("edge: refused policy update: unverifiable: "));

    genuine.terminate();
    let sent = genuine.exit_json(STEP);
    let refused = &sent["pushes"]["policies_refused"];
    assert_eq!(refused, &serde_json::json!({"unverifiable": 1}), "only the cloud's push arrived: {sent}");
    cloud.wait_line(STEP, |l| l == "edge left: track/veh-a");
    cloud.terminate();
    let summary = cloud.exit_json(STEP);
    // Nothing of the forger's arrived: not a duplicate, not a conflict, not a drop.
    assert_received_all(&summary, &sent, "veh-a");
    assert_eq!(summary["total_dropped"], 0, "{summary}");
    assert_eq!(summary["id_conflicts"].as_object().map_or(0, |c| c.len()), 0, "{summary}");
}

#[test]
fn the_cloud_recovers_from_an_edge_cache_across_a_router_restart_under_tls() {
    let certs = Certs::init(&TLS_IDENTITIES);
    let outage = Duration::from_millis(1300);
    let outcome = run_with_fault("30", Fault::RouterRestart(outage), "client", Some(&certs));
    assert_accounted(&outcome, outage);
    assert_held_back(&outcome, outage);
    let rows = per_stream(&outcome);
    assert!(rows.iter().all(|r| r.lost == 0), "a 1.3 s outage within a 30 s cache loses nothing: {rows:?}");
    assert!(rows.iter().any(|r| r.recovered > 0), "something came from a cache: {rows:?}");
}
