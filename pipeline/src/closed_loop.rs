//! The push phase of `risktwin run`: the top library scenarios and the trained `full` policy go
//! over Zenoh to an edge vehicle in this process ([`push_loop`]), and what the edge reports is
//! set against the same episodes driven here.
//!
//! Two in-process references per pushed episode:
//! - the edge's own code (`edge::scene::Tape`, the policy loaded from the pushed safetensors
//!   bytes as a `HostPolicy`), which the edge's result must equal exactly, every field —
//!   anything else means the spec or the weights changed on the wire;
//! - the run's own episode (the library's reference-driver outcome and the re-score of the
//!   `full` policy through candle). The edge steps the world at the same 50 ms step
//!   (`common::world::STEP_S`), so a reference-driver episode is the library's exactly; a
//!   policy's may differ in the last bits of its network's arithmetic (plain Rust on the edge,
//!   candle here).
//!
//! What goes into metrics.json ([`ClosedLoop`]) is deterministic; the traffic counts and wall
//! time ([`push_loop::LoopOutput`]) depend on timing and appear in report.md only.

use crate::error::RunError;
use crate::push_loop::{self, LoopOutput, LoopRequest};
use risktwin_cloud::network::push::ScenarioPushReport;
use risktwin_cloud::trainer::drive::drive;
use risktwin_common::episode::{EpisodeResult, evaluate};
use risktwin_common::metrics::EpisodeMetrics;
use risktwin_common::risk::RiskTerms;
use risktwin_common::scenario::{ScenarioKind, build};
use risktwin_common::telemetry::PolicyRef;
use risktwin_common::world::STEP_S;
use risktwin_edge::scene::{ActivePolicy, Tape};
use risktwin_edge::vehicle::DEFAULT_STATE_RATE_HZ;
use risktwin_learn::PolicyNet;
use risktwin_policy::HostPolicy;
use risktwin_policy::model::DriverModel;
use risktwin_store::library::{RankedScenario, ScenarioLibrary};
use risktwin_transport::Shutdown;
use serde::Serialize;
use std::fmt::Write;
use std::path::PathBuf;
use std::sync::Arc;

/// File name of the ingest role's recording in the report folder.
pub const FILE: &str = "loop.mcap";

/// One episode's outcome, as far as the three runs of it are compared.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LoopOutcome {
    pub collision: bool,
    pub offroad: bool,
    pub success: bool,
    pub route_completion: f64,
    /// `None` when no vehicle pair ever closed in.
    pub min_ttc_s: Option<f64>,
    pub risk_score: f64,
    /// Simulated time until the episode ended, s.
    pub duration_s: f64,
}

impl LoopOutcome {
    fn new(metrics: &EpisodeMetrics, risk: &RiskTerms, step_s: f64) -> Self {
        LoopOutcome {
            collision: metrics.collision,
            offroad: metrics.offroad,
            success: metrics.success,
            route_completion: metrics.route_completion,
            min_ttc_s: metrics.min_ttc_s,
            risk_score: risk.score,
            duration_s: metrics.steps as f64 * step_s,
        }
    }
}

/// One pushed episode: the edge's result and the two in-process runs of it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Compared {
    /// The policy version that drove on the edge, as its `ScenarioResult` says (`None`: the
    /// reference driver).
    pub driven_by: Option<PolicyRef>,
    pub edge: LoopOutcome,
    /// The edge's code run here on the same spec and weights.
    pub edge_code_here: LoopOutcome,
    /// Whether the edge's metrics and risk terms equal those of the edge's code run here, every
    /// field (not only those shown) and exactly (f64 equality: the wire carries doubles).
    pub edge_equals_here: bool,
    /// The run's own episode: the library's outcome, or the re-score.
    pub run: LoopOutcome,
}

/// One scenario pushed twice.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LoopScenario {
    pub id: String,
    pub kind: ScenarioKind,
    /// Pushed before the policy: driven by the edge's reference driver.
    pub reference: Compared,
    /// Pushed after the policy.
    pub policy: Compared,
}

/// The deterministic part of the push phase (metrics.json).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClosedLoop {
    /// `<site>/<id>` of the edge vehicle.
    pub edge: String,
    /// The state rate the edge played pushed episodes at, Hz.
    pub rate_hz: f64,
    /// The policy pushed (the `full` variant, first seed).
    pub policy: PolicyRef,
    pub algo: String,
    pub scenarios: Vec<LoopScenario>,
}

/// Pushes the first `n` of `top` and the `full` policy (`weights`: its safetensors bytes) to an
/// edge, and compares; `Ok(None)` when there is nothing to push.
#[allow(clippy::too_many_arguments)]
pub fn push_phase(
    library: &ScenarioLibrary,
    top: &[RankedScenario],
    n: usize,
    policy: &PolicyNet,
    weights: Vec<u8>,
    algo: &str,
    record: Option<PathBuf>,
    shutdown: &Shutdown,
    progress: &mut dyn FnMut(&str),
) -> Result<Option<(ClosedLoop, LoopOutput)>, RunError> {
    let mut scenarios = Vec::new();
    let mut kinds = Vec::new();
    for r in top.iter().take(n) {
        if let Some(stored) = library.get(&r.id)? {
            scenarios.push((r.id.clone(), stored.spec));
            kinds.push(r.kind);
        }
    }
    if scenarios.is_empty() {
        return Ok(None);
    }
    let host = HostPolicy::from_safetensors(&weights).map_err(push_loop::LoopError::from)?;
    let request = LoopRequest {
        scenarios,
        policy_id: format!("{algo}-full-final"),
        version: 1,
        algo: algo.to_owned(),
        weights,
        record,
    };
    let output = push_loop::run_loop(&request, shutdown, progress)?;
    let id = PolicyRef { policy_id: request.policy_id.clone(), version: request.version };
    let active = ActivePolicy { id: id.clone(), model: DriverModel::Native(Arc::new(host)) };
    let mut compared = Vec::new();
    for (((spec_id, spec), kind), (reference, pushed)) in
        request.scenarios.iter().zip(kinds).zip(output.by_reference.iter().zip(&output.by_policy))
    {
        compared.push(LoopScenario {
            id: spec_id.clone(),
            kind,
            reference: compare(reference, &Tape::record(spec, None), &evaluate(spec)),
            policy: compare(
                pushed,
                &Tape::record(spec, Some(&active)),
                &drive(policy, &mut build(spec), &mut |_, _| {}),
            ),
        });
    }
    let closed = ClosedLoop {
        edge: format!("{}/{}", push_loop::SITE, push_loop::VEHICLE),
        rate_hz: push_loop::RATE_HZ,
        policy: id,
        algo: algo.to_owned(),
        scenarios: compared,
    };
    Ok(Some((closed, output)))
}

fn compare(edge: &ScenarioPushReport, here: &Tape, run: &EpisodeResult) -> Compared {
    Compared {
        driven_by: edge.policy.clone(),
        edge: LoopOutcome::new(&edge.metrics, &edge.risk, STEP_S),
        edge_code_here: LoopOutcome::new(&here.result.metrics, &here.result.risk, STEP_S),
        edge_equals_here: edge.metrics == here.result.metrics && edge.risk == here.result.risk,
        run: LoopOutcome::new(&run.metrics, &run.risk, STEP_S),
    }
}

fn cells(o: &LoopOutcome) -> String {
    let ttc = o.min_ttc_s.map_or("∞".to_owned(), |t| format!("{t:.2}"));
    format!(
        "{} | {} | {:.3} | {ttc} | {:.3} | {:.2}",
        if o.collision { "yes" } else { "no" },
        if o.success { "yes" } else { "no" },
        o.route_completion,
        o.risk_score,
        o.duration_s
    )
}

fn driver(p: &Option<PolicyRef>) -> String {
    p.as_ref().map_or("reference driver".to_owned(), |p| format!("`{}` v{}", p.policy_id, p.version))
}

/// The report's "Closed loop over Zenoh" section.
pub fn section(s: &mut String, closed: &ClosedLoop, traffic: Option<&LoopOutput>) {
    let _ = writeln!(s, "\n## Closed loop over Zenoh\n");
    let _ = writeln!(
        s,
        "In this process: a Zenoh router on loopback{}, the cloud's ingest role (recording to `{FILE}`) and an edge \
         vehicle `{}` (its 50 Hz state stream published at {} Hz, {}× real time), every session a Zenoh client of the \
         router. The cloud pushed the top {} library scenario(s) to the vehicle as scenario messages (driven by its \
         reference driver), then the `full` policy (`{}` version {}, {}, the weights of `policy_full.safetensors`) \
         as a policy update, waited until the vehicle had taken it, and pushed the same scenarios again. Each \
         outcome is the vehicle's `ScenarioResult`, received over Zenoh.\n",
        traffic.map_or(String::new(), |t| format!(" (`{}`)", t.locator)),
        closed.edge,
        closed.rate_hz,
        closed.rate_hz / DEFAULT_STATE_RATE_HZ,
        closed.scenarios.len(),
        closed.policy.policy_id,
        closed.policy.version,
        closed.algo
    );
    let _ = writeln!(
        s,
        "Each episode three ways: **edge** — what the vehicle reported; **edge code here** — the vehicle's own \
         episode code (`edge::scene::Tape`) run in this process on the same spec and weights; **run** — this run's \
         episode (the library's reference-driver outcome, or the re-score above). All three step the world at the \
         same 50 ms step. Edge and edge code here must agree exactly, every field (same code, same inputs: the spec \
         and the weights crossed the wire unchanged). For the reference driver, run is the same code too; a \
         policy's run evaluates the network through candle, the edge in plain Rust, which may differ in the last \
         bits.\n"
    );
    let _ = writeln!(
        s,
        "| scenario | kind | driven by (edge) | as | collision | success | route completion | min TTC s | S_risk | \
         duration s | edge = edge code here |\n|---|---|---|---|---|---|---|---|---|---|---|"
    );
    for sc in &closed.scenarios {
        for c in [&sc.reference, &sc.policy] {
            let same = if c.edge_equals_here { "yes" } else { "**no**" };
            let who = driver(&c.driven_by);
            let _ = writeln!(s, "| `{}` | {} | {who} | edge | {} | {same} |", sc.id, sc.kind, cells(&c.edge));
            let _ = writeln!(s, "| | | | edge code here | {} | |", cells(&c.edge_code_here));
            let _ = writeln!(s, "| | | | run | {} | |", cells(&c.run));
        }
    }
    let all_equal = closed.scenarios.iter().all(|sc| sc.reference.edge_equals_here && sc.policy.edge_equals_here);
    let same_kind = closed
        .scenarios
        .iter()
        .flat_map(|sc| [&sc.reference, &sc.policy])
        .filter(|c| c.edge.collision == c.run.collision && c.edge.success == c.run.success)
        .count();
    let _ = writeln!(
        s,
        "\n{} Against the run, {same_kind} of {} episodes ended the same way (collision and success).",
        if all_equal {
            "Every edge result equals the edge code run here, exactly."
        } else {
            "Some edge results differ from the edge code run here (marked **no**): the wire changed an input."
        },
        2 * closed.scenarios.len()
    );
    let Some(t) = traffic else { return };
    let _ = writeln!(
        s,
        "\nTraffic (timing-dependent, so not in metrics.json): the loop took {:.1} s; the vehicle sent {:?}; ingest received {:?}, dropped {} ({:?}), recorded \
         {}; edges seen joining {:?}, leaving {:?}. The vehicle accepted {} scenario push(es), refused {:?}; it holds \
         policy `{}` version {} ({} bytes), refused {:?}.",
        t.wall_s,
        t.vehicle.sent.sent,
        t.cloud.ingest.received,
        t.cloud.ingest.total_dropped,
        t.cloud.ingest.dropped,
        t.cloud.ingest.recorded,
        t.cloud.liveliness.joined,
        t.cloud.liveliness.left,
        t.vehicle.pushes.scenarios_accepted,
        t.vehicle.pushes.scenarios_refused,
        t.held.policy_id,
        t.held.version,
        t.held.weights_bytes,
        t.vehicle.pushes.policies_refused
    );
}
