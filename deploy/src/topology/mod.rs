//! Deployment topologies: the TOML file `risktwin deploy` reads (docs/topology.md), parsed into
//! a checked [`Topology`]. Every mistake is refused before anything starts, with the line it is
//! on: an unknown host or site in a link, a duplicate name, a negative latency, a host no router
//! can reach, an unknown role.
//!
//! Work in progress for issue 15 (deployment emulation): the file format and its checks; hosts,
//! links, the event schedule's execution and the commands come next.

mod check;
mod events;
mod model;

pub use check::{Endpoint, Host, Link, Process, Site, Topology, TopologyError, parse};
pub use events::{Action, Event};
pub use model::{Jitter, ROLES};
