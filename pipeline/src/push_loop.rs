//! The distributed roles of the closed loop, started inside `risktwin run`: a Zenoh router
//! listening on loopback only (`tcp/127.0.0.1:0`, the port the OS picks), the cloud's ingest
//! role (recording what it accepts), one edge vehicle, and the cloud→edge pushes of
//! `risktwin push scenario|policy` — the same library code as the separate processes of the
//! pipeline tests, every session a Zenoh client of that router. Router, ingest and pushes are
//! tasks of one tokio runtime; the edge has a thread and runtime of its own, as it would have a
//! process: its reliable publishers block under congestion, and sharing a task with the pushes
//! that drain it deadlocked the loop under CPU load.
//!
//! Order: each scenario pushed under the edge's reference driver, then the policy update, then
//! each scenario again, through one cloud session ([`EdgeLink`]). Every wait is bounded and on a
//! real event (the router's listening callback, the ingest's ready callback, the edge's
//! liveliness token and push subscriber matching, the edge accepting the policy, the
//! `ScenarioResult` arriving); any failure shuts every role down and comes back as an error.

use risktwin_cloud::network::push::{EdgeLink, PushError, PushTarget, ScenarioPushReport};
use risktwin_cloud::network::{CloudConfig, CloudSummary};
use risktwin_common::scenario::{ScenarioSpec, build};
use risktwin_edge::publish::run_producer;
use risktwin_edge::vehicle::push::{PolicyLine, PushSummary};
use risktwin_edge::vehicle::{DEFAULT_STATE_RATE_HZ, Vehicle, VehicleSummary};
use risktwin_edge::{EdgeConfig, EdgeError, Producer, Stamper};
use risktwin_policy::signature::PolicySigningKey;
use risktwin_transport::keyexpr::{CloudToEdge, EdgeReport, KeyError};
use risktwin_transport::router::RouterConfig;
use risktwin_transport::shutdown::channel;
use risktwin_transport::{EdgeStream, Mode, Shutdown, SiteId, SourceId, TransportConfig};
use std::collections::BTreeMap;
use std::future::Future;
use std::path::PathBuf;
use std::time::{Duration, Instant};
use tokio::sync::{oneshot, watch};
use tokio::task::JoinHandle;

/// The site of the run's edge vehicle.
pub const SITE: &str = "run";
/// The run's edge vehicle.
pub const VEHICLE: &str = "veh-1";
/// State rate of the edge vehicle, Hz: 20× real time for its 50 Hz state stream (samples of
/// its 20 Hz simulation), so that a pushed episode plays out in a twentieth of its duration.
pub const RATE_HZ: f64 = 1000.0;
/// Longest wait for a role to come up, the edge to subscribe or to accept the policy.
const WAIT: Duration = Duration::from_secs(20);
/// Fixed part of the wait for one pushed scenario's result, s (the rest scales with its playback
/// time: a 30 s episode plays in 1.5 s at [`RATE_HZ`]).
const RESULT_BASE_S: f64 = 10.0;

/// Why the closed loop failed; every message starts with `closed loop:` except an id's.
#[derive(Debug, thiserror::Error)]
pub enum LoopError {
    /// A tokio runtime or the edge's thread could not be started.
    #[error("closed loop: {what}: {source}")]
    Start { what: &'static str, source: std::io::Error },
    /// A bounded wait ran out.
    #[error("closed loop: {what} within {limit_s} s")]
    Timeout { what: String, limit_s: u64 },
    /// A role's task panicked or was cancelled.
    #[error("closed loop: {what} task: {message}")]
    Task { what: &'static str, message: String },
    /// A role ended with an error.
    #[error("closed loop: {what}: {source}")]
    Role { what: &'static str, source: Box<dyn std::error::Error + Send + Sync> },
    #[error("closed loop: the router stopped before it listened")]
    RouterStopped,
    #[error("closed loop: the router listens on no tcp/127.0.0.1 locator")]
    NoLoopback,
    #[error(transparent)]
    Id(#[from] KeyError),
    #[error("closed loop: the ingest role stopped before it was ready")]
    IngestNotReady,
    #[error("closed loop: the edge vehicle stopped before the pushes were done")]
    EdgeStoppedEarly,
    #[error("closed loop: the edge vehicle stopped before it took the policy")]
    EdgeStoppedBeforePolicy,
    #[error("closed loop: the edge vehicle's thread ended without a word")]
    EdgeSilent,
    #[error("closed loop: edge vehicle: {0}")]
    Edge(EdgeError),
    #[error("closed loop: cloud push session: {0}")]
    OpenSession(PushError),
    #[error("closed loop: closing the cloud push session: {0}")]
    CloseSession(PushError),
    #[error("closed loop: pushing policy {policy_id}: {source}")]
    PushPolicy { policy_id: String, source: PushError },
    #[error("closed loop: the edge refused policy {policy_id} version {version}: {refused:?}")]
    PolicyRefused { policy_id: String, version: u32, refused: BTreeMap<String, u64> },
    #[error("closed loop: pushing scenario {id}: {source}")]
    PushScenario { id: String, source: PushError },
    #[error("closed loop: the full policy file: {0}")]
    PolicyFile(#[from] risktwin_policy::NetError),
}

/// What to push.
pub struct LoopRequest {
    /// Library id and spec of each scenario, in push order.
    pub scenarios: Vec<(String, ScenarioSpec)>,
    pub policy_id: String,
    pub version: u32,
    /// `ppo` or `sac`.
    pub algo: String,
    /// The policy as a safetensors file's bytes.
    pub weights: Vec<u8>,
    /// Where the ingest role records what it accepted.
    pub record: Option<PathBuf>,
}

/// What came back.
pub struct LoopOutput {
    /// The edge's result per scenario, pushed before the policy.
    pub by_reference: Vec<ScenarioPushReport>,
    /// The edge's result per scenario, pushed after the policy.
    pub by_policy: Vec<ScenarioPushReport>,
    /// The policy the edge held when the second round was pushed.
    pub held: PolicyLine,
    /// The vehicle's exit summary (what it sent, what it was pushed).
    pub vehicle: VehicleSummary,
    /// The cloud's exit summary (what ingest received and dropped).
    pub cloud: CloudSummary,
    /// The router's loopback locator.
    pub locator: String,
    pub wall_s: f64,
}

/// A vehicle whose accepted and refused pushes are published on a watch channel, so the loop
/// can wait for the policy to be in force instead of guessing.
struct Watched {
    vehicle: Vehicle,
    seen: watch::Sender<PushSummary>,
}

impl Producer for Watched {
    fn streams(&self) -> &[EdgeStream] {
        self.vehicle.streams()
    }

    fn ticks_per_base(&self) -> u32 {
        self.vehicle.ticks_per_base()
    }

    fn messages_per_base(&self, stream: EdgeStream) -> f64 {
        self.vehicle.messages_per_base(stream)
    }

    fn tick(&mut self, tick: u64, stamper: &mut Stamper<'_>, out: &mut Vec<(EdgeStream, Vec<u8>)>) {
        self.vehicle.tick(tick, stamper, out);
    }

    fn pushes(&self) -> &[CloudToEdge] {
        Producer::pushes(&self.vehicle)
    }

    fn on_push(&mut self, push: CloudToEdge, encoding: &str, payload: &[u8]) {
        self.vehicle.on_push(push, encoding, payload);
        self.seen.send_replace(self.vehicle.pushes().clone());
    }

    fn reports(&mut self, out: &mut Vec<(EdgeReport, Vec<u8>)>) {
        self.vehicle.reports(out);
    }
}

/// Starts the roles, pushes, shuts everything down; `progress` hears of each step.
pub fn run_loop(
    request: &LoopRequest,
    shutdown: &Shutdown,
    progress: &mut dyn FnMut(&str),
) -> Result<LoopOutput, LoopError> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .map_err(|source| LoopError::Start { what: "tokio runtime", source })?;
    let result = runtime.block_on(roles(request, shutdown, progress));
    // Tasks still running after a failed, bounded join are dropped here, never waited for.
    runtime.shutdown_timeout(Duration::from_secs(1));
    result
}

/// Waits up to `limit` for `what`.
async fn bounded<T>(what: &str, limit: Duration, fut: impl Future<Output = T>) -> Result<T, LoopError> {
    tokio::time::timeout(limit, fut)
        .await
        .map_err(|_| LoopError::Timeout { what: what.to_owned(), limit_s: limit.as_secs() })
}

/// Joins a role's task, bounded.
async fn join<T, E: std::error::Error + Send + Sync + 'static>(
    what: &'static str,
    task: JoinHandle<Result<T, E>>,
) -> Result<T, LoopError> {
    bounded(&format!("{what} did not stop"), WAIT, task)
        .await?
        .map_err(|e| LoopError::Task { what, message: e.to_string() })?
        .map_err(|e| LoopError::Role { what, source: Box::new(e) })
}

async fn roles(
    request: &LoopRequest,
    shutdown: &Shutdown,
    progress: &mut dyn FnMut(&str),
) -> Result<LoopOutput, LoopError> {
    let started = Instant::now();
    let (router_stop, router_shutdown) = channel();
    let (listening_tx, listening_rx) = oneshot::channel();
    let router = tokio::spawn(async move {
        let config = RouterConfig { listen: vec!["tcp/127.0.0.1:0".to_owned()], ..RouterConfig::default() };
        risktwin_transport::router::run(&config, router_shutdown, |locators| {
            let _ = listening_tx.send(locators.to_vec());
        })
        .await
    });
    let locator = match bounded("the router did not listen", WAIT, listening_rx).await {
        Ok(Ok(locators)) => locators.into_iter().find(|l| l.starts_with("tcp/127.0.0.1:")),
        // The router ended before it listened: its own error says why.
        Ok(Err(_)) => {
            router_stop.fire();
            join("router", router).await?;
            return Err(LoopError::RouterStopped);
        }
        Err(e) => return Err(e),
    };
    let Some(locator) = locator else {
        router_stop.fire();
        join("router", router).await?;
        return Err(LoopError::NoLoopback);
    };
    progress(&format!("router on {locator}"));
    // Clients of the router: no session listens, and every message goes through the router,
    // in order per link (which waiting for the edge's liveliness token before a push relies on).
    let transport =
        TransportConfig { mode: Mode::Client, connect: vec![locator.clone()], ..TransportConfig::default() };
    let site = SiteId::new(SITE)?;
    let edge_id = SourceId::new(VEHICLE)?;

    let (cloud_stop, cloud_shutdown) = channel();
    let (ready_tx, ready_rx) = oneshot::channel();
    let mut cloud_config = CloudConfig::new(transport.clone());
    cloud_config.site = Some(site.clone());
    cloud_config.record.clone_from(&request.record);
    let cloud = tokio::spawn(async move {
        risktwin_cloud::network::run(&cloud_config, cloud_shutdown, move |_| {
            let _ = ready_tx.send(());
        })
        .await
    });

    let (edge_stop, edge_shutdown) = channel();
    let mut edge_config = EdgeConfig::new(site.clone(), edge_id.clone(), RATE_HZ);
    edge_config.transport = transport.clone();
    // Both ends are this run's: a key made for it alone signs the update, and the edge trusts
    // its public half, so the policy goes through the same verification as a fleet's.
    let signer = ephemeral_key()?;
    edge_config.trust_key = Some(signer.verifying_key());
    let target = PushTarget { transport, site, edge: edge_id, wait_for_edge: WAIT };
    let outcome = async {
        bounded("the ingest role was not ready", WAIT, ready_rx).await?.map_err(|_| LoopError::IngestNotReady)?;
        // The edge runs on a thread of its own, as it would in its own process: its producer is
        // not `Send`, and its reliable puts block under congestion, which must never stall the
        // pushes that drain it. An edge that stops before the pushes are done fails the phase.
        let (seen_tx, seen_rx) = watch::channel(PushSummary::default());
        let mut edge = spawn_edge(edge_config, seen_tx, edge_shutdown)?;
        let pushed = tokio::select! {
            pushed = pushes(request, &target, &signer, shutdown, seen_rx, progress) => pushed,
            ended = &mut edge => {
                return Err(match ended {
                    Ok(Ok(_)) => LoopError::EdgeStoppedEarly,
                    Ok(Err(e)) => e,
                    Err(_) => LoopError::EdgeSilent,
                });
            }
        };
        edge_stop.fire();
        let vehicle =
            bounded("the edge vehicle did not stop", WAIT, edge).await?.map_err(|_| LoopError::EdgeSilent)??;
        Ok((pushed?, vehicle))
    }
    .await;

    // Shut down in order — the edge is down by now, so ingest drains what it sent — and join
    // each role, whatever happened above.
    cloud_stop.fire();
    let cloud = join("cloud ingest", cloud).await;
    router_stop.fire();
    let router = join("router", router).await;
    let (Pushed { by_reference, by_policy, held }, vehicle) = outcome?;
    let cloud = cloud?;
    router?;
    Ok(LoopOutput { by_reference, by_policy, held, vehicle, cloud, locator, wall_s: started.elapsed().as_secs_f64() })
}

/// Starts the edge vehicle on its own thread and runtime; its summary (or error) comes back
/// on the returned channel when it stops.
fn spawn_edge(
    config: EdgeConfig,
    seen: watch::Sender<PushSummary>,
    shutdown: Shutdown,
) -> Result<oneshot::Receiver<Result<VehicleSummary, LoopError>>, LoopError> {
    let (done_tx, done_rx) = oneshot::channel();
    std::thread::Builder::new()
        .name("edge-vehicle".to_owned())
        .spawn(move || {
            let result = tokio::runtime::Builder::new_multi_thread()
                .worker_threads(1)
                .enable_all()
                .build()
                .map_err(|source| LoopError::Start { what: "edge vehicle runtime", source })
                .and_then(|runtime| runtime.block_on(drive_edge(&config, seen, shutdown)).map_err(LoopError::Edge));
            let _ = done_tx.send(result);
        })
        .map_err(|source| LoopError::Start { what: "edge vehicle thread", source })?;
    Ok(done_rx)
}

/// The edge vehicle role, its pushes watched.
async fn drive_edge(
    config: &EdgeConfig,
    seen: watch::Sender<PushSummary>,
    shutdown: Shutdown,
) -> Result<VehicleSummary, EdgeError> {
    let mut watched = Watched { vehicle: Vehicle::new(config)?, seen };
    let sent = run_producer(config, &mut watched, shutdown).await?;
    Ok(VehicleSummary { sent, pushes: watched.vehicle.pushes().clone() })
}

/// What the pushes brought back.
struct Pushed {
    by_reference: Vec<ScenarioPushReport>,
    by_policy: Vec<ScenarioPushReport>,
    held: PolicyLine,
}

async fn pushes(
    request: &LoopRequest,
    target: &PushTarget,
    signer: &PolicySigningKey,
    shutdown: &Shutdown,
    mut seen: watch::Receiver<PushSummary>,
    progress: &mut dyn FnMut(&str),
) -> Result<Pushed, LoopError> {
    // The pushes end at their own bounds or at the run's shutdown.
    // One cloud session for every push, its result subscriber declared once; each push waits
    // for the edge's liveliness token, which the edge declares after its push subscribers (the
    // ingest role's wildcard subscription makes matching status alone unreliable).
    let link = EdgeLink::open(target).await.map_err(LoopError::OpenSession)?;
    let pushed = push_rounds(request, &link, signer, shutdown, &mut seen, progress).await;
    let closed = link.close().await.map_err(LoopError::CloseSession);
    let pushed = pushed?;
    closed?;
    Ok(pushed)
}

/// A signing key for this run alone, from the operating system's random source.
fn ephemeral_key() -> Result<PolicySigningKey, LoopError> {
    let mut seed = [0u8; 32];
    getrandom::getrandom(&mut seed)
        .map_err(|e| LoopError::Start { what: "random source for the policy key", source: std::io::Error::other(e) })?;
    Ok(PolicySigningKey::from_seed(seed))
}

/// Scenarios under the reference driver, the policy, the scenarios again.
async fn push_rounds(
    request: &LoopRequest,
    link: &EdgeLink,
    signer: &PolicySigningKey,
    shutdown: &Shutdown,
    seen: &mut watch::Receiver<PushSummary>,
    progress: &mut dyn FnMut(&str),
) -> Result<Pushed, LoopError> {
    let by_reference = push_all(request, link, shutdown, progress, "reference driver").await?;

    let refused_before: u64 = seen.borrow().policies_refused.values().sum();
    let weights = request.weights.clone();
    link.policy(&request.policy_id, request.version, &request.algo, weights, Some(signer), shutdown.clone())
        .await
        .map_err(|source| LoopError::PushPolicy { policy_id: request.policy_id.clone(), source })?;
    let holds = |p: &PushSummary| {
        p.policy.as_ref().is_some_and(|l| l.policy_id == request.policy_id && l.version == request.version)
    };
    let summary = bounded(
        "the edge did not take the policy",
        WAIT,
        seen.wait_for(|p| holds(p) || p.policies_refused.values().sum::<u64>() > refused_before),
    )
    .await?
    .map_err(|_| LoopError::EdgeStoppedBeforePolicy)?
    .clone();
    let Some(held) = summary.policy.clone().filter(|_| holds(&summary)) else {
        return Err(LoopError::PolicyRefused {
            policy_id: request.policy_id.clone(),
            version: request.version,
            refused: summary.policies_refused.clone(),
        });
    };
    progress(&format!("edge drives with policy {} version {}", held.policy_id, held.version));
    let by_policy = push_all(request, link, shutdown, progress, "pushed policy").await?;
    Ok(Pushed { by_reference, by_policy, held })
}

/// Pushes every scenario of `request` in turn, each awaiting its result (for a few times the
/// episode's playback time).
async fn push_all(
    request: &LoopRequest,
    link: &EdgeLink,
    shutdown: &Shutdown,
    progress: &mut dyn FnMut(&str),
    driver: &str,
) -> Result<Vec<ScenarioPushReport>, LoopError> {
    let mut out = Vec::with_capacity(request.scenarios.len());
    for (id, spec) in &request.scenarios {
        // The edge plays an episode of at most the horizon's 50 Hz state samples at RATE_HZ.
        let playback_s = build(spec).horizon_s * DEFAULT_STATE_RATE_HZ / RATE_HZ;
        let wait = Duration::from_secs_f64(RESULT_BASE_S + 4.0 * playback_s);
        let report = link
            .scenario(id, spec, wait, shutdown.clone())
            .await
            .map_err(|source| LoopError::PushScenario { id: id.clone(), source })?;
        progress(&format!("scenario {id} ({driver}): collision {}", report.metrics.collision));
        out.push(report);
    }
    Ok(out)
}
