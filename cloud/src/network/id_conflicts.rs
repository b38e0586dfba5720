//! Two live processes under one edge id: seen from the cloud through the Zenoh session that
//! published each sample (its source info). An edge refuses to start while its id's liveliness
//! token is held (`risktwin_transport::declare_alive`); this catches what slips past that (two
//! partitions that meet, a publisher that is not a RiskTwin edge) and says so in the summary.

use risktwin_transport::zenoh::session::ZenohId;
use std::collections::{BTreeMap, HashMap};
use std::time::{Duration, Instant};

/// A change of publishing session within this long of the other's last sample counts as a
/// conflict; a longer silence is taken for a restart (a new process, the old one gone).
pub const CONFLICT_WINDOW: Duration = Duration::from_secs(2);

/// The last publishing session per source, and the conflicts seen.
#[derive(Debug, Default)]
pub struct IdConflicts {
    last: HashMap<String, (ZenohId, Instant)>,
    /// Per source: the times its samples switched between two sessions both alive.
    switches: BTreeMap<String, u64>,
}

impl IdConflicts {
    /// Notes a sample of `source` published by session `publisher` at `now`; allocates only for
    /// a new source or a conflict.
    pub fn observe(&mut self, source: &str, publisher: ZenohId, now: Instant) {
        let Some((last, at)) = self.last.get_mut(source) else {
            self.last.insert(source.to_owned(), (publisher, now));
            return;
        };
        if *last != publisher && now.saturating_duration_since(*at) < CONFLICT_WINDOW {
            let n = self.switches.entry(source.to_owned()).or_default();
            if *n == 0 {
                tracing::warn!(
                    "ingest: source {source} is published by two sessions at once ({last} and {publisher}): two \
                     processes share its id (counted in id_conflicts)"
                );
            }
            *n += 1;
        }
        *last = publisher;
        *at = now;
    }

    /// The session that published `source`'s last sample, if any was numbered.
    pub fn last_publisher(&self, source: &str) -> Option<ZenohId> {
        self.last.get(source).map(|(publisher, _)| *publisher)
    }

    /// Per source, how often its samples switched between two live sessions.
    pub fn summary(&self) -> BTreeMap<String, u64> {
        self.switches.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn zid(n: u8) -> ZenohId {
        ZenohId::try_from([n; 16].as_slice()).expect("a 16-byte id")
    }

    #[test]
    fn interleaved_sessions_under_one_id_are_counted_and_a_restart_is_not() {
        let t0 = Instant::now();
        let mut c = IdConflicts::default();
        let ms = |n: u64| t0 + Duration::from_millis(n);
        c.observe("veh-1", zid(1), ms(0));
        c.observe("veh-2", zid(3), ms(5));
        c.observe("veh-1", zid(1), ms(20));
        c.observe("veh-1", zid(2), ms(30));
        c.observe("veh-1", zid(1), ms(40));
        c.observe("veh-1", zid(1), ms(60));
        assert_eq!(c.summary(), BTreeMap::from([("veh-1".to_owned(), 2)]));
        // veh-2 silent for longer than the window, then a new session: a restart.
        c.observe("veh-2", zid(4), ms(5) + CONFLICT_WINDOW);
        assert_eq!(c.summary().get("veh-2"), None);
    }
}
