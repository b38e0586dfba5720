//! Cross-process tests: the `risktwin` binary driven as a user would, checked against the
//! contract in `shared/docs/cli.md`.

mod support;
