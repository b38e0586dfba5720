//! Bad scenario spec files (`--spec`): every one is an input error that names the file and what
//! is wrong with it, for `simulate` and `risk-field` alike.

use crate::support::{assert_input_error, write_file};
use tempfile::tempdir;

/// Emergency-braking parameters, as the text inside `"params": {...}`, with three values chosen.
fn eb_params(ego_speed: &str, decel: &str, mu: &str) -> String {
    format!(
        r#""ego_speed_mps": {ego_speed}, "initial_headway_m": 20, "braking_decel_mps2": {decel}, "brake_time_s": 1, "friction_mu": {mu}"#
    )
}

/// Writes `text` as `name` and checks both spec-reading commands refuse it, naming the file and
/// `needle`.
fn refused(name: &str, text: &str, needle: &str) {
    let dir = tempdir().unwrap();
    write_file(dir.path(), name, text);
    for cmd in ["simulate", "risk-field"] {
        let line = assert_input_error(dir.path(), &[cmd, "--spec", name, "--format", "json"], needle);
        assert!(line.contains(name), "the error does not name the spec file {name}: {line}");
    }
}

#[test]
fn missing_parameter() {
    let text = r#"{"kind": "emergency-braking", "seed": 3, "params": {"ego_speed_mps": 30, "initial_headway_m": 20,
        "braking_decel_mps2": 6, "brake_time_s": 1}}"#;
    refused("missing.json", text, "'friction_mu'");
}

#[test]
fn out_of_range_parameter() {
    let text = format!(r#"{{"kind": "emergency-braking", "seed": 3, "params": {{{}}}}}"#, eb_params("99", "6", "0.9"));
    let dir = tempdir().unwrap();
    write_file(dir.path(), "range.json", &text);
    let line = assert_input_error(dir.path(), &["simulate", "--spec", "range.json"], "'ego_speed_mps'");
    // The bad value and the allowed range, as docs/cli.md's "what and where" asks.
    assert!(line.contains("99") && line.contains("[10, 35]"), "{line}");
}

#[test]
fn string_parameter_value() {
    let text =
        format!(r#"{{"kind": "emergency-braking", "seed": 3, "params": {{{}}}}}"#, eb_params(r#""fast""#, "6", "0.9"));
    refused("string.json", &text, "fast");
}

#[test]
fn nan_like_parameter_values() {
    // JSON has no NaN: a bare NaN is a syntax error, "NaN" a string, null no number, 1e999 overflows.
    for (name, value, needle) in [
        ("nan.json", "NaN", "expected value"),
        ("nanstr.json", r#""NaN""#, "NaN"),
        ("null.json", "null", "null"),
        ("huge.json", "1e999", "out of range"),
    ] {
        let text =
            format!(r#"{{"kind": "emergency-braking", "seed": 3, "params": {{{}}}}}"#, eb_params(value, "6", "0.9"));
        refused(name, &text, needle);
    }
}

#[test]
fn unknown_parameter() {
    let text = format!(
        r#"{{"kind": "emergency-braking", "seed": 3, "params": {{{}, "wind_mps": 3}}}}"#,
        eb_params("30", "6", "0.9")
    );
    refused("extra.json", &text, "'wind_mps'");
}

#[test]
fn unknown_top_level_field() {
    let text = format!(
        r#"{{"kind": "emergency-braking", "seed": 3, "colour": "red", "params": {{{}}}}}"#,
        eb_params("30", "6", "0.9")
    );
    refused("field.json", &text, "colour");
}

#[test]
fn missing_or_negative_seed() {
    let params = eb_params("30", "6", "0.9");
    refused("noseed.json", &format!(r#"{{"kind": "emergency-braking", "params": {{{params}}}}}"#), "seed");
    refused("negseed.json", &format!(r#"{{"kind": "emergency-braking", "seed": -3, "params": {{{params}}}}}"#), "-3");
}

#[test]
fn unknown_kind() {
    let text = format!(r#"{{"kind": "cutin", "seed": 3, "params": {{{}}}}}"#, eb_params("30", "6", "0.9"));
    refused("kind.json", &text, "'cutin'");
}

#[test]
fn infeasible_spec() {
    // Braking at 8 m/s² needs μ ≥ 8 / 9.81 ≈ 0.82; μ = 0.3 allows 2.94 m/s².
    let text = format!(r#"{{"kind": "emergency-braking", "seed": 3, "params": {{{}}}}}"#, eb_params("30", "8", "0.3"));
    refused("infeasible.json", &text, "infeasible");
}

#[test]
fn malformed_json() {
    let text = format!(r#"{{"kind": "emergency-braking", "seed": 3, "params": {{{}}}"#, eb_params("30", "6", "0.9"));
    refused("malformed.json", &text, "EOF");
    refused("empty.json", "", "EOF");
    refused("array.json", "[1, 2, 3]", "spec");
}

#[test]
fn spec_file_that_does_not_exist() {
    let dir = tempdir().unwrap();
    assert_input_error(dir.path(), &["simulate", "--spec", "absent.json"], "absent.json");
    assert_input_error(dir.path(), &["risk-field", "--spec", "absent.json"], "absent.json");
}
