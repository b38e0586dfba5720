//! The event-driven warning path (the cloud's `warning` role): on every accepted state message,
//! the pairs it touches are re-assessed at once and a hazard warning leaves for each vehicle of
//! a critical pair. The aligned snapshots wait for a tick and its lateness (61 ms p50 from edge
//! publish, most of a 100 ms V2X budget); this path waits for nothing, and leaves the snapshots
//! as they are for recording, replay and determinism.
//!
//! Per site, the latest state of every source that sent one, on the cloud's clock (the ingest's
//! clock mapping). A state from `a` at `t` is paired with every other source `b` of its site
//! whose latest state lies within [`WarningConfig::max_age_ns`] of `t`, moved on at constant
//! velocity to `t`. A broad phase ([`assess::within_reach`]) skips pairs too far apart to meet
//! within the TTC threshold; the rest are assessed ([`assess::assess_pair`]). Both vehicles of a
//! critical pair are warned, each about the other, at most once per
//! [`WarningConfig::repeat_ns`] of message time per (warned, hazard) pair (a pair that comes to
//! contact is warned about at once, whatever went before).
//!
//! Members are forgotten once not heard for [`WarningConfig::forget_ns`] of message time (found
//! in the scan of a later state of their site; their publisher goes with them), and the repeat
//! limit's entries once older than [`WarningConfig::repeat_ns`] (swept once per that much message
//! time per site), so both stay bounded by the vehicles that are live. Each state still scans
//! every live member of its site (no spatial index): measured at 1–1.6 µs per state with 10
//! vehicles on the site, 3.3–5.6 µs with 100 and 18–20 µs with 1,000, about 16 ns per member
//! (`risktwin bench warning`, docs/results.md).
//!
//! Transport-free and clock-free like the ingest: the caller passes the receive time and a
//! [`WarningSink`] that puts each warning on its key (`risktwin/v1/<site>/<warned>/warning`) and is
//! told when a vehicle joins (its first state) and leaves. Nothing is allocated per message once
//! a site's sources and critical pairs are known; a warning that goes out allocates its message.

pub mod assess;

use crate::ingest::{AcceptedMessage, ObservedKinematics};
use crate::twin::fidelity::CRITICAL_TTC_S;
use crate::twin::moved_on;
use assess::{PairRisk, assess_pair, vehicle_state, within_reach};
use risktwin_common::geometry::{Footprint, Pose, Vec2};
use risktwin_common::risk::EgoLaneFrame;
use risktwin_common::road::Road;
use risktwin_common::telemetry::{Frame, HazardKind, HazardWarning, Header};
use risktwin_transport::keyexpr::{CLOUD_CHUNK, CloudToEdge, cloud_to_edge};
use risktwin_transport::{SiteId, SourceId};
use serde::Serialize;
use std::collections::{BTreeMap, HashMap};

/// When a pair is critical and how often it is warned about.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WarningConfig {
    /// A pair is critical when its TTC (lane or predicted contact) lies below this, s; the
    /// twin's critical-event threshold (`twin::fidelity::CRITICAL_TTC_S`, 2 s).
    pub critical_ttc_s: f64,
    /// Step of the predicted-contact check, s.
    pub step_s: f64,
    /// Another source's latest state is moved on to a message's time only when it lies at most
    /// this far from it, ns; a message this much older than its receipt warns no one.
    pub max_age_ns: i64,
    /// At most one warning per (warned, hazard) pair per this much message time, ns (0: every
    /// critical message warns).
    pub repeat_ns: i64,
    /// A member not heard for this much message time is forgotten (its warnings, numbered
    /// from 0 again, and its publisher start over when it is heard again), ns. Beyond
    /// `max_age_ns` it is never paired anyway; the longer bound keeps a loss burst from
    /// redeclaring its publisher.
    pub forget_ns: i64,
}

impl Default for WarningConfig {
    /// TTC below 2 s, 50 ms steps, states up to 200 ms old (10 periods of a 50 Hz stream: a
    /// short loss burst; constant velocity is off by ½·a·t² = 0.2 m at 10 m/s² over 0.2 s),
    /// one warning per pair per 500 ms, members forgotten after 2 s.
    fn default() -> Self {
        WarningConfig {
            critical_ttc_s: CRITICAL_TTC_S,
            step_s: 0.05,
            max_age_ns: 200_000_000,
            repeat_ns: 500_000_000,
            forget_ns: 2_000_000_000,
        }
    }
}

/// What the warning role did, for the cloud's summary.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct WarningSummary {
    /// State messages the path took in.
    pub states: u64,
    /// Of those, too old on receipt (late, recovered from a cache) or older than the source's
    /// latest: its latest state kept, no one warned.
    pub late_states: u64,
    /// Pairs within reach of each other, assessed.
    pub pairs_assessed: u64,
    /// Assessments that found the pair critical.
    pub critical: u64,
    /// Warnings handed to the transport.
    pub sent: u64,
    /// Warnings held back by the per-pair repeat limit.
    pub rate_limited: u64,
    /// Warnings the transport refused, or with no key (an id the key scheme does not allow).
    pub failed: u64,
    /// Of `sent`, those put through the vehicle's declared publisher, and those put once on
    /// the session because its publisher was not declared yet (the network sink's counts).
    pub via_publisher: u64,
    pub one_off: u64,
    /// Members forgotten (not heard for `forget_ns`, or their edge left).
    pub forgotten: u64,
    /// Warnings sent per `site/vehicle`.
    pub sent_to: BTreeMap<String, u64>,
}

/// Where the warning path's output goes.
pub trait WarningSink: Send {
    /// A vehicle whose warnings go on `key` sent its first state: warnings to it may follow.
    fn joined(&mut self, _key: &str) {}
    /// The vehicle of `key` is forgotten: nothing goes to it until it is heard again.
    fn left(&mut self, _key: &str) {}
    /// Puts one warning on `key`; `false` when it did not go out.
    fn put(&mut self, key: &str, warning: &HazardWarning) -> bool;
    /// Adds the sink's own counts to `summary`.
    fn count(&self, _summary: &mut WarningSummary) {}
}

/// A closure that puts warnings is a sink that ignores joins and leaves.
impl<F: FnMut(&str, &HazardWarning) -> bool + Send> WarningSink for F {
    fn put(&mut self, key: &str, warning: &HazardWarning) -> bool {
        self(key, warning)
    }
}

/// The latest states of one site's sources (members), as structure of arrays.
#[derive(Debug, Default)]
struct Site {
    name: String,
    road: Option<Road>,
    names: Vec<String>,
    /// The key each member's warnings go to; `None` when an id is not a valid key chunk.
    keys: Vec<Option<String>>,
    /// Each member's ingest source index.
    sources: Vec<u32>,
    /// The time of each member's latest state, cloud clock, ns.
    t_ns: Vec<i64>,
    latest: Vec<ObservedKinematics>,
    /// Warnings sent to each member (its next warning's seq).
    sent: Vec<u64>,
    /// The message time and kind of the last warning to `warned` about `hazard` (ingest source
    /// indices).
    last_warned: HashMap<(u32, u32), (i64, HazardKind)>,
    /// The message time from which `last_warned` is swept next.
    next_sweep_ns: i64,
}

/// One critical pair found for a message, before the repeat limit.
#[derive(Debug, Clone, Copy)]
struct Alert {
    other: u32,
    /// The other member at the message's time.
    other_now: ObservedKinematics,
    risk: PairRisk,
}

/// The warning path's state: every site's latest states and the pairs' last warnings.
#[derive(Debug)]
pub struct HazardWarner {
    config: WarningConfig,
    /// The road of sites that published none (`--road`); `None`: lane TTC only where a site's
    /// scene published its map.
    default_road: Option<Road>,
    sites: Vec<Site>,
    site_index: HashMap<String, usize>,
    /// Per ingest source index: (site, member) once it sent a state.
    members: Vec<Option<(u32, u32)>>,
    alerts: Vec<Alert>,
    /// Members of the site being scanned that are to be forgotten.
    gone: Vec<u32>,
    summary: WarningSummary,
}

impl HazardWarner {
    /// A warner with `config`, assessing lane TTC on `default_road` where a site has no map.
    pub fn new(config: WarningConfig, default_road: Option<Road>) -> Self {
        HazardWarner {
            config,
            default_road,
            sites: Vec::new(),
            site_index: HashMap::new(),
            members: Vec::new(),
            alerts: Vec::new(),
            gone: Vec::new(),
            summary: WarningSummary::default(),
        }
    }

    /// `site` published its road map: its lane TTC is measured on `road` from now on.
    pub fn set_site_road(&mut self, site: &str, road: Road) {
        let index = self.site(site);
        self.sites[index].road = Some(road);
    }

    /// Takes in an accepted state message of `source` at `site` (`msg.state` set; other messages
    /// are ignored), received at `receive_ns` (cloud clock), and hands the warnings it raises to
    /// `sink`.
    pub fn on_state(
        &mut self,
        site: &str,
        source: &str,
        msg: &AcceptedMessage,
        receive_ns: i64,
        sink: &mut dyn WarningSink,
    ) {
        let Some(state) = msg.state else { return };
        self.summary.states += 1;
        let (s, m) = self.member(site, source, msg.source.0 as usize, sink);
        let t_ns = msg.cloud_ns;
        let site = &mut self.sites[s];
        let newest = site.t_ns[m] <= t_ns;
        if newest {
            site.t_ns[m] = t_ns;
            site.latest[m] = state;
        }
        if !newest || receive_ns.saturating_sub(t_ns) > self.config.max_age_ns {
            self.summary.late_states += 1;
            return;
        }
        let horizon_s = self.config.critical_ttc_s;
        let a = vehicle_state(&state);
        let road = site.road.as_ref().or(self.default_road.as_ref());
        let mut frame: Option<EgoLaneFrame> = None;
        self.alerts.clear();
        self.gone.clear();
        for other in 0..site.names.len() {
            let age_ns = t_ns.saturating_sub(site.t_ns[other]);
            if other == m {
                continue;
            }
            if age_ns > self.config.forget_ns {
                self.gone.push(other as u32);
                continue;
            }
            if age_ns.saturating_abs() > self.config.max_age_ns {
                continue;
            }
            let then = site.latest[other];
            let other_now = ObservedKinematics { pose: moved_on(then.pose, then.velocity, age_ns), ..then };
            if !within_reach(&state, &other_now, horizon_s) {
                continue;
            }
            self.summary.pairs_assessed += 1;
            let lane = road.map(|r| (r, &*frame.get_or_insert_with(|| EgoLaneFrame::new(r, &a))));
            if let Some(risk) = assess_pair(lane, &a, &vehicle_state(&other_now), &self.config) {
                self.summary.critical += 1;
                self.alerts.push(Alert { other: other as u32, other_now, risk });
            }
        }
        let trigger = Trigger { source, seq: msg.seq, capture_ns: msg.capture_ns, t_ns, receive_ns };
        let mut out = Out { summary: &mut self.summary, sink: &mut *sink };
        for alert in &self.alerts {
            // The trigger's source about the other, then the other about the trigger's source.
            site.warn(
                (m as u32, alert.other),
                &alert.other_now,
                &alert.risk,
                &trigger,
                self.config.repeat_ns,
                &mut out,
            );
            site.warn((alert.other, m as u32), &state, &alert.risk, &trigger, self.config.repeat_ns, &mut out);
        }
        if t_ns >= site.next_sweep_ns {
            // Entries older than the repeat window hold nothing back any more.
            let repeat_ns = self.config.repeat_ns;
            site.last_warned.retain(|_, (last, _)| t_ns.saturating_sub(*last) < repeat_ns);
            site.next_sweep_ns = t_ns.saturating_add(repeat_ns.max(1));
        }
        // Highest first: a swap-remove moves the last member, never one still to go.
        while let Some(gone) = self.gone.pop() {
            self.forget(s, gone as usize, sink);
        }
    }

    /// Edge `source` of `site` left (its liveliness token went): it is forgotten, so that a new
    /// process under its name is taken in afresh (its clock estimate is reset too, and its
    /// first states may map before the old one's last).
    pub fn source_left(&mut self, site: &str, source: &str, sink: &mut dyn WarningSink) {
        let Some(&s) = self.site_index.get(site) else { return };
        if let Some(m) = self.sites[s].names.iter().position(|n| n == source) {
            self.forget(s, m, sink);
        }
    }

    /// What the path did so far.
    pub fn summary(&self) -> WarningSummary {
        let mut summary = self.summary.clone();
        for site in &self.sites {
            for (name, sent) in site.names.iter().zip(&site.sent).filter(|(_, n)| **n > 0) {
                *summary.sent_to.entry(format!("{}/{name}", site.name)).or_default() += *sent;
            }
        }
        summary
    }

    /// How many members (vehicles heard within `forget_ns`, not yet forgotten) all sites hold.
    pub fn members(&self) -> usize {
        self.sites.iter().map(|s| s.names.len()).sum()
    }

    /// Forgets member `m` of site `s`: its publisher goes (`sink.left`), its warnings sent are
    /// kept in the summary, its repeat-limit entries go.
    fn forget(&mut self, s: usize, m: usize, sink: &mut dyn WarningSink) {
        let site = &mut self.sites[s];
        if let Some(key) = site.keys[m].as_deref() {
            sink.left(key);
        }
        if site.sent[m] > 0 {
            *self.summary.sent_to.entry(format!("{}/{}", site.name, site.names[m])).or_default() += site.sent[m];
        }
        let source = site.sources[m];
        site.names.swap_remove(m);
        site.keys.swap_remove(m);
        site.sources.swap_remove(m);
        site.t_ns.swap_remove(m);
        site.latest.swap_remove(m);
        site.sent.swap_remove(m);
        site.last_warned.retain(|&(w, h), _| w != source && h != source);
        self.members[source as usize] = None;
        if let Some(&moved) = site.sources.get(m) {
            self.members[moved as usize] = Some((s as u32, m as u32));
        }
        self.summary.forgotten += 1;
    }

    /// The index of `site`, added if new.
    fn site(&mut self, site: &str) -> usize {
        if let Some(&i) = self.site_index.get(site) {
            return i;
        }
        self.sites.push(Site { name: site.to_owned(), ..Site::default() });
        self.site_index.insert(site.to_owned(), self.sites.len() - 1);
        self.sites.len() - 1
    }

    /// The (site, member) of ingest source `index`, added at `site` if new (a source stays at the
    /// site of its first state, as the ingest's other counts do).
    fn member(&mut self, site: &str, source: &str, index: usize, sink: &mut dyn WarningSink) -> (usize, usize) {
        if let Some(Some((s, m))) = self.members.get(index) {
            return (*s as usize, *m as usize);
        }
        let s = self.site(site);
        let key = match (SiteId::new(site), SourceId::new(source)) {
            (Ok(site), Ok(source)) => Some(cloud_to_edge(&site, &source, CloudToEdge::Warning)),
            _ => None,
        };
        if let Some(key) = key.as_deref() {
            sink.joined(key);
        }
        let site = &mut self.sites[s];
        site.names.push(source.to_owned());
        site.keys.push(key);
        site.sources.push(index as u32);
        site.t_ns.push(i64::MIN);
        site.latest.push(ObservedKinematics {
            pose: Pose::default(),
            velocity: Vec2::zeros(),
            speed_mps: 0.0,
            accel_mps2: 0.0,
            footprint: Footprint::new(1.0, 1.0),
            seqs: (0, 0),
        });
        site.sent.push(0);
        let m = site.names.len() - 1;
        if self.members.len() <= index {
            self.members.resize(index + 1, None);
        }
        self.members[index] = Some((s as u32, m as u32));
        (s, m)
    }
}

/// The state message that raised the assessments.
struct Trigger<'a> {
    source: &'a str,
    seq: u64,
    capture_ns: i64,
    /// Its time on the cloud's clock.
    t_ns: i64,
    receive_ns: i64,
}

/// Where warnings go and are counted.
struct Out<'a> {
    summary: &'a mut WarningSummary,
    sink: &'a mut dyn WarningSink,
}

impl Site {
    /// Sends one warning to member `warned` about member `hazard` (`hazard_now`: its state at the
    /// trigger's time), unless the pair was warned about within `repeat_ns` of message time.
    fn warn(
        &mut self,
        (warned, hazard): (u32, u32),
        hazard_now: &ObservedKinematics,
        risk: &PairRisk,
        trigger: &Trigger<'_>,
        repeat_ns: i64,
        out: &mut Out<'_>,
    ) {
        let pair = (self.sources[warned as usize], self.sources[hazard as usize]);
        let last = self.last_warned.get(&pair).copied();
        // Sources' clock estimates differ, so message times of two sources may come out of
        // order: with no limit, nothing is held back. A pair that comes to contact is warned
        // about at once (an escalation is news).
        let escalates = |kind: HazardKind| risk.kind == HazardKind::Contact && kind != HazardKind::Contact;
        if repeat_ns > 0 && last.is_some_and(|(t, kind)| trigger.t_ns.saturating_sub(t) < repeat_ns && !escalates(kind))
        {
            out.summary.rate_limited += 1;
            return;
        }
        let (w, h) = (warned as usize, hazard as usize);
        let Some(key) = self.keys[w].as_deref() else {
            out.summary.failed += 1;
            return;
        };
        let warning = HazardWarning {
            header: Header {
                source: CLOUD_CHUNK.to_owned(),
                seq: self.sent[w],
                capture_time_ns: trigger.t_ns,
                // The network sink stamps the put's time; until then, the trigger's receipt.
                publish_time_ns: trigger.receive_ns,
                frame: Frame::World,
            },
            warned_source: self.names[w].clone(),
            hazard_source: self.names[h].clone(),
            hazard_pose: hazard_now.pose,
            hazard_velocity: hazard_now.velocity,
            hazard_footprint: hazard_now.footprint,
            kind: risk.kind,
            ttc_s: risk.ttc_s,
            distance_m: risk.distance_m,
            trigger_source: trigger.source.to_owned(),
            trigger_seq: trigger.seq,
            trigger_capture_time_ns: trigger.capture_ns,
        };
        if !out.sink.put(key, &warning) {
            out.summary.failed += 1;
            return;
        }
        out.summary.sent += 1;
        self.sent[w] += 1;
        if repeat_ns > 0 {
            match self.last_warned.get_mut(&pair) {
                Some(last) => *last = (trigger.t_ns, risk.kind),
                None => {
                    self.last_warned.insert(pair, (trigger.t_ns, risk.kind));
                }
            }
        }
    }
}

#[cfg(test)]
mod tests;
