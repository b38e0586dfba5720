//! `risktwin deploy`: topologies run as emulated deployments — network namespaces joined by
//! veth pairs (CI runs as root), relays emulating each link, a real router per site, real edge
//! and cloud processes. Every test takes its deployment down however it ends, and checks that
//! nothing is left: no namespace, no veth, no process.

use prost::Message as _;
use risktwin_protos::foxglove::Log;
use risktwin_protos::recording::read_messages;
use risktwin_protos::v1::LinkCondition;
use risktwin_transport::sync::LockExt;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

mod v2x;

const BIN: &str = env!("CARGO_BIN_EXE_risktwin");

/// Runs `risktwin args…` to its end, killed after `limit`.
fn risktwin(args: &[&str], limit: Duration) -> Output {
    let mut child = Command::new(BIN)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the binary starts");
    let deadline = Instant::now() + limit;
    while child.try_wait().expect("waits").is_none() {
        if Instant::now() > deadline {
            let _ = child.kill();
            let out = child.wait_with_output().expect("output");
            panic!("risktwin {args:?} ran past {limit:?}: {}", String::from_utf8_lossy(&out.stderr));
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    child.wait_with_output().expect("output")
}

/// One deployment at a time: four at once on a 2-core machine would measure the machine.
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

/// A topology file in a temporary folder, taken down when the test ends however it ends.
struct Deployment {
    dir: tempfile::TempDir,
    file: PathBuf,
    _turn: MutexGuard<'static, ()>,
}

impl Deployment {
    fn new(topology: &str) -> Deployment {
        let turn = ONE_AT_A_TIME.locked();
        let dir = tempfile::tempdir().expect("a temp dir");
        let file = dir.path().join("topology.toml");
        std::fs::write(&file, topology).expect("writes the topology");
        Deployment { dir, file, _turn: turn }
    }

    fn file(&self) -> &str {
        self.file.to_str().expect("a UTF-8 path")
    }

    fn out(&self) -> PathBuf {
        self.dir.path().join("out")
    }

    /// `deploy run --for …`, its report.
    fn run(&self, duration: &str) -> Value {
        let out = self.out();
        let o =
            risktwin(&["deploy", "run", self.file(), "--for", duration, "--out", out.to_str().expect("utf-8")], LIMIT);
        assert!(o.status.success(), "deploy run: {}", String::from_utf8_lossy(&o.stderr));
        let report: Value = serde_json::from_slice(&o.stdout).expect("the report on stdout");
        let written: Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).expect("report.json"))
                .expect("json");
        assert_eq!(report, written, "the printed report is the written one");
        assert!(out.join("report.md").exists() && out.join("topology.toml").exists());
        report
    }

    /// Namespaces, veths, processes and the state folder of this deployment still there.
    fn leftovers(&self) -> Vec<String> {
        let tag = self.tag();
        let mut left: Vec<String> = ip(&["netns", "list"])
            .lines()
            .filter_map(|l| l.split_whitespace().next())
            .filter(|n| n.starts_with(&format!("rt-{tag}-")))
            .map(str::to_owned)
            .collect();
        left.extend(
            ip(&["-o", "link", "show"])
                .lines()
                .filter_map(|l| l.split(':').nth(1))
                .map(|n| n.trim().split('@').next().unwrap_or("").to_owned())
                .filter(|n| n.starts_with(&format!("rt{tag}"))),
        );
        left.extend(processes_under(self.dir.path()).into_iter().map(|p| format!("process {p}")));
        // The supervisor's state folder (its lock, pid, output path) goes with it.
        let state = std::env::temp_dir().join(format!("risktwin-deploy-{tag}"));
        if state.exists() {
            left.push(format!("state folder {}", state.display()));
        }
        left
    }

    /// The deployment's tag, as its namespaces carry it: `deploy` derives it from the file's
    /// canonical path (FNV-1a 64, low 24 bits), and so does the test, to look for leftovers
    /// of a deployment that never said its tag.
    fn tag(&self) -> String {
        let canonical = std::fs::canonicalize(&self.file).expect("the file exists");
        // FNV-1a 64 of the canonical path, low 24 bits: as `deploy` derives it.
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for b in canonical.as_os_str().as_encoded_bytes() {
            h = (h ^ u64::from(*b)).wrapping_mul(0x0100_0000_01b3);
        }
        format!("{:06x}", h & 0xff_ffff)
    }
}

impl Drop for Deployment {
    fn drop(&mut self) {
        let _ = risktwin(&["deploy", "down", self.file()], LIMIT);
    }
}

/// Every `deploy` command ends well within this.
const LIMIT: Duration = Duration::from_secs(180);

fn ip(args: &[&str]) -> String {
    let out = Command::new("ip").args(args).output().expect("iproute2 is installed");
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Processes whose working directory lies under `dir` (a deployment's processes run in their
/// host's folder of its output).
fn processes_under(dir: &Path) -> Vec<u32> {
    let dir = std::fs::canonicalize(dir).expect("the dir exists");
    std::fs::read_dir("/proc")
        .expect("/proc")
        .filter_map(|e| e.ok()?.file_name().to_str()?.parse::<u32>().ok())
        .filter(|pid| {
            let zombie = std::fs::read_to_string(format!("/proc/{pid}/stat")).is_ok_and(|s| s.contains(") Z "));
            !zombie && std::fs::read_link(format!("/proc/{pid}/cwd")).is_ok_and(|cwd| cwd.starts_with(&dir))
        })
        .collect()
}

/// An edge site (a vehicle and a roadside unit, each its own host) and a cloud site, over a
/// 20 ms ± 2 ms link.
const THREE_HOSTS: &str = r#"
[[site]]
name = "cloud"

[[site]]
name = "edge"

[[host]]
name = "cloud-0"
site = "cloud"
run = [{ role = "cloud", args = ["--roles", "ingest"] }]

[[host]]
name = "car-1"
site = "edge"
run = [{ role = "vehicle", args = ["--count", "300", "--rate-hz", "50"] }]

[[host]]
name = "rsu-1"
site = "edge"
run = [{ role = "rsu", args = ["--count", "60"] }]

[[link]]
between = ["edge", "cloud"]
latency_ms = 20
jitter = { dist = "normal", sd_ms = 2 }
"#;

fn link<'a>(report: &'a Value, name: &str) -> &'a Value {
    report["links"].as_array().expect("links").iter().find(|l| l["name"] == name).expect("the link is reported")
}

/// Every stream of every edge: sent > 0 and received = sent (nothing lost, nothing missing).
fn assert_nothing_missing(report: &Value, streams: usize) {
    let all = report["streams"].as_array().expect("streams");
    assert_eq!(all.len(), streams, "{all:#?}");
    for s in all {
        assert!(s["sent"].as_u64().expect("sent") > 0, "{s}");
        assert_eq!(s["received"], s["sent"], "{s}");
        assert_eq!(
            (&s["unsent"], &s["lost"], &s["missing"]),
            (&Value::from(0), &Value::from(0), &Value::from(0)),
            "{s}"
        );
        assert_eq!((&s["sent_complete"], &s["received_complete"]), (&Value::Bool(true), &Value::Bool(true)), "{s}");
    }
}

#[test]
fn three_hosts_over_a_20_ms_link_lose_nothing_and_see_its_delay() {
    let d = Deployment::new(THREE_HOSTS);
    let report = d.run("60s");
    assert!(
        report["machines"].as_str().expect("machines").contains("5 network namespaces"),
        "three hosts and two site routers, each in its namespace (CI runs as root): {}",
        report["machines"]
    );
    // How the run was made: the commit the binary was built from (a git checkout, as in CI).
    let commit = report["commit"].as_str().expect("commit");
    assert!([40, 64].contains(&commit.len()) && commit.chars().all(|c| c.is_ascii_hexdigit()), "commit {commit}");
    let wan = link(&report, "edge-cloud");
    let p50 = wan["measured_p50_ms"].as_f64().expect("bytes crossed the link");
    // 20 ms plus the timer's rounding up; the tight figure is the benchmark's.
    assert!((19.0..26.0).contains(&p50), "p50 {p50} ms over a 20 ms link: {wan}");
    assert!(wan["bytes_down"].as_u64().expect("bytes") > 10_000, "the edges' data crossed it toward the cloud");
    // car-1: state, can, perception; rsu-1: rsu, signal.
    assert_nothing_missing(&report, 5);
    // No fault, nothing recovered: live samples are never taken for a cache's answers.
    let streams = report["streams"].as_array().expect("streams");
    assert!(streams.iter().all(|s| s["recovered"] == 0), "{streams:#?}");
    // The twin's lag behind the cloud's clock, measured on every snapshot: at least the
    // aligner's wait for late samples, and no outage here.
    let lag = &report["twin_lag"]["cloud-0/cloud"];
    assert!(lag["n"].as_u64().expect("snapshots") > 50, "{lag}");
    let p95_us = lag["p95_us"].as_u64().expect("a lag");
    assert!((10_000..1_000_000).contains(&p95_us), "{lag}");
    let ended = report["timeline"]
        .as_array()
        .expect("timeline")
        .iter()
        .any(|e| e["what"].as_str().is_some_and(|w| w.contains("ended by every edge process ending")));
    assert!(ended, "the run ends when its edges are done, not at --for");
    assert_eq!(d.leftovers(), Vec::<String>::new(), "a finished run leaves nothing");
    // A second run into the same folder reports itself only.
    let again = d.run("60s");
    assert_eq!(again["streams"], report["streams"], "counted once, not added to the last run's");
}

#[test]
fn a_tls_deployment_gives_every_process_a_certificate_and_loses_nothing() {
    let d = Deployment::new(&format!("tls = true\n{THREE_HOSTS}"));
    let report = d.run("60s");
    // Every link mutual TLS through the relays, the routers' access rules on: still all of it.
    assert_nothing_missing(&report, 5);
    let certs = d.out().join("certs");
    let mut names: Vec<String> = std::fs::read_dir(&certs)
        .expect("the run's certificates")
        .map(|e| e.expect("an entry").file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".pem") && !n.ends_with("-key.pem"))
        .collect();
    names.sort();
    let expected = ["ca.pem", "cloud:cloud-0.cloud.pem", "edge:edge:car-1.pem", "edge:edge:rsu-1.pem"];
    assert!(expected.iter().all(|n| names.contains(&(*n).to_owned())), "{names:?}");
    assert_eq!(names.iter().filter(|n| n.starts_with("router:")).count(), 2, "one per site router: {names:?}");
    let command = std::fs::read_to_string(d.out().join("hosts/car-1/vehicle.cmd")).expect("the vehicle's command");
    assert!(command.contains("--connect tls/") && command.contains("--identity edge:edge:car-1"), "{command}");
}

#[test]
fn a_partition_of_the_edge_site_holds_its_data_until_the_heal() {
    let partitioned = THREE_HOSTS.replace("\"--count\", \"300\"", "\"--count\", \"400\"")
        + "\n[[event]]\nat_s = 2\npartition = \"edge\"\nfor_s = 3\n";
    let d = Deployment::new(&partitioned);
    let report = d.run("60s");
    let timeline: Vec<&str> =
        report["timeline"].as_array().expect("timeline").iter().filter_map(|e| e["what"].as_str()).collect();
    let at = |what: &str| {
        report["timeline"]
            .as_array()
            .expect("timeline")
            .iter()
            .find(|e| e["what"].as_str() == Some(what))
            .map(|e| e["at_s"].as_f64().expect("a time"))
    };
    let (cut, healed) = (at("partition: edge-cloud").expect("partitioned"), at("heal: edge-cloud").expect("healed"));
    assert!((2.9..4.0).contains(&(healed - cut)), "3 s apart: {timeline:?}");
    // The network's recording shows the link cut between the two, and the timeline.
    let bytes = std::fs::read(d.out().join("network.mcap")).expect("network.mcap written");
    let messages = read_messages(&bytes).expect("a valid MCAP file");
    let conditions: Vec<(u64, LinkCondition)> = messages
        .iter()
        .filter(|m| m.topic == "/deploy/link/edge-cloud")
        .map(|m| {
            assert_eq!(m.schema_name, "risktwin.v1.LinkCondition");
            (m.log_time_ns, LinkCondition::decode(m.data.as_slice()).expect("a LinkCondition"))
        })
        .collect();
    let cut_for_s: Vec<f64> = conditions
        .iter()
        .filter(|(_, c)| c.partitioned)
        .map(|(t, _)| *t as f64 * 1e-9)
        .collect::<Vec<_>>()
        .windows(2)
        .map(|w| w[1] - w[0])
        .collect();
    let cut_s: f64 = cut_for_s.iter().sum();
    assert!((2.0..4.0).contains(&cut_s), "recorded partitioned for {cut_s} s of 3: {conditions:?}");
    assert!(conditions.last().is_some_and(|(_, c)| !c.partitioned && c.bytes_down > 10_000), "{conditions:?}");
    let timeline: Vec<String> = messages
        .iter()
        .filter(|m| m.topic == "/deploy/timeline")
        .map(|m| Log::decode(m.data.as_slice()).expect("a foxglove.Log").message)
        .collect();
    assert!(timeline.iter().any(|l| l == "partition: edge-cloud") && timeline.iter().any(|l| l == "heal: edge-cloud"));
    let wan = link(&report, "edge-cloud");
    // Bytes read at the start of the partition waited through it.
    let p99 = wan["measured_p99_ms"].as_f64().expect("bytes crossed");
    assert!(p99 > 1_000.0, "the link held data through the partition: p99 {p99} ms, {wan}");
    assert_nothing_missing(&report, 5);
    assert_eq!(d.leftovers(), Vec::<String>::new());
}

/// The edge site's router runs on a host of its own, which the schedule restarts mid-run.
const ROUTER_RESTART: &str = r#"
[[site]]
name = "cloud"

[[site]]
name = "edge"

[[host]]
name = "cloud-0"
site = "cloud"
run = [{ role = "cloud", args = ["--roles", "ingest"] }]

[[host]]
name = "edge-gw"
site = "edge"
run = [{ role = "router" }]

[[host]]
name = "car-1"
site = "edge"
run = [{ role = "vehicle", args = ["--count", "400", "--rate-hz", "50"] }]

[[host]]
name = "rsu-1"
site = "edge"
run = [{ role = "rsu", args = ["--count", "80"] }]

[[link]]
between = ["edge", "cloud"]
latency_ms = 5

[[event]]
at_s = 2
restart = "edge-gw/router"
"#;

#[test]
fn a_router_restart_mid_run_loses_nothing_and_its_clients_are_back_within_2_s() {
    let d = Deployment::new(ROUTER_RESTART);
    let report = d.run("60s");
    let restarted = report["timeline"]
        .as_array()
        .expect("timeline")
        .iter()
        .find(|e| e["what"] == "restart edge-gw/router")
        .and_then(|e| e["at_s"].as_f64())
        .unwrap_or_else(|| panic!("the router was restarted: {}", report["timeline"]));
    let times = |hop: &str| -> Vec<f64> {
        let hop = link(&report, hop);
        hop["connected_at_s"].as_array().expect("times").iter().filter_map(Value::as_f64).collect()
    };
    for host in ["car-1", "rsu-1"] {
        assert!(times(&format!("lan:{host}")).iter().any(|t| *t < restarted), "{host} was connected before");
    }
    // The router's own hop: a connection there is made only while the router listens (the
    // edges' hops also carry their retries while it is down). Everyone who was connected
    // through it before the restart (both edges, and the peering with the cloud's router if
    // that side connects) comes back through it.
    let router_hop = times("lan:edge-gw");
    let before = router_hop.iter().filter(|t| **t < restarted).count();
    let back: Vec<f64> = router_hop.iter().filter(|t| **t > restarted).map(|t| t - restarted).collect();
    assert!(before >= 2 && back.len() >= before, "connections before and after: {router_hop:?}");
    // The 2 s target plus slack for a loaded 2-core machine (measured: see docs/results.md).
    let all_back = back[before - 1];
    assert!(all_back < 3.0, "all back {all_back:.2} s after the router's restart: {router_hop:?}");
    eprintln!("router restart: connections back after {back:?} s");
    // What the edges published while their router was down came out of their caches.
    assert_nothing_missing(&report, 5);
    let car_state = report["streams"]
        .as_array()
        .expect("streams")
        .iter()
        .find(|s| s["source"] == "car-1" && s["stream"] == "state")
        .expect("car-1's state stream");
    let recovered = car_state["recovered"].as_u64().expect("recovered");
    // At 50 Hz, a router down for a few tenths of a second holds back a few samples or more.
    assert!(recovered > 0 && recovered < car_state["received"].as_u64().expect("received"), "{car_state}");
    assert_eq!(d.leftovers(), Vec::<String>::new());
}

/// Two sharded ingest workers in two cloud sites (each its own router) and a union, four
/// edges; each worker is killed once, 4 s apart, and restarted.
const SHARDED: &str = r#"
[[site]]
name = "cloud"

[[site]]
name = "dc2"

[[site]]
name = "edge"

[[host]]
name = "cloud-0"
site = "cloud"
run = [{ role = "cloud", args = ["--roles", "union,twin", "--site", "edge"] }]

[[host]]
name = "w-1"
site = "cloud"
run = [{ role = "cloud", args = ["--roles", "ingest", "--shard", "--site", "edge"] }]

[[host]]
name = "w-2"
site = "dc2"
run = [{ role = "cloud", args = ["--roles", "ingest", "--shard", "--site", "edge"] }]

[[host]]
name = "car-1"
site = "edge"
run = [{ role = "vehicle", args = ["--count", "500", "--rate-hz", "50"] }]

[[host]]
name = "car-2"
site = "edge"
run = [{ role = "vehicle", args = ["--count", "500", "--rate-hz", "50"] }]

[[host]]
name = "car-3"
site = "edge"
run = [{ role = "vehicle", args = ["--count", "500", "--rate-hz", "50"] }]

[[host]]
name = "rsu-4"
site = "edge"
run = [{ role = "rsu", args = ["--count", "100"] }]

[[link]]
between = ["edge", "cloud"]
latency_ms = 5

[[link]]
between = ["dc2", "cloud"]
latency_ms = 5

[[event]]
at_s = 2
kill = "w-1/cloud"

[[event]]
at_s = 6
kill = "w-2/cloud"
"#;

#[test]
fn sharded_workers_on_two_sites_each_killed_once_lose_nothing_at_the_union() {
    let d = Deployment::new(SHARDED);
    let report = d.run("60s");
    let processes = report["processes"].as_array().expect("processes");
    for worker in ["w-1/cloud", "w-2/cloud"] {
        let p = processes.iter().find(|p| p["name"] == worker).unwrap_or_else(|| panic!("{worker}: {processes:?}"));
        assert_eq!(p["restarts"], Value::from(1), "{worker} killed once and restarted: {p}");
    }
    // Each group changed owner at least once while the edges published (its owner was killed,
    // or the restarted worker, a new id, took it on joining); the union holds every message.
    assert_nothing_missing(&report, 11);
    assert_eq!(d.leftovers(), Vec::<String>::new());
}

#[test]
fn a_sites_own_router_is_restarted_by_name_and_nothing_is_lost() {
    // The edge site has no host that runs a router: its router runs on the site's gateway.
    let d = Deployment::new(&(THREE_HOSTS.to_owned() + "\n[[event]]\nat_s = 2\nrestart = \"edge/router\"\n"));
    let report = d.run("60s");
    let timeline = &report["timeline"];
    assert!(timeline.as_array().expect("timeline").iter().any(|e| e["what"] == "restart edge/router"), "{timeline}");
    let router = report["processes"].as_array().expect("processes").iter().find(|p| p["name"] == "edge/router");
    assert_eq!(router.map(|p| &p["restarts"]), Some(&Value::from(1)), "{}", report["processes"]);
    assert_nothing_missing(&report, 5);
    assert_eq!(d.leftovers(), Vec::<String>::new());
}

#[test]
fn a_clock_step_moves_a_hosts_edge_clock_and_the_cloud_counts_what_it_refused() {
    // At 8 s of a 14 s run: well after the vehicle started publishing, on a loaded machine too,
    // and after the cloud's estimate of its clock was fitted (4 s of samples): a warming one
    // takes a run of future stamps at their receive times instead of refusing them.
    let stepped = THREE_HOSTS.replace("\"--count\", \"300\"", "\"--count\", \"700\"")
        + "\n[[event]]\nat_s = 8\nclock_step = \"car-1\"\nby_ms = 2000\n";
    let d = Deployment::new(&stepped);
    let report = d.run("60s");
    let timeline: Vec<&str> =
        report["timeline"].as_array().expect("timeline").iter().filter_map(|e| e["what"].as_str()).collect();
    assert!(timeline.contains(&"clock_step car-1: +2000 ms"), "{timeline:?}");
    let log = std::fs::read_to_string(d.out().join("hosts/car-1/vehicle.log")).expect("the vehicle's log");
    let stepped_at = log.find("edge car-1: clock stepped by 2000 ms").unwrap_or_else(|| panic!("{log}"));
    let publishing_at = log.find("edge car-1: publishing").unwrap_or_else(|| panic!("{log}"));
    assert!(publishing_at < stepped_at, "stepped while it published, not before it began: {log}");
    // The cloud sees the vehicle's stamps jump 2 s ahead: it refuses them as future ones until
    // it has re-anchored the clock, and what it refused is exactly what went missing.
    let refused = report["cloud_dropped"]["future-timestamp"].as_u64().unwrap_or(0);
    assert!(refused > 0, "{}", report["cloud_dropped"]);
    let streams = report["streams"].as_array().expect("streams");
    let missing = |source: &str| -> i64 {
        streams.iter().filter(|s| s["source"] == source).map(|s| s["missing"].as_i64().expect("missing")).sum()
    };
    assert_eq!(missing("car-1"), refused as i64, "{streams:#?}");
    assert_eq!(missing("rsu-1"), 0, "the other host's clock did not move: {streams:#?}");
    assert_eq!(d.leftovers(), Vec::<String>::new());
}

/// A scene on a road-side host; its site's router is a gateway of its own. The scene's
/// authority and participants meet on the scene's own router on the host; only its data
/// crosses the host's hop and the link to the cloud. The host starts cut off (its hop, and so
/// every route out), later the link to the cloud is cut.
const SCENE_ON_ITS_HOST: &str = r#"
[[site]]
name = "cloud"

[[site]]
name = "road"

[[host]]
name = "cloud-0"
site = "cloud"
run = [{ role = "cloud", args = ["--roles", "ingest"] }]

[[host]]
name = "road-0"
site = "road"
run = [{ role = "scene", args = ["--kind", "cut-in", "--seed", "1", "--connected", "2", "--rsus", "1"] }]

[[link]]
between = ["road", "cloud"]
latency_ms = 20

[[event]]
at_s = 0
partition = "road-0"
for_s = 3

[[event]]
at_s = 7
partition = "road-cloud"
for_s = 2
"#;

#[test]
fn a_partition_cuts_a_scenes_data_not_its_physics() {
    let d = Deployment::new(SCENE_ON_ITS_HOST);
    let report = d.run("60s");
    let out = std::fs::read_to_string(d.out().join("hosts/road-0/scene.out")).expect("the scene's outcome");
    let scene: Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}"));
    // Real time, every answer on time through both partitions: physics never crossed a link.
    let deadlines = &scene["deadlines"];
    assert!(deadlines["due"].as_u64().expect("due") > 500, "{scene}");
    assert_eq!(deadlines["missed"], 0, "{scene}");
    let ended = &report["processes"].as_array().expect("processes").iter().find(|p| p["name"] == "road-0/scene");
    assert_eq!(ended.map(|p| &p["ends"]), Some(&serde_json::json!(["exit 0"])), "{report}");
    let at = |what: &str| {
        let timeline = report["timeline"].as_array().expect("timeline");
        timeline.iter().find(|e| e["what"] == what).and_then(|e| e["at_s"].as_f64()).expect(what)
    };
    let (healed, ended_at) = (at("heal: lan:road-0"), at("road-0/scene ended (exit 0)"));
    // The scene did not wait for its host's network: it drove while the host was cut off.
    let (steps, step_s) = (scene["steps"].as_u64().expect("steps"), scene["step_s"].as_f64().expect("step_s"));
    // Its end comes after its participants' linger (1 s, for their caches to answer).
    let started = ended_at - steps as f64 * step_s - 1.0;
    assert!(started < healed - 0.5, "physics started at {started:.2} s, the host's network came at {healed:.2} s");
    // Its data all reached the cloud: what it made before its router answered waited in the
    // participants and went out then, and the second partition only delayed the rest.
    // Two vehicles' state and perception, the RSU's object lists.
    assert_nothing_missing(&report, 5);
    let ego =
        report["streams"].as_array().expect("streams").iter().find(|s| s["source"] == "v0" && s["stream"] == "state");
    assert_eq!(ego.map(|s| &s["sent"]), Some(&Value::from(steps + 1)), "every step's state and the final one");
    assert_eq!(d.leftovers(), Vec::<String>::new());
}

#[test]
fn down_removes_everything_after_a_crash_and_again_after_that() {
    // Edges without a count run until the deployment is taken down.
    let forever = THREE_HOSTS.replace(r#", "--count", "300""#, "").replace(r#""--count", "60""#, "");
    let d = Deployment::new(&forever);
    let out = d.out();
    let o = risktwin(&["deploy", "up", d.file(), "--out", out.to_str().expect("utf-8")], LIMIT);
    assert!(o.status.success(), "deploy up: {}", String::from_utf8_lossy(&o.stderr));
    let up: Value = serde_json::from_slice(&o.stdout).expect("the status");
    let processes = up["status"]["processes"].as_array().expect("processes");
    assert_eq!(processes.len(), 5);
    assert!(processes.iter().all(|p| p["running"] == true), "{processes:#?}");
    let again = risktwin(&["deploy", "up", d.file()], LIMIT);
    assert_eq!(again.status.code(), Some(2), "a second up of the same file is refused");
    let status = risktwin(&["deploy", "status", d.file()], LIMIT);
    assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));
    // The same file under another path (moved, copied) names the same deployment, by its bytes.
    let copy = d.dir.path().join("moved.toml");
    std::fs::copy(&d.file, &copy).expect("copies the topology");
    let copy = copy.to_str().expect("utf-8");
    let status = risktwin(&["deploy", "status", copy], LIMIT);
    assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));
    // The supervisor crashes: its processes, namespaces and veths stay behind…
    let pid = up["status"]["supervisor_pid"].as_i64().expect("the supervisor's pid");
    Command::new("kill").args(["-9", &pid.to_string()]).status().expect("kill");
    std::thread::sleep(Duration::from_millis(300));
    assert!(!d.leftovers().is_empty(), "a crashed supervisor leaves its deployment running");
    // …and `down` finds them all, by the copy's bytes, then by the file's tag; twice is fine.
    for file in [copy, d.file()] {
        let o = risktwin(&["deploy", "down", file], LIMIT);
        assert!(o.status.success(), "deploy down: {}", String::from_utf8_lossy(&o.stderr));
        assert_eq!(d.leftovers(), Vec::<String>::new());
    }
    let o = risktwin(&["deploy", "status", d.file()], LIMIT);
    assert_eq!(o.status.code(), Some(1), "nothing is up");
}

#[test]
fn up_without_out_writes_into_a_folder_it_prints_and_down_names_its_report() {
    let d = Deployment::new(THREE_HOSTS);
    let o = risktwin(&["deploy", "up", d.file()], LIMIT);
    assert!(o.status.success(), "deploy up: {}", String::from_utf8_lossy(&o.stderr));
    let up: Value = serde_json::from_slice(&o.stdout).expect("the status");
    /// The default output folder lies outside the test's temporary folder: removed however the test ends.
    struct Remove(PathBuf);
    impl Drop for Remove {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
    let out = Remove(PathBuf::from(up["out"].as_str().expect("the output folder")));
    assert!(out.0.join("status.json").exists(), "{up}");
    let o = risktwin(&["deploy", "down", d.file()], LIMIT);
    assert!(o.status.success(), "deploy down: {}", String::from_utf8_lossy(&o.stderr));
    let down: Value = serde_json::from_slice(&o.stdout).expect("down's answer");
    let report = out.0.join("report.md");
    assert_eq!(down["report"].as_str(), report.to_str(), "{down}");
    assert!(report.exists() && down["was_up"] == true, "{down}");
    assert_eq!(d.leftovers(), Vec::<String>::new());
}

#[test]
fn a_failed_start_leaves_nothing() {
    let broken = THREE_HOSTS.replace(r#"args = ["--roles", "ingest"]"#, r#"args = ["--roles", "no-such-role"]"#);
    let d = Deployment::new(&broken);
    let out = d.out();
    let o = risktwin(&["deploy", "run", d.file(), "--for", "30s", "--out", out.to_str().expect("utf-8")], LIMIT);
    assert_eq!(o.status.code(), Some(1), "{}", String::from_utf8_lossy(&o.stderr));
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("error: cloud-0/cloud did not become ready"), "{stderr}");
    assert_eq!(d.leftovers(), Vec::<String>::new());
}

#[test]
fn bad_topologies_are_refused_with_their_line_and_nothing_starts() {
    let cases = [
        ("unknown host", r#"between = ["edge", "cloud"]"#, r#"between = ["edge", "nowhere"]"#, 24),
        ("negative latency", "latency_ms = 20", "latency_ms = -20", 25),
        ("duplicate name", r#"name = "rsu-1""#, r#"name = "car-1""#, 19),
        ("unknown role", r#"{ role = "rsu", args"#, r#"{ role = "teleporter", args"#, 21),
        ("unreachable host", "name = \"edge\"\n", "name = \"edge\"\nrouter = false\n", 15),
    ];
    for (what, from, to, line) in cases {
        let mut text = THREE_HOSTS.replacen(from, to, 1);
        if what == "unreachable host" {
            text =
                text.replace("[[link]]\nbetween = [\"edge\", \"cloud\"]", "[[link]]\nbetween = [\"car-1\", \"rsu-1\"]");
        }
        assert_ne!(text, THREE_HOSTS, "{what}");
        let d = Deployment::new(&text);
        let out = d.out();
        let o = risktwin(&["deploy", "run", d.file(), "--for", "5s", "--out", out.to_str().expect("utf-8")], LIMIT);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{what}: {stderr}");
        assert!(stderr.starts_with("error: ") && stderr.contains(&format!("line {line}:")), "{what}: {stderr}");
        assert!(!out.join("hosts").exists(), "{what}: nothing started");
        assert_eq!(d.leftovers(), Vec::<String>::new(), "{what}");
    }
}
