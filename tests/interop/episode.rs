//! A short recorded episode: the MCAP file the interop tests read (it also carries every
//! protobuf schema as a FileDescriptorSet).

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// Records an emergency-braking episode with sensor-noise `seed` into `dir/name`.
pub fn record(dir: &Path, seed: u64, name: &str) -> PathBuf {
    let spec = dir.join("spec.json");
    std::fs::write(
        &spec,
        format!(
            r#"{{"kind": "emergency-braking", "seed": {seed}, "params": {{"ego_speed_mps": 20, "initial_headway_m": 30,
                "braking_decel_mps2": 5, "brake_time_s": 1, "friction_mu": 0.9}}}}"#
        ),
    )
    .expect("write spec");
    let recording = dir.join(name);
    let out = Command::new(env!("CARGO_BIN_EXE_risktwin"))
        .args(["simulate", "--format", "json", "--spec"])
        .arg(&spec)
        .arg("--record")
        .arg(&recording)
        .stdout(Stdio::null())
        .output()
        .expect("risktwin runs");
    assert!(out.status.success(), "risktwin simulate --record: {}", String::from_utf8_lossy(&out.stderr));
    recording
}
