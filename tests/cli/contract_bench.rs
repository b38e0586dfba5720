//! `bench sim`, `bench risk-field`, `bench fanout` and `bench warning` with tiny sizes: the fields docs/cli.md
//! promises and sane rates.

use crate::support::{assert_input_error, keys, num, ok_json, uint};
use tempfile::tempdir;

#[test]
fn bench_sim_json() {
    let dir = tempdir().unwrap();
    let b = ok_json(
        dir.path(),
        &["bench", "sim", "--vehicles", "40", "--steps", "20", "--threads", "1", "--format", "json"],
    );
    let present = keys(&b);
    for key in ["vehicles", "steps", "vehicle_steps_per_s", "threads"] {
        assert!(present.contains(&key), "bench sim JSON lacks {key}: {b}");
    }
    assert_eq!((uint(&b, "vehicles"), uint(&b, "steps"), uint(&b, "threads")), (40, 20, 1), "echoes its flags");
    assert!(num(&b, "vehicle_steps_per_s") > 0.0);
}

#[test]
fn bench_risk_field_json() {
    let dir = tempdir().unwrap();
    let args =
        ["bench", "risk-field", "--agents", "3", "--cols", "16", "--rows", "8", "--seconds", "0.2", "--format", "json"];
    let b = ok_json(dir.path(), &args);
    let present = keys(&b);
    for key in ["fields_per_s", "cells", "agents"] {
        assert!(present.contains(&key), "bench risk-field JSON lacks {key}: {b}");
    }
    assert_eq!((uint(&b, "cells"), uint(&b, "agents")), (16 * 8, 3));
    assert!(num(&b, "fields_per_s") > 0.0);
}

#[test]
fn bench_fanout_json_and_bad_sizes() {
    let dir = tempdir().unwrap();
    let args = ["bench", "fanout", "--echoes", "2", "--rounds", "20", "--out-bytes", "64", "--format", "json"];
    let b = ok_json(dir.path(), &args);
    let present = keys(&b);
    for key in ["echoes", "rounds", "out_bytes", "reply_bytes", "ms_per_round"] {
        assert!(present.contains(&key), "bench fanout JSON lacks {key}: {b}");
    }
    assert_eq!((uint(&b, "echoes"), uint(&b, "rounds"), uint(&b, "out_bytes")), (2, 20, 64), "echoes its flags");
    assert!(num(&b, "ms_per_round") > 0.0);
    for bad in [["--echoes", "0"], ["--out-bytes", "4"], ["--reply-bytes", "8"]] {
        let args: Vec<&str> = ["bench", "fanout"].into_iter().chain(bad).collect();
        assert_input_error(dir.path(), &args, "--echoes and --rounds must be positive");
    }
}

#[test]
fn bench_warning_json_and_bad_flags() {
    let dir = tempdir().unwrap();
    let b = ok_json(dir.path(), &["bench", "warning", "--messages", "80", "--rate-hz", "100", "--format", "json"]);
    let present = keys(&b);
    for key in
        ["raw_p50_ms", "warning_p50_ms", "warning_p99_ms", "cloud_p50_ms", "ratio", "warnings", "assess_us_per_state"]
    {
        assert!(present.contains(&key), "bench warning JSON lacks {key}: {b}");
    }
    // 80 messages, 50 of them warm-up: each of the other 30 states of warn-0 raises a warning to
    // it (the repeat limit is off). Put with `Drop`, a few may be lost on a loaded machine.
    let samples = uint(&b, "warning_samples");
    assert!((25..=30).contains(&samples), "{samples} warnings timed: {b}");
    assert!(num(&b, "warning_p50_ms") > 0.0 && num(&b, "ratio") > 0.0, "{b}");
    for bad in [["--messages", "50"], ["--rate-hz", "0"]] {
        let args: Vec<&str> = ["bench", "warning"].into_iter().chain(bad).collect();
        assert_input_error(dir.path(), &args, "--messages must exceed 50");
    }
}
