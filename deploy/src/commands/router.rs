//! `risktwin router`: a Zenoh router in our own binary. Also the Zenoh plumbing the other
//! distributed-role commands (`edge`, `cloud`) share: the runtime, the transport config and
//! the shutdown on SIGINT/SIGTERM.
//!
//! stderr gets one `listening on <locator>` line per locator, with the port the OS picked for
//! `:0`, so that tests and scripts can start a router on a free port and read it back.

use crate::cli::{RouterArgs, ZenohArgs};
use crate::error::{CliError, CliResult};
use risktwin_transport::router::{RouterConfig, run};
use risktwin_transport::{Mode, Shutdown, TransportConfig};
use std::future::Future;

pub fn router(args: RouterArgs) -> CliResult {
    let config = RouterConfig { listen: args.listen, connect: args.connect };
    with_signals(|shutdown| async move {
        run(&config, shutdown, |locators| {
            for locator in locators {
                eprintln!("listening on {locator}");
            }
        })
        .await
        .map_err(CliError::runtime)
    })
}

/// The transport config of `--connect/--listen/--mode/--multicast-scouting`.
pub(super) fn transport_config(args: ZenohArgs) -> CliResult<TransportConfig> {
    let mode: Mode = args.mode.parse().map_err(CliError::input)?;
    if mode == Mode::Router {
        return Err(CliError::input("--mode router is `risktwin router`; use peer or client"));
    }
    let config = TransportConfig {
        mode,
        connect: args.connect,
        listen: args.listen,
        multicast_scouting: args.multicast_scouting,
        ..TransportConfig::default()
    };
    // Bad locators are the user's input: refuse them here (exit 2), not when connecting.
    config.to_zenoh().map_err(CliError::input)?;
    Ok(config)
}

/// Runs `role` on a multi-threaded tokio runtime (zenoh needs one) with a shutdown fired by
/// SIGINT or SIGTERM.
pub(super) fn with_signals<F, Fut, T>(role: F) -> CliResult<T>
where
    F: FnOnce(Shutdown) -> Fut,
    Fut: Future<Output = CliResult<T>>,
{
    let runtime = tokio::runtime::Builder::new_multi_thread().enable_all().build().map_err(CliError::runtime)?;
    runtime.block_on(async move {
        let shutdown = Shutdown::on_signals().map_err(CliError::runtime)?;
        role(shutdown).await
    })
}
