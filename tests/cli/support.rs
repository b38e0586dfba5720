//! Running the binary and reading what it printed.

use std::path::Path;
use std::process::{Command, Output};

/// Runs `risktwin` with `args` in `dir`.
pub fn risktwin(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_risktwin")).args(args).current_dir(dir).output().expect("the risktwin binary runs")
}
