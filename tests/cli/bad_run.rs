//! `risktwin run` refusing bad configs and an already used report folder, before it writes
//! anything.

use crate::support::{assert_input_error, write_file};
use tempfile::tempdir;

#[test]
fn config_with_unknown_field_is_refused_before_any_output() {
    let dir = tempdir().unwrap();
    write_file(dir.path(), "c.json", r#"{"count_per_kind": 5, "colour": "red"}"#);
    let line = assert_input_error(dir.path(), &["run", "--config", "c.json", "--out", "out"], "colour");
    assert!(line.contains("c.json"), "the error does not name the config file: {line}");
    assert!(!dir.path().join("out").exists(), "a refused run created its report folder");
}

#[test]
fn config_with_out_of_range_values_is_refused() {
    let dir = tempdir().unwrap();
    for (text, needle) in [
        (r#"{"count_per_kind": 0}"#, "count_per_kind 0"),
        (r#"{"mutation_radius": 2.5}"#, "mutation_radius 2.5"),
        (r#"{"count_per_kind": -4}"#, "-4"),
        (r#"{"heatmaps": 500}"#, "heatmaps"),
        (r#"{"seeds": 0}"#, "seeds 0"),
        (r#"{"train_steps": 0}"#, "train_steps 0"),
        (r#"{"eval_per_kind": 0}"#, "eval_per_kind 0"),
    ] {
        write_file(dir.path(), "c.json", text);
        assert_input_error(dir.path(), &["run", "--config", "c.json", "--out", "out"], needle);
        assert!(!dir.path().join("out").exists(), "a refused run created its report folder");
    }
}

#[test]
fn malformed_or_missing_config_names_the_file() {
    let dir = tempdir().unwrap();
    write_file(dir.path(), "broken.json", r#"{"count_per_kind": 5"#);
    assert_input_error(dir.path(), &["run", "--config", "broken.json", "--out", "out"], "broken.json");
    assert_input_error(dir.path(), &["run", "--config", "absent.json", "--out", "out"], "absent.json");
}

#[test]
fn too_many_iterations_flag_is_refused() {
    let dir = tempdir().unwrap();
    assert_input_error(dir.path(), &["run", "--quick", "--iterations", "5000", "--out", "out"], "iterations");
    assert!(!dir.path().join("out").exists());
}

#[test]
fn out_folder_with_a_library_is_refused_and_left_alone() {
    let dir = tempdir().unwrap();
    std::fs::create_dir(dir.path().join("used")).unwrap();
    let db = write_file(&dir.path().join("used"), "library.db", "the previous run's library");
    let line = assert_input_error(dir.path(), &["run", "--quick", "--out", "used"], "library.db");
    assert!(line.contains("used"), "{line}");
    assert_eq!(std::fs::read_to_string(db).unwrap(), "the previous run's library");
    assert!(!dir.path().join("used/metrics.json").exists(), "a refused run wrote metrics.json");
}

#[test]
fn config_range_error_names_the_file() {
    let dir = tempdir().unwrap();
    write_file(dir.path(), "range.json", r#"{"count_per_kind": 0}"#);
    assert_input_error(dir.path(), &["run", "--config", "range.json", "--out", "out"], "range.json");
}

#[test]
fn unknown_algorithm_is_refused_before_any_output() {
    let dir = tempdir().unwrap();
    assert_input_error(dir.path(), &["run", "--quick", "--algo", "dreamer", "--out", "out"], "dreamer");
    assert!(!dir.path().join("out").exists(), "a refused run created its report folder");
}

#[test]
fn a_warm_start_with_another_learner_than_ppo_is_refused_before_any_output() {
    let dir = tempdir().unwrap();
    write_file(dir.path(), "c.json", r#"{"warm_start": true}"#);
    let args = ["run", "--config", "c.json", "--algo", "sac", "--out", "out"];
    assert_input_error(dir.path(), &args, "warm_start needs --algo ppo");
    assert!(!dir.path().join("out").exists(), "a refused run created its report folder");
}

#[test]
fn a_cost_limit_outside_a_share_or_with_another_learner_than_ppo_is_refused() {
    let dir = tempdir().unwrap();
    write_file(dir.path(), "share.json", r#"{"cost_limit": 1.5}"#);
    assert_input_error(dir.path(), &["run", "--config", "share.json", "--out", "out"], "cost_limit 1.5");
    write_file(dir.path(), "c.json", r#"{"cost_limit": 0.1}"#);
    let args = ["run", "--config", "c.json", "--algo", "ppo-gru", "--out", "out"];
    assert_input_error(dir.path(), &args, "cost_limit needs --algo ppo");
    assert!(!dir.path().join("out").exists(), "a refused run created its report folder");
}

#[test]
fn the_frontier_replay_rule_with_sac_or_an_unknown_rule_is_refused() {
    let dir = tempdir().unwrap();
    write_file(dir.path(), "c.json", r#"{"replay_rule": "frontier"}"#);
    let args = ["run", "--config", "c.json", "--algo", "sac", "--out", "out"];
    assert_input_error(dir.path(), &args, "needs --algo ppo or ppo-gru");
    write_file(dir.path(), "u.json", r#"{"replay_rule": "hardest"}"#);
    assert_input_error(dir.path(), &["run", "--config", "u.json", "--out", "out"], "u.json");
    assert!(!dir.path().join("out").exists(), "a refused run created its report folder");
}
