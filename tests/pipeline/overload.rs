//! Overload (docs/keyexpr.md, "Overload"): a cloud asked to shed (`--shed-after-ms 200`), held
//! to 1 % of one core by the kernel (a cgroup-v1 CPU quota, a real limit, not a slowed build),
//! under 20 vehicles' 5,200 msg/s.
//! It sees its live states wait, sheds CAN and then everything but states, counts what it
//! sheds under `shed`, and tells the edges, which hold those streams back at the source and
//! count them; its memory stays small, and no vehicle state is ever shed.

use crate::support::{Proc, start_router};
use serde_json::Value;
use std::path::PathBuf;
use std::time::{Duration, Instant};

const STEP: Duration = Duration::from_secs(60);
const VEHICLES: usize = 20;
/// 1 ms of CPU every 100 ms: the smallest quota the kernel takes.
const QUOTA_US: &str = "1000";
const PERIOD_US: &str = "100000";
/// The cloud's resident memory may not pass this while overloaded.
const RSS_BOUND_KIB: u64 = 128 * 1024;

/// A cgroup-v1 CPU controller group, removed on drop (after its processes are gone).
struct CpuLimit(PathBuf);

impl CpuLimit {
    fn new() -> CpuLimit {
        let dir = PathBuf::from(format!("/sys/fs/cgroup/cpu/risktwin-overload-{}", std::process::id()));
        std::fs::create_dir_all(&dir)
            .unwrap_or_else(|e| panic!("the cgroup-v1 CPU controller is needed (as root): {}: {e}", dir.display()));
        let limit = CpuLimit(dir);
        limit.write("cpu.cfs_period_us", PERIOD_US);
        limit.write("cpu.cfs_quota_us", QUOTA_US);
        limit
    }

    fn write(&self, file: &str, value: &str) {
        let path = self.0.join(file);
        std::fs::write(&path, value).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    }

    fn add(&self, pid: u32) {
        self.write("cgroup.procs", &pid.to_string());
    }
}

impl Drop for CpuLimit {
    fn drop(&mut self) {
        // A killed process leaves its group a moment after it is reaped.
        let deadline = Instant::now() + Duration::from_secs(5);
        while std::fs::remove_dir(&self.0).is_err() && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

fn rss_kib(pid: u32) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    status.lines().find_map(|l| l.strip_prefix("VmRSS:")).and_then(|v| v.trim().trim_end_matches(" kB").parse().ok())
}

fn count(v: &Value) -> u64 {
    v.as_u64().unwrap_or_else(|| panic!("{v} is not a count"))
}

#[test]
fn a_cloud_held_to_1_percent_of_a_core_sheds_counts_and_tells_the_edges_with_bounded_memory() {
    // Declared before the cloud: dropped after it, once the cloud is gone.
    let limit = CpuLimit::new();
    let (_router, locator) = start_router();
    let client = ["--mode", "client", "--connect", locator.as_str()];
    let mut cloud = Proc::spawn(
        "cloud",
        &[&["cloud", "--roles", "ingest", "--site", "ov", "--shed-after-ms", "200"][..], &client].concat(),
    );
    cloud.wait_line(STEP, |l| l == "ready");
    limit.add(cloud.id());
    let mut edges: Vec<Proc> = (0..VEHICLES)
        .map(|v| {
            let id = format!("veh-{v}");
            let args = ["edge", "vehicle", "--id", &id, "--site", "ov", "--rate-hz", "50", "--duration", "8"];
            Proc::spawn(&id, &[&args[..], &client].concat())
        })
        .collect();
    // The cloud says when it starts shedding; meanwhile its memory is sampled.
    let mut rss_max = 0;
    let deadline = Instant::now() + STEP;
    while cloud.count_lines(|l| l.contains("shedding level 2")) == 0 {
        assert!(Instant::now() < deadline, "no shedding within {STEP:?}:\n{}", cloud.drain_stderr());
        rss_max = rss_max.max(rss_kib(cloud.id()).unwrap_or(0));
        std::thread::sleep(Duration::from_millis(100));
    }
    let sent: Vec<Value> = edges
        .iter_mut()
        .map(|e| {
            rss_max = rss_max.max(rss_kib(cloud.id()).unwrap_or(0));
            // An edge whose messages the overloaded cloud has not acknowledged by its end says
            // so (exit 1, `undelivered`): that is its honest report, not this test's failure.
            let (status, stdout) = e.wait_exit(STEP);
            assert!(matches!(status.code(), Some(0 | 1)), "{}: {status}", e.name);
            serde_json::from_str(&stdout).unwrap_or_else(|err| panic!("{}: {err}: {stdout}", e.name))
        })
        .collect();
    cloud.terminate();
    let summary = cloud.exit_json(STEP);
    eprintln!("cloud: {}; RSS at most {} MiB", summary["overload"], rss_max / 1024);
    assert!(rss_max > 0 && rss_max < RSS_BOUND_KIB, "RSS {rss_max} KiB");

    assert_eq!(count(&summary["overload"]["shed_level_max"]), 2, "{summary}");
    let shed_at_cloud = count(&summary["dropped"]["shed"]);
    assert!(shed_at_cloud > 0, "{summary}");
    let mut held_back = 0;
    for (v, edge) in sent.iter().enumerate() {
        let shed = edge.get("shed").and_then(Value::as_object).cloned().unwrap_or_default();
        assert!(!shed.contains_key("state"), "veh-{v} held states back: {edge}");
        held_back += shed.values().map(count).sum::<u64>();
        // Nothing vanished: what the edge sent is acknowledged, counted lost or undelivered.
        for (stream, n) in edge["sent"].as_object().expect("sent") {
            let parts = ["acknowledged", "lost", "undelivered"].map(|k| edge[k][stream].as_u64().unwrap_or(0));
            assert_eq!(parts.iter().sum::<u64>(), count(n), "veh-{v}/{stream}: {edge}");
        }
    }
    assert!(held_back > 0, "no edge held anything back: {sent:?}");
    let edge_lines = edges.iter_mut().map(|e| e.count_lines(|l| l.contains("the cloud is overloaded"))).sum::<usize>();
    assert!(edge_lines > 0, "no edge said it holds streams back");
    eprintln!("edges held back {held_back}; the cloud shed {shed_at_cloud} on arrival");
}
