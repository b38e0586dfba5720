//! The V2X layer of a scene's participants, in real time: each connected vehicle sends CAMs by
//! the ETSI generation rules from its own state in each step's truth, on
//! `risktwin/v1/<site>/scene/v2x/<participant>`; every other participant (vehicles and RSUs)
//! receives them and applies the channel per message and per receiver, from the distance
//! between the CAM's position and its own position in the truth of the step the CAM was made
//! in: the copy is lost or passed (`MessageChannel::passes`), and a passed copy is held until
//! its sent wall time plus the broadcast's latency (`MessageChannel::latency_ms`) by a delivery
//! thread, never by the physics. The decisions derive from (seed, sender, receiver, sequence),
//! so `risktwin_v2x::messages::VirtualScene`, which the embedded scene runs, makes the
//! same ones in virtual time.
//!
//! The latency is imposed, not measured: the hold ends at sent + the seeded draw that virtual
//! time records. What real time adds is the **excess**, per delivered copy: arrival − (sent +
//! drawn latency), the delivery timer's overshoot, or the transport's where the copy came (or
//! could be decided) only after its drawn latency had passed (then counted `late`, its hold 0).
//! Sent and arrival are wall clocks of two processes: on different hosts they must be
//! synchronised. At the scene's end each sender announces how many CAMs it sent, and a receiver
//! waits (at most [`FINISH_WAIT`]) until it has decided every copy it can still expect; what it
//! could not is counted `undecided`, never dropped silently.
//!
//! With warnings (`--v2x-warnings`) or CPMs (`--v2x-cpm`), each RSU also sends, every step
//! before it answers, the DENM-like warnings and the CPM it made in that step (often none: the
//! batch then says the step is done),
//! and a vehicle, before its driver acts in step k, waits (at most [`WARNING_WAIT`]) for every
//! RSU's batch of step k − 1 and decides its copies as virtual time does
//! (`risktwin_v2x::messages::WarningInbox`): from the distance between the mast and its
//! own position in the step the warning was made, heard from the first step at or after made +
//! drawn latency. So a warned episode is the embedded one step for step. What real time adds is
//! counted: copies whose batch came after their drawn latency had passed (`warnings_late`,
//! `cpms_late`), and batches that had not come when a step needed them (`warning_batches_late`).

mod rsu;
mod wire;

use super::onboard::Onboard;
use super::reliable::reliable_publisher;
use super::wire::Truth;
use super::{Role, SceneError, SceneSetup};
use risktwin_common::histogram::Histogram;
use risktwin_common::sensor::PerceivedObject;
use risktwin_transport::keyexpr::{scene_v2x, scene_v2x_all};
use risktwin_transport::sync::{CondvarExt, LockExt};
use risktwin_transport::wall_clock::unix_ns;
use risktwin_transport::zenoh::pubsub::{Publisher, Subscriber};
use risktwin_transport::zenoh::sample::Sample;
use risktwin_transport::zenoh::{Session, Wait};
use risktwin_transport::{SiteId, SourceId};
use risktwin_v2x::cam::{CamState, CamTrigger};
use risktwin_v2x::loss::BurstState;
use risktwin_v2x::messages::{CpmSender, MessageChannel, V2xSummary, V2xTally, WarningInbox, WarningSender};
use rsu::{RsuBatches, after};
use serde::Serialize;
use std::cmp::Reverse;
use std::collections::{BTreeMap, BinaryHeap};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use wire::V2X_SCHEMA;
pub use wire::{RsuBatch, V2xBody, WireCam, WireCpm, WireV2x};

/// Steps of its own positions a receiver keeps for CAMs made in them (10 s of scene).
const OWN_HISTORY_STEPS: u64 = 200;

/// How far ahead of its own latest step a CAM may be made and still wait for that step; and
/// how many CAMs may wait at once. Beyond, a CAM is dropped and counted (`ahead`).
const AHEAD_STEPS: u64 = OWN_HISTORY_STEPS;
const MAX_WAITING: usize = 4096;

/// How long [`V2xLayer::finish`] waits for the copies it can still expect.
pub const FINISH_WAIT: Duration = Duration::from_millis(500);

/// How long a vehicle waits for the RSUs' warnings of the step before the one it answers. They
/// were sent before the RSUs answered that step, so through one router they are already here;
/// the wait covers paths that reorder, well inside the authority's step timeout.
pub const WARNING_WAIT: Duration = Duration::from_millis(500);

/// The longest a passed copy is held: a sent time far in the future (a wrong clock, a hostile
/// sender) neither holds it for ever nor overflows the timer.
const MAX_HOLD: Duration = Duration::from_secs(60);

/// A participant's own state in `truth` as a CAM carries it: a vehicle's pose and speed, an
/// RSU's mast (standing); `None` for a vehicle not in the world now.
pub fn cam_state(truth: &Truth, stack: &Onboard) -> Option<CamState> {
    let time_s = truth.time_s;
    let (x_m, y_m, heading_rad, speed_mps) = match stack.role() {
        Role::Ego => {
            let [x, y, heading] = truth.ego.pose;
            (x, y, heading, truth.ego.speed_mps)
        }
        Role::Agent { traffic_index } => {
            let o = truth.objects.iter().find(|o| o.id == traffic_index as u32)?;
            (o.centre[0], o.centre[1], o.axis[1].atan2(o.axis[0]), o.velocity[0].hypot(o.velocity[1]))
        }
        Role::Rsu { .. } => {
            let (mast, _) = stack.mast();
            (mast.x_m, mast.y_m, mast.heading_rad, 0.0)
        }
    };
    Some(CamState { time_s, x_m, y_m, heading_rad, speed_mps })
}

/// A participant's V2X counts in real time: the decisions (as virtual time counts them) and
/// what only real time has.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct V2xReport {
    #[serde(flatten)]
    pub summary: V2xSummary,
    /// Passed copies whose drawn latency had already passed when they could be decided (the
    /// transport, or this participant's own step, took longer): handed over at once.
    pub late: u64,
    /// Arrival − (sent + drawn latency) of the delivered copies, ms: the delivery timer's
    /// overshoot, and the transport's for late copies.
    pub excess_p50_ms: Option<f64>,
    pub excess_p99_ms: Option<f64>,
    /// CAMs of others this layer knows were sent but could not decide by the end: still
    /// waiting for their step, or announced (by a later sequence number or the sender's end)
    /// and never arrived. Each is at most one copy.
    pub undecided: u64,
    /// CAMs (and warning batches) made in a step whose own position this layer no longer (or
    /// never) held.
    pub stale: u64,
    /// CAMs (and RSU batches) dropped for being made too far ahead of this participant's own
    /// steps.
    pub ahead: u64,
    /// Messages that did not decode, of another schema, from no sending participant of the
    /// scene, on another participant's key, repeated, or with a non-finite state.
    pub malformed: u64,
    /// Messages of another scene (or of the same scene with another V2X channel).
    pub foreign: u64,
    /// Passed warning (CPM) copies whose batch came after their drawn latency had passed: heard
    /// in the step virtual time hears them, but real time could not have.
    pub warnings_late: u64,
    pub cpms_late: u64,
    /// RSU warning batches that had not come when the step that needed them was answered
    /// (decided later, or never): the episode may then differ from virtual time's.
    pub warning_batches_late: u64,
    /// RSU warning batches that never came (a later step's came first): their copies were never
    /// decided.
    pub warning_batches_lost: u64,
}

/// One sending participant, as a receiver sees it.
#[derive(Debug, Default)]
struct Peer {
    /// The pair's burst chain, stepped in the sender's sequence order.
    burst: BurstState,
    /// CAMs taken from it: decided, waiting, or dropped and counted.
    taken: u64,
    /// The sequence number expected next (one past the highest taken).
    next_seq: u64,
    /// The count its end announced.
    ended: Option<u64>,
    /// Whether its hello came: its messages reach this participant.
    hello: bool,
}

/// A passed copy held until its due time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
struct Held {
    due: Instant,
    sent_unix_ns: i64,
    /// sent + the drawn latency, ns since the Unix epoch.
    due_unix_ns: i64,
}

/// What the receiving side holds, shared by the subscriber's callback, the stepping callback,
/// the delivery thread and the end.
#[derive(Default)]
struct Receiving {
    /// This participant's position by step (`None`: not in the world then).
    own: BTreeMap<u64, Option<(f64, f64)>>,
    latest_step: Option<u64>,
    /// CAMs made in a step this participant has not seen yet, with their sender.
    waiting: Vec<(String, WireCam)>,
    /// Every other sending participant of the scene, by id.
    peers: BTreeMap<String, Peer>,
    held: BinaryHeap<Reverse<Held>>,
    tally: V2xTally,
    late: u64,
    excess_us: Histogram,
    stale: u64,
    ahead: u64,
    malformed: u64,
    foreign: u64,
    closed: bool,
    /// At a vehicle of a scene with warnings: every RSU's batches, in participant order.
    rsus: Vec<RsuBatches>,
    warnings: WarningInbox,
    warnings_late: u64,
    cpms_late: u64,
    warning_batches_late: u64,
    warning_batches_lost: u64,
}

impl Receiving {
    /// Every copy this layer can still expect is decided: nothing waits, every sender has
    /// announced its end and all its CAMs have come, and every RSU's warnings of the last step
    /// have come.
    fn settled(&self) -> bool {
        self.waiting.is_empty()
            && self.peers.values().all(|p| p.ended.is_some_and(|n| p.taken >= n))
            && self.has_warnings_through(self.latest_step)
    }

    /// Every participant whose messages this one decides has been heard (its hello came).
    fn heard_everyone(&self) -> bool {
        self.peers.values().all(|p| p.hello) && self.rsus.iter().all(|r| r.hello)
    }

    /// Every RSU's warning batch of `step` (and before) has come.
    fn has_warnings_through(&self, step: Option<u64>) -> bool {
        self.rsus.iter().all(|r| after(r.through) >= after(step))
    }

    /// CAMs known to be sent and not decided.
    fn undecided(&self) -> u64 {
        let unarrived = self.peers.values().map(|p| p.ended.unwrap_or(0).max(p.next_seq).saturating_sub(p.taken));
        self.waiting.len() as u64 + unarrived.sum::<u64>()
    }
}

struct Inbox {
    id: String,
    scene: u64,
    channel: MessageChannel,
    /// The scene's RSUs, when it has warnings: their batches are not malformed anywhere.
    warners: Vec<String>,
    state: Mutex<Receiving>,
    /// Wakes the delivery thread: a copy held, or the layer closed.
    wake: Condvar,
    /// Wakes the end: a message taken.
    taken: Condvar,
}

impl Inbox {
    /// A message on `key`.
    fn on_sample(&self, key: &str, payload: &[u8]) {
        let mut state = self.state.locked();
        self.take(&mut state, key, payload);
        self.taken.notify_all();
    }

    fn take(&self, state: &mut Receiving, key: &str, payload: &[u8]) {
        let message = match postcard::from_bytes::<WireV2x>(payload) {
            Ok(message) if message.schema == V2X_SCHEMA => message,
            Ok(_) | Err(_) => {
                state.malformed += 1;
                return;
            }
        };
        if message.scene != self.scene {
            state.foreign += 1;
            return;
        }
        // The sender is the key's: nobody speaks for another participant.
        if key.rsplit('/').next() != Some(message.sender.as_str()) {
            state.malformed += 1;
            return;
        }
        if message.sender == self.id {
            return;
        }
        if let V2xBody::Rsu(batch) = message.body {
            self.take_warnings(state, &message.sender, batch);
            return;
        }
        if message.body == V2xBody::Hello {
            let sender = message.sender.as_str();
            if let Some(peer) = state.peers.get_mut(sender) {
                peer.hello = true;
            } else if let Some(rsu) = state.rsus.iter_mut().find(|r| r.id == sender) {
                rsu.hello = true;
            } else if !self.warners.iter().any(|w| w == sender) {
                state.malformed += 1;
            }
            return;
        }
        let Some(peer) = state.peers.get_mut(&message.sender) else {
            // Not a sending participant of this scene (an RSU sends nothing).
            state.malformed += 1;
            return;
        };
        let cam = match message.body {
            V2xBody::End { cams } if peer.ended.is_none() => {
                peer.ended = Some(cams);
                return;
            }
            V2xBody::Cam(cam) if cam.seq >= peer.next_seq && cam.state.iter().all(|v| v.is_finite()) => cam,
            V2xBody::End { .. } | V2xBody::Cam(_) | V2xBody::Rsu(_) | V2xBody::Hello => {
                state.malformed += 1;
                return;
            }
        };
        peer.next_seq = cam.seq + 1;
        peer.taken += 1;
        let latest = state.latest_step;
        if latest.is_some_and(|latest| cam.step <= latest) {
            self.decide(state, &message.sender, &cam);
        } else if cam.step > latest.unwrap_or(0).saturating_add(AHEAD_STEPS) || state.waiting.len() >= MAX_WAITING {
            state.ahead += 1;
        } else {
            state.waiting.push((message.sender, cam));
        }
    }

    /// Applies the channel to this participant's copy of `sender`'s `cam`: counted, and held
    /// if it passes.
    fn decide(&self, state: &mut Receiving, sender: &str, cam: &WireCam) {
        let (x_m, y_m) = match state.own.get(&cam.step) {
            Some(&Some(own)) => own,
            // Not in the world when the CAM was made: no copy (as in virtual time).
            Some(None) => return,
            None => {
                state.stale += 1;
                if state.stale == 1 {
                    tracing::warn!(
                        "V2X {}: no own position for step {} (CAM {} of {sender}); counted stale",
                        self.id,
                        cam.step,
                        cam.seq
                    );
                }
                return;
            }
        };
        let Some(peer) = state.peers.get_mut(sender) else { return };
        let distance_m = (cam.state[0] - x_m).hypot(cam.state[1] - y_m);
        let passes = self.channel.passes(sender, &self.id, cam.seq, distance_m, &mut peer.burst);
        state.tally.copies += 1;
        if !passes {
            return;
        }
        state.tally.passed += 1;
        // The same draw virtual time records: the latency is imposed here, not measured.
        let latency_ns = (self.channel.latency_ms(sender, cam.seq) * 1e6).round() as i64;
        let due_unix_ns = cam.sent_unix_ns.saturating_add(latency_ns);
        let wait_ns = due_unix_ns.saturating_sub(unix_ns());
        if wait_ns <= 0 {
            state.late += 1;
        }
        let wait = Duration::from_nanos(wait_ns.max(0) as u64).min(MAX_HOLD);
        state.held.push(Reverse(Held { due: Instant::now() + wait, sent_unix_ns: cam.sent_unix_ns, due_unix_ns }));
        self.wake.notify_one();
    }

    /// This participant's position in step `step`; decides the CAMs that waited for it.
    fn on_step(&self, step: u64, own: Option<(f64, f64)>) {
        let mut state = self.state.locked();
        state.own.insert(step, own);
        state.own.retain(|&k, _| k + OWN_HISTORY_STEPS > step);
        state.latest_step = Some(step);
        let (ready, waiting): (Vec<_>, Vec<_>) =
            std::mem::take(&mut state.waiting).into_iter().partition(|(_, cam)| cam.step <= step);
        state.waiting = waiting;
        for (sender, cam) in &ready {
            self.decide(&mut state, sender, cam);
        }
        self.taken.notify_all();
    }

    /// Hands over each held copy at its due time, measuring its latency and excess on the wall
    /// clock.
    fn deliver(&self) {
        let mut state = self.state.locked();
        while !state.closed {
            let now = Instant::now();
            while let Some(&Reverse(held)) = state.held.peek() {
                if held.due > now {
                    break;
                }
                state.held.pop();
                let arrival_ns = unix_ns();
                let us = |ns: i64| (ns.max(0) as u64).div_ceil(1000);
                state.tally.delivered += 1;
                state.tally.latency_us.record(us(arrival_ns.saturating_sub(held.sent_unix_ns)));
                state.excess_us.record(us(arrival_ns.saturating_sub(held.due_unix_ns)));
            }
            state = match state.held.peek() {
                Some(&Reverse(held)) => {
                    let wait = held.due.saturating_duration_since(now);
                    self.wake.waited_for(state, wait)
                }
                None => self.wake.waited(state),
            };
        }
    }
}

/// One participant's V2X layer on a Zenoh session.
pub struct V2xLayer {
    inbox: Arc<Inbox>,
    _subscriber: Subscriber<()>,
    publisher: Publisher<'static>,
    deliverer: Option<JoinHandle<()>>,
    /// A vehicle's CAM generation; an RSU sends none.
    trigger: Option<CamTrigger>,
    seq: u64,
    /// An RSU's warnings and CPMs, when the scene has them, and those it made in a step.
    warnings: Option<WarningSender>,
    cpms: Option<CpmSender>,
    made: Vec<(u64, PerceivedObject)>,
    cpm_objects: Vec<PerceivedObject>,
    /// What a vehicle's driver is warned of in this step.
    warned: Vec<PerceivedObject>,
}

impl V2xLayer {
    /// Declares participant `id`'s V2X publisher and its subscriber to every participant's
    /// broadcasts in scene `setup` over `channel`, and starts its delivery thread.
    pub fn open(
        session: &Session,
        site: &SiteId,
        setup: &SceneSetup,
        id: &SourceId,
        channel: MessageChannel,
    ) -> Result<V2xLayer, SceneError> {
        let transport =
            |key: &str, e: Box<dyn std::error::Error + Send + Sync>| SceneError::Transport(format!("{key}: {e}"));
        let sends = |p: &str| setup.role_of(p).is_ok_and(|role| !matches!(role, Role::Rsu { .. }));
        let peers = setup.participants().into_iter().filter(|p| sends(p) && p != id.as_str());
        let warners: Vec<String> = match setup.rsus_send() {
            true => setup.participants().into_iter().filter(|p| !sends(p)).collect(),
            false => Vec::new(),
        };
        let is_vehicle = sends(id.as_str());
        let rsus = warners.iter().filter(|_| is_vehicle);
        let rsus =
            rsus.map(|w| RsuBatches { id: w.clone(), hello: false, through: None, counted: None, batches: Vec::new() });
        let own_object = setup.role_of(id.as_str()).ok().and_then(Role::object_id);
        let receiving = Receiving {
            peers: peers.map(|p| (p, Peer::default())).collect(),
            rsus: rsus.collect(),
            warnings: own_object.map_or_else(WarningInbox::default, WarningInbox::new),
            ..Receiving::default()
        };
        // Reliable and blocking: every loss is the channel's, none the transport's.
        let publisher = reliable_publisher(session, scene_v2x(site, id))?;
        let inbox = Arc::new(Inbox {
            id: id.to_string(),
            scene: setup.digest(),
            channel,
            warners,
            state: Mutex::new(receiving),
            wake: Condvar::new(),
            taken: Condvar::new(),
        });
        let all = scene_v2x_all(site);
        let subscriber = session
            .declare_subscriber(all.clone())
            .callback({
                let inbox = Arc::clone(&inbox);
                move |sample: Sample| inbox.on_sample(sample.key_expr().as_str(), &sample.payload().to_bytes())
            })
            .wait()
            .map_err(|e| transport(&all, e))?;
        let deliverer = std::thread::Builder::new()
            .name(format!("v2x-{id}"))
            .spawn({
                let inbox = Arc::clone(&inbox);
                move || inbox.deliver()
            })
            .map_err(|e| SceneError::Failed { reason: format!("cannot start the V2X delivery thread: {e}") })?;
        let trigger = is_vehicle.then(CamTrigger::default);
        let warnings = (setup.warnings() && !is_vehicle).then(WarningSender::default);
        let cpms = (setup.cpm() && !is_vehicle).then(CpmSender::default);
        Ok(V2xLayer {
            inbox,
            _subscriber: subscriber,
            publisher,
            deliverer: Some(deliverer),
            trigger,
            seq: 0,
            warnings,
            cpms,
            made: Vec::new(),
            cpm_objects: Vec::new(),
            warned: Vec::new(),
        })
    }

    /// Says hello to the scene's participants; whether this one has heard every participant
    /// whose messages it decides. Repeated until the scene starts, and a participant joins only
    /// once it has heard everyone: a message sent before its sender's session knew of a
    /// receiver's subscription never reaches it, so without this a scene's first messages could
    /// be lost on the way, and not to the channel.
    pub fn hello(&self) -> Result<bool, SceneError> {
        if self.trigger.is_some() || self.warnings.is_some() || self.cpms.is_some() {
            self.put(V2xBody::Hello)?;
        }
        let state = self.inbox.state.locked();
        // Hearing another scene's messages, it joins anyway: the authority names the mismatch.
        Ok(state.heard_everyone() || state.foreign > 0)
    }

    /// The participants whose hello has not come.
    pub fn unheard(&self) -> Vec<String> {
        let state = self.inbox.state.locked();
        let peers = state.peers.iter().filter(|(_, p)| !p.hello).map(|(id, _)| id.clone());
        peers.chain(state.rsus.iter().filter(|r| !r.hello).map(|r| r.id.clone())).collect()
    }

    fn put(&self, body: V2xBody) -> Result<(), SceneError> {
        let message = WireV2x { schema: V2X_SCHEMA, scene: self.inbox.scene, sender: self.inbox.id.clone(), body };
        let bytes = postcard::to_allocvec(&message).map_err(|e| SceneError::Failed { reason: e.to_string() })?;
        self.publisher.put(bytes).wait().map_err(|e| SceneError::Transport(format!("V2X: {e}")))
    }

    /// What a vehicle's driver is warned of in step `truth`, given what it `perceived` (call it
    /// before the driver acts, and only in steps the vehicle is in the world, as virtual time
    /// does): the RSUs' warnings through the step before are decided (waiting for them at most
    /// [`WARNING_WAIT`]), those due are heard. Nothing without warnings, or at an RSU.
    pub fn warned(&mut self, truth: &Truth, perceived: &[PerceivedObject]) -> &[PerceivedObject] {
        self.warned.clear();
        let mut state = self.inbox.state.locked();
        if state.rsus.is_empty() {
            return &self.warned;
        }
        if let Some(before) = truth.step.checked_sub(1) {
            state = self.inbox.decide_warnings_through(state, before);
        }
        let receiving = &mut *state;
        self.warned.extend_from_slice(receiving.warnings.warned(truth.time_s, perceived, &mut receiving.tally));
        &self.warned
    }

    /// Step `truth`, before it is answered: records this participant's position for the CAMs
    /// made in it, sends a CAM if the generation rules say so, and at an RSU of a scene with
    /// warnings the step's warnings of the hazards it `perceived`. Before the answer, so that
    /// the authority never ends the scene with a message of its last step not yet sent, and a
    /// vehicle finds the warnings of a step before the next.
    pub fn on_step(
        &mut self,
        truth: &Truth,
        own: Option<CamState>,
        perceived: &[PerceivedObject],
    ) -> Result<(), SceneError> {
        // A vehicle out of the world hears nothing, but its copies are decided as virtual time
        // decides them (none for steps it was out); in the world, `warned` already did.
        if let Some(before) = truth.step.checked_sub(1) {
            let state = self.inbox.state.locked();
            if !state.rsus.is_empty() {
                drop(self.inbox.decide_warnings_through(state, before));
            }
        }
        self.inbox.on_step(truth.step, own.map(|s| (s.x_m, s.y_m)));
        let sends = self.warnings.is_some() || self.cpms.is_some();
        if let (true, Some(mast)) = (sends, own) {
            let mut state = self.inbox.state.locked();
            self.made.clear();
            if let Some(warnings) = &mut self.warnings {
                warnings.make(truth.time_s, perceived, &mut self.made, &mut state.tally);
            }
            let cpm = self
                .cpms
                .as_mut()
                .and_then(|c| c.make(truth.time_s, perceived, &mut self.cpm_objects, &mut state.tally));
            drop(state);
            let batch = RsuBatch {
                step: truth.step,
                made_s: truth.time_s,
                sent_unix_ns: unix_ns(),
                from: [mast.x_m, mast.y_m],
                first_seq: self.made.first().map_or(0, |&(seq, _)| seq),
                objects: self.made.iter().map(|&(_, o)| o).collect(),
                cpm: cpm.map(|seq| WireCpm { seq, objects: self.cpm_objects.clone() }),
            };
            self.put(V2xBody::Rsu(batch))?;
        }
        let (Some(trigger), Some(state)) = (&mut self.trigger, own) else { return Ok(()) };
        if trigger.check(state).is_none() {
            return Ok(());
        }
        self.put(V2xBody::Cam(WireCam {
            seq: self.seq,
            step: truth.step,
            made_s: truth.time_s,
            sent_unix_ns: unix_ns(),
            state: [state.x_m, state.y_m, state.heading_rad, state.speed_mps],
        }))?;
        self.seq += 1;
        self.inbox.state.locked().tally.cams_sent += 1;
        Ok(())
    }

    /// Ends the layer once the scene is over: announces how many CAMs it sent, waits (at most
    /// [`FINISH_WAIT`]) until every copy it can still expect is decided, and stops; its counts.
    /// Copies still held are passed, not delivered. Blocks: never call it on a Zenoh callback
    /// (the messages it waits for may come on that thread).
    pub fn finish(mut self) -> V2xReport {
        if self.trigger.is_some()
            && let Err(e) = self.put(V2xBody::End { cams: self.seq })
        {
            tracing::warn!("V2X {}: could not announce the end: {e}", self.inbox.id);
        }
        let deadline = Instant::now() + FINISH_WAIT;
        let mut state = self.inbox.state.locked();
        while !state.settled() {
            let now = Instant::now();
            if now >= deadline {
                break;
            }
            state = self.inbox.taken.waited_for(state, deadline - now);
        }
        // The warnings of the last step are decided (counted), as virtual time decides them;
        // none is heard any more.
        if let (false, Some(last)) = (state.rsus.is_empty(), state.latest_step) {
            state = self.inbox.decide_warnings_through(state, last);
        }
        state.closed = true;
        drop(state);
        self.inbox.wake.notify_one();
        if let Some(thread) = self.deliverer.take() {
            // The thread only counts; had it panicked, the counts it left are still reported.
            let _ = thread.join();
        }
        let state = self.inbox.state.locked();
        let id = &self.inbox.id;
        let silent: Vec<&str> =
            state.peers.iter().filter(|(_, p)| p.ended.is_none()).map(|(s, _)| s.as_str()).collect();
        if !silent.is_empty() {
            tracing::warn!("V2X {id}: no end announced by {} within {FINISH_WAIT:?}", silent.join(", "));
        }
        let ms = |q| state.excess_us.quantile(q).map(|us| us / 1e3);
        let report = V2xReport {
            summary: state.tally.summary(),
            late: state.late,
            excess_p50_ms: ms(0.5),
            excess_p99_ms: ms(0.99),
            undecided: state.undecided(),
            stale: state.stale,
            ahead: state.ahead,
            malformed: state.malformed,
            foreign: state.foreign,
            warnings_late: state.warnings_late,
            cpms_late: state.cpms_late,
            warning_batches_late: state.warning_batches_late,
            warning_batches_lost: state.warning_batches_lost,
        };
        let dropped = [
            ("undecided", report.undecided),
            ("stale", report.stale),
            ("ahead of its steps", report.ahead),
            ("malformed", report.malformed),
            ("of another scene", report.foreign),
        ];
        for (what, n) in dropped.into_iter().filter(|(_, n)| *n > 0) {
            tracing::warn!("V2X {id}: {n} CAMs {what}");
        }
        if report.warning_batches_late > 0 {
            tracing::warn!("V2X {id}: {} RSU warning batches late for their step", report.warning_batches_late);
        }
        report
    }
}

impl Drop for V2xLayer {
    fn drop(&mut self) {
        self.inbox.state.locked().closed = true;
        self.inbox.wake.notify_one();
    }
}

#[cfg(test)]
mod tests;
