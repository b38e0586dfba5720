//! The cloud on the Zenoh network: the `risktwin cloud` roles' subscriptions, queryables and
//! publications, and the cloud→edge pushes ([`push`]).
//!
//! Named for what it is — the cloud's network side — rather than `zenoh` (which would shadow
//! the crate) or `transport` (the `risktwin-transport` crate it builds on). Everything here only
//! moves bytes in and out and keeps counts: what the cloud computes lives in
//! [`crate::ingest`] (decode, validate, align), [`crate::twin`] (the twin, its per-tick scene
//! and risk outputs), [`crate::criticality`] and [`risktwin_store::library`].
//!
//! - `ingest`: subscribe to every edge→cloud stream, hand each sample to [`LiveIngest`] (which
//!   runs the [`crate::ingest::IngestWorker`]), optionally record what was accepted to MCAP,
//!   watch liveliness;
//! - `twin` (needs `ingest`): the [`crate::twin::Twin`] follows every ingest snapshot, and the
//!   site's vehicles go out as `foxglove.SceneUpdate` boxes on `…/cloud/scene` each tick;
//! - `risk` (needs `twin`): at 2 Hz of twin time per site, the risk field around every vehicle
//!   (`foxglove.Grid` on `…/cloud/risk_field`) and its `RiskReport` (`…/cloud/risk_report`);
//! - `warning` (needs `ingest`): every accepted state re-assesses the pairs it touches
//!   ([`crate::warning`]) and a `HazardWarning` goes to each vehicle of a critical pair on
//!   `…/<vehicle>/warning`, put from the receive callback ([`warning`]);
//! - `library` (needs `--db`): the queryable of [`library`] answering ranked scenarios;
//! - `criticality` (needs `--criticality-out` or `--db`): the road map and obstacle states of a
//!   site (a replayed `risktwin import commonroad` recording), and on shutdown their CommonRoad
//!   criticality, written as `risktwin criticality` writes it, and with `--db` the drive stored
//!   as a recorded case of the library ([`criticality`]).
//!
//! - `loop` (needs `twin` and `--db`): the closed loop over the fleet ([`fleet_loop`]): pushes
//!   the library's riskiest untested scenarios to live vehicles, stores what comes back (the
//!   edge's outcome beside the twin's) and mutates around failures;
//! - `trainer` (needs `loop`): retrains a policy on the library when enough new fleet failures
//!   are in, gates it against the deployed version and has the loop push the versions it lets
//!   through ([`crate::fleet_loop::trainer`]);
//! - `viz` (needs `twin`): the live twin for the Foxglove app over its WebSocket protocol
//!   ([`crate::viz`]): what the publisher task puts on Zenoh, every accepted vehicle state and
//!   each site's road, under the recording's topics and schemas.
//!
//! With `--record`, the twin's scene and risk outputs are recorded next to the accepted edge
//! messages, under their keys.

mod ack;
pub mod criticality;
pub mod edges;
pub mod fleet_loop;
mod id_conflicts;
pub mod library;
mod live_metrics;
pub mod liveliness;
pub mod loss;
mod publisher;
pub mod push;
mod receive;
pub mod routes;
mod scene;
pub mod shard;
pub mod summary;
#[cfg(test)]
mod test_harness;
mod union;
pub mod warning;
#[cfg(test)]
mod warning_tests;
#[cfg(test)]
mod wire_tests;

use crate::fleet_loop::trainer::TrainerConfig;
use crate::fleet_loop::{FleetLoop, LoopConfig};
use crate::twin::outputs::{TwinOutputs, TwinSummary};
use crate::twin::risk::{RiskAssessor, RiskConfig};
use crate::viz::{VizConfig, VizError, VizRole, VizSummary};
use crate::warning::{HazardWarner, WarningConfig, WarningSink, WarningSummary};
use criticality::{CriticalityCollect, CriticalityConfig, CriticalityRoleError, CriticalitySummary};
use library::LibrarySummary;
use liveliness::LivenessLog;
pub use receive::{Handled, LiveIngest, OUTPUT_SCHEMAS, Origin, RecordError, RecordTo, RecordingFile};
use risktwin_common::road::Road;
use risktwin_policy::signature::PolicySigningKey;
use risktwin_protos::recording::decode_replay_time;
use risktwin_store::library::ScenarioLibrary;
use risktwin_store::recordings::RotationConfig;
use risktwin_transport::sync::LockExt;
use risktwin_transport::zenoh::sample::Sample;
use risktwin_transport::{Shutdown, SiteId, StreamLoss, TransportConfig, TransportError, close, connect};
use serde::Serialize;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};
pub use summary::IngestSummary;
use summary::LoopRoleSummary;
use thiserror::Error;

/// A cloud worker role (docs/cli.md: `--roles ingest,twin,risk,library,criticality,trainer`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// Validate, align and record the edge streams.
    Ingest,
    /// The live twin, from the ingest snapshots.
    Twin,
    /// Risk on the live twin.
    Risk,
    /// The scenario library queryable.
    Library,
    /// CommonRoad criticality of a replayed scenario, on shutdown.
    Criticality,
    /// The closed loop over the fleet.
    Loop,
    /// Hazard warnings on every accepted state (the event-driven path).
    Warning,
    /// Policy retraining on the library, gated before every push (with `loop`).
    Trainer,
    /// The live twin over the Foxglove WebSocket protocol.
    Viz,
    /// What sharded ingest workers accepted, deduplicated: the twin's input instead of `ingest`.
    Union,
}

impl Role {
    fn name(self) -> &'static str {
        match self {
            Role::Ingest => "ingest",
            Role::Twin => "twin",
            Role::Risk => "risk",
            Role::Library => "library",
            Role::Criticality => "criticality",
            Role::Loop => "loop",
            Role::Trainer => "trainer",
            Role::Warning => "warning",
            Role::Viz => "viz",
            Role::Union => "union",
        }
    }
}

impl std::str::FromStr for Role {
    type Err = CloudError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "ingest" => Ok(Role::Ingest),
            "twin" => Ok(Role::Twin),
            "risk" => Ok(Role::Risk),
            "library" => Ok(Role::Library),
            "criticality" => Ok(Role::Criticality),
            "loop" => Ok(Role::Loop),
            "trainer" => Ok(Role::Trainer),
            "warning" => Ok(Role::Warning),
            "viz" => Ok(Role::Viz),
            "union" => Ok(Role::Union),
            other => Err(CloudError::UnknownRole { role: other.to_owned() }),
        }
    }
}

/// Why the cloud role failed.
#[derive(Debug, Error)]
pub enum CloudError {
    #[error("role {role:?} is not one of ingest, union, twin, risk, library, criticality, loop, trainer, warning, viz")]
    UnknownRole { role: String },
    #[error("role {role:?} needs role {needs:?} in the same process (e.g. --roles ingest,twin,risk)")]
    RoleNeeds { role: &'static str, needs: &'static str },
    #[error("role {role} needs --db FILE")]
    NeedsDb { role: &'static str },
    #[error("role criticality needs --criticality-out FILE.csv|FILE.json or --db FILE (or both)")]
    CriticalityNeedsOut,
    #[error(transparent)]
    Criticality(#[from] CriticalityRoleError),
    #[error("no role to run")]
    NoRole,
    #[error("record to one file or to a folder of segments, not both")]
    RecordTwice,
    #[error("role union takes what sharded ingest workers accepted: not with role ingest in the same process")]
    UnionWithIngest,
    #[error(
        "--shard needs role ingest, --site, and no other role (a worker sees only its share: the twin runs with role union)"
    )]
    ShardRoles,
    #[error("risk field: {0}")]
    Field(#[from] risktwin_common::risk::FieldError),
    #[error(transparent)]
    Library(#[from] risktwin_store::library::LibraryError),
    #[error(transparent)]
    Transport(#[from] TransportError),
    #[error(transparent)]
    Record(#[from] RecordError),
    #[error(transparent)]
    Viz(#[from] VizError),
}

/// What the cloud runs and how it joins the network.
#[derive(Debug, Clone)]
pub struct CloudConfig {
    /// The site to serve; `None` serves every site.
    pub site: Option<SiteId>,
    /// The roles to run.
    pub roles: Vec<Role>,
    /// How to join the Zenoh network.
    pub transport: TransportConfig,
    /// On shutdown, keep receiving until no sample came for this long...
    pub drain_quiet: Duration,
    /// ...but no longer than this.
    pub drain_max: Duration,
    /// Record every accepted message (and the twin's outputs) into this MCAP file (closed
    /// properly on shutdown).
    pub record: Option<PathBuf>,
    /// Record as [`record`](Self::record) does, into rotating segments with a catalogue
    /// ([`risktwin_store::recordings`]); not with `record`.
    pub record_dir: Option<RotationConfig>,
    /// Replay-ingest mode: take each message's receive time from its replay-time attachment
    /// (put there by `risktwin edge replay`) instead of the cloud's clock, so that a replayed
    /// recording rebuilds the live run's snapshots; a message without one is dropped as
    /// `no-replay-time`. Off, attachments are ignored (a live edge cannot set the cloud's clock).
    pub replay_time: bool,
    /// The road the risk role evaluates on (every site drives the same road for now).
    pub road: Road,
    /// How the risk role evaluates.
    pub risk: RiskConfig,
    /// The scenario library the `library` role serves.
    pub db: Option<PathBuf>,
    /// Where the `criticality` role writes, and for which ego.
    pub criticality: Option<CriticalityConfig>,
    /// How the `loop` role behaves.
    pub fleet_loop: LoopConfig,
    /// How the `trainer` role trains and gates.
    pub trainer: TrainerConfig,
    /// When the `warning` role finds a pair critical, and how often it warns.
    pub warning: WarningConfig,
    /// The key the `loop` role signs each policy update with, per vehicle (`--signing-key`);
    /// `None`: updates go unsigned and vehicles refuse them.
    pub signing_key: Option<PolicySigningKey>,
    /// Where the `viz` role serves.
    pub viz: VizConfig,
    /// Ingest as one of several workers sharing the site ([`shard`]); needs `site`.
    pub shard: bool,
    /// Shed lower-priority streams, and have the edges hold them back, while live states wait
    /// longer than this (docs/keyexpr.md, "Overload"); `None`: never.
    pub shed_after: Option<Duration>,
}

impl CloudConfig {
    /// Ingest for every site, with the default transport and drain, risk on the road of the
    /// edges' default scenario (a feasible cut-in).
    pub fn new(transport: TransportConfig) -> Self {
        CloudConfig {
            site: None,
            roles: vec![Role::Ingest],
            transport,
            drain_quiet: Duration::from_millis(200),
            drain_max: Duration::from_secs(2),
            record: None,
            record_dir: None,
            replay_time: false,
            road: crate::twin::scenario_road(risktwin_common::scenario::ScenarioKind::CutIn),
            risk: RiskConfig::default(),
            db: None,
            criticality: None,
            fleet_loop: LoopConfig::default(),
            trainer: TrainerConfig::default(),
            warning: WarningConfig::default(),
            signing_key: None,
            viz: VizConfig::default(),
            shard: false,
            shed_after: None,
        }
    }

    fn has(&self, role: Role) -> bool {
        self.roles.contains(&role)
    }

    /// Refuses role sets that cannot run.
    fn check_roles(&self) -> Result<(), CloudError> {
        if self.roles.is_empty() {
            return Err(CloudError::NoRole);
        }
        if self.record.is_some() && self.record_dir.is_some() {
            return Err(CloudError::RecordTwice);
        }
        if self.has(Role::Union) && self.has(Role::Ingest) {
            return Err(CloudError::UnionWithIngest);
        }
        if self.shard && (self.site.is_none() || self.roles.iter().any(|&r| r != Role::Ingest)) {
            return Err(CloudError::ShardRoles);
        }
        for (role, needs) in [
            (Role::Twin, Role::Ingest),
            (Role::Risk, Role::Twin),
            (Role::Loop, Role::Twin),
            (Role::Trainer, Role::Loop),
            (Role::Warning, Role::Ingest),
            (Role::Viz, Role::Twin),
        ] {
            // The union is the ingest of a sharded site.
            let met = self.has(needs) || (needs == Role::Ingest && self.has(Role::Union));
            if self.has(role) && !met {
                return Err(CloudError::RoleNeeds { role: role.name(), needs: needs.name() });
            }
        }
        for role in [Role::Library, Role::Loop] {
            if self.has(role) && self.db.is_none() {
                return Err(CloudError::NeedsDb { role: role.name() });
            }
        }
        if self.has(Role::Criticality) {
            let config = self.criticality.as_ref().filter(|c| c.out.is_some() || c.library.is_some());
            config.ok_or(CloudError::CriticalityNeedsOut)?.format()?;
        }
        Ok(())
    }
}

/// How long the cloud waits at shutdown for the last Zenoh callback to let go of the ingest.
const LAST_OWNER_WAIT: std::time::Duration = std::time::Duration::from_secs(5);

/// The JSON the cloud prints on exit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CloudSummary {
    /// Counts of the ingest role.
    #[serde(flatten)]
    pub ingest: IngestSummary,
    /// Edges whose liveliness token was seen, and those seen leaving.
    pub liveliness: liveliness::LivenessSummary,
    /// The twin and risk roles, when they ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub twin: Option<TwinSummary>,
    /// The library role, when it ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub library: Option<LibrarySummary>,
    /// The criticality role, when it ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub criticality: Option<CriticalitySummary>,
    /// The loop role, when it ran.
    #[serde(rename = "loop", skip_serializing_if = "Option::is_none")]
    pub fleet_loop: Option<LoopRoleSummary>,
    /// The warning role, when it ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub warning: Option<WarningSummary>,
    /// The viz role, when it ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub viz: Option<VizSummary>,
    /// The sharded worker, when it ran (`--shard`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shard: Option<shard::ShardSummary>,
}

/// What a started cloud tells its caller (see [`run`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CloudReady {
    /// Where the viz role serves, when it runs.
    pub viz: Option<SocketAddr>,
}

/// Runs the cloud roles until `shutdown` fires; `on_ready` is called once every subscription
/// and queryable is declared (edges started after that lose nothing).
pub async fn run(
    config: &CloudConfig,
    mut shutdown: Shutdown,
    on_ready: impl FnOnce(&CloudReady),
) -> Result<CloudSummary, CloudError> {
    config.check_roles()?;
    // Open the library and build the risk raster before joining: a bad file or config fails fast.
    let library = config.db.as_ref().filter(|_| config.has(Role::Library)).map(ScenarioLibrary::open).transpose()?;
    // Opened now, so that a bad file fails before the drive is collected, not after.
    let crit_library = config.criticality.as_ref().filter(|_| config.has(Role::Criticality));
    let mut crit_library = crit_library.and_then(|c| c.library.as_ref()).map(ScenarioLibrary::open).transpose()?;
    let risk = if config.has(Role::Risk) { Some(RiskAssessor::new(config.road.clone(), config.risk)?) } else { None };
    let fleet = match config.db.as_ref().filter(|_| config.has(Role::Loop)) {
        Some(db) => {
            let trainer = config.has(Role::Trainer).then(|| config.trainer.clone());
            Some(FleetLoop::open(ScenarioLibrary::open(db)?, config.fleet_loop.clone(), trainer)?)
        }
        None => None,
    };
    let empty = CloudSummary {
        ingest: IngestSummary::default(),
        liveliness: Default::default(),
        twin: None,
        library: None,
        criticality: None,
        fleet_loop: None,
        warning: None,
        viz: None,
        shard: None,
    };
    // Before joining too: a port in use fails the start at once.
    let (viz, viz_feed) = if config.has(Role::Viz) {
        let (role, feed) = VizRole::start(config.viz, config.road.clone()).await?;
        (Some(role), Some(feed))
    } else {
        (None, None)
    };
    let session = tokio::select! {
        opened = connect(&config.transport) => opened?,
        _ = shutdown.wait() => {
            if let Some(viz) = viz {
                viz.finish().await;
            }
            return Ok(empty);
        }
    };

    let (publish_tx, publish_rx) = tokio::sync::mpsc::unbounded_channel();
    let outputs = config.has(Role::Twin).then(|| TwinOutputs::new(risk));
    let publisher = tokio::spawn(publisher::publish_outputs(session.clone(), publish_rx, viz_feed.clone()));
    let queryable = match library {
        Some(lib) => Some((library::declare(&session, config.site.as_ref()).await?, lib)),
        None => None,
    };
    let (episodes_tx, episodes_rx) = tokio::sync::mpsc::unbounded_channel();
    let route_keys = config.has(Role::Ingest).then(|| routes::declare_route_keys(&session));
    let (route_keys, keys_tx) = route_keys.unzip();
    // The warning role's publishers are declared by a task, never in the ingest's callback.
    let (warning_sink, warning_publishers) = if config.has(Role::Warning) {
        let (sink, publishers) = warning::warning_sink(&session);
        let warner = HazardWarner::new(config.warning, Some(config.road.clone()));
        (Some((warner, Box::new(sink) as Box<dyn WarningSink>)), Some(publishers))
    } else {
        (None, None)
    };
    let record = match (&config.record, &config.record_dir) {
        (Some(file), _) => Some(RecordTo::File(file)),
        (None, Some(rotation)) => Some(RecordTo::Segments(rotation)),
        (None, None) => None,
    };
    let mut ingest_config = risktwin_align::ingest::IngestConfig::default();
    if config.shard {
        // A worker that takes a source over sees it from the middle: its count starts at the
        // first number it gets (the union counts from 0).
        ingest_config.dedup.first_seq = None;
    }
    let ingest = LiveIngest::with_config(record, outputs, ingest_config)?
        .with_replay_time(config.replay_time)
        .with_shedding(config.shed_after)
        .with_route_keys(keys_tx)
        .with_publisher(config.has(Role::Twin).then_some(publish_tx))
        .with_episodes(fleet.is_some().then_some(episodes_tx))
        .with_warnings(warning_sink)
        .with_viz(viz_feed);
    let ingest = Arc::new(Mutex::new(ingest));
    let flusher = record.is_some().then(|| tokio::spawn(flush_recording(Arc::clone(&ingest), shutdown.clone())));
    let subscriber = if config.has(Role::Ingest) && !config.shard {
        Some(
            risktwin_transport::subscribe_edge_streams(
                &session,
                config.site.as_ref(),
                ingest_sink(Arc::clone(&ingest)),
                loss_sink(Arc::clone(&ingest)),
            )
            .await?,
        )
    } else {
        None
    };
    let shard = match config.site.as_ref().filter(|_| config.shard) {
        Some(site) => Some(shard::ShardRole::start(&session, site, Arc::clone(&ingest), shutdown.clone()).await?),
        None => None,
    };
    let union = if config.has(Role::Union) {
        Some(union::subscribe(&session, config.site.as_ref(), Arc::clone(&ingest)).await?)
    } else {
        None
    };
    let crit = Arc::new(Mutex::new(CriticalityCollect::default()));
    let crit_subscriber = match config.criticality.as_ref().filter(|_| config.has(Role::Criticality)) {
        Some(_) => Some(criticality::subscribe(&session, config.site.as_ref(), Arc::clone(&crit)).await?),
        None => None,
    };
    // The loop needs the scene maps too: they start the twin's watch of a scene's episode.
    let map_subscriber = if [Role::Risk, Role::Loop, Role::Warning, Role::Viz].iter().any(|&r| config.has(r)) {
        Some(scene::subscribe_maps(&session, config.site.as_ref(), Arc::clone(&ingest)).await?)
    } else {
        None
    };
    let truth_subscriber = if config.has(Role::Twin) {
        Some(scene::subscribe_ground_truth(&session, config.site.as_ref(), Arc::clone(&ingest)).await?)
    } else {
        None
    };
    // After the subscriber: an edge that sees the token may count on its samples being taken
    // and acknowledged.
    let (cloud_token, acks) = if subscriber.is_some() || shard.is_some() {
        let key = risktwin_transport::keyexpr::cloud_liveliness(config.site.as_ref());
        let token = session.liveliness().declare_token(key.clone()).await.map_err(|e| TransportError::Declare {
            what: "cloud liveliness token",
            key,
            reason: e.to_string(),
        })?;
        (Some(token), Some(receive::spawn_acks(session.clone(), Arc::clone(&ingest))))
    } else {
        (None, None)
    };
    let liveness = Arc::new(Mutex::new(LivenessLog::default()));
    if risktwin_transport::metrics::enabled() {
        receive::watch_metrics(&ingest, &liveness);
    }
    let edges = edges::watch_edges(&session, config.site.as_ref(), Arc::clone(&liveness), Arc::clone(&ingest)).await?;
    let library_task = queryable.map(|(q, lib)| tokio::spawn(library::serve(q, lib, shutdown.clone())));
    let loop_role = match fleet {
        Some(fleet) => {
            let (ingest, liveness) = (Arc::clone(&ingest), Arc::clone(&liveness));
            let role = fleet_loop::start(&session, config, fleet, ingest, liveness, episodes_rx, shutdown.clone());
            Some(role.await?)
        }
        None => None,
    };
    on_ready(&CloudReady { viz: viz.as_ref().map(VizRole::addr) });

    shutdown.wait().await;
    if subscriber.is_some() || shard.is_some() || union.is_some() || crit_subscriber.is_some() {
        let last_sample = || {
            let ingest = ingest.locked().last_sample();
            ingest.max(crit.locked().last_sample())
        };
        drain(last_sample, config.drain_quiet, config.drain_max).await;
    }
    if let Some(acks) = acks {
        acks.abort();
    }
    if let Some(token) = cloud_token {
        token.undeclare().await.map_err(|e| undeclare_error("cloud liveliness token", e))?;
    }

    if let Some(subscriber) = subscriber {
        subscriber.undeclare().await.map_err(|e| undeclare_error("subscriber", e))?;
    }
    let shard = match shard {
        Some(role) => Some(role.finish().await?),
        None => None,
    };
    if let Some(subscriber) = union {
        subscriber.undeclare().await.map_err(|e| undeclare_error("union subscriber", e))?;
    }
    if let Some(subscriber) = map_subscriber {
        subscriber.undeclare().await.map_err(|e| undeclare_error("scene-map subscriber", e))?;
    }
    for subscriber in truth_subscriber.into_iter().flatten() {
        subscriber.undeclare().await.map_err(|e| undeclare_error("ground-truth subscriber", e))?;
    }
    if let Some(subscriber) = crit_subscriber {
        subscriber.undeclare().await.map_err(|e| undeclare_error("criticality subscriber", e))?;
    }
    edges.undeclare().await.map_err(|e| undeclare_error("liveliness subscriber", e))?;
    if let Some(keys) = route_keys {
        keys.task.abort();
    }
    if let Some(publishers) = warning_publishers {
        publishers.task.abort();
    }
    if let Some(flusher) = flusher {
        flusher.abort();
    }
    let library_summary = match library_task {
        Some(task) => Some(task.await.map_err(|e| join_error("library", e))??),
        None => None,
    };
    // Before the ingest is taken apart: the loop's task holds it.
    let fleet_loop = match loop_role {
        Some(role) => Some(role.finish(&ingest).await?),
        None => None,
    };
    // The publisher task ends once the ingest lets go of its sender and the queue is empty.
    ingest.locked().close_publisher();
    publisher.await.map_err(|e| join_error("publisher", e))??;
    close(session).await?;
    // The subscribers are undeclared, so their callbacks (the other owners) go; Zenoh drops a
    // callback that was running at the undeclaration a moment later, so wait for that, briefly.
    let mut ingest = ingest;
    let waited = tokio::time::Instant::now();
    let ingest = loop {
        match Arc::try_unwrap(ingest) {
            Ok(alone) => break alone,
            Err(shared) if waited.elapsed() < LAST_OWNER_WAIT => {
                ingest = shared;
                tokio::time::sleep(std::time::Duration::from_millis(10)).await;
            }
            Err(_) => {
                let reason = "ingest still in use".to_owned();
                return Err(CloudError::Transport(TransportError::Close { reason }));
            }
        }
    };
    let ingest = ingest.into_inner().unwrap_or_else(PoisonError::into_inner);
    let warning = ingest.warning_summary();
    let (ingest, twin) = ingest.finish()?;
    let liveliness = liveness.locked().summary();
    let viz = match viz {
        Some(viz) => Some(viz.finish().await),
        None => None,
    };
    if risktwin_transport::metrics::enabled() {
        // The ingest's final counts went out in `finish`.
        live_metrics::export_liveliness(&liveliness);
        warning.iter().for_each(live_metrics::export_warning);
        fleet_loop.iter().for_each(live_metrics::export_loop_results);
    }
    // Computed last, once every other role has flushed: a scenario that cannot be rebuilt fails
    // the run without losing the recording or the database.
    let criticality = match config.criticality.as_ref().filter(|_| config.has(Role::Criticality)) {
        Some(crit_config) => {
            let collected = std::mem::take(&mut *crit.locked());
            Some(collected.finish(crit_config, crit_library.as_mut())?)
        }
        None => None,
    };
    Ok(CloudSummary {
        ingest,
        liveliness,
        twin,
        library: library_summary,
        criticality,
        fleet_loop,
        warning,
        viz,
        shard,
    })
}

/// How often the recording's open chunk is looked at: a quarter of its time bound
/// (`risktwin_protos::recording::CHUNK_WALL`), so a quiet cloud's chunk closes within 1.25 s.
const FLUSH_PERIOD: Duration = Duration::from_millis(250);

/// Closes the recording's chunks of a quiet cloud (see [`LiveIngest::flush_recording_if_due`])
/// until shutdown; a failed flush is logged once and ends the task (the next write reports it
/// in the summary).
async fn flush_recording(ingest: Arc<Mutex<LiveIngest>>, mut shutdown: Shutdown) {
    let mut every = tokio::time::interval(FLUSH_PERIOD);
    loop {
        tokio::select! {
            _ = every.tick() => {
                if let Err(e) = ingest.locked().flush_recording_if_due() {
                    tracing::error!("recording: {e}");
                    return;
                }
            }
            () = shutdown.wait() => return,
        }
    }
}

fn join_error(what: &str, e: tokio::task::JoinError) -> CloudError {
    CloudError::Transport(TransportError::Close { reason: format!("{what} task: {e}") })
}

/// The subscriber callback of the ingest role: runs on Zenoh's receive path.
fn ingest_sink(
    ingest: Arc<Mutex<LiveIngest>>,
) -> impl Fn(risktwin_transport::EdgeStream, &Sample) + Send + Sync + 'static {
    ingest_sink_then(ingest, |_, _| {})
}

/// [`ingest_sink`], calling `on_handled` with each sample and what became of it, outside the
/// ingest's lock.
fn ingest_sink_then(
    ingest: Arc<Mutex<LiveIngest>>,
    on_handled: impl Fn(&Sample, Handled) + Send + Sync + 'static,
) -> impl Fn(risktwin_transport::EdgeStream, &Sample) + Send + Sync + 'static {
    move |_, sample| {
        // Contiguous payloads (the common case) are borrowed, not copied.
        let payload = sample.payload().to_bytes();
        let replay_ns = sample.attachment().and_then(|a| decode_replay_time(&a.to_bytes()));
        let handled = ingest.locked().handle(
            sample.key_expr().as_str(),
            sample.encoding(),
            &payload,
            replay_ns,
            Origin::of(sample),
        );
        // Drops are counted inside; only a failing recording comes back, and the receive path
        // cannot stop for it: say so and go on counting.
        match handled {
            Ok(handled) => on_handled(sample, handled),
            Err(e) => tracing::error!("cloud: {e}"),
        }
    }
}

/// The edge-stream subscriber's loss reports: counted in the ingest's summary.
fn loss_sink(ingest: Arc<Mutex<LiveIngest>>) -> impl Fn(StreamLoss) + Send + Sync + 'static {
    move |loss| ingest.locked().record_loss(&loss)
}

/// Lets samples already on their way arrive: waits until none came for `quiet` (as `last_sample`
/// tells), at most `max`.
async fn drain(last_sample: impl Fn() -> Option<Instant>, quiet: Duration, max: Duration) {
    let start = Instant::now();
    loop {
        let last = last_sample();
        let quiet_since = last.map_or(start, |t| t.max(start));
        let until = (quiet_since + quiet).min(start + max);
        if Instant::now() >= until {
            return;
        }
        tokio::time::sleep_until(until.into()).await;
    }
}

fn undeclare_error(what: &'static str, e: risktwin_transport::zenoh::Error) -> CloudError {
    CloudError::Transport(TransportError::Declare { what, key: "(undeclare)".to_owned(), reason: e.to_string() })
}
