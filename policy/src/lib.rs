//! Plain-Rust policy networks for acting, without a tensor library: what an edge vehicle (or any
//! process without candle) needs to drive with a policy trained by the `learn` crate.
//!
//! - [`tanh`]: the fast tanh the networks use, shared with learning so both compute the same
//!   function.
//! - [`HostMlp`]: a tanh MLP evaluated row by row, allocation-free once its [`Scratch`] exists.
//! - [`HostGru`]: the recurrent policy's GRU cell, row by row.
//! - [`HostPolicy`]: a policy's deterministic action (feed-forward, or recurrent with its state
//!   in a [`Memory`]), read from a policy file
//!   (safetensors with metadata, the layout the `learn` crate saves; [`file`]) with every
//!   shape checked against [`OBS_DIM`](risktwin_common::env::OBS_DIM)/[`ACT_DIM`](risktwin_common::env::ACT_DIM),
//!   and turned into a [`risktwin_common::driver::Policy`] by [`model::DriverModel::driver`] through the
//!   training environment's own observation and action mapping ([`risktwin_common::env::ObsPolicy`]).
//! - [`signature`]: the cloud's ed25519 signature over a policy update, and the keys.
//! - [`model`]: a driver model read from a file (either format), and its label.
//! - [`onnx`]: ONNX models as drivers (tract), and a host policy written as one.
//! - [`spec`]: how a driver is named on the command line ([`spec::DriverSpec`]).
//!
//! A policy that does not fit is a typed [`NetError`], never a panic: the bytes may come off
//! the wire.

pub mod file;
mod gru;
mod mlp;
pub mod model;
pub mod onnx;
mod policy;
pub mod signature;
pub mod spec;
pub mod tanh;

pub use file::POLICY_FORMAT_VERSION;
#[cfg(test)]
use test_policy::random_policy;

#[cfg(test)]
mod test_policy;
pub use gru::{GruScratch, HostGru};
pub use mlp::{Dense, HostMlp, Scratch};
pub use policy::{BoxedActor, HostDriver, HostPolicy, Memory, PolicyKind};

/// Why a network or a policy file was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NetError {
    #[error("not a safetensors file: {0}")]
    Safetensors(String),
    #[error("policy file metadata lacks '{0}'")]
    MissingMetadata(&'static str),
    #[error("policy file format version '{found}', this build reads {expected}")]
    FormatVersion { found: String, expected: u32 },
    #[error("policy file has {name} = '{found}', this build uses {expected}")]
    Dimension { name: &'static str, found: String, expected: usize },
    #[error(
        "policy file decides at {found} Hz, this build's policies decide at {expected_hz} Hz (once per physics step)"
    )]
    DecisionRate { found: String, expected_hz: f64 },
    #[error("unknown algorithm '{0}' (a host policy is one of ppo, ppo-gru, sac)")]
    UnknownAlgo(String),
    #[error("'{0}' is recurrent: it is built with its GRU")]
    Recurrent(String),
    #[error("bad hidden sizes '{0}' (comma-separated positive integers)")]
    BadHidden(String),
    #[error("policy file lacks tensor '{0}'")]
    MissingTensor(String),
    #[error("tensor '{name}' has dtype {found}, expected F32")]
    Dtype { name: String, found: String },
    #[error("tensor '{name}' has shape {found:?}, expected {expected:?}")]
    TensorShape { name: String, expected: Vec<usize>, found: Vec<usize> },
    #[error("layer '{layer}' has {found} values, expected {expected}")]
    LayerSize { layer: String, found: usize, expected: usize },
    #[error("layer '{layer}' has a non-finite value at index {index}")]
    NonFinite { layer: String, index: usize },
    #[error("layer {layer} takes {n_in} inputs but the previous layer gives {previous_out}")]
    Chain { layer: usize, n_in: usize, previous_out: usize },
    #[error("a network needs at least one layer")]
    NoLayers,
    #[error("network maps {found_in} → {found_out}, a {kind} policy maps {expected_in} → {expected_out}")]
    PolicyShape { kind: &'static str, expected_in: usize, expected_out: usize, found_in: usize, found_out: usize },
}

impl NetError {
    /// A short stable name for counting refusals by reason.
    pub fn reason(&self) -> &'static str {
        match self {
            NetError::Safetensors(_) => "not-safetensors",
            NetError::MissingMetadata(_) | NetError::FormatVersion { .. } | NetError::BadHidden(_) => "bad-metadata",
            NetError::Dimension { .. } | NetError::PolicyShape { .. } | NetError::Chain { .. } => "wrong-dims",
            NetError::DecisionRate { .. } => "wrong-decision-rate",
            NetError::UnknownAlgo(_) | NetError::Recurrent(_) => "unsupported-algo",
            NetError::MissingTensor(_) => "missing-tensor",
            NetError::Dtype { .. } | NetError::TensorShape { .. } | NetError::LayerSize { .. } | NetError::NoLayers => {
                "bad-tensor"
            }
            NetError::NonFinite { .. } => "non-finite",
        }
    }
}
