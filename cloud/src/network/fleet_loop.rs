//! The `loop` role on Zenoh: the edges' `ScenarioResult`s come in on
//! `risktwin/v1/<site>/*/scenario_result` and go to the twin's watch ([`LiveIngest`]), which
//! hands each finished episode, with the twin's ticks of it, to the task here; the task runs
//! [`FleetLoop`] and sends the scenarios it decides on to the edges' push keys
//! (`…/<edge>/scenario`), starting the twin's watch first so that no tick of the episode is
//! missed; with the trainer, training runs go to a thread of their own and the version the gate
//! lets through goes to every live vehicle (`…/<edge>/policy`). Live vehicles are the edges whose liveliness token is up and whose `state` stream
//! the ingest has received (an RSU has none, and runs no pushed scenario).
//!
//! A result that does not decode, or whose header names another source than its key, is
//! counted and dropped.

use super::liveliness::LivenessLog;
use super::push::header;
use super::receive::LiveIngest;
use super::summary::LoopRoleSummary;
use super::{CloudConfig, CloudError};
use crate::fleet_loop::trainer::TrainJob;
use crate::fleet_loop::{FleetLoop, LoopSummary, PolicyOrder, PushOrder};
use crate::trainer::TrainerError;
use crate::trainer::gate::GateReport;
use crate::twin::watch::WatchedEpisode;
use risktwin_common::telemetry::{PolicyUpdate, ScenarioPush, ScenarioResult};
use risktwin_policy::signature::PolicySigningKey;
use risktwin_protos::{decode_tagged, encode, v1};
use risktwin_store::library::PolicyVersion;
use risktwin_transport::keyexpr::{CloudToEdge, EdgeReport, cloud_to_edge, edge_report_all, parse_edge_report_key};
use risktwin_transport::sync::LockExt;
use risktwin_transport::zenoh::Session;
use risktwin_transport::zenoh::pubsub::{Publisher, Subscriber};
use risktwin_transport::zenoh::qos::CongestionControl;
use risktwin_transport::{Shutdown, SiteId, SourceId, TransportError, protobuf};
use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::sync::mpsc::UnboundedReceiver;
use tokio::sync::oneshot;
use tokio::task::JoinHandle;

/// How often live edges are looked at for a first push, a resend or a timeout.
const IDLE_PERIOD: Duration = Duration::from_millis(200);

/// Results received on the wire.
#[derive(Debug, Default)]
struct ResultCounts {
    received: AtomicU64,
    malformed: AtomicU64,
    source_mismatch: AtomicU64,
}

/// The running role: undeclare `results`, then await `task`.
pub(crate) struct LoopRole {
    pub(crate) results: Subscriber<()>,
    pub(crate) task: JoinHandle<Result<LoopSummary, CloudError>>,
    counts: Arc<ResultCounts>,
}

impl LoopRole {
    /// Ends the role (after `shutdown` fired): the summary of the loop and its results.
    pub(crate) async fn finish(self, ingest: &Mutex<LiveIngest>) -> Result<LoopRoleSummary, CloudError> {
        self.results.undeclare().await.map_err(|e| super::undeclare_error("result subscriber", e))?;
        let fleet = self.task.await.map_err(|e| super::join_error("loop", e))??;
        let watch = ingest.locked().watch_counts();
        Ok(LoopRoleSummary {
            fleet,
            results_received: self.counts.received.load(Ordering::Relaxed),
            results_malformed: self.counts.malformed.load(Ordering::Relaxed),
            results_source_mismatch: self.counts.source_mismatch.load(Ordering::Relaxed),
            watch,
        })
    }
}

/// Starts the loop role: the result subscriber and the task running `fleet`.
pub(crate) async fn start(
    session: &Session,
    config: &CloudConfig,
    fleet: FleetLoop,
    ingest: Arc<Mutex<LiveIngest>>,
    liveness: Arc<Mutex<LivenessLog>>,
    episodes: UnboundedReceiver<WatchedEpisode>,
    shutdown: Shutdown,
) -> Result<LoopRole, CloudError> {
    // The config's site (`None`: every site) and the key policy updates are signed with.
    let (site, signer) = (config.site.as_ref(), config.signing_key.clone());
    let counts = Arc::new(ResultCounts::default());
    let key = edge_report_all(site, EdgeReport::ScenarioResult);
    let results = {
        let (ingest, counts) = (Arc::clone(&ingest), Arc::clone(&counts));
        session
            .declare_subscriber(key.clone())
            .callback(move |sample| {
                let Some((site, edge)) = parse_edge_report_key(sample.key_expr().as_str(), EdgeReport::ScenarioResult)
                else {
                    return;
                };
                counts.received.fetch_add(1, Ordering::Relaxed);
                let payload = sample.payload().to_bytes();
                match decode_tagged::<ScenarioResult>(&sample.encoding().to_string(), &payload) {
                    Ok(result) if result.header.source != edge => {
                        counts.source_mismatch.fetch_add(1, Ordering::Relaxed);
                        tracing::warn!("loop: dropped a result on {site}/{edge} from {}", result.header.source);
                    }
                    Ok(result) => ingest.locked().episode_result(site, edge, result),
                    Err(e) => {
                        counts.malformed.fetch_add(1, Ordering::Relaxed);
                        tracing::warn!("loop: dropped a result from {site}/{edge}: {e}");
                    }
                }
            })
            .await
            .map_err(|e| TransportError::Declare { what: "subscriber", key, reason: e.to_string() })?
    };
    let pushes = Pushes { session: session.clone(), publishers: HashMap::new(), sent: 0, signer };
    let task = tokio::spawn(drive(pushes, fleet, ingest, liveness, episodes, shutdown));
    Ok(LoopRole { results, task, counts })
}

/// A training run on a thread of its own: its result comes on this channel. The thread is not
/// joined: a run still going at shutdown is left behind (the process ends with it; the trainer
/// only reads a snapshot, and the next start trains the version again).
type Training = oneshot::Receiver<Result<(PolicyVersion, GateReport), TrainerError>>;

/// Starts `job` on a thread of its own.
fn start_training(job: TrainJob) -> Training {
    let (tx, rx) = oneshot::channel();
    std::thread::spawn(move || {
        // The receiver is gone only at shutdown: nobody wants the result then.
        let _ = tx.send(job.run());
    });
    rx
}

/// The loop's task, until `shutdown` fires.
async fn drive(
    mut pushes: Pushes,
    mut fleet: FleetLoop,
    ingest: Arc<Mutex<LiveIngest>>,
    liveness: Arc<Mutex<LivenessLog>>,
    mut episodes: UnboundedReceiver<WatchedEpisode>,
    mut shutdown: Shutdown,
) -> Result<LoopSummary, CloudError> {
    let mut idle = tokio::time::interval(IDLE_PERIOD);
    let mut training: Option<Training> = None;
    // The header seq of the loop's recorded events.
    let mut events = 0u64;
    let failed = |e: &dyn std::fmt::Display| tracing::error!("loop: stopped: {e}");
    loop {
        tokio::select! {
            episode = episodes.recv() => {
                let Some(episode) = episode else { break };
                let key = (episode.site.clone(), episode.edge.clone());
                let alive = live_vehicles(&ingest, &liveness).contains(&key);
                let order = fleet.on_episode(&episode, alive).inspect_err(|e| failed(e))?;
                if let Some(order) = order {
                    pushes.scenario(&order, &ingest).await.inspect_err(|e| failed(e))?;
                    fleet.sent(&order, Some(&episode));
                }
                // After the next push is out: the children rank in for the pushes after it.
                fleet.mutate_failures().inspect_err(|e| failed(e))?;
                if training.is_none()
                    && let Some(job) = fleet.due_training().inspect_err(|e| failed(e))?
                {
                    training = Some(start_training(job));
                }
                record(&mut fleet, &ingest, &liveness, &mut events);
            }
            done = async { training.as_mut().expect("guarded by the condition").await }, if training.is_some() => {
                training = None;
                // A thread that ended without sending panicked: its run is lost, the loop goes on.
                let run = done.unwrap_or(Err(TrainerError::Lost));
                fleet.on_trained(run).inspect_err(|e| failed(e))?;
                record(&mut fleet, &ingest, &liveness, &mut events);
            }
            _ = idle.tick() => {
                ingest.locked().expire_episodes();
                let alive = live_vehicles(&ingest, &liveness);
                for order in fleet.policy_orders(&alive).inspect_err(|e| failed(e))? {
                    pushes.policy(&order).await.inspect_err(|e| failed(e))?;
                    fleet.policy_sent(&order).inspect_err(|e| failed(e))?;
                }
                for order in fleet.on_idle(&alive, Instant::now()).inspect_err(|e| failed(e))? {
                    pushes.scenario(&order, &ingest).await.inspect_err(|e| failed(e))?;
                    fleet.sent(&order, None);
                }
                // The trainer's schedule comes due without an episode.
                if training.is_none()
                    && fleet.schedule_due()
                    && let Some(job) = fleet.due_training().inspect_err(|e| failed(e))?
                {
                    training = Some(start_training(job));
                }
                record(&mut fleet, &ingest, &liveness, &mut events);
            }
            () = shutdown.wait() => break,
        }
    }
    // Episodes already handed on are stored (no next push goes out any more).
    while let Ok(episode) = episodes.try_recv() {
        fleet.on_episode(&episode, false)?;
    }
    record(&mut fleet, &ingest, &liveness, &mut events);
    drop(training);
    pushes.close().await?;
    Ok(fleet.finish()?)
}

/// The live vehicles a scenario can be pushed to: edges whose liveliness token is up and whose
/// `state` stream the ingest has received (an RSU has none), at a site where no scene runs (a
/// scene's participants drive the scene).
fn live_vehicles(ingest: &Mutex<LiveIngest>, liveness: &Mutex<LivenessLog>) -> Vec<(String, String)> {
    let ingest = ingest.locked();
    let alive = liveness.locked().alive().into_iter();
    alive.filter(|(site, edge)| !ingest.is_scene_site(site) && ingest.states_from(site, edge) > 0).collect()
}

/// Records the loop's events into the cloud's recording (when it records): each on its
/// site's loop topic; a fleet-wide one (a gate decision) on that of every site with a live edge.
fn record(fleet: &mut FleetLoop, ingest: &Mutex<LiveIngest>, liveness: &Mutex<LivenessLog>, seq: &mut u64) {
    if risktwin_transport::metrics::enabled() {
        super::live_metrics::export_loop(fleet.running());
    }
    let events = fleet.take_events();
    if events.is_empty() {
        return;
    }
    let mut sites: Vec<String> = liveness.locked().alive().into_iter().map(|(site, _)| site).collect();
    sites.dedup();
    let mut ingest = ingest.locked();
    for e in events {
        *seq += 1;
        let event = v1::LoopEvent {
            header: Some((&header(*seq)).into()),
            kind: e.kind.to_owned(),
            edge: e.edge,
            scenario_id: e.scenario_id,
            push_seq: e.push_seq.unwrap_or(0),
            attempt: e.attempt,
            policy_version: e.policy_version.unwrap_or(0),
            collision: e.collision,
            risk_score: e.risk_score,
            detail: e.detail.unwrap_or_default(),
        };
        let on: &[String] = if e.site.is_empty() { &sites } else { std::slice::from_ref(&e.site) };
        for site in on {
            if let Err(err) = ingest.record_loop_event(site, &event) {
                // The recording failing must not stop the loop; the ingest reports the same file.
                tracing::error!("loop: recording an event failed: {err}");
            }
        }
    }
}

/// The publishers of the edges' push keys, declared on first use.
struct Pushes {
    session: Session,
    publishers: HashMap<(String, String, CloudToEdge), Publisher<'static>>,
    sent: u64,
    /// Signs each policy update for the vehicle it goes to.
    signer: Option<PolicySigningKey>,
}

impl Pushes {
    /// Starts the twin's watch of `order`'s episode, then sends it.
    async fn scenario(&mut self, order: &PushOrder, ingest: &Mutex<LiveIngest>) -> Result<(), CloudError> {
        ingest.locked().watch_episode(&order.site, &order.edge, &order.spec_id, &order.spec, Some(order.push_seq));
        let push = ScenarioPush { header: header(self.sent), spec_id: order.spec_id.clone(), spec: order.spec.clone() };
        self.put(&order.site, &order.edge, CloudToEdge::Scenario, encode(&push)).await?;
        tracing::info!(
            "loop: pushed scenario {} to {}/{} (push {}, attempt {})",
            order.spec_id,
            order.site,
            order.edge,
            order.push_seq,
            order.attempt
        );
        Ok(())
    }

    /// Sends a policy version, signed for its vehicle when the loop has a key.
    async fn policy(&mut self, order: &PolicyOrder) -> Result<(), CloudError> {
        let mut update = PolicyUpdate {
            header: header(self.sent),
            policy_id: order.policy_id.clone(),
            version: order.version,
            algo: order.algo.clone(),
            weights: order.weights.clone(),
            target: format!("{}/{}", order.site, order.edge),
            signature: Vec::new(),
        };
        if let Some(signer) = &self.signer {
            signer.sign(&mut update);
        }
        self.put(&order.site, &order.edge, CloudToEdge::Policy, encode(&update)).await?;
        tracing::info!(
            "loop: pushed policy {} version {} to {}/{}",
            order.policy_id,
            order.version,
            order.site,
            order.edge
        );
        Ok(())
    }

    async fn put(&mut self, site: &str, edge: &str, push: CloudToEdge, payload: Vec<u8>) -> Result<(), CloudError> {
        let key = (site.to_owned(), edge.to_owned(), push);
        if !self.publishers.contains_key(&key) {
            let bad_id = |e: risktwin_transport::keyexpr::KeyError| TransportError::Declare {
                what: "publisher",
                key: format!("{site}/{edge}"),
                reason: e.to_string(),
            };
            let push_key =
                cloud_to_edge(&SiteId::new(site).map_err(bad_id)?, &SourceId::new(edge).map_err(bad_id)?, push);
            let publisher = self
                .session
                .declare_publisher(push_key.clone())
                .encoding(protobuf(push.message()))
                .congestion_control(CongestionControl::Block)
                .await
                .map_err(|e| TransportError::Declare { what: "publisher", key: push_key, reason: e.to_string() })?;
            self.publishers.insert(key.clone(), publisher);
        }
        self.sent += 1;
        let publisher = &self.publishers[&key];
        publisher
            .put(payload)
            .await
            .map_err(|e| TransportError::Put { key: publisher.key_expr().to_string(), reason: e.to_string() })?;
        Ok(())
    }

    async fn close(self) -> Result<(), CloudError> {
        for (_, publisher) in self.publishers {
            publisher.undeclare().await.map_err(|e| super::undeclare_error("push publisher", e))?;
        }
        Ok(())
    }
}
