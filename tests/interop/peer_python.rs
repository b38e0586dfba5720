//! A Python with the reference packages, made on first use: a virtualenv under the target
//! directory (or $RISKTWIN_PEER_VENV), shared by every test and reused across runs. Creating it
//! needs `python3` and the PyPI registry; without them the test fails and says why.

use std::path::PathBuf;
use std::process::Command;

fn venv_dir() -> PathBuf {
    if let Some(dir) = std::env::var_os("RISKTWIN_PEER_VENV") {
        return PathBuf::from(dir);
    }
    // The test executable lives in <target>/<profile>/deps/.
    let exe = std::env::current_exe().expect("test executable path");
    let target = exe.ancestors().nth(3).expect("target directory").to_path_buf();
    target.join("peer-venv")
}

/// The venv's python, with `packages` (pip requirement strings) installed.
pub fn python(packages: &[&str]) -> PathBuf {
    let dir = venv_dir();
    let python = dir.join("bin").join("python");
    // One creator at a time: tests in other processes wait on the lock directory.
    let lock = dir.with_extension("lock");
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(600);
    while std::fs::create_dir(&lock).is_err() {
        assert!(std::time::Instant::now() < deadline, "timed out waiting for {}", lock.display());
        std::thread::sleep(std::time::Duration::from_millis(200));
    }
    let result = std::panic::catch_unwind(|| ensure(&dir, &python, packages));
    let _ = std::fs::remove_dir(&lock);
    if let Err(e) = result {
        std::panic::resume_unwind(e);
    }
    python
}

fn ensure(dir: &PathBuf, python: &PathBuf, packages: &[&str]) {
    if !python.exists() {
        let status = Command::new("python3").args(["-m", "venv"]).arg(dir).status().expect("python3 is installed");
        assert!(status.success(), "python3 -m venv {} failed", dir.display());
    }
    let missing: Vec<&str> = packages.iter().copied().filter(|p| !installed(python, p)).collect();
    if !missing.is_empty() {
        let status =
            Command::new(python).args(["-m", "pip", "install", "-q"]).args(&missing).status().expect("pip runs");
        assert!(status.success(), "pip install {missing:?} failed");
    }
}

/// `pip show` knows a requirement like `name==1.2.3` by its name and version.
fn installed(python: &PathBuf, requirement: &str) -> bool {
    let (name, version) = requirement.split_once("==").unwrap_or((requirement, ""));
    let Ok(out) = Command::new(python).args(["-m", "pip", "show", name]).output() else { return false };
    out.status.success()
        && (version.is_empty() || String::from_utf8_lossy(&out.stdout).contains(&format!("Version: {version}")))
}
