//! `risktwin keys generate`: the cloud's policy-signing key pair, and reading key files for the
//! roles that sign (`push policy`, `cloud --signing-key`) or verify (`edge vehicle --trust-key`).

use super::input_file::read_text_bounded;
use crate::cli::KeysGenerateArgs;
use crate::error::{CliError, CliResult};
use crate::output::print_json;
use risktwin_policy::signature::{PolicySigningKey, PolicyVerifyingKey};
use std::io::Write;
use std::path::Path;

/// The signing key's file name in `--out DIR`.
pub const SIGNING_KEY_FILE: &str = "policy-signing.key";
/// The verifying key's file name in `--out DIR`.
pub const VERIFYING_KEY_FILE: &str = "policy-verifying.key";
/// A key file is two short lines; anything longer is not one.
const MAX_KEY_FILE_BYTES: u64 = 4096;

/// A fresh key from the operating system's random source.
pub fn fresh_signing_key() -> CliResult<PolicySigningKey> {
    let mut seed = [0u8; 32];
    getrandom::getrandom(&mut seed).map_err(|e| CliError::runtime(format!("no random source for a key: {e}")))?;
    Ok(PolicySigningKey::from_seed(seed))
}

pub fn generate(args: KeysGenerateArgs) -> CliResult {
    let signing = args.out.join(SIGNING_KEY_FILE);
    let verifying = args.out.join(VERIFYING_KEY_FILE);
    for path in [&signing, &verifying] {
        if path.exists() {
            return Err(CliError::input(format!("{} exists: keys are never overwritten", path.display())));
        }
    }
    std::fs::create_dir_all(&args.out)
        .map_err(|e| CliError::runtime(format!("cannot create {}: {e}", args.out.display())))?;
    let key = fresh_signing_key()?;
    write_new(&signing, &key.to_text(), 0o600)?;
    write_new(&verifying, &key.verifying_key().to_text(), 0o644)?;
    print_json(&serde_json::json!({
        "signing_key": signing.display().to_string(),
        "verifying_key": verifying.display().to_string(),
    }))
}

/// Writes `text` into a file that must not exist yet, readable per `mode`.
fn write_new(path: &Path, text: &str, mode: u32) -> CliResult {
    use std::os::unix::fs::OpenOptionsExt;
    let mut file = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(mode)
        .open(path)
        .map_err(|e| CliError::runtime(format!("cannot write {}: {e}", path.display())))?;
    file.write_all(text.as_bytes()).map_err(|e| CliError::runtime(format!("cannot write {}: {e}", path.display())))
}

/// A key file's text, bounded; every problem is an input error naming the flag and file.
fn read_key_text(flag: &str, path: &Path) -> CliResult<String> {
    read_text_bounded(path, MAX_KEY_FILE_BYTES, &format!("{flag} "))
}

/// The signing key of `--signing-key FILE`.
pub fn read_signing_key(path: &Path) -> CliResult<PolicySigningKey> {
    let text = read_key_text("--signing-key", path)?;
    PolicySigningKey::from_text(&text).map_err(|e| CliError::input(format!("--signing-key {}: {e}", path.display())))
}

/// The verifying key of `--trust-key FILE`.
pub fn read_trust_key(path: &Path) -> CliResult<PolicyVerifyingKey> {
    let text = read_key_text("--trust-key", path)?;
    PolicyVerifyingKey::from_text(&text).map_err(|e| CliError::input(format!("--trust-key {}: {e}", path.display())))
}
