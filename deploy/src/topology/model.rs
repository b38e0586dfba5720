//! The topology file as written: sites, hosts with the processes they run, and links. Names
//! carry their place in the file so that a check can name the line.

use serde::{Deserialize, Serialize};
use toml::Spanned;

/// The roles a host can run (the `risktwin` commands it starts).
pub const ROLES: [&str; 6] = ["router", "cloud", "vehicle", "rsu", "replay", "scene"];

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct File {
    /// Mutual TLS with the routers' access rules on every link (docs/security.md); off: plain
    /// TCP.
    #[serde(default)]
    pub tls: bool,
    #[serde(default)]
    pub site: Vec<SiteDef>,
    #[serde(default)]
    pub host: Vec<HostDef>,
    #[serde(default)]
    pub link: Vec<LinkDef>,
    #[serde(default)]
    pub event: Vec<EventDef>,
}

/// A site: hosts that share a router (one per site unless `router = false`, when its hosts
/// reach another site's router over a link).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct SiteDef {
    pub name: Spanned<String>,
    #[serde(default = "yes")]
    pub router: bool,
}

fn yes() -> bool {
    true
}

/// A host: an emulated machine of a site and the processes it runs.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct HostDef {
    pub name: Spanned<String>,
    pub site: Spanned<String>,
    #[serde(default)]
    pub run: Vec<ProcessDef>,
}

/// A process of a host: a role and its arguments (addresses are the deployment's to give).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ProcessDef {
    pub role: Spanned<String>,
    #[serde(default)]
    pub args: Vec<String>,
    /// When the supervisor starts the process again: `on-failure` (default), `always`, `never`.
    pub restart: Option<Spanned<Restart>>,
}

/// When a process that ended is started again (after a back-off of 0.5 s, doubling to 8 s).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Restart {
    /// When it exits with a failure or is killed by a signal the supervisor did not send.
    #[default]
    OnFailure,
    /// Whenever it ends, until the deployment stops.
    Always,
    Never,
}

/// A link between two sites or hosts, as emulated in user space.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct LinkDef {
    /// How events name the link (default `<a>-<b>`).
    pub name: Option<Spanned<String>>,
    pub between: Spanned<Vec<String>>,
    /// 0 when not given.
    pub latency_ms: Option<Spanned<f64>>,
    pub jitter: Option<Spanned<Jitter>>,
    pub bandwidth_mbps: Option<Spanned<f64>>,
    pub queue_kib: Option<Spanned<u64>>,
}

/// How a link's delay varies around its latency.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(tag = "dist", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Jitter {
    /// Normal, standard deviation `sd_ms`, cut at ± 3 standard deviations.
    Normal { sd_ms: f64 },
    /// Uniform in ± `max_ms`.
    Uniform { max_ms: f64 },
}

/// A scheduled event: at `at_s` seconds into the run, one action, for `for_s` seconds where it
/// lasts (a partition, a degraded link).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct EventDef {
    pub at_s: Spanned<f64>,
    pub for_s: Option<Spanned<f64>>,
    /// A site, a host or a link: every link of it is cut.
    pub partition: Option<Spanned<String>>,
    /// A link, with its new `latency_ms` and/or `bandwidth_mbps`.
    pub degrade: Option<Spanned<String>>,
    pub latency_ms: Option<f64>,
    pub bandwidth_mbps: Option<f64>,
    /// `host/role`: the process is killed (and restarted by its policy).
    pub kill: Option<Spanned<String>>,
    /// `host/role`: the process is stopped and started again.
    pub restart: Option<Spanned<String>>,
    /// A host whose processes' clocks step by `by_ms`.
    pub clock_step: Option<Spanned<String>>,
    pub by_ms: Option<f64>,
}
