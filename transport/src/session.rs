//! Opening a Zenoh session from a small, typed [`TransportConfig`] instead of a JSON5 file.
//!
//! The config is built programmatically so that every role (router, edge, cloud, benchmarks,
//! tests) states exactly what it relies on. Multicast scouting is OFF by default: sessions find
//! each other only through the endpoints they are given, which keeps tests deterministic and
//! stops a test run from joining whatever Zenoh network happens to share the LAN. Gossip
//! scouting (peers learning about each other through the router) keeps Zenoh's default.

use crate::tls::{self, Identity, Security, TlsError};
use std::time::Duration;
use thiserror::Error;
use zenoh::{Config, Session};

/// How often a role retries its `connect` endpoints once it has lost them (a router restart):
/// flow resumes at most this long after the router is back.
pub const RECONNECT_PERIOD: Duration = Duration::from_millis(500);

/// The largest message a session takes in, bytes (Zenoh's `transport/link/rx/max_message_size`,
/// its defragmentation buffer; Zenoh's default is 1 GiB). Set on every role, routers included,
/// so that anything up to it reaches our code to be counted (an edge stream's sample above 64 KiB
/// as `too-large`), and room is left for the largest message we send (a policy update, at most
/// 64 MiB of weights). A larger message is dropped by the first Zenoh hop that defragments it,
/// logged only at trace level: beyond this bound nothing can count it (docs/keyexpr.md).
pub const MAX_MESSAGE_BYTES: usize = 128 << 20;

/// The Zenoh role of a session.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Mode {
    /// Talks to routers and, through gossip, directly to other peers (the default).
    #[default]
    Peer,
    /// Talks only to the one router it connects to.
    Client,
    /// Routes between clients, peers and other routers.
    Router,
}

impl std::str::FromStr for Mode {
    type Err = TransportError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "peer" => Ok(Mode::Peer),
            "client" => Ok(Mode::Client),
            "router" => Ok(Mode::Router),
            other => Err(TransportError::BadMode { mode: other.to_owned() }),
        }
    }
}

/// Everything a role needs to join the Zenoh network.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TransportConfig {
    /// Peer, client or router.
    pub mode: Mode,
    /// Locators to connect to (`tcp/127.0.0.1:7447`).
    pub connect: Vec<String>,
    /// Locators to listen on; empty: loopback only (`DEFAULT_ROUTER_PORT` for a router, a port
    /// the OS picks for a peer, none under TLS or for a client).
    pub listen: Vec<String>,
    /// Multicast scouting on UDP 224.0.0.224:7446; off unless asked for.
    pub multicast_scouting: bool,
    /// How long opening the session may wait for the `connect` endpoints.
    pub connect_timeout: Duration,
    /// A peer that opens at once and keeps trying its `connect` endpoints in the background,
    /// and that neither tells nor learns of other peers (no gossip): a link to one router that
    /// may not be reachable yet, for what must not wait for the network (a scene's data beside
    /// its physics). A client cannot: it opens only once its router answers.
    pub detached: bool,
    /// Plain TCP or mutual TLS on every link (docs/security.md).
    pub security: Security,
    /// Access rules this session enforces on its links (a router under TLS): those of these
    /// identities, everything else denied.
    pub acl: Option<Vec<Identity>>,
}

/// The port a router listens on when not told where (Zenoh's usual one), on loopback.
pub const DEFAULT_ROUTER_PORT: u16 = 7447;

impl Default for TransportConfig {
    fn default() -> Self {
        TransportConfig {
            mode: Mode::Peer,
            connect: Vec::new(),
            listen: Vec::new(),
            multicast_scouting: false,
            connect_timeout: Duration::from_secs(10),
            detached: false,
            security: Security::Insecure,
            acl: None,
        }
    }
}

/// Why a session could not be configured, opened or used.
#[derive(Debug, Error)]
pub enum TransportError {
    #[error("mode {mode:?} is not one of peer, client, router")]
    BadMode { mode: String },
    #[error("endpoint {endpoint:?} is not a Zenoh locator like tcp/127.0.0.1:7447: {reason}")]
    BadEndpoint { endpoint: String, reason: String },
    #[error("zenoh config key {key} = {value}: {reason}")]
    Config { key: &'static str, value: String, reason: String },
    #[error("opening the zenoh session (connect {connect:?}, listen {listen:?}) failed: {reason}")]
    Open { connect: Vec<String>, listen: Vec<String>, reason: String },
    #[error("{what} on {key:?} failed: {reason}")]
    Declare { what: &'static str, key: String, reason: String },
    #[error("publishing on {key:?} failed: {reason}")]
    Put { key: String, reason: String },
    #[error(
        "another process is alive as {site}/{id} (its liveliness token was still there after {wait:?}); give this one another --id"
    )]
    DuplicateId { site: String, id: String, wait: Duration },
    #[error("closing the zenoh session failed: {reason}")]
    Close { reason: String },
    #[error(transparent)]
    Tls(#[from] TlsError),
}

impl TransportConfig {
    /// The zenoh configuration this stands for.
    pub fn to_zenoh(&self) -> Result<Config, TransportError> {
        let mut config = Config::default();
        let tls = match &self.security {
            Security::Tls(files) => Some(files),
            Security::Insecure => None,
        };
        for endpoint in self.connect.iter().chain(&self.listen) {
            check_endpoint(endpoint)?;
            check_protocol(endpoint, tls.is_some())?;
        }
        if tls.is_some() && self.mode != Mode::Router && !self.listen.is_empty() {
            let reason = "under TLS only routers listen: every other session reaches the rest through a router, \
                          whose access rules it must not bypass"
                .to_owned();
            return Err(TransportError::Config { key: "listen/endpoints", value: self.listen.join(","), reason });
        }
        set(&mut config, "mode", json_str(self.mode_str()))?;
        set(&mut config, "scouting/multicast/enabled", self.multicast_scouting.to_string())?;
        if !self.connect.is_empty() {
            set(&mut config, "connect/endpoints", json_list(&self.connect))?;
            let timeout_ms = i64::try_from(self.connect_timeout.as_millis()).unwrap_or(i64::MAX);
            set(&mut config, "connect/timeout_ms", timeout_ms.to_string())?;
            // A role that cannot reach its router should say so and stop, not wait forever
            // (unless detached: then it keeps trying in the background).
            set(&mut config, "connect/exit_on_failure", (!self.detached).to_string())?;
            // Once connected, a lost router is retried every RECONNECT_PERIOD, forever (Zenoh's
            // 1 s doubling to 4 s finds a router that is back up to 4 s later).
            let period_ms = RECONNECT_PERIOD.as_millis();
            let retry =
                format!(r#"{{"period_init_ms":{period_ms},"period_max_ms":{period_ms},"period_increase_factor":1.0}}"#);
            set(&mut config, "connect/retry", retry)?;
        }
        if self.detached {
            if self.mode != Mode::Peer {
                let value = self.mode_str().to_owned();
                let reason = "only a peer opens before its router answers".to_owned();
                return Err(TransportError::Config { key: "mode", value, reason });
            }
            set(&mut config, "scouting/gossip/enabled", "false".to_owned())?;
        }
        if self.mode == Mode::Router {
            // A router's timestamps would order every plain publisher it forwards under one clock
            // id, and an advanced subscriber silently drops a sample stamped before the last
            // (two publishers' samples can leave the router out of stamp order).
            set(&mut config, "timestamping/enabled", "false".to_owned())?;
        }
        set(&mut config, "listen/endpoints", json_list(&self.listen_endpoints()))?;
        if let Some(files) = tls {
            let path = |key: &'static str, p: &std::path::Path| match p.to_str() {
                Some(p) => Ok(json_str(p)),
                None => Err(TransportError::Config { key, value: p.display().to_string(), reason: "not UTF-8".into() }),
            };
            const TLS: &str = "transport/link/tls";
            set(&mut config, "transport/link/tls/root_ca_certificate", path(TLS, &files.ca_cert)?)?;
            for key in ["transport/link/tls/listen_certificate", "transport/link/tls/connect_certificate"] {
                set(&mut config, key, path(TLS, &files.cert)?)?;
            }
            for key in ["transport/link/tls/listen_private_key", "transport/link/tls/connect_private_key"] {
                set(&mut config, key, path(TLS, &files.key)?)?;
            }
            // Mutual: a router accepts only links whose certificate its CA signed, and the name
            // in that certificate is what its access rules match.
            set(&mut config, "transport/link/tls/enable_mtls", "true".to_owned())?;
            set(&mut config, "transport/link/tls/verify_name_on_connect", "true".to_owned())?;
        }
        if let Some(identities) = &self.acl {
            set(&mut config, "access_control", tls::acl::access_control(identities).to_string())?;
        }
        set(&mut config, "transport/link/rx/max_message_size", MAX_MESSAGE_BYTES.to_string())?;
        Ok(config)
    }

    /// The endpoints listened on: those given, else loopback only (never every interface by
    /// surprise): a router on `DEFAULT_ROUTER_PORT`, a plain peer on a port the OS picks.
    pub fn listen_endpoints(&self) -> Vec<String> {
        if !self.listen.is_empty() {
            return self.listen.clone();
        }
        match (self.mode, &self.security) {
            (Mode::Router, Security::Insecure) => vec![format!("tcp/127.0.0.1:{DEFAULT_ROUTER_PORT}")],
            (Mode::Router, Security::Tls(_)) => vec![format!("tls/127.0.0.1:{DEFAULT_ROUTER_PORT}")],
            (Mode::Peer, Security::Insecure) => vec!["tcp/127.0.0.1:0".to_owned()],
            _ => Vec::new(),
        }
    }

    /// The first endpoint that plain TCP would take off this host (not loopback), if any:
    /// such a session should say once that it is insecure.
    pub fn insecure_endpoint(&self) -> Option<&str> {
        if self.security != Security::Insecure {
            return None;
        }
        self.connect.iter().chain(&self.listen).map(String::as_str).find(|e| !is_loopback(e))
    }

    fn mode_str(&self) -> &'static str {
        match self.mode {
            Mode::Peer => "peer",
            Mode::Client => "client",
            Mode::Router => "router",
        }
    }
}

/// A locator must look like `<protocol>/<address>`; zenoh checks the rest when it opens.
fn check_endpoint(endpoint: &str) -> Result<(), TransportError> {
    let bad = |reason: &str| TransportError::BadEndpoint { endpoint: endpoint.to_owned(), reason: reason.to_owned() };
    let (proto, addr) = endpoint.split_once('/').ok_or_else(|| bad("no '/' between protocol and address"))?;
    if proto.is_empty() || addr.is_empty() {
        return Err(bad("empty protocol or address"));
    }
    if endpoint.contains(['"', '\\']) {
        return Err(bad("quotes and backslashes are not allowed"));
    }
    endpoint.parse::<zenoh::config::EndPoint>().map_err(|e| bad(&e.to_string()))?;
    Ok(())
}

/// Under TLS every endpoint is `tls/`; without it none is (a `tls/` link needs certificates).
fn check_protocol(endpoint: &str, tls: bool) -> Result<(), TransportError> {
    let is_tls = endpoint.starts_with("tls/");
    let reason = match (tls, is_tls) {
        (true, false) => "TLS is on: only tls/ endpoints, plain links are refused",
        (false, true) => {
            "a tls/ endpoint needs a certificate (--tls-dir and --identity, or --tls-ca/--tls-cert/--tls-key)"
        }
        _ => return Ok(()),
    };
    Err(TransportError::BadEndpoint { endpoint: endpoint.to_owned(), reason: reason.to_owned() })
}

/// Whether a locator's host is this machine only (`127.0.0.0/8`, `::1`, `localhost`).
fn is_loopback(endpoint: &str) -> bool {
    let address = endpoint.split_once('/').map_or(endpoint, |(_, a)| a);
    let address = address.split(['?', '#']).next().unwrap_or(address);
    let host = address.rsplit_once(':').map_or(address, |(h, _)| h);
    let host = host.trim_start_matches('[').trim_end_matches(']');
    host == "localhost" || host.parse::<std::net::IpAddr>().is_ok_and(|ip| ip.is_loopback())
}

fn set(config: &mut Config, key: &'static str, value: String) -> Result<(), TransportError> {
    config.insert_json5(key, &value).map_err(|e| TransportError::Config { key, value, reason: e.to_string() })
}

fn json_str(s: &str) -> String {
    serde_json::Value::from(s).to_string()
}

fn json_list(items: &[String]) -> String {
    serde_json::Value::from(items.to_vec()).to_string()
}

/// Opens a session as `config` says.
pub async fn connect(config: &TransportConfig) -> Result<Session, TransportError> {
    let zconfig = config.to_zenoh()?;
    zenoh::open(zconfig).await.map_err(|e| TransportError::Open {
        connect: config.connect.clone(),
        listen: config.listen.clone(),
        reason: e.to_string(),
    })
}

/// The locators `session` listens on, with the ports the OS picked for `:0`.
pub async fn listening_locators(session: &Session) -> Vec<String> {
    // `SessionInfo::locators` is behind zenoh's `unstable` feature in 1.10 (hence that feature).
    session.info().locators().await.iter().map(ToString::to_string).collect()
}

/// Closes `session`, flushing what its transports still hold.
pub async fn close(session: Session) -> Result<(), TransportError> {
    session.close().await.map_err(|e| TransportError::Close { reason: e.to_string() })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn config_carries_mode_endpoints_and_no_multicast() {
        let cfg = TransportConfig {
            mode: Mode::Client,
            connect: vec!["tcp/127.0.0.1:7447".into()],
            listen: vec!["tcp/127.0.0.1:0".into()],
            ..TransportConfig::default()
        };
        let z = cfg.to_zenoh().unwrap();
        assert_eq!(z.get_json("mode").unwrap(), "\"client\"");
        assert_eq!(z.get_json("scouting/multicast/enabled").unwrap(), "false");
        assert_eq!(z.get_json("connect/endpoints").unwrap(), "[\"tcp/127.0.0.1:7447\"]");
        assert_eq!(z.get_json("listen/endpoints").unwrap(), "[\"tcp/127.0.0.1:0\"]");
        let retry: serde_json::Value = serde_json::from_str(&z.get_json("connect/retry").unwrap()).unwrap();
        assert_eq!(
            retry,
            serde_json::json!({"period_init_ms": 500, "period_max_ms": 500, "period_increase_factor": 1.0})
        );
        let router = TransportConfig { mode: Mode::Router, ..TransportConfig::default() }.to_zenoh().unwrap();
        assert_eq!(router.get_json("timestamping/enabled").unwrap(), "false");
        assert_eq!(z.get_json("connect/exit_on_failure").unwrap(), "true");
        assert_eq!(z.get_json("transport/link/rx/max_message_size").unwrap(), MAX_MESSAGE_BYTES.to_string());
    }

    #[test]
    fn a_detached_peer_is_configured_not_to_wait_for_its_router_nor_to_gossip() {
        let detached = TransportConfig {
            connect: vec!["tcp/127.0.0.1:7447".into()],
            detached: true,
            ..TransportConfig::default()
        };
        let z = detached.to_zenoh().unwrap();
        assert_eq!(z.get_json("connect/exit_on_failure").unwrap(), "false");
        assert_eq!(z.get_json("scouting/gossip/enabled").unwrap(), "false");
        let client = TransportConfig { mode: Mode::Client, ..detached };
        assert!(matches!(client.to_zenoh(), Err(TransportError::Config { key: "mode", .. })));
    }

    #[test]
    fn bad_endpoints_and_modes_are_typed_errors() {
        for bad in ["127.0.0.1:7447", "tcp/", "tcp/\"x"] {
            let cfg = TransportConfig { connect: vec![bad.into()], ..TransportConfig::default() };
            assert!(
                matches!(cfg.to_zenoh(), Err(TransportError::BadEndpoint { ref endpoint, .. }) if endpoint == bad),
                "{bad}"
            );
        }
        assert!(matches!("bridge".parse::<Mode>(), Err(TransportError::BadMode { mode }) if mode == "bridge"));
        assert_eq!("router".parse::<Mode>().unwrap(), Mode::Router);
    }

    #[test]
    fn listeners_default_to_loopback_and_plain_tcp_off_this_host_is_flagged() {
        let peer = TransportConfig::default();
        assert_eq!(peer.to_zenoh().unwrap().get_json("listen/endpoints").unwrap(), r#"["tcp/127.0.0.1:0"]"#);
        let router = TransportConfig { mode: Mode::Router, ..TransportConfig::default() };
        assert_eq!(router.listen_endpoints(), vec!["tcp/127.0.0.1:7447".to_owned()]);
        let client = TransportConfig { mode: Mode::Client, ..TransportConfig::default() };
        assert_eq!(client.to_zenoh().unwrap().get_json("listen/endpoints").unwrap(), "[]");
        assert_eq!(peer.insecure_endpoint(), None);
        for local in ["tcp/127.0.0.1:7447", "tcp/[::1]:7447", "tcp/localhost:1"] {
            let cfg = TransportConfig { connect: vec![local.into()], ..TransportConfig::default() };
            assert_eq!(cfg.insecure_endpoint(), None, "{local}");
        }
        let wide = TransportConfig { listen: vec!["tcp/[::]:7447".into()], ..TransportConfig::default() };
        assert_eq!(wide.insecure_endpoint(), Some("tcp/[::]:7447"));
    }

    #[test]
    fn tls_takes_tls_endpoints_only_and_only_routers_listen() {
        let files = tls::TlsFiles::in_dir(std::path::Path::new("/certs"), "edge:s:v");
        let tls = Security::Tls(files);
        let client = TransportConfig {
            mode: Mode::Client,
            connect: vec!["tls/127.0.0.1:7447".into()],
            security: tls.clone(),
            ..TransportConfig::default()
        };
        let z = client.to_zenoh().unwrap();
        assert_eq!(z.get_json("transport/link/tls/enable_mtls").unwrap(), "true");
        assert_eq!(z.get_json("transport/link/tls/connect_certificate").unwrap(), r#""/certs/edge:s:v.pem""#);
        assert_eq!(z.get_json("transport/link/tls/root_ca_certificate").unwrap(), r#""/certs/ca.pem""#);
        let plain = TransportConfig { connect: vec!["tcp/127.0.0.1:7447".into()], ..client.clone() };
        assert!(matches!(plain.to_zenoh(), Err(TransportError::BadEndpoint { .. })));
        let listening = TransportConfig { listen: vec!["tls/127.0.0.1:0".into()], ..client.clone() };
        assert!(matches!(listening.to_zenoh(), Err(TransportError::Config { key: "listen/endpoints", .. })));
        let peer = TransportConfig { mode: Mode::Peer, ..client.clone() };
        assert_eq!(peer.to_zenoh().unwrap().get_json("listen/endpoints").unwrap(), "[]");
        let router = TransportConfig { mode: Mode::Router, connect: vec![], ..client };
        assert_eq!(router.listen_endpoints(), vec!["tls/127.0.0.1:7447".to_owned()]);
        let tls_without_files =
            TransportConfig { connect: vec!["tls/127.0.0.1:1".into()], ..TransportConfig::default() };
        assert!(matches!(tls_without_files.to_zenoh(), Err(TransportError::BadEndpoint { .. })));
    }
}
