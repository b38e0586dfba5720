//! Criticality from fleet data: a CommonRoad scenario rebuilt from its road map and obstacle
//! states ([`collect`], shared by `risktwin criticality --mcap` and the cloud's `criticality`
//! role) and the report both write ([`report`]).

pub mod collect;
pub mod report;

pub use collect::{Pushed, RebuildError, Rejected, ScenarioCollector};
pub use report::{CSV_HEADER, ReportFormat, write_report};

#[cfg(test)]
pub(crate) mod tests;
