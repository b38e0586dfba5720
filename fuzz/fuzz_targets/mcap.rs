//! A recording file, as the binary reads one: every message streamed by `MessageCursor`
//! (strict and salvaging collectors), a CommonRoad import rebuilt from it
//! (`risktwin criticality --mcap`), its messages replayed through an ingest worker (`risktwin
//! replay-ingest`), and `risktwin recover` rewriting its readable part.
#![no_main]

use libfuzzer_sys::fuzz_target;
use risktwin_cloud::commonroad_recording::read_scenario;
use risktwin_cloud::ingest::{IngestWorker, replay_into};
use risktwin_align::IngestConfig;
use risktwin_commonroad::criticality::scenario_criticality;
use risktwin_protos::recording::scan::RecordScanner;
use risktwin_protos::recording::{MessageCursor, read_messages, recover, salvage_messages};
use std::io::Cursor;

fuzz_target!(|data: &[u8]| {
    let len = data.len() as u64;
    let _ = read_messages(data);
    let _ = salvage_messages(data);
    if let Ok((scenario, _)) = read_scenario(MessageCursor::new(data).with_source_len(len)) {
        let _ = scenario_criticality(&scenario, None);
    }
    let mut worker: IngestWorker<Cursor<Vec<u8>>> = IngestWorker::new(IngestConfig::default(), None);
    let _ = replay_into(&mut MessageCursor::new(data).with_source_len(len), &mut worker, |_| {});
    let _ = recover(RecordScanner::new(data).with_source_len(len), Cursor::new(Vec::new()));
});
