//! The router role: a Zenoh router inside our own binary (no `zenohd` install needed).

use crate::session::{self, Mode, TransportConfig, TransportError};
use crate::shutdown::Shutdown;

/// What the router is asked to do.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct RouterConfig {
    /// Locators to listen on; `:0` lets the OS pick a port. Empty: Zenoh's `tcp/[::]:7447`.
    pub listen: Vec<String>,
    /// Other routers to connect to.
    pub connect: Vec<String>,
}

/// Runs a router until `shutdown` fires. `on_listening` is called once, as soon as the router
/// listens, with the locators it listens on (actual ports, not `:0`).
pub async fn run(
    config: &RouterConfig,
    mut shutdown: Shutdown,
    on_listening: impl FnOnce(&[String]),
) -> Result<(), TransportError> {
    let transport = TransportConfig {
        mode: Mode::Router,
        connect: config.connect.clone(),
        listen: config.listen.clone(),
        ..TransportConfig::default()
    };
    let session = tokio::select! {
        opened = session::connect(&transport) => opened?,
        _ = shutdown.wait() => return Ok(()),
    };
    let locators = session::listening_locators(&session).await;
    on_listening(&locators);
    shutdown.wait().await;
    session::close(session).await
}
