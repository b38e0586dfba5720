//! The held-out evaluation set: feasible scenarios of all five kinds from a seed stream of its
//! own, never trained on. Disjoint by construction (no other part of the loop samples from this
//! stream) and checked: [`HeldOut::check_disjoint`] refuses any training or library spec whose
//! content id is in the set.

use super::plan::TrainerError;
use risktwin_common::rng::Rng;
use risktwin_common::scenario::{ScenarioKind, ScenarioSpec, check_feasible, sample};
use risktwin_store::library::content_id;
use std::collections::BTreeSet;

/// Stream tag of the held-out sampler ("HELDOUT" in ASCII), distinct from generation's run seed
/// and from every training stream.
const HELD_OUT_STREAM: u64 = 0x48_454C_444F_5554;

/// Candidates tried per wanted spec before giving up on a kind (kinds are mostly feasible).
const MAX_TRIES_PER_SPEC: u64 = 50;

/// The held-out scenarios and their content ids.
#[derive(Debug, Clone, PartialEq)]
pub struct HeldOut {
    pub specs: Vec<ScenarioSpec>,
    ids: BTreeSet<String>,
}

impl HeldOut {
    /// `per_kind` feasible specs of each kind (kinds in [`ScenarioKind::ALL`] order) for `run_seed`.
    pub fn new(run_seed: u64, per_kind: usize) -> Self {
        let stream_seed = Rng::derive(run_seed, HELD_OUT_STREAM).next_u64();
        let specs: Vec<ScenarioSpec> = ScenarioKind::ALL
            .iter()
            .flat_map(|&kind| {
                (0..MAX_TRIES_PER_SPEC * per_kind as u64)
                    .map(move |i| sample(stream_seed, kind, i))
                    .filter(|s| check_feasible(s).is_ok())
                    .take(per_kind)
            })
            .collect();
        let ids = specs.iter().map(content_id).collect();
        Self { specs, ids }
    }

    /// Whether the spec is in the held-out set.
    pub fn contains(&self, spec: &ScenarioSpec) -> bool {
        self.ids.contains(&content_id(spec))
    }

    /// Fails with the first spec of `specs` that is in the held-out set.
    pub fn check_disjoint<'a>(&self, specs: impl IntoIterator<Item = &'a ScenarioSpec>) -> Result<(), TrainerError> {
        match specs.into_iter().find(|s| self.contains(s)) {
            Some(s) => Err(TrainerError::HeldOutLeak(content_id(s))),
            None => Ok(()),
        }
    }
}
