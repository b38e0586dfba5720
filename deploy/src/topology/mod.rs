//! Deployment topologies: the TOML file `risktwin deploy` reads (docs/topology.md), parsed into
//! a checked [`Topology`]. Every mistake is refused before anything starts, with the line it is
//! on: an unknown host or site in a link, a duplicate name, a negative latency, a host no router
//! can reach, an unknown role.
//!

mod check;
mod events;
mod model;

pub use check::{Endpoint, Link, Topology, parse, router_on_gateway};
pub use events::{Action, Target};
pub use model::{Jitter, Restart};
