//! Where the tests' outside peers (a Python virtualenv, npm packages) are installed: a folder
//! under the target directory, or the one an environment variable names, shared by every test
//! and reused across runs; and one installer at a time across test processes.

use std::path::{Path, PathBuf};

/// `$env_var` when set, else `<target>/<name>`.
pub fn folder(env_var: &str, name: &str) -> PathBuf {
    if let Some(dir) = std::env::var_os(env_var) {
        return PathBuf::from(dir);
    }
    // The test executable lives in <target>/<profile>/deps/.
    let exe = std::env::current_exe().expect("test executable path");
    let target = exe.ancestors().nth(3).expect("target directory").to_path_buf();
    target.join(name)
}

/// Runs `install` into `dir` while holding its lock directory (other test processes wait); a
/// failed install panics after letting go of the lock.
pub fn installing<T>(dir: &Path, install: impl FnOnce() -> T + std::panic::UnwindSafe) -> T {
    let lock = dir.with_extension("lock");
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(600);
    while std::fs::create_dir(&lock).is_err() {
        assert!(std::time::Instant::now() < deadline, "timed out waiting for {}", lock.display());
        std::thread::sleep(std::time::Duration::from_millis(200));
    }
    let result = std::panic::catch_unwind(install);
    let _ = std::fs::remove_dir(&lock);
    result.unwrap_or_else(|e| std::panic::resume_unwind(e))
}
