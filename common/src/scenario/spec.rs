//! A scenario spec: kind, seed and a complete, in-range parameter set.

use super::kind::{ScenarioKind, UnknownKind};
use crate::digest::fnv1a64;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// A validated scenario description (the `--spec` file format of docs/cli.md).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScenarioSpec {
    pub kind: ScenarioKind,
    pub seed: u64,
    /// Every parameter of the kind, by name (ordered, so serialisation is deterministic).
    pub params: BTreeMap<String, f64>,
}

/// Why a spec is not acceptable.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SpecError {
    #[error(transparent)]
    UnknownKind(#[from] UnknownKind),
    #[error("unknown parameter '{name}' for kind {kind}")]
    UnknownParam { kind: ScenarioKind, name: String },
    #[error("missing parameter '{name}' for kind {kind}")]
    MissingParam { kind: ScenarioKind, name: &'static str },
    #[error("parameter '{name}' = {value} is out of range [{min}, {max}]")]
    ParamOutOfRange { name: String, value: f64, min: f64, max: f64 },
}

impl ScenarioSpec {
    /// Checks names, completeness, finiteness and ranges.
    pub fn new(kind: ScenarioKind, seed: u64, params: BTreeMap<String, f64>) -> Result<Self, SpecError> {
        for name in params.keys() {
            if kind.param(name).is_none() {
                return Err(SpecError::UnknownParam { kind, name: name.clone() });
            }
        }
        for def in kind.params() {
            let value = *params.get(def.name).ok_or(SpecError::MissingParam { kind, name: def.name })?;
            if !(value >= def.min && value <= def.max) {
                return Err(SpecError::ParamOutOfRange {
                    name: def.name.to_string(),
                    value,
                    min: def.min,
                    max: def.max,
                });
            }
        }
        Ok(Self { kind, seed, params })
    }

    /// A parameter of this spec. Every parameter of the kind is present after validation.
    pub fn get(&self, name: &str) -> f64 {
        *self.params.get(name).expect("validated specs hold every parameter of their kind")
    }
}

/// The stable content id of a spec: FNV-1a over kind, seed and the exact parameter bits, in hex.
///
/// Same kind, seed and parameters give the same id on every machine, so storing a scenario
/// twice yields one row. −0.0 and +0.0 count as the same value.
pub fn content_id(spec: &ScenarioSpec) -> String {
    let mut bytes = Vec::with_capacity(32 + 40 * spec.params.len());
    bytes.extend_from_slice(spec.kind.name().as_bytes());
    bytes.push(0);
    bytes.extend_from_slice(&spec.seed.to_le_bytes());
    for (name, value) in &spec.params {
        bytes.extend_from_slice(name.as_bytes());
        bytes.push(0);
        let canonical = if *value == 0.0 { 0.0f64 } else { *value };
        bytes.extend_from_slice(&canonical.to_bits().to_le_bytes());
    }
    format!("{:016x}", fnv1a64(bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(kind: ScenarioKind) -> BTreeMap<String, f64> {
        kind.params().iter().map(|d| (d.name.to_string(), 0.5 * (d.min + d.max))).collect()
    }

    #[test]
    fn validation_names_the_problem() {
        let k = ScenarioKind::EmergencyBraking;
        assert!(ScenarioSpec::new(k, 1, params(k)).is_ok());
        let mut p = params(k);
        p.remove("friction_mu");
        assert_eq!(ScenarioSpec::new(k, 1, p), Err(SpecError::MissingParam { kind: k, name: "friction_mu" }));
        let mut p = params(k);
        p.insert("friction_mu".into(), 3.0);
        assert!(matches!(ScenarioSpec::new(k, 1, p), Err(SpecError::ParamOutOfRange { .. })));
        let mut p = params(k);
        p.insert("friction_mu".into(), f64::NAN);
        assert!(matches!(ScenarioSpec::new(k, 1, p), Err(SpecError::ParamOutOfRange { .. })));
        let mut p = params(k);
        p.insert("bogus".into(), 1.0);
        assert!(matches!(ScenarioSpec::new(k, 1, p), Err(SpecError::UnknownParam { .. })));
        assert!("cut-in".parse::<ScenarioKind>().is_ok());
        assert!("cutin".parse::<ScenarioKind>().is_err());
    }
}
