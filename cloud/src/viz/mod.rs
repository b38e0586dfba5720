//! The `viz` role: the live twin over the Foxglove WebSocket protocol (the official `foxglove`
//! crate's server), so that the Foxglove app shows a running cloud as it shows the cloud's
//! recording. Every topic and schema is the recording's (`--record`): the twin's scene boxes
//! (`…/cloud/scene`, `foxglove.SceneUpdate`), the risk field (`…/cloud/risk_field`,
//! `foxglove.Grid`) and report (`…/cloud/risk_report`), every accepted vehicle state on its
//! edge key (`risktwin.v1.VehicleState`), plus the road each site's twin runs on as lines
//! (`…/cloud/road`, `foxglove.SceneUpdate`; a live-view topic only). Messages are the bytes
//! already encoded for Zenoh or received from the edge, never encoded again.
//!
//! Nothing waits for a client: producers hand messages to a [`VizFeed`], which copies them into
//! a bounded queue only while a client is connected and counts what the queue had no room for;
//! the relay task ([`relay`]) logs them on the server's channels. The server itself queues up to
//! [`feed::QUEUE_MESSAGES`] messages per client and drops the oldest for a client that falls
//! behind (the crate does not say how many; they are not in [`VizSummary`]).
//!
//! The protocol has no authentication: the role listens on loopback unless told otherwise.

mod feed;
mod relay;

pub use feed::VizFeed;

use feed::{QUEUE_MESSAGES, VizShared};
use foxglove::websocket::ServerListener;
use foxglove::{Context, WebSocketServer, WebSocketServerHandle};
use risktwin_common::road::Road;
use serde::Serialize;
use std::collections::BTreeMap;
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use thiserror::Error;

/// The Foxglove convention: what the app's "Foxglove WebSocket" connection proposes.
pub const DEFAULT_VIZ_LISTEN: SocketAddr = SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), 8765);

/// Where the viz role serves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct VizConfig {
    /// The address to listen on (port 0: a free one).
    pub listen: SocketAddr,
}

impl Default for VizConfig {
    fn default() -> Self {
        VizConfig { listen: DEFAULT_VIZ_LISTEN }
    }
}

/// Why the viz role could not start.
#[derive(Debug, Error)]
#[error("viz: cannot serve the Foxglove WebSocket protocol on {listen}: {reason}")]
pub struct VizError {
    pub listen: SocketAddr,
    pub reason: String,
}

/// What the viz role did, for the cloud's summary.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct VizSummary {
    /// `ws://<address>` it served on.
    pub url: String,
    /// Clients that connected.
    pub clients_seen: u64,
    /// Messages handed to the server for subscribed clients, per topic.
    pub sent: BTreeMap<String, u64>,
    pub total_sent: u64,
    /// Messages not relayed because the queue to the relay was full, per topic.
    pub dropped: BTreeMap<String, u64>,
    pub total_dropped: u64,
}

/// The running role: the server and the relay task.
pub struct VizRole {
    server: WebSocketServerHandle,
    relay: tokio::task::JoinHandle<()>,
    shared: Arc<VizShared>,
    addr: SocketAddr,
}

/// Counts clients for the feed (which copies nothing while there is none) and the summary.
struct ClientCount(Arc<VizShared>);

impl ServerListener for ClientCount {
    fn on_client_connect(&self) {
        let now = self.0.clients.fetch_add(1, Ordering::Relaxed) + 1;
        self.0.clients_seen.fetch_add(1, Ordering::Relaxed);
        tracing::info!("viz: a Foxglove client connected ({now} connected)");
    }

    fn on_client_disconnect(&self) {
        let now = self.0.clients.fetch_sub(1, Ordering::Relaxed).saturating_sub(1);
        tracing::info!("viz: a Foxglove client left ({now} connected)");
    }
}

impl VizRole {
    /// Starts the server on `config.listen` and the relay; a site without a road map of its own
    /// is shown on `default_road`. Call inside a tokio runtime (the server runs on it).
    pub async fn start(config: VizConfig, default_road: Road) -> Result<(VizRole, VizFeed), VizError> {
        let shared = Arc::new(VizShared::default());
        let context = Context::new();
        // An IPv6 host goes in brackets: the crate binds "<host>:<port>".
        let host = match config.listen.ip() {
            IpAddr::V4(ip) => ip.to_string(),
            IpAddr::V6(ip) => format!("[{ip}]"),
        };
        let server = WebSocketServer::new()
            .name(concat!("risktwin ", env!("CARGO_PKG_VERSION")))
            .context(&context)
            .bind(host, config.listen.port())
            .message_backlog_size(QUEUE_MESSAGES)
            .listener(Arc::new(ClientCount(Arc::clone(&shared))))
            .start()
            .await
            .map_err(|e| VizError { listen: config.listen, reason: e.to_string() })?;
        let addr = SocketAddr::new(config.listen.ip(), server.port());
        let (messages, messages_rx) = tokio::sync::mpsc::channel(QUEUE_MESSAGES);
        let (roads, roads_rx) = tokio::sync::mpsc::unbounded_channel();
        let relay = relay::Relay::new(context, default_road, Arc::clone(&shared));
        let relay = tokio::spawn(relay.run(messages_rx, roads_rx));
        let feed = VizFeed { messages, roads, shared: Arc::clone(&shared) };
        Ok((VizRole { server, relay, shared, addr }, feed))
    }

    /// The address it serves on (the port the OS picked for port 0).
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Stops relaying, disconnects the clients and closes the port; what it did.
    pub async fn finish(self) -> VizSummary {
        self.relay.abort();
        self.server.stop().wait().await;
        let counts = self.shared.counts();
        VizSummary {
            url: format!("ws://{}", self.addr),
            clients_seen: self.shared.clients_seen.load(Ordering::Relaxed),
            total_sent: counts.sent.values().sum(),
            sent: counts.sent.clone(),
            total_dropped: counts.dropped.values().sum(),
            dropped: counts.dropped.clone(),
        }
    }
}
