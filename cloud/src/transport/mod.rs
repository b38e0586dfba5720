//! The cloud's side of the Zenoh pipeline: the `risktwin cloud` role. Today it runs the
//! `ingest` role (subscribe to every edge→cloud stream, run each sample through the
//! [`crate::ingest::IngestWorker`], optionally record what was accepted to MCAP, watch
//! liveliness); twin, risk, library and trainer join it as they are built.

pub mod bench;
mod edges;
pub mod ingest;
mod live;
mod liveliness;
#[cfg(test)]
mod wire_tests;

use live::LiveIngest;
pub use live::{IngestSummary, RecordError};
use liveliness::LivenessLog;
use risktwin_protos::recording::decode_replay_time;
use risktwin_transport::zenoh::sample::Sample;
use risktwin_transport::{Shutdown, SiteId, TransportConfig, TransportError, close, connect};
use serde::Serialize;
use std::path::PathBuf;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};
use thiserror::Error;

/// A cloud worker role (cli.md: `--roles ingest,twin,risk,library,trainer`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// Validate and count the edge streams.
    Ingest,
    /// The live twin (not built yet).
    Twin,
    /// Risk on the live twin (not built yet).
    Risk,
    /// The scenario library queryable (not built yet).
    Library,
    /// Policy training (not built yet).
    Trainer,
}

impl std::str::FromStr for Role {
    type Err = CloudError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "ingest" => Ok(Role::Ingest),
            "twin" => Ok(Role::Twin),
            "risk" => Ok(Role::Risk),
            "library" => Ok(Role::Library),
            "trainer" => Ok(Role::Trainer),
            other => Err(CloudError::UnknownRole { role: other.to_owned() }),
        }
    }
}

/// Why the cloud role failed.
#[derive(Debug, Error)]
pub enum CloudError {
    #[error("role {role:?} is not one of ingest, twin, risk, library, trainer")]
    UnknownRole { role: String },
    #[error("role {role:?} is not built yet; available: ingest")]
    RoleNotBuilt { role: String },
    #[error("no role to run")]
    NoRole,
    #[error(transparent)]
    Transport(#[from] TransportError),
    #[error(transparent)]
    Record(#[from] RecordError),
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
    /// Record every accepted message into this MCAP file (closed properly on shutdown).
    pub record: Option<PathBuf>,
    /// Replay-ingest mode: take each message's receive time from its replay-time attachment
    /// (put there by `risktwin edge replay`) instead of the cloud's clock, so that a replayed
    /// recording rebuilds the live run's snapshots; a message without one is dropped as
    /// `no-replay-time`. Off, attachments are ignored (a live edge cannot set the cloud's clock).
    pub replay_time: bool,
}

impl CloudConfig {
    /// Ingest for every site, with the default transport and drain.
    pub fn new(transport: TransportConfig) -> Self {
        CloudConfig {
            site: None,
            roles: vec![Role::Ingest],
            transport,
            drain_quiet: Duration::from_millis(200),
            drain_max: Duration::from_secs(2),
            record: None,
            replay_time: false,
        }
    }
}

/// The JSON the cloud prints on exit.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct CloudSummary {
    /// Counts of the ingest role.
    #[serde(flatten)]
    pub ingest: IngestSummary,
    /// Edges whose liveliness token was seen, and those seen leaving.
    pub liveliness: liveliness::LivenessSummary,
}

/// Runs the cloud roles until `shutdown` fires; `on_ready` is called once every subscription
/// is declared (edges started after that lose nothing).
pub async fn run(
    config: &CloudConfig,
    mut shutdown: Shutdown,
    on_ready: impl FnOnce(),
) -> Result<CloudSummary, CloudError> {
    if config.roles.is_empty() {
        return Err(CloudError::NoRole);
    }
    if let Some(role) = config.roles.iter().find(|r| **r != Role::Ingest) {
        return Err(CloudError::RoleNotBuilt { role: format!("{role:?}").to_lowercase() });
    }
    let session = tokio::select! {
        opened = connect(&config.transport) => opened?,
        _ = shutdown.wait() => return Ok(CloudSummary { ingest: IngestSummary::default(), liveliness: Default::default() }),
    };
    let ingest = Arc::new(Mutex::new(LiveIngest::new(config.record.as_deref(), config.replay_time)?));
    let subscriber =
        risktwin_transport::subscribe_edge_streams(&session, config.site.as_ref(), ingest_sink(Arc::clone(&ingest)))
            .await?;
    let liveness = Arc::new(Mutex::new(LivenessLog::default()));
    let edges = edges::watch_edges(&session, config.site.as_ref(), Arc::clone(&liveness)).await?;
    on_ready();

    shutdown.wait().await;
    drain(&ingest, config.drain_quiet, config.drain_max).await;

    subscriber.undeclare().await.map_err(|e| undeclare_error("subscriber", e))?;
    edges.subscriber.undeclare().await.map_err(|e| undeclare_error("liveliness subscriber", e))?;
    // With the subscriber gone its callback (and channel) is dropped, so the task ends.
    let _ = edges.declarer.await;
    close(session).await?;
    // The subscriber is undeclared, so its callback (the other owner) is gone by now; should a
    // straggler still hold it, the summary waits for nothing and the error says so.
    let ingest = Arc::try_unwrap(ingest)
        .map_err(|_| CloudError::Transport(TransportError::Close { reason: "ingest still in use".to_owned() }))?
        .into_inner()
        .unwrap_or_else(PoisonError::into_inner)
        .finish()?;
    let liveliness = liveness.lock().unwrap_or_else(PoisonError::into_inner).summary();
    Ok(CloudSummary { ingest, liveliness })
}

/// The subscriber callback of the ingest role: runs on Zenoh's receive path.
fn ingest_sink(
    ingest: Arc<Mutex<LiveIngest>>,
) -> impl Fn(risktwin_transport::EdgeStream, &Sample) + Send + Sync + 'static {
    move |_, sample| {
        // Contiguous payloads (the common case) are borrowed, not copied.
        let payload = sample.payload().to_bytes();
        let replay_ns = sample.attachment().and_then(|a| decode_replay_time(&a.to_bytes()));
        let mut ingest = ingest.lock().unwrap_or_else(PoisonError::into_inner);
        // Drops are counted inside; only a failing recording comes back, and the receive path
        // cannot stop for it: say so and go on counting.
        if let Err(e) = ingest.handle(sample.key_expr().as_str(), &payload, replay_ns) {
            eprintln!("cloud: {e}");
        }
    }
}

/// Lets samples already on their way arrive: waits until none came for `quiet`, at most `max`.
async fn drain(ingest: &Mutex<LiveIngest>, quiet: Duration, max: Duration) {
    let start = Instant::now();
    loop {
        let last = ingest.lock().unwrap_or_else(PoisonError::into_inner).last_sample();
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
