//! Loading a scenario from `--spec FILE` or `--db FILE --id ID`, validated and feasible.

use super::input_file::{MAX_CONFIG_BYTES, read_text_bounded};
use crate::cli::ScenarioSource;
use crate::error::{CliError, CliResult};
use risktwin_common::scenario::{ScenarioKind, ScenarioSpec, check_feasible};
use risktwin_store::library::ScenarioLibrary;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::Path;

/// The spec file as written by a person: checked field by field before it becomes a spec.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SpecFile {
    kind: String,
    seed: u64,
    params: BTreeMap<String, f64>,
}

/// Reads and validates a spec file; every problem is an input error naming the file.
pub fn read_spec_file(path: &Path) -> CliResult<ScenarioSpec> {
    let shown = path.display();
    let text = read_text_bounded(path, MAX_CONFIG_BYTES, "spec ")?;
    let raw: SpecFile = serde_json::from_str(&text).map_err(|e| CliError::input(format!("spec {shown}: {e}")))?;
    let kind: ScenarioKind = raw.kind.parse().map_err(|e| CliError::input(format!("spec {shown}: {e}")))?;
    let spec =
        ScenarioSpec::new(kind, raw.seed, raw.params).map_err(|e| CliError::input(format!("spec {shown}: {e}")))?;
    check_feasible(&spec).map_err(|e| CliError::input(format!("spec {shown}: infeasible: {e}")))?;
    Ok(spec)
}

/// Opens a library database that must already exist (reading never creates one).
pub fn open_existing_library(path: &Path) -> CliResult<ScenarioLibrary> {
    Ok(ScenarioLibrary::open_existing(path)?)
}

/// The scenario a `--spec` or `--db/--id` pair names.
pub fn load(source: &ScenarioSource) -> CliResult<ScenarioSpec> {
    match (&source.spec, &source.db, &source.id) {
        (Some(path), None, None) => read_spec_file(path),
        (None, Some(db), Some(id)) => {
            let lib = open_existing_library(db)?;
            let stored = lib.get(id).map_err(CliError::input)?;
            stored.map(|s| s.spec).ok_or_else(|| CliError::input(format!("no scenario '{id}' in {}", db.display())))
        }
        _ => Err(CliError::input("give either --spec FILE or --db FILE --id ID")),
    }
}

/// `--kind KIND|all` → the kinds it names.
pub fn parse_kinds(kind: &str) -> CliResult<Vec<ScenarioKind>> {
    if kind == "all" {
        return Ok(ScenarioKind::ALL.to_vec());
    }
    kind.parse::<ScenarioKind>().map(|k| vec![k]).map_err(CliError::input)
}
