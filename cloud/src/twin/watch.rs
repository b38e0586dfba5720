//! Episodes watched in the twin: a scenario the cloud pushed (from the push on, every tick's
//! view of the edge: the vehicle and what it perceived) and the episode of a distributed scene
//! (from its first road map on, every tick of the site; scored on every connected vehicle,
//! which all live in the scene's one world, and what the ego perceived). When the edge's
//! `ScenarioResult` names the `state` messages the episode was published on, the ticks made
//! only of those messages (a tick interpolated across the episode's start or end mixes in the
//! vehicle's own drive before or after it) are handed on, to be scored as a [`TwinEpisode`].
//! The result comes in before the twin has ticked through the episode's end (the aligner waits
//! out the lateness), so an episode is scored once the edge's ticks have moved past its last
//! message (or started over: a new process), [`SETTLE_NS`] of twin time after the result, or
//! [`SETTLE`] of wall time after it (the twin ticks only as data comes, and after a scene none
//! may), whichever is first.

use super::episode::TwinEpisode;
use super::{SiteTwin, Twin};
use crate::ingest::ObservedKinematics;
use risktwin_common::episode::EpisodeResult;
use risktwin_common::scenario::ScenarioSpec;
use risktwin_common::telemetry::ScenarioResult;
use risktwin_common::world::STEP_S;
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
/// How long after the result an episode is handed on with what the twin saw of it, whatever
/// else comes (see [`EpisodeWatch::expire`]).
pub const SETTLE: std::time::Duration = std::time::Duration::from_secs(2);

/// State messages the twin's last tick of an episode may lag its final one by for the final state
/// to be put on the next tick: the aligner holds back its last tick or two when no data follows.
/// A twin that missed more of the end (a lockstep scene) gets no made-up tick.
const FINAL_GAP_MESSAGES: u64 = 5;

/// What a watch is for.
#[derive(Debug, Clone, PartialEq)]
enum Subject {
    /// A pushed scenario at one edge, scored on the edge's own view.
    Push { edge: String, spec_id: String, spec: ScenarioSpec, push_seq: Option<i64> },
    /// Whatever episode a scene at the site reports next, scored on the whole site.
    Scene,
}

/// One episode under watch.
#[derive(Debug)]
struct Watched {
    site: String,
    subject: Subject,
    /// `(tick_ns, the site at that tick)`, oldest first.
    views: VecDeque<(i64, SiteTwin)>,
    /// Per edge, its latest state messages as received, up to the episode's last once it is
    /// known (one edge for a push; every vehicle of the site for a scene).
    raw: Vec<(String, VecDeque<ObservedKinematics>)>,
    /// The result: the edge that sent it, the result, the twin's tick when it came, and when
    /// it came.
    result: Option<(String, ScenarioResult, i64, Instant)>,
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
    /// The scenario: the pushed one when watched, or the scene's.
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
    /// Scene episodes handed on (of `scored` and `unwatched`).
    pub scenes: u64,
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
        while let Some(k) = self.watched.iter().position(|w| w.site == site && w.pushed_to(edge)) {
            let old = self.watched.swap_remove(k);
            if old.result.is_some() {
                self.finish(old);
            } else {
                self.counts.replaced += 1;
            }
        }
        let (edge, spec_id, spec) = (edge.to_owned(), spec_id.to_owned(), spec.clone());
        self.watched.push(Watched::new(site, Subject::Push { edge, spec_id, spec, push_seq }));
    }

    /// A scene runs at `site` (its road map came): watches it for the episode its ego reports,
    /// unless a watch of it waits for one already. A scene watch whose result came is handed
    /// on: a new scene has begun, and the last one's end is past.
    pub fn begin_scene(&mut self, site: &str) {
        let scene_at = |w: &Watched| w.site == site && w.subject == Subject::Scene;
        if self.watched.iter().any(|w| scene_at(w) && w.result.is_none()) {
            return;
        }
        while let Some(k) = self.watched.iter().position(scene_at) {
            let old = self.watched.swap_remove(k);
            self.finish(old);
        }
        self.watched.push(Watched::new(site, Subject::Scene));
    }

    /// Whether `site/edge` is under watch (its state messages are then wanted, see
    /// [`Self::state`]).
    pub fn is_watching(&self, site: &str, edge: &str) -> bool {
        self.watched.iter().any(|w| w.site == site && (w.pushed_to(edge) || w.subject == Subject::Scene))
    }

    /// A state message of a watched edge, as received: the episode's last one is its final
    /// state, which no tick may show (a tick after it is interpolated towards the vehicle's own
    /// drive, and a contact at the last step would be missed).
    pub fn state(&mut self, site: &str, edge: &str, kinematics: ObservedKinematics) {
        for w in self.watched.iter_mut().filter(|w| w.site == site) {
            if !(w.pushed_to(edge) || w.subject == Subject::Scene) {
                continue;
            }
            let last = match &w.result {
                Some((from, r, _, _)) if from == edge => r.state_seqs.map_or(u64::MAX, |(_, last)| last),
                Some(_) => continue,
                None => u64::MAX,
            };
            if kinematics.seqs.0 > last {
                continue;
            }
            let k = match w.raw.iter().position(|(e, _)| e == edge) {
                Some(k) => k,
                None => {
                    w.raw.push((edge.to_owned(), VecDeque::with_capacity(RAW_STATES)));
                    w.raw.len() - 1
                }
            };
            let raw = &mut w.raw[k].1;
            if raw.len() == RAW_STATES {
                raw.pop_front();
            }
            raw.push_back(kinematics);
        }
    }

    /// After the twin applied a snapshot: keeps each watched edge's view of its site, and scores
    /// the episodes whose ends the twin has now seen.
    pub fn observe(&mut self, twin: &Twin) {
        let Some(tick_ns) = twin.tick_ns() else { return };
        let mut k = 0;
        while k < self.watched.len() {
            let w = &mut self.watched[k];
            let view = twin.site(&w.site).and_then(|site| match &w.subject {
                Subject::Push { edge, .. } => own_view(site, edge),
                Subject::Scene => Some(site.clone()),
            });
            if view.as_ref().is_some_and(|v| w.started_over(v)) {
                // The edge's process started over: its episode is behind it.
                let w = self.watched.swap_remove(k);
                self.finish(w);
                continue;
            }
            if let Some(view) = view {
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
        let answers = |w: &Watched| {
            w.site == site
                && w.result.is_none()
                && match (&w.subject, &result.scene) {
                    (Subject::Push { edge: e, spec_id, .. }, None) => e == edge && *spec_id == result.spec_id,
                    (Subject::Scene, Some(_)) => true,
                    _ => false,
                }
        };
        let Some(k) = self.watched.iter().position(answers) else {
            self.counts.unwatched += 1;
            self.counts.scenes += u64::from(result.scene.is_some());
            let (site, edge) = (site.to_owned(), edge.to_owned());
            let spec = result.scene.as_ref().map(|s| s.spec.clone());
            let handed = Instant::now();
            let views = Vec::new();
            self.done.push(WatchedEpisode { site, edge, push_seq: None, result, spec, views, received, handed });
            return;
        };
        let tick_ns = tick_ns.unwrap_or(i64::MIN);
        let w = &mut self.watched[k];
        w.result = Some((edge.to_owned(), result, tick_ns, received));
        if w.is_settled(tick_ns) {
            let w = self.watched.swap_remove(k);
            self.finish(w);
        }
    }

    /// Hands on every episode whose result came [`SETTLE`] or longer before `now`, with what
    /// the twin saw of it (the twin ticks only as data comes: after a scene, none may).
    pub fn expire(&mut self, now: Instant) {
        let mut k = 0;
        while k < self.watched.len() {
            let due = self.watched[k].result.as_ref().is_some_and(|(_, _, _, at)| now.duration_since(*at) >= SETTLE);
            if due {
                let w = self.watched.swap_remove(k);
                self.finish(w);
            } else {
                k += 1;
            }
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
        let Some((edge, result, _, received)) = w.result else { return };
        let raw = w.raw.iter().find(|(e, _)| *e == edge).map(|(_, raw)| raw);
        let mut views = match (result.state_seqs, raw) {
            (Some(range), Some(raw)) => episode_views(w.views, raw, &edge, range),
            (Some(range), None) => episode_views(w.views, &VecDeque::new(), &edge, range),
            (None, _) => Vec::new(),
        };
        if w.subject == Subject::Scene {
            for (_, site) in &mut views {
                scene_view(site, &edge);
            }
        }
        if views.is_empty() {
            self.counts.unwatched += 1;
        } else {
            self.counts.scored += 1;
        }
        let (spec, push_seq) = match w.subject {
            Subject::Push { spec, push_seq, .. } => (Some(spec), push_seq),
            Subject::Scene => {
                self.counts.scenes += 1;
                (result.scene.as_ref().map(|s| s.spec.clone()), None)
            }
        };
        let handed = Instant::now();
        self.done.push(WatchedEpisode { site: w.site, edge, push_seq, result, spec, views, received, handed });
    }
}

impl Watched {
    fn new(site: &str, subject: Subject) -> Self {
        Watched { site: site.to_owned(), subject, views: VecDeque::new(), raw: Vec::new(), result: None }
    }

    /// Whether this watches a push to `edge`.
    fn pushed_to(&self, edge: &str) -> bool {
        matches!(&self.subject, Subject::Push { edge: e, .. } if e == edge)
    }

    /// Whether the reporting edge's state messages in `view` number from below those of the last
    /// tick kept: its process started over (a new scene's participant), so what follows is not
    /// this episode.
    fn started_over(&self, view: &SiteTwin) -> bool {
        let Some((edge, _, _, _)) = &self.result else { return false };
        let last_kept = self.views.back().and_then(|(_, site)| edge_seqs(site, edge));
        matches!((last_kept, edge_seqs(view, edge)), (Some(kept), Some(now)) if now.1 < kept.0)
    }

    /// Whether the twin has seen the end of the reported episode: the edge's latest tick is made
    /// of messages after its last, or [`SETTLE_NS`] have passed since the result.
    fn is_settled(&self, tick_ns: i64) -> bool {
        let Some((edge, result, result_tick_ns, _)) = &self.result else { return false };
        let Some((_, last)) = result.state_seqs else { return true };
        let past_end = self.views.back().and_then(|(_, site)| edge_seqs(site, edge)).is_some_and(|s| s.0 > last);
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

/// What a scene's ego is scored against at a tick: every connected vehicle of the scene (their
/// own states) and what the ego perceived. The objects other sources perceived are left out:
/// a roadside unit's sighting of the ego itself was measured 1.3–1.8 m behind it at 27 m/s
/// (a cut-in scene), beyond the radius within which the twin takes a sighting for the ego
/// ([`super::risk::SELF_RADIUS_M`]), and scored as a contact that never happened.
fn scene_view(site: &mut SiteTwin, edge: &str) {
    site.objects.retain(|o| *o.observer == *edge);
}

/// The seqs of the state messages `edge`'s kinematics come from at a tick.
fn edge_seqs(site: &SiteTwin, edge: &str) -> Option<(u64, u64)> {
    site.vehicles.iter().find(|v| *v.source == *edge).map(|v| v.kinematics.seqs)
}

/// The ticks of the episode published on state messages `first..=last`: every tick made only of
/// those messages (since the edge's numbers last went back), then (unless one of them already
/// showed the last message) the episode's final state as received: on the first tick after the
/// end, or, when the twin has no tick after it (nothing came after a scene's end) but its last
/// tick came within [`FINAL_GAP_MESSAGES`] of the final one, on a tick one tick period after that.
fn episode_views(
    views: VecDeque<(i64, SiteTwin)>,
    raw: &VecDeque<ObservedKinematics>,
    edge: &str,
    (first, last): (u64, u64),
) -> Vec<(i64, SiteTwin)> {
    let final_state = raw.iter().find(|k| k.seqs.0 == last);
    let with_final = |mut site: SiteTwin, state: &ObservedKinematics| {
        if let Some(v) = site.vehicles.iter_mut().find(|v| *v.source == *edge) {
            v.kinematics = *state;
        }
        site
    };
    // Numbers that go back are the edge's next process (a scene's participant after the last one
    // of the same name): what came before the last such step was not this episode.
    let seqs: Vec<Option<u64>> = views.iter().map(|(_, site)| edge_seqs(site, edge).map(|s| s.0)).collect();
    let mut since = 0;
    let mut kept = None;
    for (k, a) in seqs.iter().enumerate() {
        let Some(a) = *a else { continue };
        if kept.is_some_and(|kept| a < kept) {
            since = k;
        }
        kept = Some(a);
    }
    let mut episode: Vec<(i64, SiteTwin)> = Vec::new();
    for (tick_ns, site) in views.into_iter().skip(since) {
        match edge_seqs(&site, edge) {
            Some((a, b)) if first <= a && b <= last => {
                episode.push((tick_ns, site));
                if a == last {
                    // This tick already shows the final state as it is.
                    return episode;
                }
            }
            Some((a, b)) if a <= last && last < b && first <= a => {
                if let Some(state) = final_state {
                    episode.push((tick_ns, with_final(site, state)));
                }
                return episode;
            }
            _ => {}
        }
    }
    let reached_end =
        |site: &SiteTwin| edge_seqs(site, edge).is_some_and(|(_, b)| b.saturating_add(FINAL_GAP_MESSAGES) >= last);
    if let (Some(state), Some((tick_ns, site))) = (final_state, episode.last().filter(|(_, site)| reached_end(site))) {
        let period_ns = match episode.len() {
            n if n >= 2 => tick_ns - episode[n - 2].0,
            _ => (STEP_S * 1e9) as i64,
        };
        let view = (tick_ns + period_ns, with_final(site.clone(), state));
        episode.push(view);
    }
    episode
}
