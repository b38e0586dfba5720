//! A scene's V2X messages decided one by one from a seed: each broadcast's latency from (seed,
//! sender, sequence) and each copy's fate from (seed, sender, receiver, sequence), so a decision
//! never depends on the order messages arrive in. A deployed scene's participants decide so in
//! real time, each in its own process (`risktwin_edge::fleet::v2x`); [`VirtualScene`] decides
//! the same CAM stream in virtual time in one process. Both agree message for message; only the
//! transport's own time differs.
//!
//! An RSU's warnings (DENM-like, [`super::warning`]'s hazard rule) are decided the same way
//! under their own stream tags, from (seed, RSU, warning sequence) and (seed, RSU, vehicle,
//! warning sequence); a copy is heard from the first step at or after made + latency
//! ([`warning_due`]). [`WarningSender`] and [`WarningInbox`] are the two ends of that path, used
//! alike by [`VirtualScene`] and by a deployed scene's RSUs and vehicles.

use super::awareness::receivers;
use super::cam::{CamState, CamTrigger};
use super::channel::LinkBudget;
use super::cpm::CpmGenerator;
use super::latency::Latency;
use super::link::V2xChannel;
use super::loss::BurstState;
use super::warning::{Heard, RepeatClock, Warning, is_hazard};
use risktwin_common::digest::fnv1a64;
use risktwin_common::histogram::Histogram;
use risktwin_common::rng::Rng;
use risktwin_common::sensor::PerceivedObject;
use serde::Serialize;
use std::collections::BTreeMap;

/// Stream tags: a broadcast's latency and a copy's fate never share random numbers.
const LATENCY_TAG: u8 = 1;
const COPY_TAG: u8 = 2;
/// A warning's latency and a copy's fate: an RSU's warnings are numbered apart from CAMs.
const WARNING_LATENCY_TAG: u8 = 3;
const WARNING_COPY_TAG: u8 = 4;
/// A CPM's latency and a copy's fate: an RSU's CPMs are numbered apart from its warnings.
const CPM_LATENCY_TAG: u8 = 5;
const CPM_COPY_TAG: u8 = 6;

/// How often a scene's RSU repeats its warnings while a hazard lasts, Hz (the sweep's default).
pub const SCENE_WARNING_HZ: f64 = 10.0;

/// Whether a warning copy made at `made_s` with `latency_ms` is heard in the step at `now_s`:
/// from the first step at or after its arrival, in virtual and in real time alike.
pub fn warning_due(made_s: f64, latency_ms: f64, now_s: f64) -> bool {
    made_s + latency_ms / 1e3 <= now_s + 1e-9
}

/// The hazards an RSU warns of among what it perceives ([`super::warning`]'s rule), in order.
pub fn hazards(seen: &[PerceivedObject]) -> impl Iterator<Item = &PerceivedObject> {
    seen.iter().filter(|o| is_hazard(o))
}

/// The channel of a scene's V2X paths and the seed its decisions derive from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MessageChannel {
    pub channel: V2xChannel,
    pub seed: u64,
}

/// The random stream of one decision: FNV-1a over the tag, the ids and the sequence number.
fn stream(tag: u8, sender: &str, receiver: &str, seq: u64) -> u64 {
    // A 0 byte ends each id: ("v1", "0…") and ("v10", "…") never meet.
    let ids = sender.bytes().chain([0]).chain(receiver.bytes()).chain([0]);
    fnv1a64([tag].into_iter().chain(ids).chain(seq.to_le_bytes()))
}

impl MessageChannel {
    /// FNV-1a over everything a decision depends on: the path-loss model, every field of the
    /// link budget, the latency, the burst chain and the seed (numbers as their exact bits).
    /// Participants whose channels differ would decide the same message differently.
    pub fn digest(&self) -> u64 {
        let V2xChannel { model, budget, latency, bursts } = self.channel;
        // Every field by name: a new one must be added here.
        let LinkBudget {
            carrier_ghz,
            tx_power_dbm,
            tx_antenna_gain_dbi,
            rx_antenna_gain_dbi,
            noise_figure_db,
            bandwidth_hz,
            sinr_threshold_db,
        } = budget;
        let mut numbers = vec![
            carrier_ghz,
            tx_power_dbm,
            tx_antenna_gain_dbi,
            rx_antenna_gain_dbi,
            noise_figure_db,
            bandwidth_hz,
            sinr_threshold_db,
        ];
        let latency_tag = match latency {
            Latency::Sidelink { t1_ms, t2_ms } => {
                numbers.extend([t1_ms, t2_ms]);
                1
            }
            Latency::Gamma { offset_ms, shape, scale_ms } => {
                numbers.extend([offset_ms, shape, scale_ms]);
                2
            }
        };
        let bursts_tag = match bursts {
            None => 0,
            Some(chain) => {
                numbers.extend([chain.enter, chain.leave]);
                1
            }
        };
        let head = model.name().bytes().chain([0, latency_tag, bursts_tag]);
        let numbers = numbers.into_iter().flat_map(|v| v.to_bits().to_le_bytes());
        fnv1a64(head.chain(numbers).chain(self.seed.to_le_bytes()))
    }

    /// For messages: `V2X 3gpp-urban-nlos sidelink:4:100` (and `bursts 0.3:5`, share and mean).
    pub fn describe(&self) -> String {
        let V2xChannel { model, latency, bursts, .. } = self.channel;
        let bursts = bursts.map_or(String::new(), |c| {
            // Back from the chain: share = enter / (enter + leave), mean burst = 1 / leave.
            format!(" bursts {:.3}:{:.3}", c.enter / (c.enter + c.leave), 1.0 / c.leave)
        });
        format!("V2X {} {latency}{bursts}", model.name())
    }

    /// When broadcast `seq` of `sender` goes out, ms after it is made: the same for every
    /// receiver (one transmission on one resource).
    pub fn latency_ms(&self, sender: &str, seq: u64) -> f64 {
        self.channel.latency_ms(&mut Rng::derive(self.seed, stream(LATENCY_TAG, sender, "", seq)))
    }

    /// Whether `receiver`'s copy of broadcast `seq` of `sender` arrives over `distance_m`;
    /// `burst` is the pair's chain, stepped in the sender's sequence order.
    pub fn passes(&self, sender: &str, receiver: &str, seq: u64, distance_m: f64, burst: &mut BurstState) -> bool {
        let mut rng = Rng::derive(self.seed, stream(COPY_TAG, sender, receiver, seq));
        self.channel.receives(distance_m, burst, &mut rng)
    }

    /// When warning `seq` of RSU `sender` goes out, ms after it is made.
    pub fn warning_latency_ms(&self, sender: &str, seq: u64) -> f64 {
        self.channel.latency_ms(&mut Rng::derive(self.seed, stream(WARNING_LATENCY_TAG, sender, "", seq)))
    }

    /// Whether `receiver`'s copy of warning `seq` of RSU `sender` arrives over `distance_m`;
    /// `burst` is the pair's warning chain, stepped in the sender's warning order.
    pub fn warning_passes(
        &self,
        sender: &str,
        receiver: &str,
        seq: u64,
        distance_m: f64,
        burst: &mut BurstState,
    ) -> bool {
        let mut rng = Rng::derive(self.seed, stream(WARNING_COPY_TAG, sender, receiver, seq));
        self.channel.receives(distance_m, burst, &mut rng)
    }

    /// When CPM `seq` of RSU `sender` goes out, ms after it is made.
    pub fn cpm_latency_ms(&self, sender: &str, seq: u64) -> f64 {
        self.channel.latency_ms(&mut Rng::derive(self.seed, stream(CPM_LATENCY_TAG, sender, "", seq)))
    }

    /// Whether `receiver`'s copy of CPM `seq` of RSU `sender` arrives over `distance_m`; `burst`
    /// is the pair's CPM chain, stepped in the sender's CPM order.
    pub fn cpm_passes(&self, sender: &str, receiver: &str, seq: u64, distance_m: f64, burst: &mut BurstState) -> bool {
        let mut rng = Rng::derive(self.seed, stream(CPM_COPY_TAG, sender, receiver, seq));
        self.channel.receives(distance_m, burst, &mut rng)
    }
}

/// An RSU's warnings: its repetitions and its warning count, whose sequence numbers the copies'
/// decisions derive from.
#[derive(Debug, Clone)]
pub struct WarningSender {
    repeat: RepeatClock,
    seq: u64,
}

impl Default for WarningSender {
    fn default() -> Self {
        WarningSender { repeat: RepeatClock::new(SCENE_WARNING_HZ), seq: 0 }
    }
}

impl WarningSender {
    /// The warnings made at `now_s` of the hazards in `seen`, if a repetition is due: into `out`
    /// as (sequence, object), in `seen`'s order, counted in `tally`. `out` is cleared first.
    pub fn make(
        &mut self,
        now_s: f64,
        seen: &[PerceivedObject],
        out: &mut Vec<(u64, PerceivedObject)>,
        tally: &mut V2xTally,
    ) {
        out.clear();
        if !self.repeat.due(now_s) {
            return;
        }
        for object in hazards(seen) {
            out.push((self.seq, *object));
            self.seq += 1;
            tally.warnings_made += 1;
        }
    }
}

/// An RSU's Collective Perception Messages: which objects each includes ([`CpmGenerator`]) and
/// their count, whose sequence numbers the copies' decisions derive from.
#[derive(Debug, Clone, Default)]
pub struct CpmSender {
    generator: CpmGenerator,
    seq: u64,
}

impl CpmSender {
    /// The CPM made at `now_s` from what the RSU perceived (`seen`): its sequence number, with
    /// its objects in `out`, or `None` when no object is due (`out` then empty). Counted.
    pub fn make(
        &mut self,
        now_s: f64,
        seen: &[PerceivedObject],
        out: &mut Vec<PerceivedObject>,
        tally: &mut V2xTally,
    ) -> Option<u64> {
        self.generator.select(now_s, seen, out);
        if out.is_empty() {
            return None;
        }
        let seq = self.seq;
        self.seq += 1;
        tally.cpms_made += 1;
        tally.cpm_objects_sent += out.len() as u64;
        Some(seq)
    }
}

/// A held copy: a warning's object or a CPM's.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Carrier {
    Warning,
    Cpm,
}

/// A vehicle's end of the RSUs' warnings and CPMs: decides its copies, holds the passed ones
/// until made + latency and hears their objects into its [`Heard`] (all but the vehicle itself,
/// which an RSU perceives as any other object).
#[derive(Debug, Default)]
pub struct WarningInbox {
    /// The vehicle's own object id in the truth.
    own_object: Option<u32>,
    /// Passed copies on their way: (made, latency ms, object, carrier), in the order they were
    /// decided.
    in_flight: Vec<(f64, f64, Warning, Carrier)>,
    /// The pairs' burst chains by RSU, stepped in each RSU's warning (CPM) order.
    bursts: BTreeMap<String, BurstState>,
    cpm_bursts: BTreeMap<String, BurstState>,
    heard: Heard,
}

/// The pair's burst chain with `sender`, made on first use.
fn chain<'a>(bursts: &'a mut BTreeMap<String, BurstState>, sender: &str) -> &'a mut BurstState {
    if !bursts.contains_key(sender) {
        bursts.insert(sender.to_owned(), BurstState::default());
    }
    bursts.get_mut(sender).expect("inserted")
}

impl WarningInbox {
    /// The inbox of the vehicle that is object `own_object` in the truth.
    pub fn new(own_object: u32) -> WarningInbox {
        WarningInbox { own_object: Some(own_object), ..WarningInbox::default() }
    }

    /// `receiver`'s copy of warning `seq` of RSU `sender` over `distance_m`, with the warning's
    /// drawn `latency_ms`: counted, and held if the channel passes it. Decide each RSU's copies
    /// in its sequence order, and copies of one step before those of the next: the order they
    /// are heard in breaks ties ([`Heard::hear`]). Whether it passed.
    #[allow(clippy::too_many_arguments)]
    pub fn decide(
        &mut self,
        channel: &MessageChannel,
        (sender, receiver): (&str, &str),
        seq: u64,
        distance_m: f64,
        latency_ms: f64,
        warning: Warning,
        tally: &mut V2xTally,
    ) -> bool {
        tally.warning_copies += 1;
        let passes = channel.warning_passes(sender, receiver, seq, distance_m, chain(&mut self.bursts, sender));
        if passes {
            tally.warnings_passed += 1;
            self.in_flight.push((warning.made_s, latency_ms, warning, Carrier::Warning));
        }
        passes
    }

    /// `receiver`'s copy of CPM `seq` of RSU `sender`, made at `made_s` with `objects`, over
    /// `distance_m` with the CPM's drawn `latency_ms`: counted, and its objects held if the
    /// channel passes it (one copy, one fate for all). Decide an RSU's CPM of a step after its
    /// warnings of that step. Whether it passed.
    #[allow(clippy::too_many_arguments)]
    pub fn decide_cpm(
        &mut self,
        channel: &MessageChannel,
        (sender, receiver): (&str, &str),
        seq: u64,
        distance_m: f64,
        (made_s, latency_ms): (f64, f64),
        objects: &[PerceivedObject],
        tally: &mut V2xTally,
    ) -> bool {
        tally.cpm_copies += 1;
        let passes = channel.cpm_passes(sender, receiver, seq, distance_m, chain(&mut self.cpm_bursts, sender));
        if passes {
            tally.cpms_passed += 1;
            let held = objects.iter().map(|&object| (made_s, latency_ms, Warning { made_s, object }, Carrier::Cpm));
            self.in_flight.extend(held);
        }
        passes
    }

    /// Copies due by `now_s` are heard; what was heard and is not in `perceived`, moved on to
    /// `now_s`: the driver's warned objects. Call once per step, before the driver acts.
    pub fn warned(&mut self, now_s: f64, perceived: &[PerceivedObject], tally: &mut V2xTally) -> &[PerceivedObject] {
        let (heard, own) = (&mut self.heard, self.own_object);
        self.in_flight.retain(|&(made_s, latency_ms, w, carrier)| {
            let due = warning_due(made_s, latency_ms, now_s);
            // Its own object is dropped unheard and uncounted.
            if due && Some(w.object.id) != own {
                match carrier {
                    Carrier::Warning => tally.warnings_heard += 1,
                    Carrier::Cpm => tally.cpm_objects_heard += 1,
                }
                heard.hear(now_s, w);
            }
            !due
        });
        heard.forget_old(now_s);
        let warned = heard.warned(now_s, perceived);
        tally.warned_steps += u64::from(!warned.is_empty());
        warned
    }
}

/// One participant's V2X counts.
#[derive(Debug, Default)]
pub struct V2xTally {
    /// CAMs this participant broadcast.
    pub cams_sent: u64,
    /// Copies of others' CAMs it decided (the channel applied).
    pub copies: u64,
    /// Of those, passed by the channel (some may still be held when the scene ends).
    pub passed: u64,
    /// Passed copies handed over after their latency.
    pub delivered: u64,
    /// Latency of the delivered copies, µs: real time measures arrival wall − sent wall.
    pub latency_us: Histogram,
    /// Warnings this participant (an RSU) made: one per hazard per repetition.
    pub warnings_made: u64,
    /// Copies of RSUs' warnings it decided, passed, and heard (handed to its driver's view
    /// from the first step at or after made + latency).
    pub warning_copies: u64,
    pub warnings_passed: u64,
    pub warnings_heard: u64,
    /// Steps whose driver view held a warned object it did not perceive itself (heard of over
    /// a warning or a CPM).
    pub warned_steps: u64,
    /// CPMs this participant (an RSU) made, and the objects they carried.
    pub cpms_made: u64,
    pub cpm_objects_sent: u64,
    /// Copies of RSUs' CPMs it decided and passed, and the objects of passed copies heard.
    pub cpm_copies: u64,
    pub cpms_passed: u64,
    pub cpm_objects_heard: u64,
}

/// What [`V2xTally`] reports.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct V2xSummary {
    pub cams_sent: u64,
    pub copies: u64,
    pub passed: u64,
    pub lost: u64,
    pub delivered: u64,
    /// passed / copies; `None` with no copy.
    pub pdr: Option<f64>,
    pub latency_p50_ms: Option<f64>,
    pub latency_p95_ms: Option<f64>,
    pub warnings_made: u64,
    pub warning_copies: u64,
    pub warnings_passed: u64,
    pub warnings_heard: u64,
    pub warned_steps: u64,
    pub cpms_made: u64,
    pub cpm_objects_sent: u64,
    pub cpm_copies: u64,
    pub cpms_passed: u64,
    pub cpm_objects_heard: u64,
}

impl V2xTally {
    pub fn summary(&self) -> V2xSummary {
        let ms = |q| self.latency_us.quantile(q).map(|us| us / 1e3);
        V2xSummary {
            cams_sent: self.cams_sent,
            copies: self.copies,
            passed: self.passed,
            lost: self.copies - self.passed,
            delivered: self.delivered,
            pdr: (self.copies > 0).then(|| self.passed as f64 / self.copies as f64),
            latency_p50_ms: ms(0.5),
            latency_p95_ms: ms(0.95),
            warnings_made: self.warnings_made,
            warning_copies: self.warning_copies,
            warnings_passed: self.warnings_passed,
            warnings_heard: self.warnings_heard,
            warned_steps: self.warned_steps,
            cpms_made: self.cpms_made,
            cpm_objects_sent: self.cpm_objects_sent,
            cpm_copies: self.cpm_copies,
            cpms_passed: self.cpms_passed,
            cpm_objects_heard: self.cpm_objects_heard,
        }
    }
}

/// A participant of a [`VirtualScene`].
struct Member {
    id: String,
    /// Vehicles send CAMs; roadside units only receive.
    trigger: Option<CamTrigger>,
    seq: u64,
    tally: V2xTally,
    /// Copies on their way to this member: arrival time, s, and latency, µs.
    in_flight: Vec<(f64, u64)>,
    /// Burst chains of the pairs with this member as receiver, by sender.
    bursts: BTreeMap<usize, BurstState>,
    /// An RSU's warnings and CPMs (made only with [`VirtualScene::warning`], [`VirtualScene::cpm`]).
    sender: Option<(WarningSender, CpmSender)>,
    /// A vehicle's warnings and CPMs received.
    inbox: WarningInbox,
}

/// The V2X layers of every participant of a scene, in virtual time in one process.
pub struct VirtualScene {
    channel: MessageChannel,
    members: Vec<Member>,
    warnings: bool,
    cpm: bool,
    /// The warnings one RSU makes in one step, and its CPM's objects.
    made: Vec<(u64, PerceivedObject)>,
    cpm_objects: Vec<PerceivedObject>,
}

impl VirtualScene {
    /// `members`: each participant's id and, for a vehicle (it sends CAMs), its object id in the
    /// truth; `None` for an RSU (it only receives CAMs).
    pub fn new(channel: MessageChannel, members: &[(String, Option<u32>)]) -> VirtualScene {
        let members = members
            .iter()
            .map(|(id, object)| Member {
                id: id.clone(),
                trigger: object.map(|_| CamTrigger::default()),
                seq: 0,
                tally: V2xTally::default(),
                in_flight: Vec::new(),
                bursts: BTreeMap::new(),
                sender: object.is_none().then(Default::default),
                inbox: object.map_or_else(WarningInbox::default, WarningInbox::new),
            })
            .collect();
        let (made, cpm_objects) = (Vec::new(), Vec::new());
        VirtualScene { channel, members, warnings: false, cpm: false, made, cpm_objects }
    }

    /// With `on`, the RSUs warn the vehicles of the hazards they perceive ([`Self::warn`]).
    pub fn warning(mut self, on: bool) -> VirtualScene {
        self.warnings = on;
        self
    }

    /// With `on`, the RSUs send CPMs of what they perceive ([`Self::warn`]).
    pub fn cpm(mut self, on: bool) -> VirtualScene {
        self.cpm = on;
        self
    }

    /// Warning copies due by `now_s` are heard; what member `member` heard and does not
    /// perceive itself (`perceived`), moved on to `now_s`: its driver's warned objects. Call
    /// once per member and step, before it acts.
    pub fn warned(&mut self, member: usize, now_s: f64, perceived: &[PerceivedObject]) -> &[PerceivedObject] {
        let m = &mut self.members[member];
        m.inbox.warned(now_s, perceived, &mut m.tally)
    }

    /// The RSUs warn at `now_s` of the hazards each perceived in this step (`seen`, per member;
    /// empty for vehicles), if a repetition is due, and send a CPM if objects are due: each
    /// warning and CPM goes to every vehicle in the world now, decided per copy from the
    /// distance between the RSU's and the vehicle's states. Nothing without [`Self::warning`]
    /// or [`Self::cpm`].
    pub fn warn(&mut self, now_s: f64, states: &[Option<CamState>], seen: &[&[PerceivedObject]]) {
        assert_eq!(states.len(), self.members.len(), "VirtualScene::warn: one state per member");
        assert_eq!(seen.len(), self.members.len(), "VirtualScene::warn: one perception per member");
        if !self.warnings && !self.cpm {
            return;
        }
        for sender in 0..self.members.len() {
            let member = &mut self.members[sender];
            let Some((warnings, cpms)) = &mut member.sender else { continue };
            if states[sender].is_none() {
                continue;
            }
            self.made.clear();
            if self.warnings {
                warnings.make(now_s, seen[sender], &mut self.made, &mut member.tally);
            }
            let cpm = match self.cpm {
                true => cpms.make(now_s, seen[sender], &mut self.cpm_objects, &mut member.tally),
                false => None,
            };
            let sender_id = member.id.clone();
            for &(seq, object) in &self.made {
                let latency_ms = self.channel.warning_latency_ms(&sender_id, seq);
                let warning = Warning { made_s: now_s, object };
                for (receiver, distance_m) in receivers(states, sender) {
                    let Member { id, trigger, inbox, tally, .. } = &mut self.members[receiver];
                    if trigger.is_some() {
                        let ids = (sender_id.as_str(), id.as_str());
                        inbox.decide(&self.channel, ids, seq, distance_m, latency_ms, warning, tally);
                    }
                }
            }
            let Some(seq) = cpm else { continue };
            let latency_ms = self.channel.cpm_latency_ms(&sender_id, seq);
            for (receiver, distance_m) in receivers(states, sender) {
                let Member { id, trigger, inbox, tally, .. } = &mut self.members[receiver];
                if trigger.is_some() {
                    let ids = (sender_id.as_str(), id.as_str());
                    let objects = &self.cpm_objects;
                    inbox.decide_cpm(&self.channel, ids, seq, distance_m, (now_s, latency_ms), objects, tally);
                }
            }
        }
    }

    /// One step at `now_s`: each member's state in member order, `None` for one not in the
    /// world now (it neither sends nor receives). Copies due by `now_s` are delivered first.
    ///
    /// # Panics
    /// When `states` does not hold exactly one state per member (a caller's bug: a state would
    /// be taken for another member's).
    pub fn step(&mut self, now_s: f64, states: &[Option<CamState>]) {
        assert_eq!(states.len(), self.members.len(), "VirtualScene::step: one state per member");
        for member in &mut self.members {
            let tally = &mut member.tally;
            member.in_flight.retain(|&(arrives_s, latency_us)| {
                let due = arrives_s <= now_s;
                if due {
                    tally.delivered += 1;
                    tally.latency_us.record(latency_us);
                }
                !due
            });
        }
        for sender in 0..self.members.len() {
            let Some(state) = states[sender] else { continue };
            let member = &mut self.members[sender];
            let Some(trigger) = &mut member.trigger else { continue };
            if trigger.check(state).is_none() {
                continue;
            }
            let seq = member.seq;
            member.seq += 1;
            member.tally.cams_sent += 1;
            let sender_id = member.id.clone();
            let latency_ms = self.channel.latency_ms(&sender_id, seq);
            for (receiver, distance_m) in receivers(states, sender) {
                let member = &mut self.members[receiver];
                let burst = member.bursts.entry(sender).or_default();
                member.tally.copies += 1;
                if self.channel.passes(&sender_id, &member.id, seq, distance_m, burst) {
                    member.tally.passed += 1;
                    let latency_us = (latency_ms * 1e3).round() as u64;
                    member.in_flight.push((now_s + latency_ms / 1e3, latency_us));
                }
            }
        }
    }

    /// Each member's counts, by id.
    pub fn summaries(&self) -> BTreeMap<String, V2xSummary> {
        self.members.iter().map(|m| (m.id.clone(), m.tally.summary())).collect()
    }
}

#[cfg(test)]
mod tests;
