//! The cloud's ingest of edge streams, as its Zenoh callback drives it: a sample's key, its
//! encoding, its replay-time attachment and its payload go through `LiveIngest::handle`
//! (key parsing, encoding check, decode and validation, exactly-once, clock mapping, alignment,
//! the twin). A sequence of samples per input, so state carries from one to the next.
#![no_main]

use libfuzzer_sys::fuzz_target;
use risktwin_cloud::network::{LiveIngest, Origin};
use risktwin_cloud::twin::outputs::TwinOutputs;
use risktwin_fuzz::{INGEST_SITES, INGEST_SOURCES, Records, ingest_tag};
use risktwin_protos::recording::decode_replay_time;
use risktwin_transport::EdgeStream;
use risktwin_transport::keyexpr::edge_stream;
use risktwin_transport::stream::protobuf;
use risktwin_transport::zenoh::bytes::Encoding;
use risktwin_transport::{SiteId, SourceId};

fuzz_target!(|data: &[u8]| {
    // Replay-time mode: receive times come from the attachments, so a run is deterministic.
    let Ok(ingest) = LiveIngest::new(None, Some(TwinOutputs::new(None))) else { return };
    let mut ingest = ingest.with_replay_time(true);
    let mut records = Records::new(data);
    while let Some(tag) = records.tag() {
        let (attachment, payload) = (records.frame(), records.frame());
        let stream_index = usize::from(tag & ingest_tag::STREAM_MASK);
        let source = INGEST_SOURCES[usize::from(tag >> ingest_tag::SOURCE_SHIFT & 3)];
        let site = INGEST_SITES[usize::from(tag >> ingest_tag::SITE_SHIFT & 1)];
        let key = match EdgeStream::ALL.get(stream_index) {
            Some(&stream) => match (SiteId::new(site), SourceId::new(source)) {
                (Ok(site), Ok(source)) => edge_stream(&site, &source, stream),
                // An id the key builder refuses, as another peer could still send it.
                _ => format!("risktwin/v1/{site}/{source}/{}", stream.as_str()),
            },
            None if stream_index == 5 => format!("risktwin/v1/{site}/{source}/telemetry"),
            None => String::from_utf8_lossy(attachment).into_owned(),
        };
        let stream = EdgeStream::ALL[stream_index % EdgeStream::ALL.len()];
        let encoding = match tag >> ingest_tag::ENCODING_SHIFT {
            0 => protobuf(stream.message()),
            1 => protobuf(EdgeStream::ALL[(stream_index + 1) % EdgeStream::ALL.len()].message()),
            2 => Encoding::default(),
            _ => protobuf(&stream.message().replace("v1", "v2")),
        };
        let replay_ns = decode_replay_time(attachment);
        // A recording error cannot happen without a recorder; anything else is a finding.
        ingest.handle(&key, &encoding, payload, replay_ns, Origin::default()).expect("no recorder, no recording error");
    }
    let _ = ingest.finish();
});
