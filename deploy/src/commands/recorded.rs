//! A CommonRoad scenario named on the command line: a file (`--commonroad FILE [--ego ID]`) or a
//! recorded case of a library (`--db FILE --id ID`). Both are the same XML parsed the same way,
//! so `simulate` and `risk-field` print the same bytes for either.

use super::input_file::read_text_bounded;
use super::source::open_existing_library;
use crate::cli::ScenarioSource;
use crate::error::{CliError, CliResult};
use risktwin_commonroad::limits::MAX_XML_BYTES;
use risktwin_commonroad::{Scenario, parse_scenario};
use risktwin_store::library::ScenarioLibrary;
use std::path::Path;

/// A parsed CommonRoad scenario, its ego and where it came from.
#[derive(Debug)]
pub struct CommonRoadInput {
    pub scenario: Scenario,
    /// The ego asked for, the stored one, or the scenario's default.
    pub ego_id: Option<u64>,
    /// How errors name it: the file, or `DB case ID`.
    pub shown: String,
    /// The library and case id it was read from (policy runs store their outcome there).
    pub case: Option<(ScenarioLibrary, String)>,
}

impl CommonRoadInput {
    /// The scenario of `text` read from `shown`, with `ego` or the scenario's default ego.
    pub fn parse(text: &str, shown: String, ego: Option<u64>) -> CliResult<Self> {
        let scenario = parse_scenario(text).map_err(|e| CliError::input(format!("{shown}: {e}")))?;
        let ego_id = ego.or_else(|| scenario.default_ego_id());
        Ok(Self { scenario, ego_id, shown, case: None })
    }
}

/// Reads a whole CommonRoad file as text, refusing one over [`MAX_XML_BYTES`] before reading
/// it (and reading no more than that from a file that grows or never ends, such as a FIFO).
pub fn read_xml(path: &Path) -> CliResult<String> {
    read_text_bounded(path, MAX_XML_BYTES as u64, "")
}

/// Reads and parses a CommonRoad file; every problem is an input error naming the file.
pub fn read_commonroad(path: &Path) -> CliResult<Scenario> {
    let text = read_xml(path)?;
    parse_scenario(&text).map_err(|e| CliError::input(format!("{}: {e}", path.display())))
}

/// The CommonRoad scenario `source` names: `--commonroad FILE`, or `--db/--id` of a recorded case;
/// `None` for a spec file or a generated scenario.
pub fn commonroad_input(source: &ScenarioSource) -> CliResult<Option<CommonRoadInput>> {
    if let Some(path) = &source.commonroad {
        let scenario = read_commonroad(path)?;
        let ego_id = source.ego.or_else(|| scenario.default_ego_id());
        return Ok(Some(CommonRoadInput { scenario, ego_id, shown: path.display().to_string(), case: None }));
    }
    let (Some(db), Some(id)) = (&source.db, &source.id) else {
        return Ok(None);
    };
    let library = open_existing_library(db)?;
    let Some(stored) = library.recorded(id).map_err(CliError::input)? else {
        return Ok(None);
    };
    let shown = format!("{} case {id}", db.display());
    if let Some(ego) = source.ego.filter(|&ego| ego != stored.case.ego_id) {
        return Err(CliError::input(format!(
            "{shown}: the case's ego is {}, not {ego} (import the file again with --ego {ego} for that case)",
            stored.case.ego_id
        )));
    }
    let scenario = parse_scenario(&stored.case.xml)
        .map_err(|e| CliError::input(format!("{shown}: the stored CommonRoad XML does not parse: {e}")))?;
    Ok(Some(CommonRoadInput { scenario, ego_id: Some(stored.case.ego_id), shown, case: Some((library, stored.id)) }))
}
