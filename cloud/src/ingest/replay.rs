//! A recording fed straight into an [`IngestWorker`], unpaced and in-process, each message at
//! its recorded receive (log) time: the offline replay, and the throughput benchmark's path.
//!
//! Each channel's topic is parsed once (source, stream) and cached by channel id, so a message
//! costs the cursor's copy plus the worker; nothing is allocated per message here.

use super::sample::TwinSample;
use super::worker::IngestWorker;
use risktwin_align::Snapshot;
use risktwin_protos::recording::{MessageCursor, RecordingError};
use risktwin_transport::EdgeStream;
use risktwin_transport::keyexpr::parse_edge_key;
use std::io::{Read, Seek, Write};

/// What a replay fed in.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ReplayCounts {
    /// Messages handed to the worker.
    pub fed: u64,
    /// Messages on topics outside the edge scheme, or with a log time beyond `i64`, left out.
    pub skipped: u64,
}

/// Where a channel's messages go: `None` for a topic outside the edge scheme.
type Route = Option<(Box<str>, EdgeStream)>;

/// Feeds every edge-stream message of `cursor` through `worker` at its log time.
pub fn replay_into<R: Read, W: Write + Seek>(
    cursor: &mut MessageCursor<R>,
    worker: &mut IngestWorker<W>,
    mut on_snapshot: impl FnMut(&Snapshot<TwinSample>),
) -> Result<ReplayCounts, RecordingError> {
    let mut routes: Vec<Option<Route>> = Vec::new();
    let mut counts = ReplayCounts::default();
    while let Some(m) = cursor.next_message() {
        let m = m?;
        let slot = usize::from(m.channel_id);
        if routes.len() <= slot {
            routes.resize(slot + 1, None);
        }
        let route = routes[slot].get_or_insert_with(|| parse_edge_key(m.topic).map(|k| (k.source.into(), k.stream)));
        let (Some((source, stream)), Ok(receive_ns)) = (route.as_ref(), i64::try_from(m.log_time_ns)) else {
            counts.skipped += 1;
            continue;
        };
        worker.handle(source, *stream, m.topic, m.data, receive_ns, &mut on_snapshot)?;
        counts.fed += 1;
    }
    Ok(counts)
}
