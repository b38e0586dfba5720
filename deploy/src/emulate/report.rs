//! What a deployment shows: `status.json` while it runs, and on its end a report (`report.json`
//! and `report.md`) that also records how the run was made — per link the delay measured in
//! its relays against the configured one, per edge and stream sent / received / recovered / lost / missing, each
//! process's restarts, the event timeline.

use super::net::Net;
use super::options::{Options, topology_digest};
use super::plan::{PARTICIPANTS_EXT, Planned};
use super::relay::HopView;
use super::supervise::Supervised;
use crate::topology::Jitter;
use risktwin_transport::sync::LockExt;
use serde::Serialize;
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

#[derive(Debug, Clone, Serialize)]
pub struct TimelineEntry {
    pub at_s: f64,
    pub what: String,
}

#[derive(Debug, Serialize)]
pub struct LinkReport {
    pub name: String,
    pub latency_ms: f64,
    pub jitter: Option<Jitter>,
    pub bandwidth_mbps: Option<f64>,
    pub queue_kib: u64,
    /// Each chunk's time in the link's relays (read to written), ms; `None` when nothing crossed.
    pub measured_p50_ms: Option<f64>,
    pub measured_p99_ms: Option<f64>,
    pub chunks: u64,
    /// Bytes from the side that connects (a client; of two routers, the one first in the file)
    /// toward the router it connects to, and back.
    pub bytes_up: u64,
    pub bytes_down: u64,
    /// Both directions over the run, Mbit/s.
    pub mean_mbps: f64,
    pub connections: u64,
    /// When each connection was made, seconds into the run (the first 1000).
    pub connected_at_s: Vec<f64>,
    pub refused: u64,
}

#[derive(Debug, Serialize)]
pub struct ProcessReport {
    pub name: String,
    pub restarts: u32,
    pub ends: Vec<String>,
}

/// One stream of one edge: what the edge says it sent and the cloud says it received.
#[derive(Debug, Serialize)]
pub struct StreamReport {
    pub source: String,
    pub stream: String,
    pub sent: u64,
    /// Of `sent`, never put on the wire by the edge: a scene participant's messages made
    /// before any cloud subscribed, beyond its stream's cache.
    pub unsent: u64,
    pub received: u64,
    /// Of `received`, what came from the edge's cache after a gap (a partition, a router restart,
    /// a sample the link dropped).
    pub recovered: u64,
    /// Counted lost by the cloud: neither received nor recoverable from the edge's cache.
    pub lost: u64,
    /// sent − unsent − received − lost: not accounted for (an edge that ended during an outage, a cloud
    /// that stopped mid-recovery); negative: received more, e.g. a restarted edge's earlier
    /// incarnation.
    pub missing: i64,
    /// False when an incarnation of the edge ended without its summary (killed, crashed):
    /// what it sent is not known.
    pub sent_complete: bool,
    /// False when a run of the cloud ended without its summary: what it received is not known.
    pub received_complete: bool,
}

#[derive(Debug, Serialize)]
pub struct Report {
    pub version: &'static str,
    pub commit: &'static str,
    pub topology_file: String,
    /// FNV-1a of the file's bytes, 16 hex digits (a copy is `topology.toml` beside the report).
    pub topology_digest: String,
    pub seed: u64,
    pub machines: String,
    pub ran_s: f64,
    pub links: Vec<LinkReport>,
    pub processes: Vec<ProcessReport>,
    pub streams: Vec<StreamReport>,
    /// What the clouds dropped, by reason.
    pub cloud_dropped: BTreeMap<String, u64>,
    /// Per cloud process, its twin's lag behind its clock (its last run's `twin_lag`: `n`,
    /// `mean_us`, `p95_us`, `max_us`).
    pub twin_lag: BTreeMap<String, Value>,
    pub timeline: Vec<TimelineEntry>,
    #[serde(skip)]
    topology_text: String,
}

/// Every JSON document in the process's file with extension `ext`: its stdout (`out`: one per
/// incarnation that ended cleanly), a scene's participants' summaries.
fn printed(s: &Supervised, ext: &str) -> Vec<Value> {
    let text = std::fs::read_to_string(s.log_stem.with_extension(ext)).unwrap_or_default();
    serde_json::Deserializer::from_str(&text).into_iter::<Value>().map_while(Result::ok).collect()
}

/// What an edge says it sent on one stream: messages made, of them never put, and whether
/// every incarnation said.
#[derive(Clone, Copy, Default)]
struct Said {
    sent: u64,
    unsent: u64,
    complete: bool,
}

/// Adds what `summary` (an edge's, or a scene participant's) says `source` sent per stream.
fn add_sent(said: &mut BTreeMap<(String, String), Said>, source: &str, summary: &Value, complete: bool) {
    for (stream, n) in summary["sent"].as_object().into_iter().flatten() {
        let e = said.entry((source.to_owned(), stream.clone())).or_insert(Said { complete, ..Said::default() });
        e.sent += n.as_u64().unwrap_or(0);
        e.unsent += summary["unsent"][stream].as_u64().unwrap_or(0);
        e.complete &= complete;
    }
}

fn measured(view: &HopView, q: f64) -> Option<f64> {
    view.counts.delay_us.quantile(q).map(|us| us / 1e3)
}

impl Report {
    pub(super) fn build(
        o: &Options,
        net: &Net,
        begun: Instant,
        ran: Duration,
        processes: &[(Planned, Supervised)],
        hops: &[HopView],
        timeline: Vec<TimelineEntry>,
    ) -> Report {
        let links = hops
            .iter()
            .map(|h| {
                let bytes = h.counts.bytes.each_ref().map(|b| b.load(Ordering::Relaxed));
                LinkReport {
                    name: h.name.clone(),
                    latency_ms: h.base.latency.as_secs_f64() * 1e3,
                    jitter: h.base.jitter,
                    bandwidth_mbps: h.base.bandwidth_bps.map(|b| b / 1e6),
                    queue_kib: (h.base.queue_bytes / 1024) as u64,
                    measured_p50_ms: measured(h, 0.5),
                    measured_p99_ms: measured(h, 0.99),
                    chunks: h.counts.delay_us.count(),
                    bytes_up: bytes[0],
                    bytes_down: bytes[1],
                    mean_mbps: (bytes[0] + bytes[1]) as f64 * 8.0 / ran.as_secs_f64().max(1e-9) / 1e6,
                    connections: h.counts.connections.load(Ordering::Relaxed),
                    connected_at_s: h
                        .counts
                        .connected_at
                        .locked()
                        .iter()
                        .map(|t| t.saturating_duration_since(begun).as_secs_f64())
                        .collect(),
                    refused: h.counts.refused.load(Ordering::Relaxed),
                }
            })
            .collect();
        let mut sent: BTreeMap<(String, String), Said> = BTreeMap::new();
        let mut received: BTreeMap<(String, String), u64> = BTreeMap::new();
        let mut lost: BTreeMap<(String, String), u64> = BTreeMap::new();
        let mut recovered: BTreeMap<(String, String), u64> = BTreeMap::new();
        let mut cloud_dropped = BTreeMap::new();
        let mut received_complete = true;
        let mut twin_lag = BTreeMap::new();
        for (p, s) in processes {
            // Every run prints its summary on a clean end; one missing is a run not counted.
            let docs = printed(s, "out");
            let complete = docs.len() == s.ends.len();
            if matches!(p.role, "vehicle" | "rsu")
                && let Some(id) = &p.edge_id
            {
                for doc in &docs {
                    add_sent(&mut sent, id, doc, complete);
                }
                if docs.is_empty() {
                    // Never silent: an edge that printed nothing still has its row.
                    sent.insert((id.clone(), "(no summary)".into()), Said::default());
                }
            }
            if p.role == "scene" {
                // Each participant process of each run that ended well summed up what it sent.
                let summaries = printed(s, PARTICIPANTS_EXT);
                let expected: usize = docs.iter().map(|d| d["participants"].as_array().map_or(0, Vec::len)).sum();
                let complete = complete && summaries.len() == expected;
                for summary in &summaries {
                    add_sent(&mut sent, summary["participant"].as_str().unwrap_or("(unnamed)"), summary, complete);
                }
                if summaries.is_empty() {
                    sent.insert((p.name.clone(), "(no summary)".into()), Said::default());
                }
            }
            // A sharded ingest worker's counts are its share, and the union's count them again
            // (docs/sharding.md): the union is what the twin received.
            if p.role == "cloud" && !p.args.iter().any(|a| a == "--shard") {
                received_complete &= complete;
                for doc in &docs {
                    for (field, into) in
                        [("received", &mut received), ("lost", &mut lost), ("recovered", &mut recovered)]
                    {
                        for (source, streams) in doc[field].as_object().into_iter().flatten() {
                            for (stream, n) in streams.as_object().into_iter().flatten() {
                                *into.entry((source.clone(), stream.clone())).or_default() += n.as_u64().unwrap_or(0);
                            }
                        }
                    }
                    if !doc["twin_lag"].is_null() {
                        twin_lag.insert(p.name.clone(), doc["twin_lag"].clone());
                    }
                    for (reason, n) in doc["dropped"].as_object().into_iter().flatten() {
                        *cloud_dropped.entry(reason.clone()).or_default() += n.as_u64().unwrap_or(0);
                    }
                }
            }
        }
        let keys: std::collections::BTreeSet<(String, String)> =
            sent.keys().chain(received.keys()).chain(lost.keys()).cloned().collect();
        let streams = keys
            .into_iter()
            .map(|key| {
                let said = sent.get(&key).copied();
                let Said { sent: n_sent, unsent, complete } = said.unwrap_or_default();
                let n_received = received.get(&key).copied().unwrap_or(0);
                let n_lost = lost.get(&key).copied().unwrap_or(0);
                let n_recovered = recovered.get(&key).copied().unwrap_or(0);
                StreamReport {
                    source: key.0,
                    stream: key.1,
                    sent: n_sent,
                    unsent,
                    received: n_received,
                    recovered: n_recovered,
                    lost: n_lost,
                    // A loss counted where nothing was said sent (a road map, a forgotten key) is
                    // shown, not taken from a count it does not belong to.
                    missing: if said.is_some() {
                        n_sent as i64 - unsent as i64 - n_received as i64 - n_lost as i64
                    } else {
                        -(n_received as i64)
                    },
                    sent_complete: complete,
                    received_complete,
                }
            })
            .collect();
        Report {
            version: env!("CARGO_PKG_VERSION"),
            commit: env!("RISKTWIN_COMMIT"),
            topology_file: o.file.display().to_string(),
            topology_digest: topology_digest(o.text.as_bytes()),
            seed: o.seed,
            machines: net.describe(),
            ran_s: ran.as_secs_f64(),
            links,
            processes: processes
                .iter()
                .map(|(_, s)| ProcessReport { name: s.name.clone(), restarts: s.restarts, ends: s.ends.clone() })
                .collect(),
            streams,
            cloud_dropped,
            twin_lag,
            timeline,
            topology_text: o.text.clone(),
        }
    }

    /// Writes `report.json`, `report.md` and `topology.toml` into `dir`.
    pub fn write(&self, dir: &Path) -> std::io::Result<()> {
        std::fs::write(dir.join("topology.toml"), &self.topology_text)?;
        let json = serde_json::to_string_pretty(self).map_err(std::io::Error::other)?;
        std::fs::write(dir.join("report.json"), json + "\n")?;
        std::fs::write(dir.join("report.md"), self.markdown())
    }

    fn markdown(&self) -> String {
        let mut md = String::new();
        let ms = |v: Option<f64>| v.map_or_else(|| "–".to_owned(), |v| format!("{v:.2}"));
        let _ = writeln!(md, "# Deployment run\n");
        let _ = writeln!(
            md,
            "risktwin {} (commit {}), topology `{}` (digest {}), seed {}, {}; ran {:.1} s.\n",
            self.version, self.commit, self.topology_file, self.topology_digest, self.seed, self.machines, self.ran_s
        );
        let _ = writeln!(md, "## Links\n");
        let _ = writeln!(md, "Measured: each chunk's time in the link's relays, read to written.\n");
        let _ = writeln!(
            md,
            "| link | latency ms | jitter | Mbit/s | p50 ms | p99 ms | bytes up | bytes down | mean Mbit/s \
             | connections | refused |"
        );
        let _ = writeln!(md, "|---|---|---|---|---|---|---|---|---|---|---|");
        for l in &self.links {
            let jitter = match l.jitter {
                None => "–".to_owned(),
                Some(Jitter::Normal { sd_ms }) => format!("normal sd {sd_ms} ms"),
                Some(Jitter::Uniform { max_ms }) => format!("uniform ± {max_ms} ms"),
            };
            let bw = l.bandwidth_mbps.map_or_else(|| "–".to_owned(), |b| b.to_string());
            let _ = writeln!(
                md,
                "| {} | {} | {jitter} | {bw} | {} | {} | {} | {} | {:.3} | {} | {} |",
                l.name,
                l.latency_ms,
                ms(l.measured_p50_ms),
                ms(l.measured_p99_ms),
                l.bytes_up,
                l.bytes_down,
                l.mean_mbps,
                l.connections,
                l.refused
            );
        }
        let _ = writeln!(md, "\n## Edge streams\n");
        let _ =
            writeln!(md, "| source | stream | sent | unsent | received | recovered | lost | missing | sent known |");
        let _ = writeln!(md, "|---|---|---|---|---|---|---|---|---|");
        for s in &self.streams {
            let _ = writeln!(
                md,
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                s.source,
                s.stream,
                s.sent,
                s.unsent,
                s.received,
                s.recovered,
                s.lost,
                s.missing,
                if s.sent_complete { "yes" } else { "no" }
            );
        }
        for (cloud, lag) in &self.twin_lag {
            let ms = |field: &str| lag[field].as_f64().unwrap_or(f64::NAN) / 1e3;
            let _ = writeln!(
                md,
                "\nTwin lag of {cloud} (each snapshot's tick behind its clock when emitted): mean {:.1} ms, \
                 p95 {:.1} ms, max {:.1} ms over {} snapshots",
                ms("mean_us"),
                ms("p95_us"),
                ms("max_us"),
                lag["n"]
            );
        }
        if !self.cloud_dropped.is_empty() {
            let _ = writeln!(md, "\nDropped by the cloud: {:?}", self.cloud_dropped);
        }
        let _ = writeln!(md, "\n## Processes\n");
        let _ = writeln!(md, "| process | restarts | ends |");
        let _ = writeln!(md, "|---|---|---|");
        for p in &self.processes {
            let _ = writeln!(md, "| {} | {} | {} |", p.name, p.restarts, p.ends.join(", "));
        }
        let _ = writeln!(md, "\n## Timeline\n");
        for e in &self.timeline {
            let _ = writeln!(md, "- {:.2} s: {}", e.at_s, e.what);
        }
        md
    }
}

/// What `deploy status` shows while the deployment runs.
pub(super) fn status(
    tag: &str,
    net: &Net,
    up: Duration,
    processes: &[(Planned, Supervised)],
    hops: &[HopView],
) -> Value {
    json!({
        "tag": tag,
        "supervisor_pid": std::process::id(),
        "machines": net.describe(),
        "up_s": up.as_secs_f64(),
        "processes": processes.iter().map(|(_, s)| json!({
            "name": s.name, "pid": s.pid(), "running": s.running(), "restarts": s.restarts, "ends": s.ends,
        })).collect::<Vec<_>>(),
        "links": hops.iter().map(|h| json!({
            "name": h.name,
            "partitioned": h.partitioned,
            "bytes": h.counts.bytes.each_ref().map(|b| b.load(Ordering::Relaxed)),
            "measured_p50_ms": measured(h, 0.5),
        })).collect::<Vec<_>>(),
    })
}

/// Writes `value` to `path` through a temporary file, so a reader never sees half of it.
pub(super) fn write_atomically(path: &Path, value: &Value) -> std::io::Result<()> {
    let tmp = path.with_extension("json.tmp");
    std::fs::write(&tmp, serde_json::to_string_pretty(value).map_err(std::io::Error::other)? + "\n")?;
    std::fs::rename(tmp, path)
}
