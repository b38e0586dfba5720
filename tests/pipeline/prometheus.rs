//! A real Prometheus server (Debian's `prometheus`, installed when missing) scrapes a cloud
//! (ingest, twin, risk, rotating recording) and two vehicles through `--metrics-listen`; what it
//! stored equals the processes' JSON summaries: per source and stream sent, acknowledged and
//! received, drops by reason, snapshots and their lag, recording segments.
//!
//! The edges end on their own: each serves its final counts until one more scrape has taken
//! them, so Prometheus holds them; queries use `last_over_time` since a target that went away
//! leaves stale series behind.

use crate::support::{Proc, start_router};
use serde_json::Value;
use std::collections::BTreeMap;
use std::io::{Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const STEP: Duration = Duration::from_secs(60);
const SITE: &str = "prom";
const VEHICLES: [&str; 2] = ["veh-p0", "veh-p1"];

/// Prometheus as a child process, killed on drop.
struct Prometheus {
    child: Child,
    addr: String,
    stderr: std::path::PathBuf,
}

impl Drop for Prometheus {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The `prometheus` binary: on PATH, or installed from Debian's package. Fails (never skips)
/// when it can be neither found nor installed.
fn prometheus_binary() -> &'static str {
    let found = |bin| Command::new(bin).arg("--version").stdout(Stdio::null()).stderr(Stdio::null()).status();
    if found("prometheus").is_ok_and(|s| s.success()) {
        return "prometheus";
    }
    // A container's policy-rc.d keeps the package's service from starting; where one starts, it
    // listens on its own port, which this test never uses.
    for args in [&["update"][..], &["install", "-y", "prometheus"]] {
        let status = Command::new("apt-get")
            .args(args)
            .env("DEBIAN_FRONTEND", "noninteractive")
            .status()
            .unwrap_or_else(|e| panic!("prometheus is not on PATH and apt-get cannot run to install it: {e}"));
        assert!(status.success(), "prometheus is not on PATH and `apt-get {}` failed: {status}", args.join(" "));
    }
    assert!(found("prometheus").is_ok_and(|s| s.success()), "apt-get installed prometheus but it does not run");
    "prometheus"
}

/// A free loopback port (the OS's pick, released for the process that takes it).
fn free_port() -> u16 {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").expect("a free port");
    listener.local_addr().expect("its address").port()
}

impl Prometheus {
    /// Starts Prometheus on loopback scraping `targets` (host:port) every 500 ms, with its
    /// configuration and storage in `dir`, and waits until it is ready.
    fn start(dir: &std::path::Path, targets: &[String]) -> Prometheus {
        let bin = prometheus_binary();
        let quoted: Vec<String> = targets.iter().map(|t| format!("'{t}'")).collect();
        let config = format!(
            "global:\n  scrape_interval: 500ms\n  scrape_timeout: 400ms\nscrape_configs:\n  - job_name: risktwin\n    \
             static_configs:\n      - targets: [{}]\n",
            quoted.join(", ")
        );
        let config_file = dir.join("prometheus.yml");
        std::fs::write(&config_file, config).expect("the config is written");
        let addr = format!("127.0.0.1:{}", free_port());
        let stderr = dir.join("prometheus.log");
        let child = Command::new(bin)
            .arg(format!("--config.file={}", config_file.display()))
            .arg(format!("--storage.tsdb.path={}", dir.join("tsdb").display()))
            .arg(format!("--web.listen-address={addr}"))
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&stderr).expect("a log file"))
            .spawn()
            .expect("prometheus starts");
        let mut prom = Prometheus { child, addr, stderr };
        prom.wait("ready", Duration::from_secs(60), |p| {
            http_get(&p.addr, "/-/ready").is_some_and(|(code, _)| code == 200)
        });
        prom
    }

    /// Polls `done` every 200 ms until it holds; fails after `timeout` with Prometheus' log.
    fn wait(&mut self, what: &str, timeout: Duration, done: impl Fn(&Prometheus) -> bool) {
        let deadline = Instant::now() + timeout;
        while !done(self) {
            if let Ok(Some(status)) = self.child.try_wait() {
                panic!("prometheus exited ({status}) before {what}:\n{}", self.log());
            }
            assert!(Instant::now() < deadline, "prometheus: not {what} within {timeout:?}:\n{}", self.log());
            std::thread::sleep(Duration::from_millis(200));
        }
    }

    fn log(&self) -> String {
        std::fs::read_to_string(&self.stderr).unwrap_or_default()
    }

    /// An instant query: each series' labels (without `__name__`) and value.
    fn query(&self, promql: &str) -> Vec<(BTreeMap<String, String>, f64)> {
        let path = format!("/api/v1/query?query={}", percent_encode(promql));
        let (code, body) = http_get(&self.addr, &path).expect("prometheus answers queries");
        let doc: Value = serde_json::from_str(&body).unwrap_or_else(|e| panic!("{promql}: not JSON ({e}): {body}"));
        assert_eq!((code, doc["status"].as_str()), (200, Some("success")), "{promql}: {body}");
        let series = doc["data"]["result"].as_array().expect("a vector result");
        series
            .iter()
            .map(|s| {
                let labels = s["metric"].as_object().expect("labels").iter();
                let labels = labels.map(|(k, v)| (k.clone(), v.as_str().unwrap_or_default().to_owned())).collect();
                let value = s["value"][1].as_str().and_then(|v| v.parse().ok()).expect("a sample value");
                (labels, value)
            })
            .collect()
    }

    /// The last value Prometheus stored of each series of `selector` (stale ones included: a
    /// target that ended), keyed by the values of `keys`.
    fn last(&self, selector: &str, keys: &[&str]) -> BTreeMap<Vec<String>, u64> {
        let series = self.query(&format!("last_over_time({selector}[10m])"));
        series
            .into_iter()
            .map(|(labels, v)| {
                let key = keys.iter().map(|k| labels.get(*k).cloned().unwrap_or_default()).collect();
                (key, v as u64)
            })
            .collect()
    }

    /// Waits until the last values of `selector` equal `want` (the scrapes lag the processes).
    fn wait_equal(&mut self, selector: &str, keys: &[&str], want: &BTreeMap<Vec<String>, u64>) {
        let what = format!("{selector} = {want:?}");
        self.wait(&what, Duration::from_secs(30), |p| p.last(selector, keys) == *want);
    }
}

/// `GET path` over HTTP/1.0: the status code and body, `None` when nothing answers.
fn http_get(addr: &str, path: &str) -> Option<(u16, String)> {
    let mut stream = TcpStream::connect(addr).ok()?;
    stream.set_read_timeout(Some(Duration::from_secs(10))).ok()?;
    write!(stream, "GET {path} HTTP/1.0\r\nHost: {addr}\r\n\r\n").ok()?;
    let mut response = String::new();
    stream.read_to_string(&mut response).ok()?;
    let (head, body) = response.split_once("\r\n\r\n")?;
    let code = head.split(' ').nth(1)?.parse().ok()?;
    Some((code, body.to_owned()))
}

fn percent_encode(text: &str) -> String {
    text.bytes()
        .map(|b| match b {
            b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'-' | b'_' | b'.' | b'~' => (b as char).to_string(),
            _ => format!("%{b:02X}"),
        })
        .collect()
}

/// `source → stream → n` of a summary as the keys `[source, stream]` of [`Prometheus::last`].
fn per_stream(counts: &Value, source: Option<&str>) -> BTreeMap<Vec<String>, u64> {
    let mut out = BTreeMap::new();
    let sources = counts.as_object().expect("counts per source");
    for (name, streams) in sources.iter().filter(|(name, _)| source.is_none_or(|s| s == name.as_str())) {
        for (stream, n) in streams.as_object().expect("counts per stream") {
            out.insert(vec![name.clone(), stream.clone()], n.as_u64().expect("a count"));
        }
    }
    out
}

/// `stream → n` of one edge as the keys `[source, stream]`.
fn edge_streams(source: &str, counts: &Value) -> BTreeMap<Vec<String>, u64> {
    let streams = counts.as_object().expect("counts per stream");
    streams.iter().map(|(s, n)| (vec![source.to_owned(), s.clone()], n.as_u64().expect("a count"))).collect()
}

/// The metrics address a role printed (`metrics on http://ADDR/metrics`).
fn metrics_addr(role: &mut Proc) -> String {
    let line = role.wait_line(STEP, |l| l.starts_with("metrics on http://"));
    let addr = line.trim_start_matches("metrics on http://").trim_end_matches("/metrics").to_owned();
    assert!(addr.starts_with("127.0.0.1:") && !addr.ends_with(":0"), "{line}");
    addr
}

#[test]
fn prometheus_scrapes_every_role_and_holds_the_summaries_counts() {
    let started = Instant::now();
    let dir = tempfile::tempdir().expect("a temporary directory");
    let (_router, locator) = start_router();
    let segments = dir.path().join("segs");
    let mut cloud = Proc::spawn(
        "cloud",
        &[
            "cloud",
            "--roles",
            "ingest,twin,risk",
            "--site",
            SITE,
            "--record-dir",
            segments.to_str().expect("a UTF-8 path"),
            "--segment-s",
            "1",
            "--connect",
            &locator,
            "--metrics-listen",
            "127.0.0.1:0",
        ],
    );
    let cloud_addr = metrics_addr(&mut cloud);
    cloud.wait_line(STEP, |l| l == "ready");
    // The edges' ports are chosen here so that Prometheus knows them before they start.
    let edge_addrs: Vec<String> = VEHICLES.iter().map(|_| format!("127.0.0.1:{}", free_port())).collect();
    let targets: Vec<String> = std::iter::once(cloud_addr.clone()).chain(edge_addrs.iter().cloned()).collect();
    let mut prom = Prometheus::start(dir.path(), &targets);
    let cloud_up = format!("up{{instance=\"{cloud_addr}\"}}");
    prom.wait("scraping the cloud", STEP, |p| p.query(&cloud_up).first().is_some_and(|(_, v)| *v == 1.0));

    // Two vehicles, 3 s each at 50 Hz.
    let mut edges: Vec<Proc> = VEHICLES
        .iter()
        .zip(&edge_addrs)
        .enumerate()
        .map(|(i, (id, addr))| {
            let seed = i.to_string();
            let args = [
                "edge",
                "vehicle",
                "--id",
                id,
                "--site",
                SITE,
                "--count",
                "150",
                "--seed",
                &seed,
                "--connect",
                &locator,
            ];
            Proc::spawn(id, &[&args[..], &["--metrics-listen", addr.as_str()]].concat())
        })
        .collect();
    let sent: Vec<Value> = edges.iter_mut().map(|e| e.exit_json(STEP)).collect();
    for id in VEHICLES {
        cloud.wait_line(STEP, |l| l == format!("edge left: {SITE}/{id}"));
    }

    // Each edge's final counts, as its summary says and as Prometheus stored them.
    for (summary, id) in sent.iter().zip(VEHICLES) {
        assert_eq!(summary["sent"], serde_json::json!({"state": 150, "can": 600, "perception": 30}), "{id}");
        assert_eq!(summary["acknowledged"], summary["sent"], "{id}");
        let keys = ["source", "stream"];
        for (metric, field) in [
            ("risktwin_edge_messages_sent_total", "sent"),
            ("risktwin_edge_messages_acknowledged_total", "acknowledged"),
            ("risktwin_edge_messages_undelivered_total", "undelivered"),
        ] {
            let selector = format!("{metric}{{site=\"{SITE}\",source=\"{id}\"}}");
            prom.wait_equal(&selector, &keys, &edge_streams(id, &summary[field]));
        }
    }

    // The cloud's counts cannot change any more: Prometheus catches up with them while it runs.
    let received = sent.iter().fold(BTreeMap::new(), |mut all, s| {
        all.extend(edge_streams(s["source"].as_str().expect("a source"), &s["sent"]));
        all
    });
    let received_of = format!("risktwin_ingest_messages_received_total{{site=\"{SITE}\"}}");
    prom.wait_equal(&received_of, &["source", "stream"], &received);

    // Stopped, the cloud exports its final counts and serves them until Prometheus took them.
    cloud.terminate();
    let summary = cloud.exit_json(STEP);
    assert_eq!(per_stream(&summary["received"], None), received, "{summary}");
    let one = |n: &Value| BTreeMap::from([(Vec::new(), n.as_u64().expect("a count"))]);
    let segments = &summary["segments"];
    prom.wait_equal("risktwin_recording_segments_total{state=\"closed\"}", &[], &one(&segments["segments_closed"]));
    prom.wait_equal("risktwin_recording_bytes_total", &[], &one(&segments["bytes_written"]));
    assert!(segments["segments_closed"].as_u64().is_some_and(|n| n >= 2), "rotated at 1 s: {segments}");
    let dropped: BTreeMap<Vec<String>, u64> = summary["dropped"]
        .as_object()
        .expect("drops by reason")
        .iter()
        .map(|(reason, n)| (vec![reason.clone()], n.as_u64().expect("a count")))
        .collect();
    prom.wait_equal("risktwin_ingest_messages_dropped_total", &["reason"], &dropped);
    assert_eq!(prom.last("risktwin_twin_snapshots_total", &[]), one(&summary["snapshots"]));
    assert!(summary["snapshots"].as_u64().is_some_and(|n| n > 20), "3 s at 20 Hz: {summary}");
    assert_eq!(prom.last("risktwin_twin_snapshot_lag_seconds_count", &[]), one(&summary["twin_lag"]["n"]));
    assert_eq!(prom.last("risktwin_recording_messages_total", &[]), one(&summary["recorded"]));
    assert_eq!(prom.last("risktwin_risk_assessments_total", &[]), one(&summary["twin"]["risk_assessments"]));
    let risk = prom.query(&format!("last_over_time(risktwin_risk_field_max{{site=\"{SITE}\"}}[10m])"));
    let max_risk = summary["twin"]["max_risk"].as_f64().expect("the highest risk");
    assert!(risk.first().is_some_and(|(_, v)| *v > 0.0 && *v <= max_risk), "{risk:?}, max {max_risk}");
    // Every role says what it is.
    let info = prom.last("risktwin_build_info", &["role", "version"]);
    let version = env!("CARGO_PKG_VERSION").to_owned();
    for role in ["cloud", "edge-vehicle"] {
        assert_eq!(info.get(&vec![role.to_owned(), version.clone()]), Some(&1), "{info:?}");
    }
    eprintln!("prometheus test: {:.1} s", started.elapsed().as_secs_f64());
}
