//! The grammar of `risktwin push scenario|policy`: one cloud→edge push.

use super::roles::ZenohArgs;
use super::source::ScenarioSource;
use clap::{Args, Subcommand};
use std::path::PathBuf;

#[derive(Debug, Subcommand)]
pub enum PushCommand {
    /// Run a scenario on an edge vehicle and print its outcome.
    Scenario(PushScenarioArgs),
    /// Send new policy weights to an edge vehicle.
    Policy(PushPolicyArgs),
}

/// Which edge, and how to reach it.
#[derive(Debug, Args)]
pub struct PushTo {
    /// The edge's id (`risktwin edge vehicle --id ID`).
    #[arg(long = "to", value_name = "ID")]
    pub to: String,
    #[arg(long, default_value = "default")]
    pub site: String,
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    /// Seconds to wait for the edge to come up (its liveliness token and push subscriber).
    #[arg(long, default_value_t = 10.0)]
    pub wait_for_edge_s: f64,
}

#[derive(Debug, Args)]
pub struct PushScenarioArgs {
    #[command(flatten)]
    pub source: ScenarioSource,
    #[command(flatten)]
    pub to: PushTo,
    /// Seconds to wait for the edge's result (a pushed episode plays in real time: up to ~30 s).
    #[arg(long, default_value_t = 60.0)]
    pub wait_for_result_s: f64,
}

#[derive(Debug, Args)]
pub struct PushPolicyArgs {
    /// The weights as a safetensors file.
    #[arg(long)]
    pub weights: PathBuf,
    #[arg(long)]
    pub policy_id: String,
    /// Must exceed the version the edge holds for this policy id.
    #[arg(long)]
    pub version: u32,
    /// `ppo` or `sac`.
    #[arg(long)]
    pub algo: String,
    /// The cloud's signing key (`risktwin keys generate`), required: the update is signed for
    /// the target vehicle, which refuses unsigned ones.
    #[arg(long)]
    pub signing_key: Option<PathBuf>,
    #[command(flatten)]
    pub to: PushTo,
}
