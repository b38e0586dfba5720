//! How a driver is named wherever one is chosen (`--driver SPEC`; docs/driver-interface.md):
//! one parser and one message listing what is accepted.

use crate::model::{ModelError, ModelFile, ModelFormat};
use std::path::{Path, PathBuf};

/// A driver as the command line names it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DriverSpec {
    /// `idm`: the reference driver (IDM with MOBIL lane changes on what its sensor perceives).
    Reference,
    /// `replay`: a recording's own ego, played back (CommonRoad scenarios only).
    Replay,
    /// `PATH.safetensors`: a policy file as `risktwin train` writes it (ppo, ppo-gru, sac).
    PolicyFile(PathBuf),
    /// `PATH.onnx`: an ONNX model of the driver interface (docs/driver-interface.md).
    Onnx(PathBuf),
}

/// The reference driver's SPEC and label.
pub const REFERENCE: &str = risktwin_common::driver::REFERENCE_LABEL;
/// A recording's own ego: SPEC and label.
pub const REPLAY: &str = risktwin_common::driver::REPLAY_LABEL;

/// Why `replay` cannot drive a generated scenario (it has no recording to play).
pub const REPLAY_OFF_RECORDING: &str =
    "replay plays a recording's ego as recorded; here the ego is driven closed loop: name idm or a model file";

/// What a driver SPEC may be.
pub const ACCEPTED: &str = "idm (the reference driver), replay (a recording's ego), PATH.safetensors (a policy file), PATH.onnx (an ONNX model)";

/// A SPEC that names no driver.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown driver '{0}' (accepted: {ACCEPTED})")]
pub struct UnknownDriver(pub String);

impl std::str::FromStr for DriverSpec {
    type Err = UnknownDriver;

    fn from_str(spec: &str) -> Result<Self, Self::Err> {
        let named = |suffix: &str| spec.len() > suffix.len() && spec.ends_with(suffix);
        match spec {
            REFERENCE => Ok(DriverSpec::Reference),
            REPLAY => Ok(DriverSpec::Replay),
            path if named(".safetensors") => Ok(DriverSpec::PolicyFile(PathBuf::from(path))),
            path if named(".onnx") => Ok(DriverSpec::Onnx(PathBuf::from(path))),
            other => Err(UnknownDriver(other.to_owned())),
        }
    }
}

/// The SPEC that parses back to this driver.
impl std::fmt::Display for DriverSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DriverSpec::Reference => f.write_str(REFERENCE),
            DriverSpec::Replay => f.write_str(REPLAY),
            DriverSpec::PolicyFile(path) | DriverSpec::Onnx(path) => write!(f, "{}", path.display()),
        }
    }
}

impl DriverSpec {
    /// The model file this driver is read from, and how (`None` for the built-in drivers).
    pub fn model_path(&self) -> Option<(&Path, ModelFormat)> {
        match self {
            DriverSpec::Reference | DriverSpec::Replay => None,
            DriverSpec::PolicyFile(path) => Some((path, ModelFormat::Safetensors)),
            DriverSpec::Onnx(path) => Some((path, ModelFormat::Onnx)),
        }
    }

    /// Reads and checks the driver's model file, if it has one.
    pub fn load(&self) -> Result<Option<ModelFile>, ModelError> {
        self.model_path().map(|(path, format)| ModelFile::load(path, format)).transpose()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_accepted_spec_parses_and_anything_else_is_named_with_the_list() {
        assert_eq!("idm".parse(), Ok(DriverSpec::Reference));
        assert_eq!("replay".parse(), Ok(DriverSpec::Replay));
        assert_eq!("out/policy.safetensors".parse(), Ok(DriverSpec::PolicyFile("out/policy.safetensors".into())));
        assert_eq!("model.onnx".parse(), Ok(DriverSpec::Onnx("model.onnx".into())));
        for bad in ["", "IDM", "ppo", ".safetensors", ".onnx", "model.ONNX", "policy.safetensors.bak", "external"] {
            let err = bad.parse::<DriverSpec>().expect_err(bad);
            assert_eq!(err.to_string(), format!("unknown driver '{bad}' (accepted: {ACCEPTED})"));
        }
        for spec in ["idm", "replay", "a/p.safetensors", "m.onnx"] {
            assert_eq!(spec.parse::<DriverSpec>().expect(spec).to_string(), spec, "SPEC round trips");
        }
    }
}
