//! Sharded ingest (docs/sharding.md): three workers share a site (`cloud --shard`) and a union
//! feeds the twin. The worker owning the most vehicles is killed (`kill -9`) mid-run: its
//! vehicles move to the other two within 2 s, the new owners fetch the gap from the edges'
//! caches, and the union holds every message the edges sent, each once.

use crate::support::{Proc, start_router};
use risktwin_transport::wall_clock::unix_ns;
use serde_json::Value;
use std::collections::BTreeSet;
use std::time::{Duration, Instant};

const STEP: Duration = Duration::from_secs(60);
const SITE: &str = "shard";
const WORKERS: usize = 3;
const VEHICLES: usize = 9;
/// How long each vehicle publishes, s: the kill falls in its middle.
const DRIVE_S: &str = "6";
/// How long after every vehicle publishes the worker is killed: it has forwarded a good part.
const BEFORE_KILL: Duration = Duration::from_millis(1500);
/// The bound on a hand-over, from the kill to the new owner's subscription.
const HANDOVER: Duration = Duration::from_secs(2);

fn count(v: &Value) -> u64 {
    v.as_u64().unwrap_or_else(|| panic!("{v} is not a count"))
}

#[test]
fn three_sharded_workers_one_killed_hand_over_within_2_s_and_the_union_receives_every_message_once() {
    let (_router, locator) = start_router();
    let client = ["--mode", "client", "--connect", locator.as_str()];
    let mut union = Proc::spawn("union", &[&["cloud", "--roles", "union,twin", "--site", SITE][..], &client].concat());
    union.wait_line(STEP, |l| l == "ready");
    let mut workers: Vec<Proc> = (0..WORKERS)
        .map(|i| {
            let args = [&["cloud", "--roles", "ingest", "--shard", "--site", SITE][..], &client].concat();
            Proc::spawn(&format!("worker-{i}"), &args)
        })
        .collect();
    for worker in &mut workers {
        worker.wait_line(STEP, |l| l == "ready");
        // Every worker sees all three before any vehicle starts: no share moves at the start.
        worker.wait_line(STEP, |l| l.contains(&format!("({WORKERS} alive)")));
    }
    let mut edges: Vec<Proc> = (0..VEHICLES)
        .map(|v| {
            let id = format!("veh-{v}");
            let args = ["edge", "vehicle", "--id", &id, "--site", SITE, "--rate-hz", "50", "--duration", DRIVE_S];
            Proc::spawn(&id, &[&args[..], &client].concat())
        })
        .collect();
    for (v, edge) in edges.iter_mut().enumerate() {
        edge.wait_line(STEP, |l| l == format!("edge veh-{v}: publishing"));
    }
    let owns = |line: &str| line.contains("shard: owns ");
    // Each vehicle is owned once its edge publishes (it waits for a matching subscriber); the
    // owner's line follows its subscription at once.
    let deadline = Instant::now() + STEP;
    let mut owned = 0;
    while owned < VEHICLES && Instant::now() < deadline {
        owned = workers.iter_mut().map(|w| w.count_lines(owns)).sum();
        std::thread::sleep(Duration::from_millis(10));
    }
    assert_eq!(owned, VEHICLES, "every vehicle owned by exactly one worker");
    std::thread::sleep(BEFORE_KILL);
    let victim = (0..WORKERS).max_by_key(|&i| workers[i].count_lines(owns)).expect("three workers");
    let stderr = workers[victim].drain_stderr();
    let moved: BTreeSet<String> =
        stderr.lines().filter_map(|l| l.split("shard: owns ").nth(1).map(str::to_owned)).collect();
    let victim_id = stderr.lines().find_map(|l| l.split("shard: this worker is ").nth(1)).expect("its id").to_owned();
    let killed_ms = (unix_ns() / 1_000_000) as u64;
    workers[victim].kill();
    let sent: Vec<Value> = edges.iter_mut().map(|e| e.exit_json(STEP)).collect();
    let mut survivors = Vec::new();
    for (i, mut worker) in workers.into_iter().enumerate() {
        if i != victim {
            worker.terminate();
            survivors.push(worker.exit_json(STEP));
        }
    }
    union.terminate();
    let union = union.exit_json(STEP);

    // The victim's vehicles moved, each within the bound, and nothing else moved. (The second
    // survivor takes the first one's share when that one ends: not counted here.)
    let mut took: BTreeSet<String> = BTreeSet::new();
    let mut slowest_ms = 0;
    for worker in &survivors {
        let took_over = worker["shard"]["took_over"].as_array().expect("took_over");
        for t in took_over.iter().filter(|t| t["from"] == victim_id.as_str()) {
            let source = t["source"].as_str().expect("a source").to_owned();
            let after_ms = count(&t["at_unix_ms"]).saturating_sub(killed_ms);
            assert!(after_ms <= HANDOVER.as_millis() as u64, "{source} moved {after_ms} ms after the kill");
            slowest_ms = slowest_ms.max(after_ms);
            took.insert(source);
        }
        assert_eq!(count(&worker["shard"]["workers_max"]), WORKERS as u64, "{worker}");
        // Each worker subscribes to its own groups: the others' samples do not reach it (a
        // subscription to the whole site would let go about two thirds of what it receives).
        let (skipped, accepted) = (count(&worker["shard"]["skipped"]), count(&worker["total_received"]));
        assert!(skipped * 20 < accepted, "{skipped} skipped against {accepted} accepted: {worker}");
    }
    assert!(!moved.is_empty());
    assert_eq!(took, moved, "the killed worker's vehicles, and only they, moved");

    // The union: every message each edge sent, once; the hand-over's repeats counted as
    // duplicates, nothing presumed lost.
    assert_eq!(count(&union["total_presumed_lost"]), 0, "{union}");
    let future = union["dropped"].get("future-timestamp").map_or(0, count);
    for (reason, n) in union["dropped"].as_object().expect("dropped") {
        assert!(reason == "duplicate" || reason == "future-timestamp", "union dropped {n} as {reason}: {union}");
    }
    let (mut total_sent, mut total_received) = (0, 0);
    for (v, edge) in sent.iter().enumerate() {
        for (stream, n) in edge["sent"].as_object().expect("sent") {
            let received = union["received"][format!("veh-{v}")][stream].as_u64().unwrap_or(0);
            total_sent += count(n);
            total_received += received;
            if future == 0 {
                assert_eq!(received, count(n), "veh-{v}/{stream}: {union}");
            }
        }
        assert_eq!(edge["undelivered"].as_object().expect("undelivered").values().map(count).sum::<u64>(), 0, "{edge}");
    }
    let duplicates = union["dropped"].get("duplicate").map_or(0, count);
    eprintln!(
        "{} vehicles moved, the last {slowest_ms} ms after the kill; union: {total_received} received of \
         {total_sent} sent, {duplicates} duplicates, {future} future-timestamp",
        moved.len()
    );
    // A clock refusal at the union is counted, not lost (accepted + future-timestamp = sent).
    assert_eq!(total_received + future, total_sent, "{union}");
    assert!(total_sent > (VEHICLES * 6 * 50) as u64, "{total_sent}");
}
