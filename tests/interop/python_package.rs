//! The Python package (python/, docs/python.md) as a user installs it: one `pip install` of
//! the checkout into a throwaway virtualenv (maturin from PyPI builds the extension with the
//! workspace's release profile into its target directory), then its own tests (python/tests:
//! Gymnasium's env checker, seeded resets, the vector env, evaluation against this build's
//! `risktwin evaluate`). Fails, never skips, when Python or PyPI is not there.

use std::path::Path;
use std::process::Command;

/// Outside packages the tests use, pinned (the package's own: numpy, gymnasium).
const TEST_PACKAGES: [&str; 3] = ["pytest==9.2.0", "onnx==1.23.2", "gymnasium==1.4.0"];

#[test]
fn the_python_package_installs_from_the_checkout_and_passes_its_tests() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("the workspace root");
    let venv = tempfile::tempdir().expect("a temporary directory");
    let status = Command::new("python3").args(["-m", "venv"]).arg(venv.path()).status().expect("python3 runs");
    assert!(status.success(), "python3 -m venv failed");
    let python = venv.path().join("bin/python");
    let out = Command::new(&python)
        .args(["-m", "pip", "install", "-q"])
        .arg(repo.join("python"))
        .args(TEST_PACKAGES)
        .output()
        .expect("pip runs");
    assert!(out.status.success(), "pip install ./python failed:\n{}", String::from_utf8_lossy(&out.stderr));
    let out = Command::new(&python)
        .args(["-m", "pytest", "-q", "-p", "no:cacheprovider"])
        .arg(repo.join("python/tests"))
        .env("RISKTWIN_BIN", env!("CARGO_BIN_EXE_risktwin"))
        .current_dir(venv.path())
        .output()
        .expect("pytest runs");
    let report = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "the package's tests failed:\n{report}\n{}", String::from_utf8_lossy(&out.stderr));
    assert!(report.contains(" passed"), "{report}");
}
