//! Mutation: a seeded neighbourhood search around a failing scenario (docs/method.md §8: failures
//! are "replayed, mutated (neighbourhood search around failures) and kept for regression").
//!
//! A child moves every parameter of its parent by a Gaussian step whose standard deviation is
//! `radius × (max − min)` of that parameter, clamped into the range, and gets a fresh episode
//! seed. Children go through the same feasibility filter as sampled candidates; an infeasible
//! draw is retried, a bounded number of times, so a parent on a physical border (e.g. braking
//! just under μ·g) still yields only physically possible children.

use super::{Infeasible, ScenarioSpec, SpecError, check_feasible};
use crate::rng::Rng;
use std::collections::BTreeMap;

/// Draws tried per child before giving up on a parent.
pub const MAX_MUTATION_TRIES: u32 = 16;

/// Why no child came out of a parent.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MutateError {
    #[error("mutation radius {0} is not a finite value in [0, 1]")]
    InvalidRadius(f64),
    #[error("the parent is not a valid spec: {0}")]
    InvalidParent(#[from] SpecError),
    #[error("no feasible child in {tries} tries; the last was rejected: {last}")]
    NoFeasibleChild { tries: u32, last: Infeasible },
}

impl MutateError {
    /// The infeasibility reason of the last rejected draw, for counting by reason code.
    pub fn infeasible(&self) -> Option<&Infeasible> {
        match self {
            MutateError::NoFeasibleChild { last, .. } => Some(last),
            _ => None,
        }
    }
}

/// A feasible child of `parent` within `radius` (a share of each parameter's range, in [0, 1]).
///
/// The child's parameters and seed come only from `rng`: the same parent and the same rng
/// state give the same child.
pub fn mutate(parent: &ScenarioSpec, radius: f64, rng: &mut Rng) -> Result<ScenarioSpec, MutateError> {
    if !(0.0..=1.0).contains(&radius) {
        return Err(MutateError::InvalidRadius(radius));
    }
    // Specs have public fields; check the parent so a hand-built one cannot reach `spec.get`.
    let parent = ScenarioSpec::new(parent.kind, parent.seed, parent.params.clone())?;
    let defs = parent.kind.params();
    let mut last = None;
    for _ in 0..MAX_MUTATION_TRIES {
        let params: BTreeMap<String, f64> = defs
            .iter()
            .map(|d| {
                let step = radius * (d.max - d.min) * rng.normal();
                (d.name.to_string(), (parent.get(d.name) + step).clamp(d.min, d.max))
            })
            .collect();
        let child = ScenarioSpec { kind: parent.kind, seed: rng.next_u64(), params };
        match check_feasible(&child) {
            Ok(()) => return Ok(child),
            Err(reason) => last = Some(reason),
        }
    }
    let last = last.expect("MAX_MUTATION_TRIES > 0, so at least one draw was rejected");
    Err(MutateError::NoFeasibleChild { tries: MAX_MUTATION_TRIES, last })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::{ScenarioKind, sample};

    fn mid_spec(kind: ScenarioKind, overrides: &[(&str, f64)]) -> ScenarioSpec {
        let mut params: BTreeMap<String, f64> =
            kind.params().iter().map(|d| (d.name.to_string(), 0.5 * (d.min + d.max))).collect();
        for (k, v) in overrides {
            params.insert(k.to_string(), *v);
        }
        ScenarioSpec::new(kind, 9, params).expect("test spec in range")
    }

    #[test]
    fn children_are_valid_in_range_and_seeded() {
        for kind in ScenarioKind::ALL {
            let parent = sample(3, kind, 0);
            let mut rng = Rng::new(11);
            for _ in 0..200 {
                // A large radius pushes many draws against the range ends: clamping must hold.
                let child = mutate(&parent, 0.5, &mut rng).expect("mid-space parents have feasible children");
                assert_eq!(ScenarioSpec::new(kind, child.seed, child.params.clone()).as_ref(), Ok(&child));
                assert_eq!(check_feasible(&child), Ok(()));
            }
            let a = mutate(&parent, 0.1, &mut Rng::new(5));
            assert_eq!(a, mutate(&parent, 0.1, &mut Rng::new(5)));
            assert_ne!(a, mutate(&parent, 0.1, &mut Rng::new(6)));
            assert_ne!(a.expect("feasible").seed, parent.seed);
        }
    }

    #[test]
    fn children_stay_near_the_parent() {
        // E|N(0, σ)| = σ·√(2/π): with σ = 0.05 of the range the mean step is ≈ 0.040 of the
        // range (slightly less where clamping bites; the mid-space parent keeps that rare).
        let kind = ScenarioKind::PedestrianCrossing; // every point feasible: no retry bias
        let parent = mid_spec(kind, &[]);
        let mut rng = Rng::new(21);
        let n = 2000;
        let mut share_sum = 0.0;
        for _ in 0..n {
            let child = mutate(&parent, 0.05, &mut rng).expect("always feasible");
            for d in kind.params() {
                share_sum += (child.get(d.name) - parent.get(d.name)).abs() / (d.max - d.min);
            }
        }
        let mean_share = share_sum / (n * kind.params().len()) as f64;
        let expected = 0.05 * (2.0 / std::f64::consts::PI).sqrt();
        assert!((mean_share - expected).abs() < 0.003, "mean |Δ|/range {mean_share}, expected {expected}");
    }

    #[test]
    fn a_parent_on_the_friction_border_yields_only_feasible_children() {
        // μ·g = 0.5 · 9.81 = 4.905 m/s²: braking at 4.8 m/s² is just feasible, and about half
        // of the draws around it brake harder than the tyres allow.
        let kind = ScenarioKind::EmergencyBraking;
        let parent = mid_spec(kind, &[("friction_mu", 0.5), ("braking_decel_mps2", 4.8)]);
        assert_eq!(check_feasible(&parent), Ok(()));
        let mut rng = Rng::new(4);
        let mut harder_than_parent = 0;
        for _ in 0..300 {
            let child = mutate(&parent, 0.05, &mut rng).expect("retries find a feasible child");
            assert_eq!(check_feasible(&child), Ok(()));
            if child.get("braking_decel_mps2") > parent.get("braking_decel_mps2") {
                harder_than_parent += 1;
            }
        }
        // Feasible children may still brake harder than the parent when μ moved up too.
        assert!(harder_than_parent > 0);
    }

    #[test]
    fn an_infeasible_neighbourhood_gives_up_with_the_reason() {
        let kind = ScenarioKind::EmergencyBraking;
        let parent = mid_spec(kind, &[("friction_mu", 0.2), ("braking_decel_mps2", 10.0)]);
        // Radius 0: every draw is the parent itself, which brakes at 10 > 0.2·g m/s².
        let err = mutate(&parent, 0.0, &mut Rng::new(1)).unwrap_err();
        assert!(matches!(err, MutateError::NoFeasibleChild { tries: MAX_MUTATION_TRIES, .. }));
        assert_eq!(err.infeasible().map(Infeasible::code), Some("braking-beyond-friction"));
        assert!(matches!(mutate(&parent, f64::NAN, &mut Rng::new(1)), Err(MutateError::InvalidRadius(_))));
        assert!(matches!(mutate(&parent, -0.1, &mut Rng::new(1)), Err(MutateError::InvalidRadius(_))));
        let mut broken = parent.clone();
        broken.params.remove("friction_mu");
        assert!(matches!(mutate(&broken, 0.1, &mut Rng::new(1)), Err(MutateError::InvalidParent(_))));
    }
}
