//! The binary's one `tracing` subscriber: the library crates log through `tracing` events, and
//! this prints them on stderr, one plain line each — the message alone, with no time, level or
//! target, since tests and users read and wait on those lines (`ready`, `edge joined: …`). The
//! filter is `RUST_LOG` when set, else `info` for RiskTwin's own crates and nothing of Zenoh's
//! (its internal warnings, e.g. about matching listeners on shutdown, were never printed and
//! are not ours to act on; `RUST_LOG=info,zenoh=warn` shows them).
//!
//! The binary's `error: …` line is not a log event: it is the command-line contract
//! (docs/cli.md), printed by `main` itself.

use tracing_subscriber::EnvFilter;

/// The filter without `RUST_LOG`. The Foxglove server's info lines (each client registered,
/// server started) repeat what the viz role says in its own words.
const DEFAULT_FILTER: &str = "info,zenoh=off,foxglove=warn";

/// Installs the subscriber; call once, first thing in `main`.
pub fn init() {
    let filter = EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new(DEFAULT_FILTER));
    let installed = tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        .with_env_filter(filter)
        .without_time()
        .with_target(false)
        .with_level(false)
        .with_ansi(false)
        .try_init();
    // Only fails when a subscriber is already set, which then does the job.
    drop(installed);
}
