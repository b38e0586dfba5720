//! Cross-process tests: the `risktwin` binary driven as a user would, checked against the
//! contract in `docs/cli.md`.

mod bad_db;
mod bad_library_rows;
mod bad_run;
mod bad_spec;
mod bad_usage;
mod contract_bench;
mod contract_episode;
mod contract_scenarios;
mod criticality;
mod damaged_recording;
mod determinism;
mod driver;
mod evaluate;
mod floor;
mod hostile_commonroad;
mod mutate;
mod real_data;
mod recorded;
mod recordings;
mod regress;
mod run;
mod same_scenario;
mod support;
mod train;
mod v2x;
