//! The warning role against real Zenoh sessions in this process: a router on a free port, the
//! cloud with `ingest,twin,warning`, raw edge publishers and a subscriber on the vehicles'
//! warning keys. A pair on a collision course is warned, a safe pair is not, and bad input is
//! counted and dropped.

use super::test_harness::{Router, STEP, start_cloud, state_publisher};
use super::{CloudConfig, Role};
use risktwin_common::telemetry::{HazardKind, HazardWarning, VehicleStateSample};
use risktwin_protos::{decode_tagged, encode};
use risktwin_transport::connect;
use risktwin_transport::wall_clock::unix_ns;
use std::collections::BTreeMap;
use std::time::{Duration, Instant};
use tokio::sync::mpsc;
use tokio::time::timeout;

/// `source`'s state number `seq`, stamped now, at (`x_m`, `y_m`) driving east at `vx_mps`.
fn state(source: &str, seq: u64, x_m: f64, y_m: f64, vx_mps: f64) -> VehicleStateSample {
    let mut s = crate::test_fixtures::state(source, seq, unix_ns());
    s.pose.x_m = x_m;
    s.pose.y_m = y_m;
    s.velocity.x = vx_mps;
    s.speed_mps = vx_mps;
    s
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_collision_course_is_warned_a_safe_pair_is_not_and_bad_input_is_counted() {
    let router = Router::start().await;
    let client = router.client.clone();

    // The vehicles' side: every warning of the site.
    let vehicles = connect(&client).await.unwrap();
    let (warn_tx, mut warn_rx) = mpsc::unbounded_channel();
    let _warnings = vehicles
        .declare_subscriber("risktwin/v1/site/*/warning")
        .callback(move |sample| {
            let _ = warn_tx.send((
                sample.key_expr().to_string(),
                sample.encoding().to_string(),
                sample.payload().to_bytes().into_owned(),
            ));
        })
        .await
        .unwrap();

    let mut cloud_config = CloudConfig::new(client.clone());
    cloud_config.roles = vec![Role::Ingest, Role::Twin, Role::Warning];
    // Every critical state warns: the warnings after the first ones go through the publishers
    // the declaring task made (the repeat limit has its unit tests).
    cloud_config.warning.repeat_ns = 0;
    let (cloud_stop, cloud) = start_cloud(cloud_config).await;

    let edges = connect(&client).await.unwrap();
    let mut publishers = BTreeMap::new();
    for source in ["veh-a", "veh-b", "veh-c", "veh-d"] {
        publishers.insert(source, state_publisher(&edges, format!("risktwin/v1/site/{source}/state")).await);
    }
    // veh-a drives at 10 m/s towards veh-b standing 20 m ahead (TTC 1.55 s); veh-c and veh-d
    // drive side by side at 20 m/s, 50 m to the north. States every 20 ms until both of the
    // first pair were warned through a declared publisher.
    let mut got: Vec<HazardWarning> = Vec::new();
    let deadline = Instant::now() + STEP;
    let mut seq = 0;
    // At least 10 rounds (200 ms), so that the aligner emits snapshots too, and 5 more after
    // the first warning to each (a one-off put, sent before its publisher was declared).
    let warned = |got: &[HazardWarning], who: &str| got.iter().filter(|w| w.warned_source == who).count();
    while seq < 10 || warned(&got, "veh-a") < 5 || warned(&got, "veh-b") < 5 {
        assert!(Instant::now() < deadline, "no warning for both cars within {STEP:?}: {got:?}");
        for (source, x, y, v) in [
            ("veh-a", 0.0, 0.0, 10.0),
            ("veh-b", 20.0, 0.0, 0.0),
            ("veh-c", 0.0, 50.0, 20.0),
            ("veh-d", 0.0, 53.5, 20.0),
        ] {
            publishers[source].put(encode(&state(source, seq, x, y, v))).await.unwrap();
        }
        seq += 1;
        tokio::time::sleep(Duration::from_millis(20)).await;
        while let Ok((key, encoding, bytes)) = warn_rx.try_recv() {
            let warning = decode_tagged::<HazardWarning>(&encoding, &bytes).expect("a valid, tagged warning");
            assert_eq!(key, format!("risktwin/v1/site/{}/warning", warning.warned_source));
            got.push(warning);
        }
    }
    for w in &got {
        let pair = (w.warned_source.as_str(), w.hazard_source.as_str());
        assert!(matches!(pair, ("veh-a", "veh-b") | ("veh-b", "veh-a")), "{w:?}");
        // Stamped at the put, after the trigger's time (the clock mapping's tolerance aside).
        let (captured, published) = (w.header.capture_time_ns, w.header.publish_time_ns);
        assert!(published >= captured - 100_000_000 && published <= unix_ns(), "{w:?}");
        // Both stand in a lane of the cloud's default road (lane TTC) or off it (contact
        // predicted at a 50 ms step). The gap is 15.5 m less what veh-a's state moved on to the
        // trigger's time: its age, up to 200 ms, depends on timing, and is a little negative
        // where veh-b's mapped time lies before veh-a's (two sources' clock estimates differ by
        // a few ms; 10 ms allowed). So the TTC is checked against the distance the warning
        // gives: closing at 10 m/s.
        assert!(matches!(w.kind, HazardKind::LaneTtc | HazardKind::PredictedContact), "{w:?}");
        assert!(w.distance_m > 13.5 - 1e-6 && w.distance_m < 15.6, "{w:?}");
        let closing_s = w.distance_m / 10.0;
        assert!(w.ttc_s > closing_s - 0.01 && w.ttc_s < closing_s + 0.06, "{w:?}");
    }

    // Bad input on the same streams: counted by reason, warns no one, stops nothing.
    let mut nan = state("veh-a", seq, 0.0, 0.0, 10.0);
    nan.speed_mps = f64::NAN;
    for payload in [b"\x00garbage".to_vec(), encode(&nan), encode(&state("veh-z", seq, 0.0, 0.0, 10.0))] {
        publishers["veh-a"].put(payload).await.unwrap();
    }
    let tagged_as_list = encode(&state("veh-b", seq, 20.0, 0.0, 0.0));
    publishers["veh-b"].put(tagged_as_list).encoding("application/protobuf;risktwin.v1.ObjectList").await.unwrap();
    // A warning key is no edge stream: the ingest never sees it.
    edges.put("risktwin/v1/site/veh-a/warning", b"not a warning".to_vec()).await.unwrap();
    // One more good state after the bad ones: the path still runs.
    publishers["veh-c"].put(encode(&state("veh-c", seq, 0.0, 50.0, 20.0))).await.unwrap();
    drop(publishers);
    edges.close().await.unwrap();

    cloud_stop.fire();
    let summary = timeout(STEP, cloud).await.unwrap().unwrap().unwrap();
    let dropped = &summary.ingest.dropped;
    let expected = [("malformed", 1), ("invalid-field", 1), ("source-mismatch", 1), ("wrong-schema", 1)];
    assert_eq!(dropped, &expected.into_iter().map(|(k, n)| (k.to_owned(), n)).collect::<BTreeMap<_, _>>());
    let warning = summary.warning.expect("the warning role ran");
    // Every accepted message was a state (a sample the transport lost is neither).
    assert_eq!(warning.states, summary.ingest.total_received, "{warning:?}");
    assert!(warning.states <= 4 * seq + 1 && warning.states > 3 * seq, "{warning:?}");
    assert!(warning.sent >= 10 && warning.failed == 0, "{warning:?}");
    assert_eq!(warning.via_publisher + warning.one_off, warning.sent, "{warning:?}");
    assert!(warning.via_publisher > 0, "declared publishers carry the later warnings: {warning:?}");
    assert_eq!(warning.sent_to.keys().collect::<Vec<_>>(), ["site/veh-a", "site/veh-b"]);
    assert!(summary.ingest.snapshots > 0, "the aligned snapshots go on beside the warnings");
    vehicles.close().await.unwrap();
    router.stop().await;
}
