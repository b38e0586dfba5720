//! `risktwin.Library`: a scenario library file's ranking, specs and stored outcomes, read
//! through the same store as the CLI (`scenarios rank`, `simulate --db --id`).

use crate::error::{bad_input, failed};
use crate::evaluate::{library_error, open_library};
use pyo3::prelude::*;
use risktwin_common::driver::REFERENCE_LABEL;
use risktwin_common::scenario::ScenarioKind;
use risktwin_store::library::{LibraryError, ScenarioLibrary};
use std::path::PathBuf;
use std::sync::Mutex;

/// An open library (the connection is not shared between threads, hence the lock).
#[pyclass(module = "risktwin._native")]
pub struct Library {
    library: Mutex<ScenarioLibrary>,
}

impl Library {
    fn with<T>(&self, f: impl FnOnce(&ScenarioLibrary) -> Result<T, LibraryError>) -> PyResult<T> {
        let library = self.library.lock().map_err(|_| failed("the library's lock was poisoned"))?;
        f(&library).map_err(library_error)
    }
}

#[pymethods]
impl Library {
    /// Opens the library at `path` (which must exist).
    #[new]
    fn new(path: PathBuf) -> PyResult<Self> {
        Ok(Self { library: Mutex::new(open_library(&path)?) })
    }

    /// The `top` riskiest generated scenarios (all when None), of one kind or all, by the
    /// latest outcome of the driver `label` (default the reference driver): `scenarios rank`'s
    /// items as JSON text.
    #[pyo3(signature = (top = None, *, kind = None, label = None))]
    fn rank(&self, top: Option<usize>, kind: Option<&str>, label: Option<&str>) -> PyResult<String> {
        let kind = kind.map(str::parse::<ScenarioKind>).transpose().map_err(bad_input)?;
        let label = label.unwrap_or(REFERENCE_LABEL);
        let ranked = self.with(|lib| lib.rank_for_policy(label, top, kind))?;
        serde_json::to_string(&ranked).map_err(failed)
    }

    /// The scenario `id` as JSON text: its spec (the `--spec` file format), origin, lineage
    /// and every stored outcome (driver label, metrics, risk terms) in insertion order.
    fn scenario(&self, id: &str) -> PyResult<String> {
        let stored = self.with(|lib| lib.get(id))?.ok_or_else(|| bad_input(format!("unknown scenario '{id}'")))?;
        let outcomes: Vec<serde_json::Value> = stored
            .outcomes
            .iter()
            .map(|o| serde_json::json!({"label": o.policy, "metrics": o.metrics, "risk": o.risk}))
            .collect();
        let doc = serde_json::json!({
            "id": stored.id,
            "spec": stored.spec,
            "origin": stored.origin.as_str(),
            "parent_id": stored.parent_id,
            "generation": stored.generation,
            "outcomes": outcomes,
        });
        Ok(doc.to_string())
    }
}
