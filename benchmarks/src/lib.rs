//! RiskTwin's benchmarks, each timed side by side with its peer in the same run and reported
//! as a ratio; the `risktwin bench …` subcommands parse their arguments, call these and print
//! the report. Benchmarks and their harnesses (a synthetic fleet, a stand-in payload and ingest)
//! live here, not in the library crates they measure.
//!
//! - [`zenoh_throughput`]: edge→cloud messages per second through our publisher and a
//!   stand-in ingest, against raw Zenoh (`bench zenoh`);
//! - [`latency`]: edge publish → twin snapshot, against a raw Zenoh hop (`bench latency`);
//! - [`warning`]: edge publish → hazard warning at the vehicle, against a raw Zenoh hop
//!   (`bench warning`);
//! - [`replay`]: MCAP replay into the ingest worker, against the `mcap` reader (`bench replay`);
//! - [`fleet_ingest`]: a fleet of publisher processes against the real cloud ingest role, with
//!   its CPU cost (`bench ingest`);
//! - [`fanout`]: raw Zenoh's floor under a lockstep step, one put out and N answers back from
//!   N processes (`bench fanout`, beside `deploy/bench/scene-lockstep.sh`'s scene).
//!
//! ```no_run
//! # async fn example() -> Result<(), risktwin_cloud::network::CloudError> {
//! use risktwin_bench::zenoh_throughput::{BenchConfig, throughput};
//!
//! let report = throughput(BenchConfig { messages: 10_000, payload_bytes: 64, rounds: 3 }).await?;
//! println!("ours / raw Zenoh: {:.3}", report.ratio);
//! # Ok(())
//! # }
//! ```

pub mod fanout;
pub mod fleet_ingest;
pub mod latency;
pub mod replay;
pub mod secure_throughput;
pub mod standin;
pub mod standin_ingest;
pub mod synth;
pub mod warning;
pub mod zenoh_throughput;

use thiserror::Error;

/// Why a benchmark could not run: bad input (files, recordings) or a failure while running.
#[derive(Debug, Error)]
pub enum BenchError {
    /// A file or recording the benchmark was given is unusable.
    #[error("{0}")]
    Input(String),
    /// Anything else.
    #[error("{0}")]
    Runtime(String),
}

impl BenchError {
    fn input(what: impl std::fmt::Display) -> Self {
        BenchError::Input(what.to_string())
    }

    fn runtime(what: impl std::fmt::Display) -> Self {
        BenchError::Runtime(what.to_string())
    }
}
