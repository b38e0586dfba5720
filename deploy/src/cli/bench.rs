//! The grammar of `risktwin bench …`: throughput and latency benchmarks.

use crate::output::Format;
use clap::{Args, Subcommand};
use std::path::PathBuf;

#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Traffic simulation throughput (dynamics, IDM/MOBIL, collision checks).
    Sim(BenchSimArgs),
    /// Risk-field evaluation throughput on one core.
    RiskField(BenchRiskFieldArgs),
    /// Edge→cloud Zenoh throughput, ours against a raw publisher→subscriber pair.
    Zenoh(BenchZenohArgs),
    /// Unpaced MCAP replay into ingest, in-process, against the raw `mcap` reader.
    Replay(BenchReplayArgs),
    /// A paced fleet (2,000 vehicles at 50 Hz) into the cloud ingest over Zenoh: loss and CPU.
    Ingest(BenchIngestArgs),
    /// Edge publish → twin snapshot latency, ours against a raw Zenoh one-way hop.
    Latency(BenchLatencyArgs),
    /// Edge state publish → hazard warning at the vehicle, against a raw Zenoh one-way hop.
    Warning(BenchWarningArgs),
    /// The raw Zenoh floor of a lockstep step: one put out to N echo processes, N answers back.
    Fanout(BenchFanoutArgs),
    /// A deployment's emulated link at 0 ms against the direct TCP path: round trip and
    /// throughput of 1 KiB messages to an echo process.
    Link(BenchLinkArgs),
}

#[derive(Debug, Args)]
pub struct BenchSimArgs {
    #[arg(long, default_value_t = 1000)]
    pub vehicles: usize,
    #[arg(long, default_value_t = 1000)]
    pub steps: u64,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

#[derive(Debug, Args)]
pub struct BenchRiskFieldArgs {
    #[arg(long, default_value_t = 64)]
    pub agents: usize,
    #[arg(long, default_value_t = 256)]
    pub cols: usize,
    #[arg(long, default_value_t = 256)]
    pub rows: usize,
    /// Minimum measuring time, s.
    #[arg(long, default_value_t = 2.0)]
    pub seconds: f64,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

#[derive(Debug, Args)]
pub struct BenchZenohArgs {
    /// Messages per measurement.
    #[arg(long, default_value_t = 200_000)]
    pub messages: u64,
    /// Payload size, bytes.
    #[arg(long, default_value_t = 1024)]
    pub payload_bytes: usize,
    /// Measurements per side, alternating; medians are compared.
    #[arg(long, default_value_t = 3)]
    pub rounds: usize,
    /// Instead of ours against raw Zenoh: our state path through a router over plain TCP
    /// against mutual TLS with the routers' access rules (docs/security.md).
    #[arg(long)]
    pub vs_tls: bool,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

#[derive(Debug, Args)]
pub struct BenchReplayArgs {
    /// The recording to replay; written first (a synthetic fleet) if it does not exist.
    #[arg(long)]
    pub file: Option<PathBuf>,
    /// Vehicles of the synthetic fleet.
    #[arg(long, default_value_t = 1000)]
    pub vehicles: usize,
    /// Seconds of the synthetic fleet.
    #[arg(long, default_value_t = 10)]
    pub seconds: u64,
    /// Measurements per side, alternating; medians are compared.
    #[arg(long, default_value_t = 3)]
    pub rounds: usize,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

#[derive(Debug, Args)]
pub struct BenchIngestArgs {
    /// Vehicles in the fleet (split evenly over the publishers).
    #[arg(long, default_value_t = 2000)]
    pub vehicles: usize,
    /// State messages per vehicle per second; must divide 100.
    #[arg(long, default_value_t = 50)]
    pub rate_hz: u64,
    /// Seconds of publishing.
    #[arg(long, default_value_t = 10)]
    pub seconds: u64,
    /// Publisher processes (one Zenoh session each).
    #[arg(long, default_value_t = 1)]
    pub publishers: usize,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
    /// Serve the cloud side's metrics here while it runs (docs/metrics.md), to measure what
    /// they cost under load.
    #[command(flatten)]
    pub metrics: super::MetricsArgs,
    /// Record what the cloud side accepts as `cloud --record-dir` does (for a soak:
    /// benchmarks/soak.sh).
    #[command(flatten)]
    pub rotation: super::RecordDirArgs,
    /// Internal: run as one publisher of the fleet, connecting here.
    #[arg(long, hide = true)]
    pub fleet_connect: Option<String>,
    /// Internal: index of this publisher's first vehicle.
    #[arg(long, hide = true, default_value_t = 0)]
    pub first_vehicle: usize,
    /// Internal: each vehicle of this publisher holds a liveliness token and is published only
    /// once a subscriber matches it (sharded workers find vehicles by their tokens;
    /// benchmarks/shard_scale.sh).
    #[arg(long, hide = true)]
    pub fleet_tokens: bool,
}

/// `risktwin bench latency`.
#[derive(Debug, clap::Args)]
pub struct BenchLatencyArgs {
    /// Messages per side (the first 50 warm up and are not counted).
    #[arg(long, default_value_t = 1000)]
    pub messages: u64,
    /// Publish rate, Hz.
    #[arg(long, default_value_t = 50.0)]
    pub rate_hz: f64,
    /// Snapshot tick of the twin, ms (default: the ingest's 50).
    #[arg(long)]
    pub tick_ms: Option<f64>,
    /// Allowed lateness of the aligner, ms (default: the ingest's 30, `DEFAULT_LATENESS_NS`).
    #[arg(long)]
    pub lateness_ms: Option<f64>,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

/// `risktwin bench warning`.
#[derive(Debug, clap::Args)]
pub struct BenchWarningArgs {
    /// Messages per side (the first 50 warm up and are not counted).
    #[arg(long, default_value_t = 1000)]
    pub messages: u64,
    /// Publish rate of each vehicle's state, Hz.
    #[arg(long, default_value_t = 50.0)]
    pub rate_hz: f64,
    /// Run the risk role (risk field of every vehicle at 2 Hz) in the cloud's callback too.
    #[arg(long)]
    pub risk: bool,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

/// `risktwin bench fanout`.
#[derive(Debug, clap::Args)]
pub struct BenchFanoutArgs {
    /// Echo processes (a scene's participants).
    #[arg(long, default_value_t = 10)]
    pub echoes: usize,
    /// Timed rounds (a scene's steps).
    #[arg(long, default_value_t = 2000)]
    pub rounds: u64,
    /// Bytes out per round (a scene's truth).
    #[arg(long, default_value_t = 1024)]
    pub out_bytes: usize,
    /// Bytes of each answer (a participant's reply).
    #[arg(long, default_value_t = 40)]
    pub reply_bytes: usize,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
    /// Internal: run as echo `--echo-id`, connecting here.
    #[arg(long, hide = true)]
    pub echo_connect: Option<String>,
    /// Internal: this echo's index.
    #[arg(long, hide = true, default_value_t = 0)]
    pub echo_id: usize,
}

/// `risktwin bench link`.
#[derive(Debug, clap::Args)]
pub struct BenchLinkArgs {
    /// Timed round trips on each path.
    #[arg(long, default_value_t = 5000)]
    pub round_trips: u64,
    /// Bytes per message.
    #[arg(long, default_value_t = 1024)]
    pub message_bytes: usize,
    /// Seconds of streaming on each path.
    #[arg(long, default_value_t = 2.0)]
    pub stream_s: f64,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
    /// Run as the echo process on this port of 127.0.0.1 (internal).
    #[arg(long, hide = true)]
    pub echo_port: Option<u16>,
}
