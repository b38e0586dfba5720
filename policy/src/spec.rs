//! How a driver is named wherever one is chosen (`--driver SPEC`; docs/driver-interface.md):
//! one parser and one message listing what is accepted.

use std::path::PathBuf;

/// A driver as the command line names it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DriverSpec {
    /// `idm`: the reference driver (IDM with MOBIL lane changes on what its sensor perceives).
    Reference,
    /// `replay`: a recording's own ego, played back (CommonRoad scenarios only).
    Replay,
    /// `PATH.safetensors`: a policy file as `risktwin train` writes it (ppo, ppo-gru, sac).
    PolicyFile(PathBuf),
}

/// What a driver SPEC may be.
pub const ACCEPTED: &str = "idm (the reference driver), replay (a recording's ego), PATH.safetensors (a policy file)";

/// A SPEC that names no driver.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown driver '{0}' (accepted: {ACCEPTED})")]
pub struct UnknownDriver(pub String);

impl std::str::FromStr for DriverSpec {
    type Err = UnknownDriver;

    fn from_str(spec: &str) -> Result<Self, Self::Err> {
        match spec {
            "idm" => Ok(DriverSpec::Reference),
            "replay" => Ok(DriverSpec::Replay),
            path if path.len() > ".safetensors".len() && path.ends_with(".safetensors") => {
                Ok(DriverSpec::PolicyFile(PathBuf::from(path)))
            }
            other => Err(UnknownDriver(other.to_owned())),
        }
    }
}

impl DriverSpec {
    /// The label outcomes are stored and printed under: `idm`, `replay`, or the file's path.
    pub fn label(&self) -> String {
        match self {
            DriverSpec::Reference => "idm".to_owned(),
            DriverSpec::Replay => "replay".to_owned(),
            DriverSpec::PolicyFile(path) => path.display().to_string(),
        }
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
        for bad in ["", "IDM", "ppo", ".safetensors", "model.onnx", "policy.safetensors.bak"] {
            let err = bad.parse::<DriverSpec>().expect_err(bad);
            assert_eq!(err.to_string(), format!("unknown driver '{bad}' (accepted: {ACCEPTED})"));
        }
        assert_eq!(DriverSpec::PolicyFile("a/p.safetensors".into()).label(), "a/p.safetensors");
    }
}
