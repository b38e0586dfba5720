//! Cloud→edge pushes (`risktwin push scenario|policy`): one message on the edge's own push key
//! (`risktwin/v1/<site>/<id>/{scenario,policy}`), reliable, sent only once the edge is up — its
//! liveliness token visible, which implies its push subscriber (Zenoh drops what nobody
//! subscribes to); for a scenario, the edge's `ScenarioResult` with the same `spec_id` is then
//! awaited on `…/<id>/scenario_result`.

use risktwin_common::metrics::EpisodeMetrics;
use risktwin_common::risk::RiskTerms;
use risktwin_common::scenario::ScenarioSpec;
use risktwin_common::telemetry::{Frame, Header, PolicyRef, PolicyUpdate, ScenarioPush, ScenarioResult};
use risktwin_policy::signature::PolicySigningKey;
use risktwin_protos::{decode_tagged, encode};
use risktwin_transport::keyexpr::{CloudToEdge, EdgeReport, cloud_to_edge, edge_report, liveliness_token};
use risktwin_transport::stream::watch_edge_alive;
use risktwin_transport::wall_clock::unix_ns;
use risktwin_transport::zenoh::Session;
use risktwin_transport::zenoh::handlers::FifoChannelHandler;
use risktwin_transport::zenoh::pubsub::Subscriber;
use risktwin_transport::zenoh::qos::CongestionControl;
use risktwin_transport::zenoh::sample::Sample;
use risktwin_transport::{Shutdown, SiteId, SourceId, TransportConfig, TransportError, close, connect, protobuf};
use serde::Serialize;
use std::time::Duration;
use thiserror::Error;
use tokio::sync::watch;

/// Why a push failed.
#[derive(Debug, Error)]
pub enum PushError {
    #[error(
        "edge {target} was not up (liveliness token and subscriber of {key}) within {waited_s} s (is `risktwin edge vehicle --id {target}` running?)"
    )]
    NoEdge { target: String, key: String, waited_s: f64 },
    #[error("edge {target} sent no result for scenario {spec_id} within {waited_s} s")]
    NoResult { target: String, spec_id: String, waited_s: f64 },
    #[error("interrupted")]
    Interrupted,
    #[error(transparent)]
    Transport(#[from] TransportError),
}

/// Where a push goes and how long to wait.
#[derive(Debug, Clone)]
pub struct PushTarget {
    pub transport: TransportConfig,
    pub site: SiteId,
    pub edge: SourceId,
    /// How long to wait for the edge's push subscriber.
    pub wait_for_edge: Duration,
}

/// What `push scenario` prints.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScenarioPushReport {
    pub site: String,
    pub edge: String,
    pub spec_id: String,
    pub metrics: EpisodeMetrics,
    pub risk: RiskTerms,
    /// The policy version that drove the ego on the edge; `None`: the reference driver.
    pub policy: Option<PolicyRef>,
}

/// What `push policy` prints.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct PolicyPushReport {
    pub site: String,
    pub edge: String,
    pub policy_id: String,
    pub version: u32,
    pub delivered: bool,
}

/// The header of a cloud→edge message, stamped now.
pub(crate) fn header(seq: u64) -> Header {
    let now_ns = unix_ns();
    Header { source: "cloud".to_owned(), seq, capture_time_ns: now_ns, publish_time_ns: now_ns, frame: Frame::World }
}

fn declare_err(what: &'static str, key: &str) -> impl FnOnce(risktwin_transport::zenoh::Error) -> TransportError {
    let key = key.to_owned();
    move |e| TransportError::Declare { what, key, reason: e.to_string() }
}

/// Publishes `payload` on `target`'s `push` key once the edge is there: its liveliness token
/// is visible and the key's publisher matches.
///
/// Matching alone is not enough: a cloud ingest role's wildcard subscription
/// (`risktwin/v1/<site>/*/*`) matches the push keys too, so the publisher can match before the
/// edge has subscribed, and the push would be lost. The edge declares its push subscribers
/// before its token (edge/src/publish.rs), and Zenoh carries one session's declarations in
/// order, so a visible token means the subscribers are declared along the same path.
async fn deliver(
    session: &Session,
    target: &PushTarget,
    alive: &watch::Receiver<bool>,
    push: CloudToEdge,
    payload: Vec<u8>,
    mut shutdown: Shutdown,
) -> Result<(), PushError> {
    let key = cloud_to_edge(&target.site, &target.edge, push);
    let publisher = session
        .declare_publisher(key.clone())
        .encoding(protobuf(push.message()))
        .congestion_control(CongestionControl::Block)
        .await
        .map_err(declare_err("publisher", &key))?;
    let listener = publisher.matching_listener().await.map_err(declare_err("matching listener", &key))?;
    if !*alive.borrow() {
        tracing::info!(
            "push: waiting up to {} s for edge {}/{} to come up",
            target.wait_for_edge.as_secs_f64(),
            target.site,
            target.edge
        );
    }
    let mut alive = alive.clone();
    let reachable = async {
        if alive.wait_for(|up| *up).await.is_err() {
            return Ok(false);
        }
        // The status is read after the listener exists, so that no change falls between them.
        if publisher.matching_status().await.map_err(declare_err("matching status", &key))?.matching() {
            return Ok(true);
        }
        while let Ok(status) = listener.recv_async().await {
            if status.matching() {
                return Ok(true);
            }
        }
        Ok::<_, TransportError>(false)
    };
    let found = tokio::select! {
        m = tokio::time::timeout(target.wait_for_edge, reachable) => m.unwrap_or(Ok(false))?,
        () = shutdown.wait() => return Err(PushError::Interrupted),
    };
    if !found {
        return Err(PushError::NoEdge {
            target: target.edge.to_string(),
            key,
            waited_s: target.wait_for_edge.as_secs_f64(),
        });
    }
    publisher.put(payload).await.map_err(|e| TransportError::Put { key: key.clone(), reason: e.to_string() })?;
    publisher.undeclare().await.map_err(declare_err("undeclare", &key))?;
    Ok(())
}

/// One session to one edge, kept open across pushes, with the subscriber of the edge's
/// results declared once: a caller pushing many scenarios to the same edge (the closed loop of
/// `risktwin run`) does not open a session and re-declare that subscriber per push, so no
/// result can go to a subscriber that is still being declared or undeclared.
pub struct EdgeLink {
    session: Session,
    target: PushTarget,
    result_key: String,
    results: Subscriber<FifoChannelHandler<Sample>>,
    /// Whether the edge's liveliness token exists, kept current by `alive_watch`.
    alive: watch::Receiver<bool>,
    alive_watch: Subscriber<()>,
}

impl EdgeLink {
    /// Opens the session, subscribes to the edge's results and watches its liveliness token.
    pub async fn open(target: &PushTarget) -> Result<Self, PushError> {
        let session = connect(&target.transport).await?;
        let result_key = edge_report(&target.site, &target.edge, EdgeReport::ScenarioResult);
        // Subscribed before any push goes out, so that a quick result cannot be missed.
        let results =
            session.declare_subscriber(result_key.clone()).await.map_err(declare_err("subscriber", &result_key))?;
        let (alive_watch, alive) = watch_edge_alive(&session, &target.site, &target.edge).await?;
        Ok(EdgeLink { session, target: target.clone(), result_key, results, alive, alive_watch })
    }

    /// Pushes `spec` (library id `spec_id`) and waits up to `wait_for_result` for its outcome
    /// (results of other scenarios are skipped).
    pub async fn scenario(
        &self,
        spec_id: &str,
        spec: &ScenarioSpec,
        wait_for_result: Duration,
        mut shutdown: Shutdown,
    ) -> Result<ScenarioPushReport, PushError> {
        let target = &self.target;
        let push = ScenarioPush { header: header(0), spec_id: spec_id.to_owned(), spec: spec.clone() };
        deliver(&self.session, target, &self.alive, CloudToEdge::Scenario, encode(&push), shutdown.clone()).await?;
        tracing::info!("pushed scenario {spec_id} to {}/{}", target.site, target.edge);
        let wait = async {
            while let Ok(sample) = self.results.recv_async().await {
                match decode_tagged::<ScenarioResult>(&sample.encoding().to_string(), &sample.payload().to_bytes()) {
                    Ok(r) if r.spec_id == spec_id => return Some(r),
                    Ok(r) => tracing::warn!("push: result of another scenario ({}) ignored", r.spec_id),
                    Err(e) => tracing::warn!("push: undecodable result ignored: {e}"),
                }
            }
            None
        };
        let result = tokio::select! {
            r = tokio::time::timeout(wait_for_result, wait) => r.ok().flatten(),
            () = shutdown.wait() => return Err(PushError::Interrupted),
        };
        let result = result.ok_or_else(|| PushError::NoResult {
            target: target.edge.to_string(),
            spec_id: spec_id.to_owned(),
            waited_s: wait_for_result.as_secs_f64(),
        })?;
        Ok(ScenarioPushReport {
            site: target.site.to_string(),
            edge: target.edge.to_string(),
            spec_id: result.spec_id,
            metrics: result.metrics,
            risk: result.risk,
            policy: result.policy,
        })
    }

    /// Pushes a policy update (delivered once the edge subscribes; the edge validates it and
    /// reports what it holds in its own summary).
    pub async fn policy(
        &self,
        policy_id: &str,
        version: u32,
        algo: &str,
        weights: Vec<u8>,
        signer: Option<&PolicySigningKey>,
        shutdown: Shutdown,
    ) -> Result<PolicyPushReport, PushError> {
        let mut update = PolicyUpdate {
            header: header(u64::from(version)),
            policy_id: policy_id.to_owned(),
            version,
            algo: algo.to_owned(),
            weights,
            target: format!("{}/{}", self.target.site.as_str(), self.target.edge.as_str()),
            signature: Vec::new(),
        };
        if let Some(signer) = signer {
            signer.sign(&mut update);
        }
        deliver(&self.session, &self.target, &self.alive, CloudToEdge::Policy, encode(&update), shutdown).await?;
        Ok(PolicyPushReport {
            site: self.target.site.to_string(),
            edge: self.target.edge.to_string(),
            policy_id: policy_id.to_owned(),
            version,
            delivered: true,
        })
    }

    /// Closes the link after one push and returns that push's outcome: its own error, if any,
    /// says more than a failure to close after it.
    async fn close_after<T>(self, outcome: Result<T, PushError>) -> Result<T, PushError> {
        let closed = self.close().await;
        let value = outcome?;
        closed?;
        Ok(value)
    }

    /// Undeclares the subscribers and closes the session.
    pub async fn close(self) -> Result<(), PushError> {
        let alive_key = liveliness_token(&self.target.site, &self.target.edge);
        self.alive_watch.undeclare().await.map_err(declare_err("undeclare", &alive_key))?;
        self.results.undeclare().await.map_err(declare_err("undeclare", &self.result_key))?;
        close(self.session).await?;
        Ok(())
    }
}

/// Pushes `spec` (library id `spec_id`) to the edge and waits up to `wait_for_result` for its
/// outcome.
pub async fn push_scenario(
    target: &PushTarget,
    spec_id: &str,
    spec: &ScenarioSpec,
    wait_for_result: Duration,
    shutdown: Shutdown,
) -> Result<ScenarioPushReport, PushError> {
    let link = EdgeLink::open(target).await?;
    let report = link.scenario(spec_id, spec, wait_for_result, shutdown).await;
    link.close_after(report).await
}

/// Pushes a policy update to the edge (delivered once the edge subscribes; the edge validates
/// it and reports what it holds in its own summary).
pub async fn push_policy(
    target: &PushTarget,
    policy_id: &str,
    version: u32,
    algo: &str,
    weights: Vec<u8>,
    signer: Option<&PolicySigningKey>,
    shutdown: Shutdown,
) -> Result<PolicyPushReport, PushError> {
    let link = EdgeLink::open(target).await?;
    let report = link.policy(policy_id, version, algo, weights, signer, shutdown).await;
    link.close_after(report).await
}
