//! Deployment topologies: the TOML file `risktwin deploy` reads (docs/topology.md), parsed into
//! a checked [`Topology`]. Every mistake is refused before anything starts, with the line it is
//! on: an unknown host or site in a link, a duplicate name, a negative latency, a host no router
//! can reach, an unknown role.
//!

mod check;
mod checked;
mod events;
mod model;

pub use check::parse;
pub use checked::{Action, Endpoint, Link, Target, Topology, router_on_gateway};
pub use model::{Jitter, Restart};
