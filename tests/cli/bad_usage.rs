//! Bad flags and flag values: exit 2, one `error:` line naming the problem, nothing on stdout,
//! and no file created on the way out.

use crate::support::{GOOD_SPEC, assert_input_error, generate, risktwin, write_file};
use tempfile::tempdir;

#[test]
fn unknown_kind_is_named_and_creates_no_database() {
    let dir = tempdir().unwrap();
    let line = assert_input_error(
        dir.path(),
        &["scenarios", "generate", "--kind", "cutin", "--count", "3", "--db", "x.db"],
        "'cutin'",
    );
    // The message lists the spellings a user can pick from.
    assert!(line.contains("cut-in") && line.contains("low-friction"), "{line}");
    assert!(!dir.path().join("x.db").exists(), "a failed generate created the database");
}

#[test]
fn negative_count_is_refused() {
    let dir = tempdir().unwrap();
    assert_input_error(
        dir.path(),
        &["scenarios", "generate", "--kind", "cut-in", "--count", "-3", "--db", "x.db"],
        "-3",
    );
    assert!(!dir.path().join("x.db").exists());
}

#[test]
fn zero_count_is_refused() {
    let dir = tempdir().unwrap();
    let line = assert_input_error(
        dir.path(),
        &["scenarios", "generate", "--kind", "cut-in", "--count", "0", "--db", "x.db"],
        "--count 0",
    );
    assert!(line.contains("out of range"), "{line}");
    assert!(!dir.path().join("x.db").exists());
}

#[test]
fn non_numeric_count_is_refused() {
    let dir = tempdir().unwrap();
    assert_input_error(
        dir.path(),
        &["scenarios", "generate", "--kind", "all", "--count", "abc", "--db", "x.db"],
        "'abc'",
    );
}

#[test]
fn unknown_format_is_refused() {
    let dir = tempdir().unwrap();
    assert_input_error(
        dir.path(),
        &["scenarios", "generate", "--kind", "all", "--count", "3", "--db", "x.db", "--format", "xml"],
        "'xml'",
    );
}

#[test]
fn rank_with_unknown_kind_filter_is_refused() {
    let dir = tempdir().unwrap();
    generate(dir.path(), "x.db", 3, 1);
    assert_input_error(dir.path(), &["scenarios", "rank", "--db", "x.db", "--kind", "cutin"], "'cutin'");
}

#[test]
fn unknown_policy_is_named() {
    let dir = tempdir().unwrap();
    write_file(dir.path(), "s.json", GOOD_SPEC);
    assert_input_error(dir.path(), &["simulate", "--spec", "s.json", "--policy", "bogus"], "'bogus'");
}

#[test]
fn risk_field_resolution_zero_is_refused() {
    let dir = tempdir().unwrap();
    write_file(dir.path(), "s.json", GOOD_SPEC);
    assert_input_error(dir.path(), &["risk-field", "--spec", "s.json", "--resolution", "0"], "--resolution 0");
    assert_input_error(dir.path(), &["risk-field", "--spec", "s.json", "--resolution", "nan"], "--resolution NaN");
}

#[test]
fn risk_field_one_cell_is_refused() {
    let dir = tempdir().unwrap();
    write_file(dir.path(), "s.json", GOOD_SPEC);
    assert_input_error(dir.path(), &["risk-field", "--spec", "s.json", "--cells", "1"], "--cells 1");
}

#[test]
fn risk_field_negative_or_infinite_time_is_refused() {
    let dir = tempdir().unwrap();
    write_file(dir.path(), "s.json", GOOD_SPEC);
    assert_input_error(dir.path(), &["risk-field", "--spec", "s.json", "--time=-1"], "--time -1");
    assert_input_error(dir.path(), &["risk-field", "--spec", "s.json", "--time", "inf"], "--time inf");
}

#[test]
fn risk_field_png_into_missing_folder_names_the_path() {
    let dir = tempdir().unwrap();
    write_file(dir.path(), "s.json", GOOD_SPEC);
    assert_input_error(
        dir.path(),
        &["risk-field", "--spec", "s.json", "--png", "no/such/dir/f.png"],
        "no/such/dir/f.png",
    );
}

#[test]
fn both_sources_at_once_are_refused() {
    let dir = tempdir().unwrap();
    write_file(dir.path(), "s.json", GOOD_SPEC);
    generate(dir.path(), "x.db", 3, 1);
    assert_input_error(dir.path(), &["simulate", "--spec", "s.json", "--db", "x.db", "--id", "abc"], "--spec");
}

#[test]
fn bench_zero_sizes_are_refused() {
    let dir = tempdir().unwrap();
    assert_input_error(dir.path(), &["bench", "sim", "--vehicles", "0", "--steps", "10"], "--vehicles");
    assert_input_error(
        dir.path(),
        &["bench", "sim", "--vehicles", "10", "--steps", "10", "--threads", "0"],
        "--threads",
    );
    assert_input_error(dir.path(), &["bench", "risk-field", "--agents", "2", "--cols", "0", "--rows", "8"], "--cols");
    assert_input_error(
        dir.path(),
        &["bench", "risk-field", "--agents", "2", "--cols", "8", "--rows", "8", "--seconds", "0"],
        "--seconds",
    );
}

#[test]
fn unknown_subcommand_is_named() {
    let dir = tempdir().unwrap();
    assert_input_error(dir.path(), &["frobnicate"], "'frobnicate'");
    assert_input_error(dir.path(), &["scenarios", "shuffle"], "'shuffle'");
}

#[test]
fn unknown_flag_is_named() {
    let dir = tempdir().unwrap();
    assert_input_error(dir.path(), &["scenarios", "rank", "--db", "x.db", "--frob"], "'--frob'");
    assert_input_error(dir.path(), &["bench", "sim", "--turbo"], "'--turbo'");
}

#[test]
fn missing_required_flag_is_named() {
    let dir = tempdir().unwrap();
    assert_input_error(dir.path(), &["scenarios", "generate", "--kind", "all", "--db", "x.db"], "--count");
    assert_input_error(dir.path(), &["simulate", "--id", "abc"], "--db");
}

#[test]
fn missing_subcommand_is_named() {
    let dir = tempdir().unwrap();
    assert_input_error(dir.path(), &[], "subcommand");
    assert_input_error(dir.path(), &["scenarios"], "subcommand");
}

#[test]
fn warning_flags_without_the_warning_role_are_refused() {
    let dir = tempdir().unwrap();
    for flag in ["--warning-ttc-s", "--warning-repeat-ms"] {
        assert_input_error(dir.path(), &["cloud", "--roles", "ingest", flag, "1"], "need the warning role");
    }
    assert_input_error(
        dir.path(),
        &["cloud", "--roles", "ingest,warning", "--warning-ttc-s", "0"],
        "--warning-ttc-s 0 must lie in (0, 10]",
    );
}

#[test]
fn viz_flags_are_checked_before_the_cloud_joins() {
    let dir = tempdir().unwrap();
    for (roles, listen, needle) in [
        ("ingest,twin", "127.0.0.1:0", "--viz-listen needs the viz role"),
        ("ingest,twin,viz", "localhost:8765", "--viz-listen localhost:8765: not an IP address and port"),
        ("ingest,twin,viz", "127.0.0.1", "not an IP address and port"),
    ] {
        assert_input_error(dir.path(), &["cloud", "--roles", roles, "--viz-listen", listen], needle);
    }
    assert_input_error(dir.path(), &["cloud", "--roles", "ingest,viz"], r#"role "viz" needs role "twin""#);
    // Beyond loopback: one warning first, whatever comes after (here the missing twin role).
    let out = risktwin(dir.path(), &["cloud", "--roles", "ingest,viz", "--viz-listen", "0.0.0.0:0"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert_eq!(lines.len(), 2, "{stderr}");
    assert!(lines[0].starts_with("warning: --viz-listen 0.0.0.0:0 is reachable beyond this host"), "{stderr}");
    assert!(lines[1].starts_with("error: ") && lines[1].contains("needs role"), "{stderr}");
}

#[test]
fn sharding_shedding_and_the_union_role_are_checked_before_the_cloud_joins() {
    let dir = tempdir().unwrap();
    for (args, needle) in [
        (&["cloud", "--shard"][..], "--shard needs role ingest, --site"),
        (&["cloud", "--shard", "--roles", "ingest,twin", "--site", "s"][..], "--shard needs role ingest"),
        (&["cloud", "--roles", "union,ingest"][..], "role union takes what sharded ingest workers accepted"),
        (&["cloud", "--roles", "union,nope"][..], r#"role "nope" is not one of ingest, union"#),
        (&["cloud", "--shed-after-ms", "5"][..], "--shed-after-ms 5 must lie in [10, 60000]"),
        (&["cloud", "--shed-after-ms", "NaN"][..], "--shed-after-ms NaN must lie in [10, 60000]"),
    ] {
        assert_input_error(dir.path(), args, needle);
    }
}

#[test]
fn push_policy_without_a_signing_key_is_refused_before_sending() {
    let dir = tempdir().unwrap();
    let weights = write_file(dir.path(), "w.safetensors", "not read");
    let weights = weights.to_str().unwrap();
    let args = ["push", "policy", "--weights", weights, "--policy-id", "p", "--version", "1", "--algo", "ppo"];
    let line = assert_input_error(dir.path(), &[&args[..], &["--to", "veh-1"]].concat(), "--signing-key");
    assert!(line.contains("required"), "{line}");
}

#[test]
fn a_small_order_trust_key_is_refused() {
    let dir = tempdir().unwrap();
    let text = format!("risktwin policy verifying key (ed25519, hex)\n{}\n", "0".repeat(64));
    let key = write_file(dir.path(), "zeros.key", &text);
    let line = assert_input_error(
        dir.path(),
        &["edge", "vehicle", "--id", "veh-1", "--trust-key", key.to_str().unwrap()],
        "--trust-key",
    );
    assert!(line.contains("small-order"), "{line}");
}

#[test]
fn a_bad_metrics_address_is_refused_before_anything_starts() {
    let dir = tempdir().unwrap();
    for args in [
        &["router", "--metrics-listen", "host:9464"][..],
        &["cloud", "--metrics-listen", "70000"],
        &["edge", "vehicle", "--id", "v", "--metrics-listen", "tcp/127.0.0.1:9464"],
    ] {
        let flag = format!("--metrics-listen {}", args[args.len() - 1]);
        assert_input_error(dir.path(), args, &flag);
    }
}
