//! The edge roles' live Prometheus metrics (docs/metrics.md): messages sent per stream as they
//! go out (a counter handle per stream, set to the count the summary keeps), whether a cloud is
//! there, and at the end what the summary says became of them.

use crate::summary::{DeliverySummary, ReplaySummary};
use risktwin_transport::EdgeStream;
use risktwin_transport::keyexpr::parse_edge_key;
use std::collections::BTreeMap;

const SENT: &str = "risktwin_edge_messages_sent_total";

/// A counter of `site/source`'s sent messages per stream it publishes (by [`EdgeStream::index`];
/// a no-op for the others), to be set after each put.
pub(crate) fn sent_counters(
    site: &str,
    source: &str,
    streams: &[EdgeStream],
) -> [metrics::Counter; EdgeStream::ALL.len()] {
    EdgeStream::ALL.map(|stream| {
        if !streams.contains(&stream) {
            return metrics::Counter::noop();
        }
        metrics::counter!(SENT, "site" => site.to_owned(), "source" => source.to_owned(), "stream" => stream.as_str())
    })
}

/// Per stream counts of `site/source` under `name`.
fn per_stream(name: &'static str, site: &str, source: &str, counts: &BTreeMap<String, u64>) {
    for (stream, n) in counts {
        let labels = [("site", site.to_owned()), ("source", source.to_owned()), ("stream", stream.clone())];
        metrics::counter!(name, &labels).absolute(*n);
    }
}

/// The final counts of `site/source`: sent (forwarded, for a gateway) and, when watched, what
/// became of them.
pub(crate) fn export_final(site: &str, source: &str, sent: &BTreeMap<String, u64>, delivery: Option<&DeliverySummary>) {
    if !risktwin_transport::metrics::enabled() {
        return;
    }
    per_stream(SENT, site, source, sent);
    if let Some(d) = delivery {
        export_delivery(site, source, d);
    }
}

/// What became of `site/source`'s messages, and how long the cloud was gone.
pub(crate) fn export_delivery(site: &str, source: &str, d: &DeliverySummary) {
    per_stream("risktwin_edge_messages_acknowledged_total", site, source, &d.acknowledged);
    per_stream("risktwin_edge_messages_lost_total", site, source, &d.lost);
    per_stream("risktwin_edge_messages_undelivered_total", site, source, &d.undelivered);
    per_stream("risktwin_edge_messages_too_large_total", site, source, &d.too_large);
    let labels = [("site", site.to_owned()), ("source", source.to_owned())];
    metrics::gauge!("risktwin_edge_cloud_gone_seconds", &labels).set(d.cloud.gone_s);
    metrics::gauge!("risktwin_edge_cloud_alive", &labels).set(f64::from(u8::from(d.cloud.alive_at_exit)));
}

/// A replay's final counts: messages published per edge stream, and per source what became of
/// them.
pub(crate) fn export_replay(summary: &ReplaySummary) {
    if !risktwin_transport::metrics::enabled() {
        return;
    }
    for (topic, n) in &summary.by_key {
        if let Some(key) = parse_edge_key(topic) {
            let labels = [
                ("site", key.site.to_owned()),
                ("source", key.source.to_owned()),
                ("stream", key.stream.as_str().to_owned()),
            ];
            metrics::counter!(SENT, &labels).absolute(*n);
        }
    }
    for (name, delivery) in &summary.delivery {
        let (site, source) = name.split_once('/').unwrap_or(("", name));
        export_delivery(site, source, delivery);
    }
}

/// Whether a cloud's token is there for `site/source` (1) or not (0), as the watch sees it.
pub(crate) fn cloud_alive(site: &str, source: &str) -> metrics::Gauge {
    metrics::gauge!("risktwin_edge_cloud_alive", "site" => site.to_owned(), "source" => source.to_owned())
}
