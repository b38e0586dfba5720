//! What TLS and the routers' access rules cost the state path (`risktwin bench zenoh --vs-tls`).
//!
//! Each round opens a router and two clients in this process: the edge side (the vehicle
//! state stream's `StreamPublisher`, `Block`) and the cloud side (the edge-stream subscriber
//! and the stand-in ingest), as `zenoh_throughput`'s "ours", with every sample through the
//! router. Plain rounds use TCP with no access control; TLS rounds mutual TLS without access
//! rules; secure rounds mutual TLS with the access rules of the three identities (`tls::acl`),
//! so that the two costs show apart. Certificates are made once per run in a temporary
//! folder. Rounds alternate; medians are compared.

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
    /// Every TLS measurement without access rules.
    pub tls_msgs_per_s: Vec<f64>,
    /// Every TLS + access-rules measurement.
    pub tls_acl_msgs_per_s: Vec<f64>,
    /// Median plain.
    pub plain_median_msgs_per_s: f64,
    /// Median TLS without access rules.
    pub tls_median_msgs_per_s: f64,
    /// Median TLS + access rules.
    pub tls_acl_median_msgs_per_s: f64,
    /// TLS + access rules / plain, medians (the target is at least 0.8).
    pub ratio: f64,
    /// TLS / plain, medians: what encryption alone costs.
    pub ratio_tls: f64,
    /// TLS + access rules / TLS, medians: what the access rules alone cost.
    pub ratio_acl: f64,
}

/// How a round secures its links.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Guard {
    Plain,
    Tls,
    TlsAcl,
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
    let mut tls = Vec::with_capacity(config.rounds);
    let mut secure = Vec::with_capacity(config.rounds);
    for _ in 0..config.rounds {
        plain.push(round(config, Guard::Plain, dir.path()).await?);
        tls.push(round(config, Guard::Tls, dir.path()).await?);
        secure.push(round(config, Guard::TlsAcl, dir.path()).await?);
    }
    let (plain_median, tls_median, secure_median) = (median(&plain), median(&tls), median(&secure));
    let ratio = |a: f64, b: f64| if b > 0.0 { a / b } else { 0.0 };
    Ok(SecureReport {
        messages: config.messages,
        payload_bytes: config.payload_bytes,
        plain_msgs_per_s: plain,
        tls_msgs_per_s: tls,
        tls_acl_msgs_per_s: secure,
        plain_median_msgs_per_s: plain_median,
        tls_median_msgs_per_s: tls_median,
        tls_acl_median_msgs_per_s: secure_median,
        ratio: ratio(secure_median, plain_median),
        ratio_tls: ratio(tls_median, plain_median),
        ratio_acl: ratio(secure_median, tls_median),
    })
}

/// One measurement through a fresh router, its certificates (when TLS) from `tls_dir`.
async fn round(config: BenchConfig, guard: Guard, tls_dir: &Path) -> Result<f64, CloudError> {
    let security = |identity: &str| match guard {
        Guard::Plain => Security::Insecure,
        Guard::Tls | Guard::TlsAcl => Security::Tls(TlsFiles::in_dir(tls_dir, identity)),
    };
    let listen = if guard == Guard::Plain { "tcp/127.0.0.1:0" } else { "tls/127.0.0.1:0" };
    let router_config =
        RouterConfig { listen: vec![listen.to_owned()], connect: Vec::new(), security: security(ROUTER) };
    let mut router_transport = router_config.transport()?;
    if guard == Guard::Tls {
        router_transport.acl = None;
    }
    let router = connect(&router_transport).await?;
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
