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
//!   that rank in from then on). The ego's episode of a distributed scene comes back the same
//!   way, with the scene's digest (its scenario enters the library if it was not there); its
//!   edge is the scene's and gets no push.
//! - Edges ([`FleetLoop::on_idle`]): a live vehicle without an outstanding push gets one; an
//!   outstanding push not sent by this process (restart) is sent again; one whose result did
//!   not come within [`LoopConfig::result_timeout`] is sent again, up to
//!   [`LoopConfig::max_attempts`] times, then given up (counted).

pub mod report;
pub mod trainer;

use crate::generate::mutate_stored;
use crate::trainer::TrainerError;
use crate::trainer::gate::GateReport;
use crate::twin::watch::WatchedEpisode;
use risktwin_common::digest::fnv1a64;
use risktwin_common::episode::EpisodeResult;
use risktwin_common::scenario::ScenarioSpec;
use risktwin_common::telemetry::{PolicyRef, ScenarioResult};
use risktwin_store::library::{
    FleetCounts, FleetEpisode, LibraryError, Origin, Outcome, PolicyVersion, Push, ScenarioLibrary, ScenarioRecord,
    content_id, policy_label,
};
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
    /// Of those, the egos' episodes of distributed scenes.
    pub scene_episodes: u64,
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
    /// When the last training run began (the loop's start before the first): the schedule's
    /// origin.
    last_training: Instant,
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
            last_training: Instant::now(),
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
        if let Some(scene) = &episode.result.scene {
            // A scene's scenario may come from outside the library (`--spec`, `--kind`): it
            // enters it, to be ranked and pushed like any other (a stored one stays as it is).
            let record =
                ScenarioRecord { spec: scene.spec.clone(), origin: Origin::Imported, parent_id: None, outcome: None };
            self.library.insert_batch(std::slice::from_ref(&record))?;
        }
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
        self.summary.scene_episodes += u64::from(episode.result.scene.is_some());
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
        let job = match trainer::due(&self.library, config, self.last_training.elapsed()) {
            Ok(job) => job,
            Err(TrainerError::Library(e)) => return Err(e),
            Err(e) => {
                self.on_trained(Err(e))?;
                return Ok(None);
            }
        };
        self.training = job.is_some();
        if let Some(job) = &job {
            self.last_training = Instant::now();
            tracing::info!(
                "trainer: training version {} ({} fleet failures in the library)",
                job.version,
                job.failures
            );
        }
        Ok(job)
    }

    /// Whether the trainer's schedule has come due (its period has passed since the last run
    /// began), so that [`Self::due_training`] is worth asking without an episode.
    pub fn schedule_due(&self) -> bool {
        let every = self.trainer.as_ref().and_then(|t| t.every);
        !self.training && every.is_some_and(|every| self.last_training.elapsed() >= every)
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

    /// This run's counts so far, without the library's (no query).
    pub fn running(&self) -> &LoopSummary {
        &self.summary
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
        scene: r.scene.as_ref().map(|s| s.digest.clone()),
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
mod tests;
