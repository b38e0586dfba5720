//! `risktwin._native`: the Rust half of the Python package (python/risktwin/ is the other).
//!
//! - [`env`]: the training environment's vector of driving environments (`VecEnv`), which
//!   the Gymnasium environments of `risktwin.envs` wrap.
//! - [`evaluate`]: any driver SPEC or a Python callable over the held-out set or a library,
//!   giving `risktwin evaluate`'s document.
//! - [`library`]: a scenario library's ranking, specs and stored outcomes.
//!
//! Documents cross as JSON text (`serde_json`), which the Python side loads: the numbers are
//! exactly those the CLI prints. Bad input raises `ValueError`, a failure of the run
//! `RiskTwinError`, both with the Rust message; the twin steps with the GIL released.

mod env;
mod error;
mod evaluate;
mod library;

use error::RiskTwinError;
use pyo3::prelude::*;

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    use risktwin_common::env::{ACT_DIM, OBS_DIM, OBSERVATION_VERSION};
    use risktwin_common::world::{DECISION_RATE_HZ, STEP_S};
    m.add("RiskTwinError", m.py().get_type::<RiskTwinError>())?;
    m.add("OBS_DIM", OBS_DIM)?;
    m.add("ACT_DIM", ACT_DIM)?;
    m.add("MAX_ENVS", env::MAX_ENVS)?;
    m.add("OBSERVATION_VERSION", OBSERVATION_VERSION)?;
    m.add("DECISION_RATE_HZ", DECISION_RATE_HZ)?;
    m.add("STEP_S", STEP_S)?;
    m.add("KINDS", risktwin_common::scenario::ScenarioKind::ALL.map(|k| k.name()).to_vec())?;
    m.add("VARIANTS", risktwin_common::env::Variant::ALL.map(|v| v.name()).to_vec())?;
    m.add_class::<env::VecEnv>()?;
    m.add_function(wrap_pyfunction!(env::native_steps_per_s, m)?)?;
    m.add_function(wrap_pyfunction!(env::native_rollout, m)?)?;
    m.add_class::<library::Library>()?;
    m.add_function(wrap_pyfunction!(evaluate::evaluate, m)?)?;
    Ok(())
}
