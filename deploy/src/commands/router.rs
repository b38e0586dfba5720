//! `risktwin router`: a Zenoh router in our own binary. Also the Zenoh plumbing the other
//! distributed-role commands (`edge`, `cloud`) share: the runtime, the transport config and
//! the shutdown on SIGINT/SIGTERM.
//!
//! stderr gets one `listening on <locator>` line per locator, with the port the OS picked for
//! `:0`, so that tests and scripts can start a router on a free port and read it back.

use crate::cli::{RouterArgs, TlsArgs, ZenohArgs};
use crate::error::{CliError, CliResult};
use risktwin_transport::router::{RouterConfig, run};
use risktwin_transport::{Identity, Mode, Security, Shutdown, TlsFiles, TransportConfig};
use std::future::Future;

pub fn router(args: RouterArgs) -> CliResult {
    let config = RouterConfig { listen: args.listen, connect: args.connect, security: security(&args.tls)? };
    // Bad locators, TLS files or certificates are the user's input: exit 2 before starting.
    warn_if_insecure(&config.transport().map_err(CliError::input)?);
    // Only the process's own facts: the router's sessions are Zenoh's, not counted here.
    let _metrics = crate::metrics_endpoint::start(&args.metrics, "router")?;
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
        security: security(&args.tls)?,
        ..TransportConfig::default()
    };
    // Bad locators are the user's input: refuse them here (exit 2), not when connecting.
    config.to_zenoh().map_err(CliError::input)?;
    warn_if_insecure(&config);
    Ok(config)
}

/// The security of `--tls-dir/--identity` or `--tls-ca/--tls-cert/--tls-key` (plain TCP
/// without them), its files checked.
pub(super) fn security(args: &TlsArgs) -> CliResult<Security> {
    let files = match (&args.tls_dir, &args.identity, &args.tls_ca, &args.tls_cert, &args.tls_key) {
        (None, None, None, None, None) => return Ok(Security::Insecure),
        (Some(dir), Some(identity), None, None, None) => {
            let identity: Identity = identity.parse().map_err(CliError::input)?;
            TlsFiles::in_dir(dir, &identity.common_name())
        }
        (None, None, Some(ca), Some(cert), Some(key)) => {
            TlsFiles { ca_cert: ca.clone(), cert: cert.clone(), key: key.clone() }
        }
        _ => {
            return Err(CliError::input(
                "TLS takes --tls-dir DIR --identity NAME, or --tls-ca, --tls-cert and --tls-key together",
            ));
        }
    };
    files.check().map_err(CliError::input)?;
    Ok(Security::Tls(files))
}

/// Says once, at start, that plain TCP leaves this host unprotected.
fn warn_if_insecure(config: &TransportConfig) {
    if let Some(endpoint) = config.insecure_endpoint() {
        eprintln!(
            "warning: {endpoint} is plain TCP beyond this host: insecure (no encryption, no authentication, \
             no access control); use --tls-dir (docs/security.md)"
        );
    }
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
