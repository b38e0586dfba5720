//! `risktwin scene …`: one scene shared by several processes (docs/cli.md, "Scenes").

use super::ZenohArgs;
use crate::output::Format;
use clap::{Args, Subcommand};
use std::path::PathBuf;

#[derive(Debug, Subcommand)]
pub enum SceneCommand {
    /// Every role of a scene on this host: a router, the physics authority (this process), one
    /// process per connected vehicle and RSU; prints the outcome as JSON.
    Run(SceneRunArgs),
    /// The physics authority alone: steps the world, waits for every participant.
    Authority(SceneRoleArgs),
    /// One connected vehicle's onboard stack (`--participant v0` is the ego, `v1…` traffic).
    Vehicle(SceneParticipantArgs),
    /// One roadside unit's onboard stack (`--participant rsu0…`).
    Rsu(SceneParticipantArgs),
}

/// Which scene: the scenario and the role assignment. Every role of one scene gets the same.
#[derive(Debug, Clone, Args)]
pub struct SceneArgs {
    /// A JSON spec file: {"kind", "seed", "params"}.
    #[arg(long, conflicts_with_all = ["db", "kind"])]
    pub spec: Option<PathBuf>,
    /// A CommonRoad XML recording: its ego (v0) driven by the reference driver from its
    /// recorded start, every other obstacle played back.
    #[arg(long, conflicts_with_all = ["spec", "db", "kind"])]
    pub commonroad: Option<PathBuf>,
    /// The recording's ego, a dynamic-obstacle id (default: the planning problem's, else the
    /// first).
    #[arg(long, requires = "commonroad")]
    pub ego: Option<u64>,
    /// A scenario library; `--id` names a generated scenario or a recorded case in it.
    #[arg(long, requires = "id", conflicts_with = "kind")]
    pub db: Option<PathBuf>,
    #[arg(long, requires = "db")]
    pub id: Option<String>,
    /// A generated scenario kind: the first feasible sample of `--seed`.
    #[arg(long)]
    pub kind: Option<String>,
    #[arg(long, default_value_t = 0, requires = "kind")]
    pub seed: u64,
    /// Connected vehicles: the ego (v0) and the scenario's first moving traffic vehicles (a
    /// recording's first recorded vehicles in file order).
    #[arg(long, default_value_t = 1)]
    pub connected: u32,
    /// Roadside units along the ego's route (rsu0, rsu1, …, 150 m apart).
    #[arg(long, default_value_t = 0)]
    pub rsus: u32,
    /// Takes connected vehicle ID (v1, v2, …) out of the world: the same scene without it, to
    /// see what the others do when it is not there. Repeatable.
    #[arg(long, value_name = "ID")]
    pub without: Vec<String>,
    /// Zenoh site of the scene's keys.
    #[arg(long, default_value = "site0")]
    pub site: String,
    /// A router the scene's data goes through (its edge streams, road map and ground truth:
    /// what a cloud ingests), each role joining it with a session of its own that does not wait
    /// for it, while its physics stays on the roles' own sessions (`scene run`: its own loopback router, unless --router). A
    /// deployment gives a scene its site's router here, so that no emulated link carries
    /// physics.
    #[arg(long, value_name = "ENDPOINT")]
    pub data_router: Option<String>,
    /// V2X between the participants over path-loss MODEL (`3gpp-urban-nlos`, …, as `v2x
    /// channel --model`): each connected vehicle sends CAMs, every other participant receives
    /// them through the channel. Without it, no V2X.
    #[arg(long, value_name = "MODEL")]
    pub v2x_model: Option<String>,
    /// The V2X latency per broadcast: `sidelink:T1:T2` or `gamma:OFFSET:SHAPE:SCALE`, ms
    /// (default sidelink:4:100).
    #[arg(long, value_name = "LATENCY")]
    pub v2x_latency: Option<String>,
    /// Burst loss on each V2X link, `SHARE:MEAN_BURST` (0.3:5: 30 % of the messages lost in
    /// bursts of 5 on average); none by default.
    #[arg(long, value_name = "SHARE:MEAN")]
    pub v2x_bursts: Option<String>,
    /// With --v2x-model: each RSU warns the vehicles of the hazards it perceives (DENM-like,
    /// 10 Hz while a hazard lasts), and the ego's driver reacts to what it hears.
    #[arg(long)]
    pub v2x_warnings: bool,
    /// With --v2x-model: each RSU sends Collective Perception Messages of what it perceives
    /// (ETSI object inclusion rules, checked at 10 Hz), and the vehicles fuse what they hear.
    #[arg(long)]
    pub v2x_cpm: bool,
    /// Who drives the ego: `idm` (default), `PATH.safetensors` or `PATH.onnx`
    /// (docs/driver-interface.md); every participant loads the same file (its label, with the
    /// file's digest, is part of the scene).
    #[arg(long, value_name = "SPEC")]
    pub driver: Option<risktwin_policy::spec::DriverSpec>,
}

#[derive(Debug, Args)]
pub struct SceneRunArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// `lockstep` (virtual time, deterministic) or `realtime` (the wall clock, late answers counted).
    #[arg(long, default_value = "lockstep")]
    pub clock: String,
    /// A running router to join (`tcp/127.0.0.1:7447`; a cloud on it then ingests the scene's
    /// edge streams) instead of starting one.
    #[arg(long, value_name = "ENDPOINT", conflicts_with = "embedded")]
    pub router: Option<String>,
    /// Every participant's stack in this one process, no network: the reference a distributed
    /// lockstep run equals byte for byte.
    #[arg(long)]
    pub embedded: bool,
    /// Scene seconds per wall-clock second (1: real time); 0 steps as fast as every participant
    /// answers.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub speed: f64,
    #[arg(long, value_enum, default_value_t = Format::Json)]
    pub format: Format,
    /// Appends each participant process's summary (steps, objects perceived, messages sent per
    /// edge stream) to FILE, one JSON object per line; stdout keeps only the scene's outcome,
    /// which equals the embedded run's.
    #[arg(long, value_name = "FILE", conflicts_with = "embedded")]
    pub participant_summaries: Option<PathBuf>,
}

#[derive(Debug, Args)]
pub struct SceneRoleArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// `lockstep` (virtual time, deterministic) or `realtime` (the wall clock, late answers counted).
    #[arg(long, default_value = "lockstep")]
    pub clock: String,
    /// Scene seconds per wall-clock second (1: real time); 0 steps as fast as every participant
    /// answers.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub speed: f64,
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    #[command(flatten)]
    pub metrics: super::MetricsArgs,
}

#[derive(Debug, Args)]
pub struct SceneParticipantArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// This participant's id in the scene.
    #[arg(long)]
    pub participant: String,
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    #[command(flatten)]
    pub metrics: super::MetricsArgs,
}
