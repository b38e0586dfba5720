//! The router role: a Zenoh router inside our own binary (no `zenohd` install needed).
//!
//! Under TLS the router enforces access rules (`tls::acl`) for the identities whose
//! certificates lie beside its CA certificate when it starts: an identity issued later is
//! denied everything until the router restarts.

use crate::session::{self, Mode, TransportConfig, TransportError};
use crate::shutdown::Shutdown;
use crate::tls::{Identity, Security, certs};

/// What the router is asked to do.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct RouterConfig {
    /// Locators to listen on; `:0` lets the OS pick a port. Empty: loopback on
    /// `DEFAULT_ROUTER_PORT`.
    pub listen: Vec<String>,
    /// Other routers to connect to.
    pub connect: Vec<String>,
    /// Plain TCP or mutual TLS (then with access rules).
    pub security: Security,
}

impl RouterConfig {
    /// The session config: under TLS with the access rules of every identity known beside
    /// the CA certificate.
    pub fn transport(&self) -> Result<TransportConfig, TransportError> {
        let acl = match &self.security {
            Security::Tls(files) => Some(known_identities(&files.ca_cert)?),
            Security::Insecure => None,
        };
        let transport = TransportConfig {
            mode: Mode::Router,
            connect: self.connect.clone(),
            listen: self.listen.clone(),
            security: self.security.clone(),
            acl,
            ..TransportConfig::default()
        };
        transport.to_zenoh()?;
        Ok(transport)
    }
}

fn known_identities(ca_cert: &std::path::Path) -> Result<Vec<Identity>, TransportError> {
    let dir = ca_cert.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(std::path::Path::new("."));
    Ok(certs::known_identities(dir)?)
}

/// Runs a router until `shutdown` fires. `on_listening` is called once, as soon as the router
/// listens, with the locators it listens on (actual ports, not `:0`).
pub async fn run(
    config: &RouterConfig,
    mut shutdown: Shutdown,
    on_listening: impl FnOnce(&[String]),
) -> Result<(), TransportError> {
    let transport = config.transport()?;
    if let Some(identities) = &transport.acl {
        tracing::info!(identities = identities.len(), "access rules for the known identities, all else denied");
    }
    let session = tokio::select! {
        opened = session::connect(&transport) => opened?,
        _ = shutdown.wait() => return Ok(()),
    };
    let locators = session::listening_locators(&session).await;
    on_listening(&locators);
    shutdown.wait().await;
    session::close(session).await
}
