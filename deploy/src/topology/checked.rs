//! A checked topology: what [`super::parse`] makes of a file, every name resolved to an index,
//! every value within the limits below.

use super::model::{Jitter, Restart};
use std::time::Duration;

/// The longest latency and jitter a link may have, ms (a minute).
pub(super) const MAX_LATENCY_MS: f64 = 60_000.0;
/// The bandwidths a link may have, Mbit/s (1 kbit/s to 1 Tbit/s).
pub(super) const MIN_BANDWIDTH_MBPS: f64 = 0.001;
pub(super) const MAX_BANDWIDTH_MBPS: f64 = 1e6;

/// A checked topology.
#[derive(Debug, Clone, PartialEq)]
pub struct Topology {
    /// Mutual TLS and access rules on every link: the deployment makes a CA and a certificate
    /// per process.
    pub tls: bool,
    pub sites: Vec<Site>,
    pub hosts: Vec<Host>,
    pub links: Vec<Link>,
    /// In the order of their times.
    pub events: Vec<Event>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Site {
    pub name: String,
    /// Whether the site has its own router.
    pub router: bool,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Host {
    pub name: String,
    /// Index into [`Topology::sites`].
    pub site: usize,
    pub run: Vec<Process>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Process {
    /// One of [`ROLES`](super::model::ROLES).
    pub role: &'static str,
    pub args: Vec<String>,
    pub restart: Restart,
}

/// One end of a link.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Endpoint {
    /// Index into [`Topology::sites`].
    Site(usize),
    /// Index into [`Topology::hosts`].
    Host(usize),
}

#[derive(Debug, Clone, PartialEq)]
pub struct Link {
    pub name: String,
    pub ends: [Endpoint; 2],
    pub latency_ms: f64,
    pub jitter: Option<Jitter>,
    /// `None`: as fast as the host forwards.
    pub bandwidth_mbps: Option<f64>,
    pub queue_kib: u64,
}

/// A mistake in a topology file, with the line it is on (1-based).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("line {line}: {message}")]
pub struct TopologyError {
    pub line: usize,
    pub message: String,
}

/// Whether site `site` runs its router on a gateway of its own: it has a router and no host of
/// it runs one.
pub fn router_on_gateway(sites: &[Site], hosts: &[Host], site: usize) -> bool {
    sites[site].router && !hosts.iter().any(|h| h.site == site && h.run.iter().any(|p| p.role == "router"))
}

/// A scheduled event.
#[derive(Debug, Clone, PartialEq)]
pub struct Event {
    pub at: Duration,
    /// How long a partition or a degradation lasts (`None`: to the end of the run).
    pub lasts: Option<Duration>,
    pub action: Action,
}

#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    /// Cut these links (indices into [`Topology::links`]) and these hosts off their site's
    /// network (indices into [`Topology::hosts`]).
    Partition {
        links: Vec<usize>,
        hosts: Vec<usize>,
    },
    Degrade {
        link: usize,
        latency_ms: Option<f64>,
        bandwidth_mbps: Option<f64>,
    },
    /// Kill a process (its restart policy brings it back).
    Kill(Target),
    /// Stop a process and start it again.
    Restart(Target),
    /// Step the clocks of a host's processes.
    ClockStep {
        host: usize,
        by_ms: f64,
    },
}

/// The process a `kill` or `restart` names.
#[derive(Debug, Clone, PartialEq)]
pub enum Target {
    /// Process `process` of host `host` (`host/role`).
    Hosted { host: usize, process: usize },
    /// The router of site `site` that runs on the site's gateway (`site/router`: no host of the
    /// site runs one).
    SiteRouter { site: usize },
}
