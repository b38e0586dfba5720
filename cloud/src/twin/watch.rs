//! Episodes the cloud pushed, watched in the twin: from the push on, every tick's view of the
//! edge's site is kept; when the edge's `ScenarioResult` names the `state` messages the episode
//! was published on, the ticks made only of those messages (a tick interpolated across the
//! episode's start or end mixes in the vehicle's own drive before or after it) are handed on,
//! to be scored as a [`TwinEpisode`].
//! The result comes in before the twin has ticked through the episode's end (the aligner waits
//! out the lateness), so an episode is scored once the edge's ticks have moved past its last
//! message, or [`SETTLE_NS`] of twin time after the result, whichever is first.

use super::episode::TwinEpisode;
use super::{SiteTwin, Twin};
use crate::ingest::ObservedKinematics;
use risktwin_common::episode::EpisodeResult;
use risktwin_common::scenario::ScenarioSpec;
use risktwin_common::telemetry::ScenarioResult;
use std::collections::VecDeque;
use std::time::Instant;

/// Ticks kept per watched episode (4 minutes of 20 Hz ticks); older ones are dropped, counted.
pub const MAX_VIEWS: usize = 4_800;
/// State messages kept per watched edge before its result names the last one (1.3 s of 50 Hz
/// state; after the result only the episode's own are taken).
const RAW_STATES: usize = 64;
/// How long after the result the twin may still be catching up with the episode's end, ns of
/// twin time (the aligner waits out its lateness, 30 ms by default).
pub const SETTLE_NS: i64 = 1_000_000_000;

/// One episode under watch.
#[derive(Debug)]
struct Watched {
    site: String,
    edge: String,
    spec_id: String,
    spec: ScenarioSpec,
    push_seq: Option<i64>,
    /// `(tick_ns, the site at that tick)`, oldest first.
    views: VecDeque<(i64, SiteTwin)>,
    /// The edge's latest state messages as received, up to the episode's last once it is known.
    raw: VecDeque<ObservedKinematics>,
    /// The edge's result, the twin's tick when it came, and when it came.
    result: Option<(ScenarioResult, i64, Instant)>,
}

/// An episode the edge reported, with the twin's ticks of it.
#[derive(Debug, Clone)]
pub struct WatchedEpisode {
    pub site: String,
    pub edge: String,
    /// The push it answers, when the cloud's loop sent it (`None`: a result nobody here watched
    /// for, e.g. from a push made before a restart).
    pub push_seq: Option<i64>,
    pub result: ScenarioResult,
    /// The pushed scenario, when watched.
    pub spec: Option<ScenarioSpec>,
    /// The twin's ticks made only of the episode's `state` messages: `(tick_ns, the site)`.
    pub views: Vec<(i64, SiteTwin)>,
    /// When the result arrived.
    pub received: Instant,
    /// When the twin had seen the episode's end and handed it on: where the loop's work starts.
    pub handed: Instant,
}

impl WatchedEpisode {
    /// The twin's score of the episode, from its ticks; `None` when the twin did not watch it or
    /// saw none of it (done off the receive path, by whoever takes the episode).
    pub fn score(&self) -> Option<EpisodeResult> {
        let spec = self.spec.as_ref().filter(|_| !self.views.is_empty())?;
        let mut episode = TwinEpisode::new(spec, &self.edge);
        for (tick_ns, site) in &self.views {
            episode.tick(site, *tick_ns);
        }
        Some(episode.finish())
    }
}

/// Counts of the watch, for the summary.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct WatchCounts {
    /// Episodes handed on with ticks of the twin.
    pub scored: u64,
    /// Results the twin had not watched (or of which it saw no tick).
    pub unwatched: u64,
    /// Ticks dropped beyond [`MAX_VIEWS`].
    pub views_dropped: u64,
    /// Watches replaced by a newer push to the same edge before a result came.
    pub replaced: u64,
}

/// The episodes under watch.
#[derive(Debug, Default)]
pub struct EpisodeWatch {
    watched: Vec<Watched>,
    done: Vec<WatchedEpisode>,
    counts: WatchCounts,
}

impl EpisodeWatch {
    /// Starts watching `site/edge` for the episode of `spec` (library id `spec_id`), pushed now.
    pub fn begin(&mut self, site: &str, edge: &str, spec_id: &str, spec: &ScenarioSpec, push_seq: Option<i64>) {
        // A watch the new push replaces: one with its result is handed on with what it saw.
        while let Some(k) = self.watched.iter().position(|w| w.site == site && w.edge == edge) {
            let old = self.watched.swap_remove(k);
            if old.result.is_some() {
                self.finish(old);
            } else {
                self.counts.replaced += 1;
            }
        }
        self.watched.push(Watched {
            site: site.to_owned(),
            edge: edge.to_owned(),
            spec_id: spec_id.to_owned(),
            spec: spec.clone(),
            push_seq,
            views: VecDeque::new(),
            raw: VecDeque::new(),
            result: None,
        });
    }

    /// Whether `site/edge` is under watch (its state messages are then wanted, see
    /// [`Self::state`]).
    pub fn is_watching(&self, site: &str, edge: &str) -> bool {
        self.watched.iter().any(|w| w.site == site && w.edge == edge)
    }

    /// A state message of a watched edge, as received: the episode's last one is its final
    /// state, which no tick may show (a tick after it is interpolated towards the vehicle's own
    /// drive, and a contact at the last step would be missed).
    pub fn state(&mut self, site: &str, edge: &str, kinematics: ObservedKinematics) {
        let Some(w) = self.watched.iter_mut().find(|w| w.site == site && w.edge == edge) else { return };
        let last = w.result.as_ref().and_then(|(r, _, _)| r.state_seqs).map_or(u64::MAX, |(_, last)| last);
        if kinematics.seqs.0 <= last {
            if w.raw.len() == RAW_STATES {
                w.raw.pop_front();
            }
            w.raw.push_back(kinematics);
        }
    }

    /// After the twin applied a snapshot: keeps each watched edge's view of its site, and scores
    /// the episodes whose ends the twin has now seen.
    pub fn observe(&mut self, twin: &Twin) {
        let Some(tick_ns) = twin.tick_ns() else { return };
        let mut k = 0;
        while k < self.watched.len() {
            let w = &mut self.watched[k];
            if let Some(view) = twin.site(&w.site).and_then(|site| own_view(site, &w.edge)) {
                if w.views.len() == MAX_VIEWS {
                    w.views.pop_front();
                    self.counts.views_dropped += 1;
                }
                w.views.push_back((tick_ns, view));
            }
            if w.is_settled(tick_ns) {
                let w = self.watched.swap_remove(k);
                self.finish(w);
            } else {
                k += 1;
            }
        }
    }

    /// The edge's result of an episode, received at `received` while the twin was at `tick_ns`
    /// (its latest tick): the episode is scored once the twin has seen its end (at once if it
    /// names no `state` message, or nobody watched for it).
    pub fn result(&mut self, site: &str, edge: &str, result: ScenarioResult, tick_ns: Option<i64>, received: Instant) {
        let found = self.watched.iter().position(|w| w.site == site && w.edge == edge && w.spec_id == result.spec_id);
        let Some(k) = found else {
            self.counts.unwatched += 1;
            let (site, edge) = (site.to_owned(), edge.to_owned());
            let (spec, views) = (None, Vec::new());
            let handed = Instant::now();
            self.done.push(WatchedEpisode { site, edge, push_seq: None, result, spec, views, received, handed });
            return;
        };
        let tick_ns = tick_ns.unwrap_or(i64::MIN);
        let w = &mut self.watched[k];
        w.result = Some((result, tick_ns, received));
        if w.is_settled(tick_ns) {
            let w = self.watched.swap_remove(k);
            self.finish(w);
        }
    }

    /// The episodes scored since the last call, in the order they were finished.
    pub fn take_done(&mut self) -> Vec<WatchedEpisode> {
        std::mem::take(&mut self.done)
    }

    pub fn counts(&self) -> WatchCounts {
        self.counts
    }

    fn finish(&mut self, w: Watched) {
        let Some((result, _, received)) = w.result else { return };
        let views = match result.state_seqs {
            Some(range) => episode_views(w.views, &w.raw, &w.edge, range),
            None => Vec::new(),
        };
        if views.is_empty() {
            self.counts.unwatched += 1;
        } else {
            self.counts.scored += 1;
        }
        self.done.push(WatchedEpisode {
            site: w.site,
            edge: w.edge,
            push_seq: w.push_seq,
            result,
            spec: Some(w.spec),
            views,
            received,
            handed: Instant::now(),
        });
    }
}

impl Watched {
    /// Whether the twin has seen the end of the reported episode: the edge's latest tick is made
    /// of messages after its last, or [`SETTLE_NS`] have passed since the result.
    fn is_settled(&self, tick_ns: i64) -> bool {
        let Some((result, result_tick_ns, _)) = &self.result else { return false };
        let Some((_, last)) = result.state_seqs else { return true };
        let past_end = self.views.back().and_then(|(_, site)| edge_seqs(site, &self.edge)).is_some_and(|s| s.0 > last);
        past_end || tick_ns.saturating_sub(*result_tick_ns) >= SETTLE_NS
    }
}

/// What a pushed episode's vehicle is scored against at a tick: the vehicle and what it
/// perceived itself. A pushed scenario is the vehicle's own world: the site's other vehicles and
/// roadside units drive and watch other worlds on the same coordinates, and would be phantoms
/// in it. `None` when the vehicle is not in the twin at this tick.
fn own_view(site: &SiteTwin, edge: &str) -> Option<SiteTwin> {
    let vehicle = site.vehicles.iter().find(|v| *v.source == *edge)?;
    let objects = site.objects.iter().filter(|o| *o.observer == *edge).cloned().collect();
    Some(SiteTwin { vehicles: vec![vehicle.clone()], objects })
}

/// The seqs of the state messages `edge`'s kinematics come from at a tick.
fn edge_seqs(site: &SiteTwin, edge: &str) -> Option<(u64, u64)> {
    site.vehicles.iter().find(|v| *v.source == *edge).map(|v| v.kinematics.seqs)
}

/// The ticks of the episode published on state messages `first..=last`: every tick made only of
/// those messages, then (unless one of them already showed the last message) the first tick
/// after the end with the vehicle at its last message (the episode's final state, as received).
fn episode_views(
    views: VecDeque<(i64, SiteTwin)>,
    raw: &VecDeque<ObservedKinematics>,
    edge: &str,
    (first, last): (u64, u64),
) -> Vec<(i64, SiteTwin)> {
    let final_state = raw.iter().find(|k| k.seqs.0 == last);
    let mut episode = Vec::new();
    for (tick_ns, mut site) in views {
        match edge_seqs(&site, edge) {
            Some((a, b)) if first <= a && b <= last => {
                episode.push((tick_ns, site));
                if a == last {
                    // This tick already shows the final state as it is.
                    break;
                }
            }
            Some((a, b)) if a <= last && last < b && first <= a => {
                let Some(state) = final_state else { break };
                if let Some(v) = site.vehicles.iter_mut().find(|v| *v.source == *edge) {
                    v.kinematics = *state;
                }
                episode.push((tick_ns, site));
                break;
            }
            _ => {}
        }
    }
    episode
}
