//! `risktwin deploy …`: emulated multi-machine deployments from a topology file
//! (docs/topology.md).

use clap::{Args, Subcommand};
use std::path::PathBuf;

#[derive(Debug, Subcommand)]
pub enum DeployCommand {
    /// Starts the deployment in the background and prints its status once it is up.
    Up(DeployUpArgs),
    /// Prints the status of the deployment of FILE (JSON).
    Status(DeployFileArgs),
    /// Stops the deployment of FILE and removes every namespace, veth and process it made
    /// (also after a crash; nothing up is not an error).
    Down(DeployFileArgs),
    /// Runs the deployment in the foreground until `--for` is over, every edge process has
    /// ended or a signal comes; writes hosts' logs and the report into `--out` and prints it.
    Run(DeployRunArgs),
}

#[derive(Debug, Args)]
pub struct DeployFileArgs {
    /// The topology file (TOML).
    pub file: PathBuf,
}

#[derive(Debug, Args)]
pub struct DeployUpArgs {
    /// The topology file (TOML).
    pub file: PathBuf,
    /// Hosts' logs, the status and, after `down`, the report (default: a folder in the
    /// system's temporary directory, printed).
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub how: DeployHow,
}

#[derive(Debug, Args)]
pub struct DeployRunArgs {
    /// The topology file (TOML).
    pub file: PathBuf,
    /// How long: `90s`, `500ms`, `2m` or seconds.
    #[arg(long = "for", value_name = "DURATION")]
    pub duration: Option<String>,
    /// Hosts' logs, the status and the report.
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub how: DeployHow,
    /// Keep running after every edge process has ended (`deploy up` runs this way).
    #[arg(long, hide = true)]
    pub until_down: bool,
}

#[derive(Debug, Args)]
pub struct DeployHow {
    /// Seeds the links' jitter.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Run every machine on loopback even where network namespaces could be made.
    #[arg(long)]
    pub loopback: bool,
}
