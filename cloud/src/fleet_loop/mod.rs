//! The closed loop over the fleet, transport-free: what the `loop` role decides as episodes
//! come back and edges come and go. Its state is the library's (`pushes`, `fleet_episodes`),
//! so a cloud that is killed and restarted goes on where it stopped: a push still outstanding
//! is sent again to its edge (a retry of the same push, counted), never a second push of the
//! same scenario.
//!
//! - An episode comes back ([`FleetLoop::on_episode`]): the twin's score is computed from its
//!   ticks, both outcomes are stored with the episode (and where they disagree, the row says
//!   so), the edge gets the riskiest scenario never pushed, and a failure (collision or leaving
//!   the road) is mutated around ([`FleetLoop::mutate_failures`], feasibility-checked children
//!   that rank in from then on).
//! - Edges ([`FleetLoop::on_idle`]): a live vehicle without an outstanding push gets one; an
//!   outstanding push not sent by this process (restart) is sent again; one whose result did
//!   not come within [`LoopConfig::result_timeout`] is sent again, up to
//!   [`LoopConfig::max_attempts`] times, then given up (counted).

pub mod report;
pub mod trainer;

use crate::generate::mutate_stored;
use crate::library::{
    FleetCounts, FleetEpisode, LibraryError, Outcome, PolicyVersion, Push, ScenarioLibrary, content_id, policy_label,
};
use crate::trainer::TrainerError;
use crate::trainer::gate::GateReport;
use crate::twin::watch::WatchedEpisode;
use risktwin_common::digest::fnv1a64;
use risktwin_common::episode::EpisodeResult;
use risktwin_common::scenario::ScenarioSpec;
use risktwin_common::telemetry::{PolicyRef, ScenarioResult};
use serde::Serialize;
use std::collections::{HashMap, HashSet};
use std::time::{Duration, Instant};
use trainer::{TrainJob, TrainerConfig};

/// Route completion the edge and the twin may differ by before the row says they disagree.
pub const COMPLETION_AGREEMENT: f64 = 0.05;
/// S_risk the edge and the twin may differ by before the row says they disagree.
pub const RISK_AGREEMENT: f64 = 0.15;

/// How the loop behaves.
#[derive(Debug, Clone)]
pub struct LoopConfig {
    /// How long a pushed scenario may take to come back before it is sent again.
    pub result_timeout: Duration,
    /// Sends of one push before it is given up.
    pub max_attempts: u32,
    /// Children mutated around each failure.
    pub mutants_per_failure: u64,
    /// Their distance from the parent, as a share of each parameter's range.
    pub mutation_radius: f64,
}

impl Default for LoopConfig {
    fn default() -> Self {
        LoopConfig {
            result_timeout: Duration::from_secs(60),
            max_attempts: 3,
            mutants_per_failure: 4,
            mutation_radius: 0.1,
        }
    }
}

/// A scenario to send to an edge (the network side sends it and starts the twin's watch).
#[derive(Debug, Clone, PartialEq)]
pub struct PushOrder {
    pub site: String,
    pub edge: String,
    pub push_seq: i64,
    pub spec_id: String,
    pub spec: ScenarioSpec,
    /// 1 for the first send, more for a retry.
    pub attempt: u32,
}

/// A policy version to send to an edge.
#[derive(Debug, Clone, PartialEq)]
pub struct PolicyOrder {
    pub site: String,
    pub edge: String,
    pub version: u32,
    pub policy_id: String,
    pub algo: String,
    pub weights: Vec<u8>,
}

/// The gate's decision on one version, for the summary and the report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GateLine {
    pub version: u32,
    pub pushed: bool,
    pub reasons: Vec<String>,
    /// Fleet failures in the library when it was trained.
    pub failures: u64,
    pub regression: SetFigures,
    pub held_out: SetFigures,
}

/// The candidate against the deployed version on one set of the gate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SetFigures {
    pub collisions: usize,
    pub mean_route_completion: f64,
    pub deployed_collisions: usize,
    pub deployed_mean_route_completion: f64,
}

impl From<&crate::trainer::gate::SetComparison> for SetFigures {
    fn from(c: &crate::trainer::gate::SetComparison) -> Self {
        SetFigures {
            collisions: c.candidate.collisions,
            mean_route_completion: c.candidate.mean_route_completion,
            deployed_collisions: c.deployed.collisions,
            deployed_mean_route_completion: c.deployed.mean_route_completion,
        }
    }
}

/// Latency of the loop's iterations, ms.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct IterationTimes {
    pub count: u64,
    /// The loop's own work: the episode handed on by the twin → scored, stored, ranked → the
    /// next push sent.
    pub p50_ms: f64,
    pub max_ms: f64,
    /// From the edge's result arriving (the twin still catching up with the episode's end, up
    /// to the aligner's lateness) to the next push sent.
    pub from_result_p50_ms: f64,
    pub from_result_max_ms: f64,
}

impl IterationTimes {
    fn of(work_ms: &[f64], from_result_ms: &[f64]) -> Self {
        let p50_max = |samples: &[f64]| {
            let mut sorted = samples.to_vec();
            sorted.sort_by(f64::total_cmp);
            (sorted.get(sorted.len() / 2).copied().unwrap_or(0.0), sorted.last().copied().unwrap_or(0.0))
        };
        let ((p50_ms, max_ms), (from_result_p50_ms, from_result_max_ms)) = (p50_max(work_ms), p50_max(from_result_ms));
        IterationTimes { count: work_ms.len() as u64, p50_ms, max_ms, from_result_p50_ms, from_result_max_ms }
    }
}

/// One thing the loop did, for the recording.
#[derive(Debug, Clone, PartialEq)]
pub struct LoopEvent {
    /// `push`, `retry`, `abandon`, `episode`, `policy-pushed`, `policy-held-back` (the gate's
    /// decision) or `policy` (a version sent to an edge).
    pub kind: &'static str,
    /// Empty for an event of the whole fleet (a gate decision).
    pub site: String,
    pub edge: String,
    pub scenario_id: String,
    pub push_seq: Option<i64>,
    /// The send of a push (1 for the first).
    pub attempt: u32,
    pub policy_version: Option<u32>,
    /// An episode's outcome as the edge reported it.
    pub collision: bool,
    pub risk_score: f64,
    /// An episode's disagreement with the twin.
    pub detail: Option<String>,
}

impl LoopEvent {
    /// An event of `kind` at `site/edge` with nothing else set.
    fn at(kind: &'static str, site: &str, edge: &str) -> Self {
        LoopEvent {
            kind,
            site: site.to_owned(),
            edge: edge.to_owned(),
            scenario_id: String::new(),
            push_seq: None,
            attempt: 0,
            policy_version: None,
            collision: false,
            risk_score: 0.0,
            detail: None,
        }
    }
}

/// What the loop did, for the cloud's summary and the report.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct LoopSummary {
    /// The library at the end (scenarios, fleet episodes, failures, disagreements, pushes).
    pub library: FleetCounts,
    /// Scenarios pushed for the first time by this process.
    pub pushes: u64,
    /// Pushes sent again (result overdue, or outstanding from before a restart).
    pub retries: u64,
    /// Pushes given up after their attempts.
    pub abandoned: u64,
    /// Episodes stored by this process.
    pub episodes: u64,
    /// Of those, failures (collision or leaving the road, as the edge reported).
    pub failures: u64,
    /// Failures per hour of this process's run.
    pub failures_per_hour: f64,
    /// Of those, episodes the twin's score disagrees with the edge's on.
    pub disagreements: u64,
    /// Episodes with a twin score.
    pub twin_scored: u64,
    /// Results for scenarios the library does not hold (dropped, logged).
    pub unknown_scenario: u64,
    /// Children stored by mutating around failures.
    pub mutants: u64,
    /// Times a vehicle was free but every scenario had been pushed (once per dry spell).
    pub exhausted: u64,
    /// Results whose outcome the library refused (out of range), dropped; their push stays
    /// outstanding.
    pub invalid_results: u64,
    pub iteration: IterationTimes,
    /// Policy versions trained and gated by this run, with the gate's decisions.
    pub gate: Vec<GateLine>,
    /// The version the fleet is driven by (`None`: the reference driver).
    pub deployed_version: Option<u32>,
    /// Policy versions sent to edges by this run.
    pub policy_pushes: u64,
    /// Why training stopped, if it failed (the loop goes on without it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub training_error: Option<String>,
    /// The report ([`report::markdown`]), filled in at the end of the run.
    #[serde(skip)]
    pub report: String,
}

/// An outstanding push and when this process last sent it (`None`: not yet, e.g. after a
/// restart).
#[derive(Debug, Clone)]
struct Outstanding {
    push: Push,
    sent: Option<Instant>,
}

/// The loop's state machine.
pub struct FleetLoop {
    library: ScenarioLibrary,
    config: LoopConfig,
    outstanding: HashMap<(String, String), Outstanding>,
    /// Failures stored and not yet mutated around.
    new_failures: Vec<String>,
    started: Instant,
    /// Per iteration: the loop's work and the time from the result, ms.
    iterations_ms: (Vec<f64>, Vec<f64>),
    /// Vehicles that found no scenario left to push at their last try.
    idle_without_scenario: HashSet<(String, String)>,
    /// Events since the last [`FleetLoop::take_events`].
    events: Vec<LoopEvent>,
    /// The trainer role, when it runs; a training run is in flight while `training` is set.
    trainer: Option<TrainerConfig>,
    training: bool,
    /// The latest version the gate let through.
    deployed: Option<PolicyVersion>,
    summary: LoopSummary,
}

impl FleetLoop {
    /// The loop on `library`, resuming the pushes it holds as outstanding; with `trainer`, it
    /// retrains and gates policies too.
    pub fn open(
        library: ScenarioLibrary,
        config: LoopConfig,
        trainer: Option<TrainerConfig>,
    ) -> Result<Self, LibraryError> {
        let deployed = library.deployed_policy()?;
        let outstanding = library
            .outstanding_pushes()?
            .into_iter()
            .map(|push| ((push.site.clone(), push.edge.clone()), Outstanding { push, sent: None }))
            .collect();
        Ok(FleetLoop {
            library,
            config,
            outstanding,
            new_failures: Vec::new(),
            started: Instant::now(),
            iterations_ms: (Vec::new(), Vec::new()),
            idle_without_scenario: HashSet::new(),
            events: Vec::new(),
            trainer,
            training: false,
            deployed,
            summary: LoopSummary::default(),
        })
    }

    pub fn library(&self) -> &ScenarioLibrary {
        &self.library
    }

    /// Stores an episode that came back; then, if its edge is `alive`, the next push for it.
    pub fn on_episode(&mut self, episode: &WatchedEpisode, alive: bool) -> Result<Option<PushOrder>, LibraryError> {
        let key = (episode.site.clone(), episode.edge.clone());
        let spec_id = &episode.result.spec_id;
        // A result of the push outstanding at that edge answers it, watched or not (after a
        // restart nobody watched).
        let answers = self.outstanding.get(&key).filter(|o| o.push.scenario_id == *spec_id).map(|o| o.push.seq);
        let twin = episode.score();
        let row = fleet_episode(episode, answers, twin.as_ref());
        match self.library.record_fleet_episode(&row) {
            Ok(_) => {}
            Err(LibraryError::UnknownScenario(id)) => {
                tracing::warn!("loop: {}/{} reported scenario {id}, which the library does not hold", key.0, key.1);
                self.summary.unknown_scenario += 1;
                return Ok(None);
            }
            Err(e @ LibraryError::InvalidRecord { .. }) => {
                tracing::warn!("loop: dropped the result of {}/{}: {e}", key.0, key.1);
                self.summary.invalid_results += 1;
                return Ok(None);
            }
            Err(e) => return Err(e),
        }
        if answers.is_some() {
            self.outstanding.remove(&key);
        }
        self.events.push(LoopEvent {
            scenario_id: spec_id.clone(),
            push_seq: answers,
            collision: episode.result.metrics.collision,
            risk_score: episode.result.risk.score,
            detail: row.disagreement.clone(),
            ..LoopEvent::at("episode", &key.0, &key.1)
        });
        self.check_policy(&key, episode.result.policy.as_ref())?;
        let m = &episode.result.metrics;
        self.summary.episodes += 1;
        self.summary.twin_scored += u64::from(twin.is_some());
        self.summary.disagreements += u64::from(row.disagreement.is_some());
        if m.collision || m.offroad {
            self.summary.failures += 1;
            self.new_failures.push(spec_id.clone());
        }
        if !alive || self.outstanding.contains_key(&key) {
            return Ok(None);
        }
        let order = self.next_push(&key.0, &key.1)?;
        Ok(order)
    }

    /// Marks `order` as sent; `after` is the episode that led to it, if one did.
    pub fn sent(&mut self, order: &PushOrder, after: Option<&WatchedEpisode>) {
        let key = (order.site.clone(), order.edge.clone());
        if let Some(o) = self.outstanding.get_mut(&key) {
            o.sent = Some(Instant::now());
        }
        let kind = if order.attempt > 1 { "retry" } else { "push" };
        self.events.push(LoopEvent {
            scenario_id: order.spec_id.clone(),
            push_seq: Some(order.push_seq),
            attempt: order.attempt,
            ..LoopEvent::at(kind, &order.site, &order.edge)
        });
        if let Some(episode) = after {
            self.iterations_ms.0.push(episode.handed.elapsed().as_secs_f64() * 1e3);
            self.iterations_ms.1.push(episode.received.elapsed().as_secs_f64() * 1e3);
        }
    }

    /// The pushes due with the live vehicles `alive` (as `(site, edge)`): a first one for a
    /// vehicle without one, and resends of overdue or not yet sent ones. A push is given up once
    /// it was sent `max_attempts` times and is overdue again, or when its vehicle has not been
    /// live for `result_timeout` (since its last send, or since this loop started).
    pub fn on_idle(&mut self, alive: &[(String, String)], now: Instant) -> Result<Vec<PushOrder>, LibraryError> {
        let timeout = self.config.result_timeout;
        let gone: Vec<(String, String)> = self
            .outstanding
            .iter()
            .filter(|(key, o)| !alive.contains(key) && now.duration_since(o.sent.unwrap_or(self.started)) >= timeout)
            .map(|(key, _)| key.clone())
            .collect();
        for key in gone {
            self.abandon(&key, "its vehicle is gone")?;
        }
        let mut orders = Vec::new();
        for (site, edge) in alive {
            let key = (site.clone(), edge.clone());
            let Some(o) = self.outstanding.get(&key).cloned() else {
                orders.extend(self.next_push(site, edge)?);
                continue;
            };
            if o.sent.is_some_and(|t| now.duration_since(t) < timeout) {
                continue;
            }
            if o.push.attempts >= self.config.max_attempts {
                self.abandon(&key, "no result after its attempts")?;
                orders.extend(self.next_push(site, edge)?);
                continue;
            }
            let Some(stored) = self.library.get(&o.push.scenario_id)? else {
                self.abandon(&key, "its scenario is no longer in the library")?;
                continue;
            };
            let attempts = self.library.retry_push(o.push.seq)?;
            self.summary.retries += 1;
            if let Some(entry) = self.outstanding.get_mut(&key) {
                entry.push.attempts = attempts;
            }
            orders.push(PushOrder {
                site: site.clone(),
                edge: edge.clone(),
                push_seq: o.push.seq,
                spec_id: o.push.scenario_id.clone(),
                spec: stored.spec,
                attempt: attempts,
            });
        }
        Ok(orders)
    }

    /// Gives up the push outstanding at `key` (`why`, logged).
    fn abandon(&mut self, key: &(String, String), why: &str) -> Result<(), LibraryError> {
        let Some(o) = self.outstanding.remove(key) else { return Ok(()) };
        tracing::warn!(
            "loop: giving up push {} of scenario {} to {}/{} after {} attempts: {why}",
            o.push.seq,
            o.push.scenario_id,
            key.0,
            key.1,
            o.push.attempts
        );
        self.library.abandon_push(o.push.seq)?;
        self.summary.abandoned += 1;
        self.events.push(LoopEvent {
            scenario_id: o.push.scenario_id,
            push_seq: Some(o.push.seq),
            attempt: o.push.attempts,
            detail: Some(why.to_owned()),
            ..LoopEvent::at("abandon", &key.0, &key.1)
        });
        Ok(())
    }

    /// Mutates around the failures stored since the last call; the children stored.
    pub fn mutate_failures(&mut self) -> Result<u64, LibraryError> {
        let mut stored = 0;
        for id in std::mem::take(&mut self.new_failures) {
            // Seeded by the parent, so the same failure gives the same children in any run.
            let seed = fnv1a64(id.bytes());
            let (count, radius) = (self.config.mutants_per_failure, self.config.mutation_radius);
            match mutate_stored(&mut self.library, &id, count, radius, seed, 1) {
                Ok(report) => stored += report.stored as u64,
                Err(crate::generate::MutationError::Library(e)) => return Err(e),
                Err(e) => tracing::warn!("loop: cannot mutate around {id}: {e}"),
            }
        }
        self.summary.mutants += stored;
        Ok(stored)
    }

    /// The next training run, when the trainer runs, none is in flight and enough new failures
    /// are in the library; it is then in flight until [`Self::on_trained`].
    pub fn due_training(&mut self) -> Result<Option<TrainJob>, LibraryError> {
        let Some(config) = self.trainer.as_ref().filter(|_| !self.training) else { return Ok(None) };
        let job = match trainer::due(&self.library, config) {
            Ok(job) => job,
            Err(TrainerError::Library(e)) => return Err(e),
            Err(e) => {
                self.on_trained(Err(e))?;
                return Ok(None);
            }
        };
        self.training = job.is_some();
        if let Some(job) = &job {
            tracing::info!(
                "trainer: training version {} ({} fleet failures in the library)",
                job.version,
                job.failures
            );
        }
        Ok(job)
    }

    /// A training run ended: the version is stored with the gate's decision; a version let
    /// through is deployed (sent to every live vehicle by [`Self::policy_orders`]). A failed run
    /// stops the trainer, said in the summary; the loop goes on.
    pub fn on_trained(&mut self, run: Result<(PolicyVersion, GateReport), TrainerError>) -> Result<(), LibraryError> {
        self.training = false;
        let (version, report) = match run {
            Ok(done) => done,
            Err(e) => {
                tracing::error!("trainer: stopped: {e}");
                self.summary.training_error = Some(e.to_string());
                self.trainer = None;
                return Ok(());
            }
        };
        self.library.record_policy(&version)?;
        self.summary.gate.push(GateLine {
            version: version.version,
            pushed: version.pushed,
            reasons: version.reasons.clone(),
            failures: version.failures,
            regression: (&report.regression).into(),
            held_out: (&report.held_out).into(),
        });
        if version.pushed {
            tracing::info!("trainer: version {} passed the gate: pushed to the fleet", version.version);
        } else {
            tracing::info!("trainer: version {} held back: {}", version.version, version.reasons.join("; "));
        }
        let kind = if version.pushed { "policy-pushed" } else { "policy-held-back" };
        self.events.push(LoopEvent {
            policy_version: Some(version.version),
            detail: (!version.reasons.is_empty()).then(|| version.reasons.join("; ")),
            ..LoopEvent::at(kind, "", "")
        });
        if version.pushed {
            self.deployed = Some(version);
        }
        Ok(())
    }

    /// The deployed version for each live vehicle that has not been sent it.
    pub fn policy_orders(&self, alive: &[(String, String)]) -> Result<Vec<PolicyOrder>, LibraryError> {
        let Some(deployed) = &self.deployed else { return Ok(Vec::new()) };
        let mut orders = Vec::new();
        for (site, edge) in alive {
            if !self.library.policy_delivered(deployed.version, site, edge)? {
                orders.push(PolicyOrder {
                    site: site.clone(),
                    edge: edge.clone(),
                    version: deployed.version,
                    policy_id: deployed.policy_id.clone(),
                    algo: deployed.algo.clone(),
                    weights: deployed.weights.clone(),
                });
            }
        }
        Ok(orders)
    }

    /// A vehicle that reports driving without the deployed version though it was sent it (it
    /// restarted since) is sent it again. (An episode it recorded before the version arrived
    /// says the same: the vehicle then refuses the repeat as stale, and counts it.)
    fn check_policy(&mut self, key: &(String, String), driver: Option<&PolicyRef>) -> Result<(), LibraryError> {
        let Some(deployed) = &self.deployed else { return Ok(()) };
        let drives_it = driver.is_some_and(|p| p.policy_id == deployed.policy_id && p.version == deployed.version);
        if !drives_it && self.library.policy_delivered(deployed.version, &key.0, &key.1)? {
            self.library.forget_policy_delivery(deployed.version, &key.0, &key.1)?;
        }
        Ok(())
    }

    /// Notes that `order` went out.
    pub fn policy_sent(&mut self, order: &PolicyOrder) -> Result<(), LibraryError> {
        self.library.note_policy_delivered(order.version, &order.site, &order.edge)?;
        self.summary.policy_pushes += 1;
        self.events.push(LoopEvent {
            policy_version: Some(order.version),
            ..LoopEvent::at("policy", &order.site, &order.edge)
        });
        Ok(())
    }

    /// The events since the last call, oldest first.
    pub fn take_events(&mut self) -> Vec<LoopEvent> {
        std::mem::take(&mut self.events)
    }

    /// The summary so far, with the library's counts.
    pub fn summary(&self) -> Result<LoopSummary, LibraryError> {
        let mut summary = self.summary.clone();
        summary.library = self.library.fleet_counts()?;
        summary.iteration = IterationTimes::of(&self.iterations_ms.0, &self.iterations_ms.1);
        summary.deployed_version = self.deployed.as_ref().map(|v| v.version);
        let hours = self.started.elapsed().as_secs_f64() / 3600.0;
        summary.failures_per_hour = if hours > 0.0 { summary.failures as f64 / hours } else { 0.0 };
        Ok(summary)
    }

    /// The summary with its report, at the end of the run.
    pub fn finish(&self) -> Result<LoopSummary, LibraryError> {
        let mut summary = self.summary()?;
        summary.report = report::markdown(&summary, &self.library.fleet_episodes()?);
        Ok(summary)
    }

    /// The riskiest scenario never pushed, as a push to `site/edge` (noted in the library).
    fn next_push(&mut self, site: &str, edge: &str) -> Result<Option<PushOrder>, LibraryError> {
        let key = (site.to_owned(), edge.to_owned());
        let Some((push, next)) = self.library.start_riskiest_push(site, edge)? else {
            // Counted once per vehicle and dry spell, not once per idle check.
            if self.idle_without_scenario.insert(key) {
                self.summary.exhausted += 1;
            }
            return Ok(None);
        };
        self.idle_without_scenario.remove(&key);
        let spec = ScenarioSpec::new(next.kind, next.seed, next.params)
            .map_err(|e| LibraryError::Corrupt { id: next.id.clone(), reason: e.to_string() })?;
        debug_assert_eq!(content_id(&spec), next.id);
        let order = PushOrder {
            site: site.to_owned(),
            edge: edge.to_owned(),
            push_seq: push.seq,
            spec_id: next.id,
            spec,
            attempt: 1,
        };
        self.outstanding.insert(key, Outstanding { push, sent: None });
        self.summary.pushes += 1;
        Ok(Some(order))
    }
}

/// The library row of an episode: the edge's outcome, the twin's, and where they disagree.
fn fleet_episode(episode: &WatchedEpisode, push_seq: Option<i64>, twin: Option<&EpisodeResult>) -> FleetEpisode {
    let r = &episode.result;
    let policy = policy_label(r.policy.as_ref());
    FleetEpisode {
        scenario_id: r.spec_id.clone(),
        site: episode.site.clone(),
        edge: episode.edge.clone(),
        policy: r.policy.clone(),
        scene: None,
        push_seq,
        edge_outcome: Outcome { policy: policy.clone(), metrics: r.metrics.clone(), risk: r.risk },
        twin_outcome: twin.map(|t| Outcome { policy, metrics: t.metrics.clone(), risk: t.risk }),
        twin_ticks: episode.views.len() as u64,
        disagreement: disagreement(r, twin),
    }
}

/// Where the twin's view of an episode differs from what the edge reported: a different
/// collision, road-departure or success verdict, route completion further apart than
/// [`COMPLETION_AGREEMENT`] or S_risk further apart than [`RISK_AGREEMENT`]; or that the twin
/// saw none of it. `None` when they agree.
pub fn disagreement(edge: &ScenarioResult, twin: Option<&EpisodeResult>) -> Option<String> {
    let Some(twin) = twin else { return Some("the twin did not see the episode".to_owned()) };
    let (e, t) = (&edge.metrics, &twin.metrics);
    let yes_no = |b: bool| if b { "yes" } else { "no" };
    let mut parts = Vec::new();
    for (what, a, b) in
        [("collision", e.collision, t.collision), ("offroad", e.offroad, t.offroad), ("success", e.success, t.success)]
    {
        if a != b {
            parts.push(format!("{what}: edge {}, twin {}", yes_no(a), yes_no(b)));
        }
    }
    if (e.route_completion - t.route_completion).abs() > COMPLETION_AGREEMENT {
        parts.push(format!("route completion: edge {:.3}, twin {:.3}", e.route_completion, t.route_completion));
    }
    if (edge.risk.score - twin.risk.score).abs() > RISK_AGREEMENT {
        parts.push(format!("S_risk: edge {:.3}, twin {:.3}", edge.risk.score, twin.risk.score));
    }
    (!parts.is_empty()).then(|| parts.join("; "))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate::{evaluate_all, reference_outcome};
    use crate::library::ScenarioRecord;
    use risktwin_common::scenario::{ScenarioKind, check_feasible, sample};
    use risktwin_common::telemetry::{Frame, Header};

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
        let trainer = TrainerConfig { retrain_failures: 1, steps: 1000, held_out_per_kind: 1, seed: 1 };
        let open = || {
            let library = ScenarioLibrary::open(&path).expect("opens");
            FleetLoop::open(
                library,
                LoopConfig { mutants_per_failure: 0, ..LoopConfig::default() },
                Some(trainer.clone()),
            )
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
}
