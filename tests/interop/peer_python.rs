//! A Python with the reference packages, made on first use: a virtualenv under the target
//! directory (or $RISKTWIN_PEER_VENV), shared by every test and reused across runs. Creating it
//! needs `python3` and the PyPI registry; without them the test fails and says why.

use crate::peer_cache;
use std::path::PathBuf;
use std::process::Command;

/// The venv's python, with `packages` (pip requirement strings) installed.
pub fn python(packages: &[&str]) -> PathBuf {
    let dir = peer_cache::folder("RISKTWIN_PEER_VENV", "peer-venv");
    let python = dir.join("bin").join("python");
    peer_cache::installing(&dir, || ensure(&dir, &python, packages));
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
