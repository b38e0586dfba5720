//! Node with the npm packages a peer script needs, made on first use: a `node_modules` folder
//! under the target directory (or $RISKTWIN_PEER_NODE), shared by every test and reused across
//! runs; scripts find it through `NODE_PATH`. Node and npm come from Debian (`apt-get`) when
//! missing. Without them or the npm registry the test fails and says why; it never skips.

use crate::peer_cache;
use std::path::Path;
use std::process::Command;

/// A `node` command with `packages` (npm specs `name@version`) on its `NODE_PATH`.
pub fn node(packages: &[&str]) -> Command {
    let dir = peer_cache::folder("RISKTWIN_PEER_NODE", "peer-node");
    peer_cache::installing(&dir, || ensure(&dir, packages));
    let mut node = Command::new("node");
    node.env("NODE_PATH", dir.join("node_modules"));
    node
}

fn ensure(dir: &Path, packages: &[&str]) {
    if !runs("node") || !runs("npm") {
        let update = Command::new("apt-get").arg("update").status().expect("apt-get runs");
        assert!(update.success(), "apt-get update failed (node and npm are missing)");
        let install = Command::new("apt-get").args(["install", "-y", "nodejs", "npm"]).status().expect("apt-get runs");
        assert!(install.success(), "apt-get install nodejs npm failed");
        assert!(runs("node") && runs("npm"), "node and npm still do not run after apt-get install");
    }
    let missing: Vec<&str> = packages.iter().copied().filter(|p| !installed(dir, p)).collect();
    if !missing.is_empty() {
        std::fs::create_dir_all(dir).expect("the peer folder");
        let status = Command::new("npm")
            .args(["install", "--no-audit", "--no-fund", "--prefix"])
            .arg(dir)
            .args(&missing)
            .status()
            .expect("npm runs");
        assert!(status.success(), "npm install {missing:?} failed");
        for package in &missing {
            assert!(installed(dir, package), "npm install said yes but {package} is not in {}", dir.display());
        }
    }
}

fn runs(program: &str) -> bool {
    Command::new(program).arg("--version").output().is_ok_and(|o| o.status.success())
}

/// Whether `dir/node_modules` holds `spec` (`name@version`, the name possibly scoped) at that
/// version, as its package.json says.
fn installed(dir: &Path, spec: &str) -> bool {
    let (name, version) = match spec.rfind('@') {
        Some(at) if at > 0 => (&spec[..at], &spec[at + 1..]),
        _ => (spec, ""),
    };
    let Ok(text) = std::fs::read_to_string(dir.join("node_modules").join(name).join("package.json")) else {
        return false;
    };
    let Ok(json) = serde_json::from_str::<serde_json::Value>(&text) else { return false };
    version.is_empty() || json["version"] == version
}
