//! How a deployment is named and run: its options, the tag and state folder of its topology
//! file, and the file's digest (the report carries it).

use risktwin_common::digest::fnv1a64;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// How a deployment is run.
#[derive(Debug, Clone)]
pub struct Options {
    /// The topology file, as given (for the report and the tag).
    pub file: PathBuf,
    /// Its text.
    pub text: String,
    /// Where hosts' logs, the status and the report go.
    pub out: PathBuf,
    /// Until a signal when `None`.
    pub duration: Option<Duration>,
    /// Seeds the links' jitter.
    pub seed: u64,
    /// The `risktwin` binary the processes run.
    pub exe: PathBuf,
    /// Loopback even where namespaces could be made.
    pub loopback: bool,
    /// Keep running after every edge process has ended.
    pub until_down: bool,
}

/// The tag of a topology file: its canonical path's digest, 6 hex digits (names of namespaces
/// and veths carry it; `deploy down FILE` finds them by it).
pub fn tag_of(file: &Path) -> String {
    let path = std::fs::canonicalize(file).unwrap_or_else(|_| file.to_path_buf());
    format!("{:06x}", fnv1a64(path.as_os_str().as_encoded_bytes().iter().copied()) & 0xff_ffff)
}

/// Where a deployment of `tag` keeps its lock, its supervisor's pid and where its output is.
pub fn state_dir(tag: &str) -> PathBuf {
    std::env::temp_dir().join(format!("{STATE_DIR_PREFIX}{tag}"))
}

/// A topology file's digest: FNV-1a of its bytes, 16 hex digits.
pub fn topology_digest(text: &[u8]) -> String {
    format!("{:016x}", fnv1a64(text.iter().copied()))
}

/// The start of a state folder's name; its tag follows.
pub const STATE_DIR_PREFIX: &str = "risktwin-deploy-";

/// Makes the state folder of `tag` (owner only), or checks that the one there is a folder of
/// this user's and not a link: its name is predictable, and root writes into it.
pub fn prepare_state_dir(tag: &str) -> std::io::Result<PathBuf> {
    use std::os::unix::fs::{DirBuilderExt, MetadataExt};
    let dir = state_dir(tag);
    match std::fs::DirBuilder::new().mode(0o700).create(&dir) {
        Ok(()) => return Ok(dir),
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
        Err(e) => return Err(e),
    }
    let meta = std::fs::symlink_metadata(&dir)?;
    // SAFETY: geteuid has no preconditions.
    if !meta.is_dir() || meta.uid() != unsafe { libc::geteuid() } || meta.mode() & 0o022 != 0 {
        let what = format!("{} is not a private folder of this user's: remove it", dir.display());
        return Err(std::io::Error::other(what));
    }
    Ok(dir)
}
