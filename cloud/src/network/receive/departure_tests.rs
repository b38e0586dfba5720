//! A source whose edge left (its liveliness token went): its next sample's session decides
//! whether its numbers start over. A router restart takes every edge's token away and brings the
//! same sessions back, whose caches then send the samples of the outage again, below the newest
//! live number: those must fill the gap, not start a new count.

use super::{LiveIngest, Origin};
use risktwin_protos::encode;
use risktwin_transport::wall_clock::unix_ns;
use risktwin_transport::zenoh::session::ZenohId;
use risktwin_transport::{EdgeStream, protobuf};

const KEY: &str = "risktwin/v1/s1/veh-1/state";

fn session(n: u8) -> ZenohId {
    ZenohId::try_from([n; 16].as_slice()).expect("a 16-byte id")
}

/// Captured a second ago, 1 ms apart: never ahead of the cloud's clock.
fn feed(ingest: &mut LiveIngest, seqs: std::ops::Range<u64>, publisher: u8, recovered: bool) {
    let epoch_ns = unix_ns() - 1_000_000_000;
    for seq in seqs {
        let sample = crate::test_fixtures::state("veh-1", seq, epoch_ns + seq as i64 * 1_000_000);
        let origin = Origin { recovered, publisher: Some(session(publisher)) };
        ingest
            .handle(KEY, &protobuf(EdgeStream::State.message()), &encode(&sample), None, origin)
            .expect("no recording");
    }
}

#[test]
fn the_same_session_back_after_its_token_went_fills_its_gap_from_the_cache() {
    let mut ingest = LiveIngest::new(None, None).expect("an ingest");
    feed(&mut ingest, 0..40, 1, false);
    ingest.edge_left("s1", "veh-1");
    // Back through the new router: live numbers first, the outage's from the cache after them.
    feed(&mut ingest, 60..80, 1, false);
    feed(&mut ingest, 40..60, 1, true);
    let summary = ingest.summary();
    assert_eq!(summary.received["veh-1"]["state"], 80, "{summary:?}");
    assert!(summary.dropped.is_empty(), "{:?}", summary.dropped);
    assert_eq!(summary.total_presumed_lost, 0, "{:?}", summary.presumed_lost);
    assert_eq!(summary.total_recovered, 20);
}

#[test]
fn another_session_after_the_token_went_starts_the_count_over() {
    let mut ingest = LiveIngest::new(None, None).expect("an ingest");
    feed(&mut ingest, 0..40, 1, false);
    ingest.edge_left("s1", "veh-1");
    // A new process under the same name numbers from 0 again.
    feed(&mut ingest, 0..20, 2, false);
    let summary = ingest.summary();
    assert_eq!(summary.received["veh-1"]["state"], 60, "{summary:?}");
    assert!(summary.dropped.is_empty(), "its numbers are not duplicates: {:?}", summary.dropped);
    assert_eq!(summary.total_presumed_lost, 0, "{:?}", summary.presumed_lost);
}
