//! A driver model read from a file — a policy file (`.safetensors`) or an ONNX model
//! (`.onnx`) — checked in full at load, and the label its outcomes are stored under.

use super::onnx::{OnnxError, OnnxPolicy};
use super::{BoxedActor, HostDriver, HostPolicy, NetError};
use risktwin_common::env::ObsPolicy;
use sha2::{Digest, Sha256};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The largest model file read, bytes: far above any driving policy (a 256×256 MLP is under
/// 1 MiB), low enough that a wrong path (a disk image, a log) is refused before it is read.
pub const MAX_MODEL_BYTES: u64 = 512 << 20;

/// Hex digits of the file's SHA-256 in its label: 48 bits, so two different files under
/// one name do not share a label.
const LABEL_DIGEST_HEX: usize = 12;

/// How a model file is read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelFormat {
    /// A policy file as `risktwin train` writes it.
    Safetensors,
    /// An ONNX model.
    Onnx,
}

/// A loaded driver model.
#[derive(Debug, Clone)]
pub enum DriverModel {
    Native(Arc<HostPolicy>),
    Onnx(Arc<OnnxPolicy>),
}

/// Why a model file was refused.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    #[error("driver {path}: {error}")]
    Read { path: PathBuf, error: std::io::Error },
    #[error("driver {path}: more than the {MAX_MODEL_BYTES} bytes a driver model may be")]
    TooLarge { path: PathBuf },
    #[error("driver {path}: {error}")]
    Policy { path: PathBuf, error: NetError },
    #[error("driver {path}: {error}")]
    Onnx { path: PathBuf, error: OnnxError },
}

/// A model file, loaded: the model, where it came from, and its content's digest.
#[derive(Debug, Clone)]
pub struct ModelFile {
    pub model: DriverModel,
    pub path: PathBuf,
    /// SHA-256 of the file, hex.
    pub sha256: String,
}

impl ModelFile {
    /// Reads and checks the model at `path` (every field, tensor and, for ONNX, the probe).
    pub fn load(path: &Path, format: ModelFormat) -> Result<Self, ModelError> {
        let read = |error| ModelError::Read { path: path.to_owned(), error };
        let data = read_capped(path, MAX_MODEL_BYTES)
            .map_err(read)?
            .ok_or_else(|| ModelError::TooLarge { path: path.to_owned() })?;
        let sha256 = Sha256::digest(&data).iter().map(|b| format!("{b:02x}")).collect();
        let model = match format {
            ModelFormat::Safetensors => DriverModel::Native(Arc::new(
                HostPolicy::from_safetensors(&data)
                    .map_err(|error| ModelError::Policy { path: path.to_owned(), error })?,
            )),
            ModelFormat::Onnx => DriverModel::Onnx(Arc::new(
                OnnxPolicy::from_bytes(&data).map_err(|error| ModelError::Onnx { path: path.to_owned(), error })?,
            )),
        };
        Ok(Self { model, path: path.to_owned(), sha256 })
    }

    /// The label outcomes are stored under: the path and the start of the digest
    /// (`out/policy.onnx@3f2a…`), so two files of one name never mix.
    pub fn label(&self) -> String {
        format!("{}{}", self.path.display(), self.label_suffix())
    }

    /// The end of the label that names the content whatever the path: `@` and the digest's start.
    pub fn label_suffix(&self) -> String {
        format!("@{}", &self.sha256[..LABEL_DIGEST_HEX])
    }
}

/// The file's bytes, or `None` past `max_bytes`. Reads at most one byte past the cap
/// whatever the file is (a FIFO, a link to /dev/zero): its metadata's length cannot be
/// trusted to bound the read.
fn read_capped(path: &Path, max_bytes: u64) -> std::io::Result<Option<Vec<u8>>> {
    let file = std::fs::File::open(path)?;
    let meta = file.metadata()?;
    if meta.is_file() && meta.len() > max_bytes {
        return Ok(None); // a regular file says its length: refused unread
    }
    let mut data = Vec::new();
    file.take(max_bytes + 1).read_to_end(&mut data)?;
    Ok((data.len() as u64 <= max_bytes).then_some(data))
}

impl DriverModel {
    /// An observation → action function with a fresh memory (one per episode).
    pub fn actor(&self) -> BoxedActor {
        match self {
            DriverModel::Native(policy) => Arc::clone(policy).actor(),
            DriverModel::Onnx(model) => model.actor(),
        }
    }

    /// A driver for a world with this desired speed and step, through the training
    /// environment's observation and action mapping.
    pub fn driver(&self, desired_speed_mps: f64, dt_s: f64) -> HostDriver {
        ObsPolicy::new(self.actor(), desired_speed_mps, dt_s)
    }

    /// What the load found worth a warning.
    pub fn warnings(&self) -> &[String] {
        match self {
            DriverModel::Native(_) => &[],
            DriverModel::Onnx(model) => model.warnings(),
        }
    }

    /// Decisions so far that failed or were not finite and were driven as the zero action
    /// (ONNX models; a native policy's weights are finite and it cannot fail).
    pub fn faults(&self) -> u64 {
        match self {
            DriverModel::Native(_) => 0,
            DriverModel::Onnx(model) => model.faults(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_read_stops_one_byte_past_the_cap_whatever_the_file_claims_to_be() {
        // /dev/zero's metadata says 0 bytes and a read of it never ends.
        assert_eq!(read_capped(Path::new("/dev/zero"), 1024).unwrap(), None);
        let file = std::env::temp_dir().join(format!("risktwin-read-capped-{}.onnx", std::process::id()));
        std::fs::write(&file, [7u8; 1024]).unwrap();
        let (whole, over) = (read_capped(&file, 1024), read_capped(&file, 1023));
        std::fs::remove_file(&file).unwrap();
        assert_eq!(whole.unwrap().unwrap().len(), 1024);
        assert_eq!(over.unwrap(), None);
    }
}
