//! What TLS and the routers' access rules cost the state path (`risktwin bench zenoh --vs-tls`).
//!
//! Each round opens a router and two clients in this process: the edge side (the vehicle
//! state stream's `StreamPublisher`, `Block`) and the cloud side (the edge-stream subscriber
//! and the stand-in ingest), as `zenoh_throughput`'s "ours", with every sample through the
//! router. Plain rounds use TCP with no access control; secure rounds mutual TLS with the
//! access rules of the three identities (`tls::acl`), certificates made once per run in a
//! temporary folder. Rounds alternate; medians are compared.

use crate::zenoh_throughput::{BenchConfig, bench_error, median, state_path_round};
use risktwin_cloud::network::CloudError;
use risktwin_transport::router::RouterConfig;
use risktwin_transport::tls::certs;
use risktwin_transport::{Identity, Mode, Security, TlsFiles, TransportConfig, connect, listening_locators};
use serde::Serialize;
use std::path::Path;

/// The figures, messages per second.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SecureReport {
    /// Messages per measurement.
    pub messages: u64,
    /// Payload size, bytes.
    pub payload_bytes: usize,
    /// Every plain-TCP measurement.
    pub plain_msgs_per_s: Vec<f64>,
    /// Every TLS + access-rules measurement.
    pub tls_acl_msgs_per_s: Vec<f64>,
    /// Median plain.
    pub plain_median_msgs_per_s: f64,
    /// Median TLS + access rules.
    pub tls_acl_median_msgs_per_s: f64,
    /// TLS + access rules / plain, medians (the target is at least 0.8).
    pub ratio: f64,
}

const ROUTER: &str = "router:bench";
const CLOUD: &str = "cloud:bench";
/// The source `state_path_round` publishes as.
const EDGE: &str = "edge:bench:veh-0";

/// Runs the comparison.
pub async fn secure_throughput(config: BenchConfig) -> Result<SecureReport, CloudError> {
    let dir = tempfile::tempdir().map_err(|e| bench_error(format!("a folder for the certificates: {e}")))?;
    let mut identities = Vec::new();
    for name in [ROUTER, CLOUD, EDGE] {
        identities.push((name.parse::<Identity>().map_err(|e| bench_error(e.to_string()))?, Vec::new()));
    }
    certs::init(dir.path(), &identities).map_err(|e| bench_error(e.to_string()))?;
    let mut plain = Vec::with_capacity(config.rounds);
    let mut secure = Vec::with_capacity(config.rounds);
    for _ in 0..config.rounds {
        plain.push(round(config, None).await?);
        secure.push(round(config, Some(dir.path())).await?);
    }
    let (plain_median, secure_median) = (median(&plain), median(&secure));
    Ok(SecureReport {
        messages: config.messages,
        payload_bytes: config.payload_bytes,
        plain_msgs_per_s: plain,
        tls_acl_msgs_per_s: secure,
        plain_median_msgs_per_s: plain_median,
        tls_acl_median_msgs_per_s: secure_median,
        ratio: if plain_median > 0.0 { secure_median / plain_median } else { 0.0 },
    })
}

/// One measurement through a fresh router: plain TCP, or TLS with access rules from `tls_dir`.
async fn round(config: BenchConfig, tls_dir: Option<&Path>) -> Result<f64, CloudError> {
    let security = |identity: &str| match tls_dir {
        Some(dir) => Security::Tls(TlsFiles::in_dir(dir, identity)),
        None => Security::Insecure,
    };
    let listen = if tls_dir.is_some() { "tls/127.0.0.1:0" } else { "tcp/127.0.0.1:0" };
    let router_config =
        RouterConfig { listen: vec![listen.to_owned()], connect: Vec::new(), security: security(ROUTER) };
    let router = connect(&router_config.transport()?).await?;
    let locators = listening_locators(&router).await;
    let client = |identity: &str| TransportConfig {
        mode: Mode::Client,
        connect: locators.clone(),
        security: security(identity),
        ..TransportConfig::default()
    };
    let sub_side = connect(&client(CLOUD)).await?;
    let pub_side = connect(&client(EDGE)).await?;
    let rate = state_path_round(config, sub_side, pub_side).await;
    let _ = router.close().await;
    rate
}
