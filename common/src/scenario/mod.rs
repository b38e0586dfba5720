//! Scenario kinds, specs, sampling, feasibility and world building.

mod kind;
mod spec;

pub use kind::{ParamDef, ScenarioKind, UnknownKind};
pub use spec::{ScenarioSpec, SpecError};
