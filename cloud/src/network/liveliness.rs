//! Which edges the cloud has seen alive, from their liveliness tokens; joins and leaves are
//! logged (`info`) as they happen (tests wait on those lines on stderr).

use risktwin_transport::Liveness;
use serde::Serialize;
use std::collections::BTreeSet;

/// Edges seen joining and leaving, by `site/source`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Default)]
pub struct LivenessSummary {
    /// Every edge seen alive at some point.
    pub joined: BTreeSet<String>,
    /// Every edge seen leaving.
    pub left: BTreeSet<String>,
    /// Edges alive at shutdown.
    pub alive: BTreeSet<String>,
}

/// The running record.
#[derive(Debug, Default)]
pub struct LivenessLog(LivenessSummary);

impl LivenessLog {
    /// Notes one join or leave.
    pub fn record(&mut self, change: &Liveness) {
        let name = format!("{}/{}", change.site, change.source);
        if change.alive {
            tracing::info!("edge joined: {name}");
            self.0.joined.insert(name.clone());
            self.0.alive.insert(name);
        } else {
            tracing::info!("edge left: {name}");
            self.0.alive.remove(&name);
            self.0.left.insert(name);
        }
    }

    /// The edges alive now, as `(site, source)`.
    pub fn alive(&self) -> Vec<(String, String)> {
        let split = |name: &String| name.split_once('/').map(|(site, source)| (site.to_owned(), source.to_owned()));
        self.0.alive.iter().filter_map(split).collect()
    }

    /// Everything seen so far.
    pub fn summary(&self) -> LivenessSummary {
        self.0.clone()
    }
}
