//! Command-line grammar (cli.md, contract v1). Only parsing lives here.

use crate::output::Format;
use clap::{ArgGroup, Args, Parser, Subcommand};
use std::path::PathBuf;

#[derive(Debug, Parser)]
#[command(name = "risktwin", version, about = "Closed-loop digital twin for autonomous-driving safety validation")]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// The main job: generate, simulate, score and rank scenarios, and write a report folder.
    Run(RunArgs),
    /// Generate and rank scenarios in a library database.
    #[command(subcommand)]
    Scenarios(ScenariosCommand),
    /// Simulate one episode with the reference driver.
    Simulate(SimulateArgs),
    /// Train a driving policy (PPO, recurrent PPO or SAC) on the twin.
    Train(TrainArgs),
    /// Evaluate the driving risk field around the ego.
    RiskField(RiskFieldArgs),
    /// Criticality measures (HW, THW, TTC, a_long,req; PET) of a CommonRoad scenario's ego.
    Criticality(CriticalityArgs),
    /// Import recorded traffic as fleet data (an MCAP recording of edge messages).
    #[command(subcommand)]
    Import(ImportCommand),
    /// Throughput benchmarks.
    #[command(subcommand)]
    Bench(BenchCommand),
    /// A Zenoh router (our binary in router mode).
    Router(RouterArgs),
    /// Edge roles: a simulated vehicle or roadside unit publishing to the cloud.
    #[command(subcommand)]
    Edge(EdgeCommand),
    /// Cloud roles: ingest of the edge streams, the live twin, risk on it, the library queryable.
    Cloud(CloudArgs),
    /// Cloud→edge pushes: a scenario to run or a policy update, to one edge vehicle.
    #[command(subcommand)]
    Push(crate::commands::push::PushCommand),
}

#[derive(Debug, Args)]
pub struct RunArgs {
    /// JSON config overriding the defaults of the run.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Report folder (default ./risktwin-out/<timestamp>).
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Loop iterations (generate → rank → mutate → re-score).
    #[arg(long)]
    pub iterations: Option<u32>,
    /// A smoke-test sized run (well under a minute on 2 cores).
    #[arg(long)]
    pub quick: bool,
    /// Learner for the three variants: ppo or sac.
    #[arg(long, default_value = "ppo")]
    pub algo: String,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

#[derive(Debug, Subcommand)]
pub enum ScenariosCommand {
    /// Sample, filter, simulate, score and store scenarios.
    Generate(GenerateArgs),
    /// List stored scenarios, highest risk first.
    Rank(RankArgs),
}

#[derive(Debug, Args)]
pub struct GenerateArgs {
    /// A scenario kind or `all`.
    #[arg(long)]
    pub kind: String,
    /// Candidates to sample per kind.
    #[arg(long, allow_negative_numbers = true)]
    pub count: u64,
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    pub seed: u64,
    #[arg(long)]
    pub db: PathBuf,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

#[derive(Debug, Args)]
pub struct RankArgs {
    #[arg(long)]
    pub db: PathBuf,
    #[arg(long)]
    pub top: Option<usize>,
    /// Restrict to one kind (or `all`); `commonroad` ranks the recorded cases instead.
    #[arg(long)]
    pub kind: Option<String>,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

/// Where a scenario comes from: a library entry, a spec file or a CommonRoad file.
#[derive(Debug, Args)]
#[group(required = true, multiple = true)]
pub struct ScenarioSource {
    /// A scenario library; `--id` names a generated scenario or a recorded case in it.
    #[arg(long, requires = "id", conflicts_with = "spec")]
    pub db: Option<PathBuf>,
    #[arg(long, requires = "db")]
    pub id: Option<String>,
    /// A JSON spec file: {"kind", "seed", "params"}.
    #[arg(long)]
    pub spec: Option<PathBuf>,
    /// A CommonRoad XML scenario (recorded traffic; `simulate` and `risk-field` only).
    #[arg(long, conflicts_with_all = ["spec", "db"])]
    pub commonroad: Option<PathBuf>,
    /// The CommonRoad ego's dynamic-obstacle id (default: the planning problem's, else the first).
    #[arg(long, requires = "commonroad")]
    pub ego: Option<u64>,
}

#[derive(Debug, Args)]
pub struct TrainArgs {
    /// `ppo`, `ppo-gru` (recurrent baseline) or `sac`.
    #[arg(long, default_value = "ppo")]
    pub algo: String,
    /// `base`, `risk-only` or `full`.
    #[arg(long, default_value = "full")]
    pub variant: String,
    /// Environment steps to train for.
    #[arg(long, default_value_t = 200_000)]
    pub steps: u64,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Folder for the policy (policy.safetensors) and curves (curves.csv).
    #[arg(long)]
    pub out: PathBuf,
    /// Benign scenarios whose success is measured during training (0: none).
    #[arg(long, default_value_t = 0)]
    pub benign: usize,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

#[derive(Debug, Args)]
pub struct SimulateArgs {
    #[command(flatten)]
    pub source: ScenarioSource,
    /// `idm` (the reference driver), or `replay` (the recorded ego; `--commonroad` only).
    #[arg(long, default_value = "idm")]
    pub policy: String,
    /// Write a per-step CSV trace of the ego and its nearest object here.
    #[arg(long)]
    pub trace: Option<PathBuf>,
    /// Record the episode as MCAP (vehicle states, Foxglove scene boxes, risk grid at 2 Hz).
    #[arg(long)]
    pub record: Option<PathBuf>,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

#[derive(Debug, Args)]
pub struct RiskFieldArgs {
    #[command(flatten)]
    pub source: ScenarioSource,
    /// Simulation time at which to evaluate, s (the episode's end if it ends earlier).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub time: f64,
    /// Cell size, m.
    #[arg(long, default_value_t = 0.5)]
    pub resolution: f64,
    /// Grid size (cells per side).
    #[arg(long, default_value_t = 160)]
    pub cells: usize,
    /// Write a heatmap PNG here.
    #[arg(long)]
    pub png: Option<PathBuf>,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

#[derive(Debug, Args)]
pub struct CriticalityArgs {
    /// A CommonRoad XML scenario (2020a).
    #[arg(long, required_unless_present = "mcap", conflicts_with = "mcap")]
    pub commonroad: Option<PathBuf>,
    /// A recording written by `risktwin import commonroad` (the scenario rebuilt from its map and
    /// state messages, decoded as the cloud's ingest decodes them).
    #[arg(long)]
    pub mcap: Option<PathBuf>,
    /// The ego's dynamic-obstacle id (default: the planning problem's id, else the first obstacle).
    #[arg(long)]
    pub ego: Option<u64>,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Traffic simulation throughput (dynamics, IDM/MOBIL, collision checks).
    Sim(BenchSimArgs),
    /// Risk-field evaluation throughput on one core.
    RiskField(BenchRiskFieldArgs),
    /// Edge→cloud Zenoh throughput, ours against a raw publisher→subscriber pair.
    Zenoh(BenchZenohArgs),
    /// Unpaced MCAP replay into ingest, in-process, against the raw `mcap` reader.
    Replay(crate::commands::bench_replay::BenchReplayArgs),
    /// A paced fleet (2,000 vehicles at 50 Hz) into the cloud ingest over Zenoh: loss and CPU.
    Ingest(crate::commands::bench_ingest::BenchIngestArgs),
    /// Edge publish → twin snapshot latency, ours against a raw Zenoh one-way hop.
    Latency(crate::commands::cloud::BenchLatencyArgs),
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

/// How a distributed role joins the Zenoh network.
#[derive(Debug, Args)]
pub struct ZenohArgs {
    /// Zenoh locator to connect to (`tcp/127.0.0.1:7447`); repeatable.
    #[arg(long = "connect", value_name = "ENDPOINT")]
    pub connect: Vec<String>,
    /// Zenoh locator to listen on; repeatable.
    #[arg(long = "listen", value_name = "ENDPOINT")]
    pub listen: Vec<String>,
    /// `peer` or `client`.
    #[arg(long, default_value = "peer")]
    pub mode: String,
    /// Turn on UDP multicast scouting (off by default, see docs/keyexpr.md).
    #[arg(long)]
    pub multicast_scouting: bool,
}

#[derive(Debug, Args)]
pub struct RouterArgs {
    /// Zenoh locator to listen on (`tcp/127.0.0.1:0` picks a free port); repeatable.
    #[arg(long = "listen", value_name = "ENDPOINT")]
    pub listen: Vec<String>,
    /// Another router to connect to; repeatable.
    #[arg(long = "connect", value_name = "ENDPOINT")]
    pub connect: Vec<String>,
}

#[derive(Debug, Subcommand)]
pub enum ImportCommand {
    /// A CommonRoad XML scenario: the lanelet map and every obstacle's state per time step.
    Commonroad(ImportCommonRoadArgs),
}

#[derive(Debug, Args)]
#[command(group(ArgGroup::new("destination").required(true).multiple(true).args(["out", "db"])))]
pub struct ImportCommonRoadArgs {
    /// The CommonRoad XML scenario (2020a).
    pub scenario: PathBuf,
    /// The MCAP recording to write.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// A scenario library to store the scenario in as a recorded validation case (created if
    /// missing), with the replayed ego's metrics as its reference outcome.
    #[arg(long)]
    pub db: Option<PathBuf>,
    /// The case's ego (dynamic-obstacle id; default: the planning problem's, else the first).
    #[arg(long, requires = "db")]
    pub ego: Option<u64>,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

#[derive(Debug, Subcommand)]
pub enum EdgeCommand {
    /// A vehicle: state at the rate, CAN at twice it, perception at a fifth of it.
    Vehicle(EdgeArgs),
    /// A roadside unit: object lists and signal phases at the rate.
    Rsu(EdgeArgs),
    /// Republish a recording's edge streams (fleet data) on their recorded keys.
    Replay(ReplayArgs),
    /// A vehicle's sensor producer: the `vehicle` world and streams, published zero-copy into
    /// iceoryx2 shared memory for the vehicle's `gateway` on this host (Zenoh flags unused).
    Sensor(EdgeArgs),
    /// A vehicle's gateway: forwards its `sensor`'s shared-memory samples to Zenoh on the
    /// vehicle's keys, until the sensor ends its stream or a signal (`--kind`/`--seed` name the
    /// vehicle model, as for the sensor; rate, count and duration are the sensor's).
    Gateway(EdgeArgs),
}

#[derive(Debug, Args)]
pub struct ReplayArgs {
    /// An MCAP recording (e.g. from `risktwin cloud --record`).
    pub recording: PathBuf,
    /// Replay speed relative to the recording; 0 replays as fast as the transport allows.
    #[arg(long, default_value_t = 1.0)]
    pub speed: f64,
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    /// Seconds to wait for a subscriber before publishing anyway.
    #[arg(long, default_value_t = 10.0)]
    pub wait_for_cloud_s: f64,
}

#[derive(Debug, Args)]
pub struct EdgeArgs {
    #[arg(long)]
    pub id: String,
    #[arg(long, default_value = "default")]
    pub site: String,
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    /// Base rate, Hz (default: 50 for a vehicle's state, 10 for an RSU).
    #[arg(long)]
    pub rate_hz: Option<f64>,
    /// Stop after this many seconds.
    #[arg(long)]
    pub duration: Option<f64>,
    /// Stop each stream after this many messages.
    #[arg(long)]
    pub count: Option<u64>,
    /// Edge clock offset, ns.
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    pub clock_offset_ns: i64,
    /// Edge clock drift, parts per million.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub clock_drift_ppm: f64,
    /// Capture-stamp jitter, ± ns.
    #[arg(long, default_value_t = 0)]
    pub clock_jitter_ns: u32,
    /// Seed of the scenario sample (and of the clock jitter).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Scenario kind the edge's world is sampled from.
    #[arg(long, default_value = "cut-in")]
    pub kind: String,
    /// Seconds to wait for a subscriber before publishing anyway.
    #[arg(long, default_value_t = 10.0)]
    pub wait_for_cloud_s: f64,
}

#[derive(Debug, Args)]
pub struct CloudArgs {
    /// Comma-separated roles: ingest, twin (needs ingest), risk (needs twin), library (needs --db),
    /// criticality (needs --criticality-out).
    #[arg(long, default_value = "ingest", value_delimiter = ',')]
    pub roles: Vec<String>,
    /// Serve one site only (default: every site).
    #[arg(long)]
    pub site: Option<String>,
    /// Record every accepted message (and the twin's scene and risk outputs) into this MCAP
    /// file (closed cleanly on SIGINT/SIGTERM).
    #[arg(long)]
    pub record: Option<std::path::PathBuf>,
    /// Ingest `risktwin edge replay` output at the recorded receive times it attaches, instead
    /// of this cloud's clock (messages without one are dropped as `no-replay-time`).
    #[arg(long)]
    pub replay_time: bool,
    /// The scenario library the library role serves.
    #[arg(long)]
    pub db: Option<PathBuf>,
    /// The risk role evaluates on the road of this scenario kind (the edges' `--kind`).
    #[arg(long, default_value = "cut-in")]
    pub road: String,
    /// The criticality role writes the CommonRoad criticality of the replayed scenario here on
    /// shutdown: FILE.csv or FILE.json, as `risktwin criticality` prints them.
    #[arg(long)]
    pub criticality_out: Option<PathBuf>,
    /// The ego obstacle of the criticality role (default: the first dynamic obstacle).
    #[arg(long, requires = "criticality_out")]
    pub ego: Option<u64>,
    #[command(flatten)]
    pub zenoh: ZenohArgs,
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
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}
