//! Scenario kinds, specs, seeded sampling, the feasibility filter, mutation and world building.

mod build;
pub mod cast;
mod feasibility;
mod kind;
mod mutate;
mod sample;
mod spec;

pub use build::{HORIZON_S, build};
pub use feasibility::{Infeasible, check as check_feasible};
pub use kind::{ParamDef, ScenarioKind, UnknownKind};
pub use mutate::{MAX_MUTATION_TRIES, MutateError, mutate};
pub use sample::{candidate_seed, sample};
pub use spec::{ScenarioSpec, SpecError, content_id};
