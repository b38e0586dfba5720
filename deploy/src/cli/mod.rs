//! Command-line grammar (docs/cli.md, contract v1): every clap type of the binary, and nothing
//! else. Command modules import the grammar; the grammar imports no command.

mod bench;
mod certs;
mod deploy;
mod push;
mod recordings;
mod roles;
mod scene;
mod source;
mod v2x;

pub use bench::*;
pub use certs::*;
pub use deploy::*;
pub use push::*;
pub use recordings::*;
pub use roles::*;
pub use scene::*;
pub use source::ScenarioSource;
pub use v2x::*;

use crate::output::Format;
use clap::{ArgGroup, Args, Parser, Subcommand};
use risktwin_cloud::trainer::evaluation;
use risktwin_policy::spec::DriverSpec;
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
    /// Simulate one episode (the reference driver, a model file or a recording's ego: --driver).
    Simulate(SimulateArgs),
    /// Evaluate a driver (policy file, ONNX model or the reference driver) on the held-out set
    /// or a library's scenarios: per-kind outcome shares and means with 95 % intervals, beside
    /// the reference driver and, with --floor, the achievable floor.
    Evaluate(EvaluateArgs),
    /// Train a driving policy (PPO, recurrent PPO or SAC) on the twin.
    Train(TrainArgs),
    /// Evaluate the driving risk field around the ego.
    RiskField(RiskFieldArgs),
    /// Criticality measures (HW, THW, TTC, a_long,req; PET) of a CommonRoad scenario's ego.
    Criticality(CriticalityArgs),
    /// Import recorded traffic as fleet data (an MCAP recording of edge messages).
    #[command(subcommand)]
    Import(ImportCommand),
    /// Rewrite what is readable of an unfinished or damaged MCAP recording as a finished file.
    Recover(RecoverArgs),
    /// Read back a folder of rotating recordings (`cloud --record-dir`): list, query, export.
    #[command(subcommand)]
    Recordings(RecordingsCommand),
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
    Push(PushCommand),
    /// One scene shared by processes: a physics authority, connected vehicles and RSUs.
    #[command(subcommand)]
    Scene(SceneCommand),
    /// Emulated multi-machine deployments: hosts, links, routers and roles from a topology file.
    #[command(subcommand)]
    Deploy(DeployCommand),
    /// V2X: the sidelink radio channel of 3GPP TR 37.885.
    #[command(subcommand)]
    V2x(V2xCommand),
    /// The cloud's policy-signing key pair (docs/signing.md).
    #[command(subcommand)]
    Keys(KeysCommand),
    /// The TLS deployment's CA and its certificates, one per identity (docs/security.md).
    #[command(subcommand)]
    Certs(CertsCommand),
}

impl Command {
    /// Whether the command opens sockets (Zenoh sessions, a router, a deployment): such a
    /// process must never die of SIGPIPE (see `main`). Exhaustive, so a new command decides.
    pub fn uses_the_network(&self) -> bool {
        match self {
            Command::Run(_)
            | Command::Bench(_)
            | Command::Router(_)
            | Command::Edge(_)
            | Command::Cloud(_)
            | Command::Push(_)
            | Command::Scene(_)
            | Command::Deploy(_) => true,
            Command::Scenarios(_)
            | Command::Simulate(_)
            | Command::Evaluate(_)
            | Command::Train(_)
            | Command::RiskField(_)
            | Command::Criticality(_)
            | Command::Import(_)
            | Command::Recover(_)
            | Command::V2x(_)
            | Command::Keys(_)
            | Command::Certs(_)
            | Command::Recordings(_) => false,
        }
    }
}

#[derive(Debug, Subcommand)]
pub enum KeysCommand {
    /// Writes a new ed25519 key pair: DIR/policy-signing.key (the cloud's secret, mode 0600) and
    /// DIR/policy-verifying.key (for `edge vehicle --trust-key`); never overwrites a key.
    Generate(KeysGenerateArgs),
}

#[derive(Debug, Args)]
pub struct KeysGenerateArgs {
    /// The folder to write the two key files into (created if needed).
    #[arg(long)]
    pub out: PathBuf,
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
    /// Learner for the four variants: `ppo`, `ppo-gru` (recurrent baseline) or `sac`.
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
    /// The achievable floor of `risktwin run`'s held-out set: per scenario, whether a privileged
    /// planner finds a drive that completes the route without collision or leaving the road.
    Floor(FloorArgs),
    /// Feasible variations of one stored scenario, simulated with the reference driver and
    /// stored as its mutations.
    Mutate(MutateArgs),
    /// The regression gate by hand: a driver (policy file or ONNX model) against the deployed
    /// one (default: the reference driver) on the library's regression set and the held-out set.
    Regress(RegressArgs),
}

#[derive(Debug, Args)]
pub struct RegressArgs {
    #[arg(long)]
    pub db: PathBuf,
    /// The candidate driver: `PATH.safetensors` (a policy file as `risktwin train` writes it),
    /// `PATH.onnx` (an ONNX model, docs/driver-interface.md) or `idm`.
    #[arg(long = "driver", visible_alias = "policy", value_name = "SPEC")]
    pub driver: DriverSpec,
    /// The driver deployed now, named as `--driver`.
    #[arg(long, value_name = "SPEC", default_value = "idm")]
    pub against: DriverSpec,
    /// The run seed whose held-out set is driven (`risktwin run --seed`).
    #[arg(long, default_value_t = evaluation::DEFAULT_SEED, allow_negative_numbers = true)]
    pub seed: u64,
    /// Held-out scenarios per kind (`eval_per_kind` of the run).
    #[arg(long, default_value_t = evaluation::DEFAULT_PER_KIND, allow_negative_numbers = true)]
    pub per_kind: u64,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

#[derive(Debug, Args)]
pub struct MutateArgs {
    #[arg(long)]
    pub db: PathBuf,
    /// The stored scenario to mutate (an id from `scenarios rank`).
    #[arg(long)]
    pub id: String,
    /// Children to draw.
    #[arg(long, default_value_t = 10, allow_negative_numbers = true)]
    pub count: u64,
    /// Seed of the draws: the same library, id, seed, count and radius give the same children.
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    pub seed: u64,
    /// Step size as a share of each parameter's range, in [0, 1] (default: `risktwin run`'s).
    #[arg(long, allow_negative_numbers = true)]
    pub radius: Option<f64>,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

#[derive(Debug, Args)]
pub struct FloorArgs {
    /// A scenario kind or `all`.
    #[arg(long, default_value = "all")]
    pub kind: String,
    /// Held-out scenarios per kind (`eval_per_kind` of the run; the first N of its set).
    #[arg(long, default_value_t = evaluation::DEFAULT_PER_KIND, allow_negative_numbers = true)]
    pub count: u64,
    /// The run seed whose held-out set is searched (`risktwin run --seed`).
    #[arg(long, default_value_t = evaluation::DEFAULT_SEED, allow_negative_numbers = true)]
    pub seed: u64,
    /// A driver to show beside the floor, scenario by scenario (`PATH.safetensors`,
    /// `PATH.onnx` or `idm`, as `simulate --driver`).
    #[arg(long, value_name = "SPEC")]
    pub driver: Option<DriverSpec>,
    /// Worker threads (default: all cores); the result does not depend on it.
    #[arg(long, allow_negative_numbers = true)]
    pub threads: Option<u64>,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
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
    /// Rank by this driver's latest outcomes (`idm`, `replay`, `PATH.safetensors`,
    /// `PATH.onnx`; default: `idm`, and `replay` for `--kind commonroad`); scenarios it never
    /// drove are left out.
    #[arg(long = "driver", visible_alias = "policy", value_name = "SPEC")]
    pub driver: Option<DriverSpec>,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

#[derive(Debug, Args)]
pub struct TrainArgs {
    /// `ppo`, `ppo-gru` (recurrent baseline) or `sac`.
    #[arg(long, default_value = "ppo")]
    pub algo: String,
    /// `base`, `risk-only`, `full` or `ttc`.
    #[arg(long, default_value = "full")]
    pub variant: String,
    /// Environment steps to train for.
    #[arg(long, default_value_t = 200_000)]
    pub steps: u64,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Folder for the policy (policy.safetensors, policy.onnx) and curves (curves.csv).
    #[arg(long)]
    pub out: PathBuf,
    /// Benign scenarios whose success is measured during training (0: none).
    #[arg(long, default_value_t = 0)]
    pub benign: usize,
    /// Start from an imitation of the reference driver (PPO only); its demonstration steps
    /// count against --steps.
    #[arg(long)]
    pub warm_start: bool,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

#[derive(Debug, Args)]
pub struct EvaluateArgs {
    /// Who drives: `PATH.onnx`, `PATH.safetensors` or `idm` (docs/driver-interface.md).
    #[arg(long = "driver", visible_alias = "policy", value_name = "SPEC")]
    pub driver: DriverSpec,
    /// Drive this library's generated scenarios (instead of the held-out set) and add every
    /// episode's outcome there under the driver's label (each run adds its own).
    #[arg(long, conflicts_with = "held_out")]
    pub db: Option<PathBuf>,
    /// Drive the held-out set of `risktwin run --seed S` (the default).
    #[arg(long)]
    pub held_out: bool,
    /// Drive these CommonRoad scenarios (each with its default ego) instead: the recorded
    /// traffic played back, the ego driven closed-loop from its recorded initial state.
    #[arg(long, value_name = "FILE", num_args = 1.., conflicts_with_all = ["db", "held_out", "floor"])]
    pub commonroad: Vec<PathBuf>,
    /// The run seed whose held-out set is driven.
    #[arg(long, default_value_t = evaluation::DEFAULT_SEED, allow_negative_numbers = true, conflicts_with_all = ["db", "commonroad"])]
    pub seed: u64,
    /// Held-out scenarios per kind.
    #[arg(long, default_value_t = evaluation::DEFAULT_PER_KIND, allow_negative_numbers = true, conflicts_with_all = ["db", "commonroad"])]
    pub per_kind: u64,
    /// Also search the achievable floor (the privileged planner) of every scenario.
    #[arg(long)]
    pub floor: bool,
    /// Write a report folder: report.md, metrics.json and figures.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Worker threads (default: all cores); the result does not depend on it.
    #[arg(long, allow_negative_numbers = true)]
    pub threads: Option<u64>,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

#[derive(Debug, Args)]
pub struct SimulateArgs {
    #[command(flatten)]
    pub source: ScenarioSource,
    /// Who drives the ego: `idm` (the reference driver), `replay` (the recorded ego; CommonRoad
    /// scenarios only), `PATH.safetensors` (a policy file as `risktwin train` writes it) or
    /// `PATH.onnx` (an ONNX model, docs/driver-interface.md).
    #[arg(long = "driver", visible_alias = "policy", value_name = "SPEC", default_value = "idm")]
    pub driver: DriverSpec,
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

#[derive(Debug, Args)]
pub struct RecoverArgs {
    /// The recording to read (e.g. one whose recorder was killed).
    pub recording: PathBuf,
    /// The finished MCAP file to write (footer, summary, indexes).
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
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
