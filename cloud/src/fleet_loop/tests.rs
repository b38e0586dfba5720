//! The loop's decisions on a real library file, without the network.
use super::*;
use crate::generate::{evaluate_all, reference_outcome};
use risktwin_common::scenario::{ScenarioKind, check_feasible, sample};
use risktwin_common::telemetry::{Frame, Header};
use risktwin_store::library::ScenarioRecord;

/// A library file of `n` feasible emergency brakings with their reference outcomes, one of
/// them a collision; its path.
fn library(dir: &std::path::Path, n: usize) -> std::path::PathBuf {
    let path = dir.join("lib.db");
    let specs: Vec<ScenarioSpec> = (0..400)
        .map(|i| sample(3, ScenarioKind::EmergencyBraking, i))
        .filter(|s| check_feasible(s).is_ok())
        .take(n)
        .collect();
    let records: Vec<ScenarioRecord> = evaluate_all(specs, 1)
        .into_iter()
        .map(|e| ScenarioRecord::sampled(e.spec, reference_outcome(&e.result)))
        .collect();
    let mut lib = ScenarioLibrary::open(&path).expect("a library");
    lib.insert_batch(&records).expect("stored");
    path
}

/// The edge's report of `order`'s episode, as the reference driver plays it.
fn played(order: &PushOrder) -> WatchedEpisode {
    let r = risktwin_common::episode::evaluate(&order.spec);
    let header =
        Header { source: order.edge.clone(), seq: 0, capture_time_ns: 1, publish_time_ns: 1, frame: Frame::World };
    let result = ScenarioResult {
        header,
        spec_id: order.spec_id.clone(),
        metrics: r.metrics,
        risk: r.risk,
        policy: None,
        state_seqs: Some((10, 200)),
        scene: None,
    };
    WatchedEpisode {
        site: order.site.clone(),
        edge: order.edge.clone(),
        push_seq: Some(order.push_seq),
        result,
        spec: Some(order.spec.clone()),
        views: Vec::new(),
        received: Instant::now(),
        handed: Instant::now(),
    }
}

fn alive(edges: &[&str]) -> Vec<(String, String)> {
    edges.iter().map(|e| ("s".to_owned(), (*e).to_owned())).collect()
}

#[test]
fn the_loop_pushes_each_scenario_once_and_resumes_its_pushes_after_a_restart() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let path = library(dir.path(), 5);
    let config = LoopConfig { mutants_per_failure: 2, ..LoopConfig::default() };
    let mut fleet =
        FleetLoop::open(ScenarioLibrary::open(&path).expect("opens"), config.clone(), None).expect("a loop");
    let now = Instant::now();
    let orders = fleet.on_idle(&alive(&["v1", "v2"]), now).expect("orders");
    assert_eq!(orders.len(), 2, "one push per live vehicle");
    let ranked = fleet.library().rank(Some(2), None).expect("rank");
    assert_eq!(orders.iter().map(|o| o.spec_id.as_str()).collect::<Vec<_>>(), [&ranked[0].id, &ranked[1].id]);
    for order in &orders {
        fleet.sent(order, None);
    }
    assert_eq!(fleet.on_idle(&alive(&["v1", "v2"]), Instant::now()).expect("orders"), [], "none overdue");

    // v1's episode comes back: stored with the edge's outcome, and v1 gets the next one.
    let next = fleet.on_episode(&played(&orders[0]), true).expect("stored").expect("a next push");
    assert_eq!(next.edge, "v1");
    assert_eq!(next.spec_id, fleet.library().rank(Some(3), None).expect("rank")[2].id);
    fleet.sent(&next, Some(&played(&orders[0])));
    let summary = fleet.summary().expect("summary");
    assert_eq!((summary.pushes, summary.episodes, summary.iteration.count), (3, 1, 1));
    assert_eq!(summary.disagreements, 1, "the twin saw none of it, and the row says so");
    let episodes = fleet.library().fleet_episodes().expect("read");
    assert_eq!(episodes[0].episode.push_seq, Some(orders[0].push_seq));
    assert_eq!(episodes[0].episode.disagreement.as_deref(), Some("the twin did not see the episode"));

    // A crash: the file holds v1's and v2's outstanding pushes; a new loop sends them again.
    drop(fleet);
    let mut fleet = FleetLoop::open(ScenarioLibrary::open(&path).expect("reopens"), config, None).expect("a loop");
    let resent = fleet.on_idle(&alive(&["v1", "v2"]), Instant::now()).expect("orders");
    let mut seqs: Vec<(i64, u32)> = resent.iter().map(|o| (o.push_seq, o.attempt)).collect();
    seqs.sort_unstable();
    assert_eq!(seqs, [(orders[1].push_seq, 2), (next.push_seq, 2)], "the same pushes, a second attempt");
    assert_eq!(fleet.summary().expect("summary").pushes, 0, "no new push");
    // v2's result of its first push answers the retried push.
    let v2_next = fleet.on_episode(&played(&orders[1]), true).expect("stored");
    assert!(v2_next.is_some());
    let pushes = fleet.library().fleet_counts().expect("counts");
    assert_eq!((pushes.episodes, pushes.outstanding), (2, 2));
}

#[test]
fn an_overdue_push_is_sent_again_then_given_up_and_failures_are_mutated_around() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let path = library(dir.path(), 3);
    let config = LoopConfig { result_timeout: Duration::ZERO, max_attempts: 2, ..LoopConfig::default() };
    let mut fleet = FleetLoop::open(ScenarioLibrary::open(&path).expect("opens"), config, None).expect("a loop");
    let first = fleet.on_idle(&alive(&["v1"]), Instant::now()).expect("orders").remove(0);
    fleet.sent(&first, None);
    let again = fleet.on_idle(&alive(&["v1"]), Instant::now()).expect("orders");
    assert_eq!(again.iter().map(|o| (o.push_seq, o.attempt)).collect::<Vec<_>>(), [(first.push_seq, 2)]);
    fleet.sent(&again[0], None);
    let after = fleet.on_idle(&alive(&["v1"]), Instant::now()).expect("orders");
    assert_eq!(after.len(), 1);
    assert_ne!(after[0].push_seq, first.push_seq, "given up after 2 sends; the next scenario goes");
    let summary = fleet.summary().expect("summary");
    assert_eq!((summary.retries, summary.abandoned, summary.library.abandoned), (1, 1, 1));
    let kinds: Vec<&str> = fleet.take_events().iter().map(|e| e.kind).collect();
    assert_eq!(kinds, ["push", "retry", "abandon"], "the events, for the recording");

    // A failure reported by the edge is mutated around: its children join the library.
    let mut failed = played(&after[0]);
    failed.result.metrics.collision = true;
    let before = fleet.library().fleet_counts().expect("counts").scenarios;
    fleet.on_episode(&failed, false).expect("stored");
    let stored = fleet.mutate_failures().expect("mutated");
    assert!(stored >= 1, "no child was stored");
    assert_eq!(fleet.library().fleet_counts().expect("counts").scenarios, before + stored);
    let regression = fleet.library().regression_set().expect("read");
    assert!(regression.iter().any(|case| case.id == after[0].spec_id), "the failure is a regression case");
}

/// A gate report with the given decision (the figures do not matter here).
fn report(pushed: bool) -> GateReport {
    use crate::trainer::gate::{Decision, SetComparison, SetSummary};
    let summary = SetSummary { collisions: 0, successes: 0, mean_route_completion: 0.5 };
    let set =
        SetComparison { scenarios: 0, candidate: summary.clone(), deployed: summary, newly_colliding: Vec::new() };
    GateReport {
        decision: if pushed { Decision::Push } else { Decision::Hold },
        reasons: if pushed { Vec::new() } else { vec!["held-out set: worse".into()] },
        regression: set.clone(),
        held_out: set,
        completion_tolerance: 0.02,
    }
}

#[test]
fn training_waits_for_new_failures_and_only_a_version_the_gate_lets_through_goes_out() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let path = library(dir.path(), 4);
    let trainer = TrainerConfig { retrain_failures: 1, every: None, steps: 1000, held_out_per_kind: 1, seed: 1 };
    let open = || {
        let library = ScenarioLibrary::open(&path).expect("opens");
        FleetLoop::open(library, LoopConfig { mutants_per_failure: 0, ..LoopConfig::default() }, Some(trainer.clone()))
            .expect("a loop")
    };
    let mut fleet = open();
    assert!(fleet.due_training().expect("checked").is_none(), "no fleet failure yet");
    let order = fleet.on_idle(&alive(&["v1"]), Instant::now()).expect("orders").remove(0);
    let mut failed = played(&order);
    failed.result.metrics.collision = true;
    fleet.on_episode(&failed, false).expect("stored");
    let job = fleet.due_training().expect("checked").expect("one failure is enough");
    assert_eq!((job.version, job.failures, job.deployed.clone()), (1, 1, None));
    assert!(fleet.due_training().expect("checked").is_none(), "one run at a time");

    let version = |v: u32, pushed: bool| PolicyVersion {
        version: v,
        policy_id: trainer::POLICY_ID.into(),
        algo: "ppo".into(),
        weights: vec![v as u8; 4],
        pushed,
        reasons: report(pushed).reasons,
        failures: 1,
    };
    fleet.on_trained(Ok((version(1, false), report(false)))).expect("stored");
    assert_eq!(fleet.policy_orders(&alive(&["v1", "v2"])).expect("orders"), [], "held back: nothing goes out");
    assert!(fleet.due_training().expect("checked").is_none(), "no new failure since version 1");
    fleet.on_trained(Ok((version(2, true), report(true)))).expect("stored");
    let orders = fleet.policy_orders(&alive(&["v1", "v2"])).expect("orders");
    assert_eq!(orders.iter().map(|o| (o.edge.as_str(), o.version)).collect::<Vec<_>>(), [("v1", 2), ("v2", 2)]);
    fleet.policy_sent(&orders[0]).expect("noted");
    let summary = fleet.summary().expect("summary");
    assert_eq!((summary.deployed_version, summary.policy_pushes, summary.gate.len()), (Some(2), 1, 2));

    // After a restart the deployed version is known, and only v2 still needs it.
    drop(fleet);
    let fleet = open();
    let left = fleet.policy_orders(&alive(&["v1", "v2"])).expect("orders");
    assert_eq!(left.iter().map(|o| (o.edge.as_str(), o.version)).collect::<Vec<_>>(), [("v2", 2)]);
    // A failed run stops the trainer and says why; the loop goes on.
    let mut fleet = fleet;
    fleet.on_trained(Err(TrainerError::EmptyLibrary)).expect("handled");
    assert!(fleet.summary().expect("summary").training_error.is_some());
    assert!(fleet.due_training().expect("checked").is_none());
}

#[test]
fn on_a_schedule_one_new_failure_is_enough_once_the_period_has_passed() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let library = ScenarioLibrary::open(library(dir.path(), 4)).expect("opens");
    let config = LoopConfig { mutants_per_failure: 0, ..LoopConfig::default() };
    let mut fleet = FleetLoop::open(library, config, None).expect("a loop");
    let order = fleet.on_idle(&alive(&["v1"]), Instant::now()).expect("orders").remove(0);
    let mut failed = played(&order);
    failed.result.metrics.collision = true;
    fleet.on_episode(&failed, false).expect("stored");
    let every = Duration::from_secs(600);
    let scheduled = TrainerConfig { retrain_failures: 3, every: Some(every), ..TrainerConfig::default() };
    let due = |config: &TrainerConfig, since_last| trainer::due(fleet.library(), config, since_last).expect("checked");
    assert!(due(&scheduled, every / 2).is_none(), "1 of 3 failures, the period not yet over");
    let job = due(&scheduled, every).expect("the period is over and a failure is in");
    assert_eq!((job.version, job.failures), (1, 1));
    let unscheduled = TrainerConfig { every: None, ..scheduled };
    assert!(due(&unscheduled, every * 10).is_none(), "without a schedule, 3 failures are needed");
}
