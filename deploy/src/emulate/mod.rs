//! Emulated deployments (issue 15): a checked topology becomes machines (network namespaces, or
//! loopback where none can be made), relays that emulate its links, and supervised processes.

pub mod deployment;
pub mod lock;
pub mod net;
pub mod network_log;
pub mod options;
pub mod plan;
pub mod relay;
pub mod report;
pub mod supervise;
pub mod tls;
