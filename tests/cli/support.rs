//! Running the binary and reading what it printed.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs `risktwin` with `args` in `dir`.
pub fn risktwin(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_risktwin")).args(args).current_dir(dir).output().expect("the risktwin binary runs")
}

/// What a command printed, as text, for assertion messages.
pub fn shown(out: &Output) -> String {
    format!(
        "status {:?}\n--- stdout\n{}\n--- stderr\n{}",
        out.status.code(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// Runs `args`, asserts success and returns stdout as text.
pub fn ok_stdout(dir: &Path, args: &[&str]) -> String {
    let out = risktwin(dir, args);
    assert_eq!(out.status.code(), Some(0), "risktwin {args:?} failed:\n{}", shown(&out));
    assert_no_panic(&out);
    String::from_utf8(out.stdout).expect("stdout is UTF-8")
}

/// Runs `args` (which should include `--format json`), asserts success and parses the whole of
/// stdout as one JSON document: anything else on stdout makes the parse fail.
pub fn ok_json(dir: &Path, args: &[&str]) -> Value {
    let text = ok_stdout(dir, args);
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("stdout of {args:?} is not one JSON document ({e}):\n{text}"))
}

/// Neither panic text nor a backtrace hint anywhere in the output.
pub fn assert_no_panic(out: &Output) {
    for stream in [&out.stdout, &out.stderr] {
        let text = String::from_utf8_lossy(stream);
        for bad in ["panicked", "RUST_BACKTRACE", "stack backtrace"] {
            assert!(!text.contains(bad), "'{bad}' in the output:\n{}", shown(out));
        }
    }
}

/// Runs `args` and asserts the contract for bad input: exit 2, nothing on stdout, exactly one
/// stderr line `error: ...` that contains `needle`. Returns that line.
pub fn assert_input_error(dir: &Path, args: &[&str], needle: &str) -> String {
    let out = risktwin(dir, args);
    assert_no_panic(&out);
    assert_eq!(out.status.code(), Some(2), "risktwin {args:?} should exit 2:\n{}", shown(&out));
    assert!(out.stdout.is_empty(), "risktwin {args:?} printed on stdout:\n{}", shown(&out));
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "risktwin {args:?} should print one stderr line:\n{}", shown(&out));
    let line = lines[0];
    assert!(line.starts_with("error: "), "stderr line does not start with 'error: ': {line}");
    assert!(line.contains(needle), "error line of {args:?} does not name '{needle}': {line}");
    line.to_string()
}

/// Writes `text` into `dir/name` and returns the path.
pub fn write_file(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write test file");
    path
}

/// A feasible emergency-braking spec: 30 m/s, 20 m headway, lead brakes at 6 m/s² on μ = 0.9.
pub const GOOD_SPEC: &str = r#"{"kind": "emergency-braking", "seed": 3, "params": {"ego_speed_mps": 30,
    "initial_headway_m": 20, "braking_decel_mps2": 6, "brake_time_s": 1, "friction_mu": 0.9}}"#;

/// `scenarios generate --kind all` into `dir/db` and returns the generate report.
pub fn generate(dir: &Path, db: &str, count: u32, seed: u64) -> Value {
    let (count, seed) = (count.to_string(), seed.to_string());
    ok_json(
        dir,
        &["scenarios", "generate", "--kind", "all", "--count", &count, "--seed", &seed, "--db", db, "--format", "json"],
    )
}

/// `scenarios rank --db dir/db --format json` as an array.
pub fn rank(dir: &Path, db: &str) -> Vec<Value> {
    match ok_json(dir, &["scenarios", "rank", "--db", db, "--format", "json"]) {
        Value::Array(a) => a,
        other => panic!("rank output is not an array: {other}"),
    }
}

/// The keys of docs/cli.md's `simulate` JSON document.
pub const SIMULATE_KEYS: [&str; 12] = [
    "collision",
    "offroad",
    "success",
    "route_completion",
    "avg_speed_mps",
    "steering_smoothness",
    "longitudinal_smoothness",
    "min_ttc_s",
    "min_distance_m",
    "risk_score",
    "reward",
    "steps",
];

/// The keys of a JSON object, sorted.
pub fn keys(v: &Value) -> Vec<&str> {
    let mut k: Vec<&str> =
        v.as_object().unwrap_or_else(|| panic!("not an object: {v}")).keys().map(String::as_str).collect();
    k.sort_unstable();
    k
}

/// `v[key]` as a finite f64.
pub fn num(v: &Value, key: &str) -> f64 {
    let x = v[key].as_f64().unwrap_or_else(|| panic!("'{key}' is not a number in {v}"));
    assert!(x.is_finite(), "'{key}' = {x} is not finite");
    x
}

/// `v[key]` as a u64.
pub fn uint(v: &Value, key: &str) -> u64 {
    v[key].as_u64().unwrap_or_else(|| panic!("'{key}' is not a non-negative integer in {v}"))
}
