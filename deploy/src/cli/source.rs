//! Where a scenario comes from, shared by the commands that take one (`simulate`,
//! `risk-field`, `push scenario`).

use clap::Args;
use std::path::PathBuf;

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
