//! Scenario kinds, specs, seeded sampling, the feasibility filter and world building.

mod build;
pub mod cast;
mod feasibility;
mod kind;
mod sample;
mod spec;

pub use build::{HORIZON_S, build};
pub use feasibility::{Infeasible, check as check_feasible};
pub use kind::{ParamDef, ScenarioKind, UnknownKind};
pub use sample::{candidate_seed, sample};
pub use spec::{ScenarioSpec, SpecError};
