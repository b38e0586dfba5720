//! A `--driver SPEC` made ready to drive generated scenarios: its model file read and checked
//! before any episode, its warnings on stderr, and the label its outcomes go under.

use crate::error::{CliError, CliResult};
use risktwin_cloud::trainer::drive::Driver;
use risktwin_common::telemetry::PolicyRef;
use risktwin_edge::scene::ActivePolicy;
use risktwin_policy::model::{DriverModel, ModelFile};
use risktwin_policy::spec::{self, DriverSpec};

/// A driver of generated scenarios.
pub struct LoadedDriver {
    /// `idm`, or the model file's label (path and digest).
    pub label: String,
    /// The model (`None`: the reference driver).
    pub model: Option<ModelFile>,
}

impl LoadedDriver {
    /// Loads `spec`; `flag` names the option in the message for `replay`, which plays a
    /// recording's ego and has nothing to drive a generated scenario with.
    pub fn load(spec: &DriverSpec, flag: &str) -> CliResult<Self> {
        let loaded = Self::quietly(spec, flag)?;
        if let Some(m) = &loaded.model {
            warn_model(&m.path.display().to_string(), &m.model);
        }
        Ok(loaded)
    }

    /// [`Self::load`] without the load's warnings (for a process that does not drive it).
    pub fn quietly(spec: &DriverSpec, flag: &str) -> CliResult<Self> {
        if *spec == DriverSpec::Replay {
            return Err(CliError::input(format!("{flag} {}", spec::REPLAY_OFF_RECORDING)));
        }
        let model = spec.load().map_err(CliError::input)?;
        let label = model.as_ref().map_or_else(|| spec::REFERENCE.to_owned(), ModelFile::label);
        Ok(Self { label, model })
    }

    /// The driver to evaluate with.
    pub fn driver(&self) -> Driver<'_> {
        self.model.as_ref().map_or(Driver::Reference, |m| Driver::Model(&m.model))
    }

    /// The driver as an edge vehicle holds one (`None`: the reference driver): labelled, version 0.
    pub fn active(self) -> Option<ActivePolicy> {
        let label = self.label;
        self.model.map(|file| ActivePolicy { id: PolicyRef { policy_id: label, version: 0 }, model: file.model })
    }

    /// Says the model's faults on stderr ([`warn_faults`]).
    pub fn warn_faults(&self) {
        if let Some(m) = &self.model {
            warn_faults(&self.label, &m.model);
        }
    }
}

/// Decisions `model` failed to give and that were driven as the zero action (module
/// `risktwin_policy::onnx`), said on stderr when there were any: they change what was measured.
pub fn warn_faults(label: &str, model: &DriverModel) {
    let faults = model.faults();
    if faults > 0 {
        eprintln!("warning: driver {label}: {faults} decisions failed or were not finite (driven as the zero action)");
    }
}

/// The driver's model file, if it has one, checked in full; its warnings on stderr.
pub fn load_model(spec: &DriverSpec) -> CliResult<Option<ModelFile>> {
    let model = spec.load().map_err(CliError::input)?;
    if let Some(m) = &model {
        warn_model(&m.path.display().to_string(), &m.model);
    }
    Ok(model)
}

/// What the load of `model` found worth a warning (an ONNX model without its metadata), on
/// stderr.
pub fn warn_model(shown: &str, model: &DriverModel) {
    for warning in model.warnings() {
        eprintln!("warning: driver {shown}: {warning}");
    }
}
