//! The physics plane over Zenoh: the authority's [`Plane`] and the participant's loop.
//!
//! Keys (`risktwin_transport::keyexpr`): truth on `risktwin/v1/<site>/scene/truth`, replies on
//! `risktwin/v1/<site>/scene/reply/<participant>`; both reliable with blocking congestion
//! control, since lockstep needs every message. Join: a participant subscribes to the truth,
//! then repeats its `Join` until the first truth arrives; the authority starts stepping once
//! every participant has joined with the same scene digest. A participant that does not answer
//! a step within [`Timeouts::step`] ends the scene with its name; so does an authority that
//! falls silent, for the participants.

use super::authority::Plane;
use super::onboard::{Onboard, vehicle_state};
use super::physics::SceneWorld;
use super::reliable::{reliable_publisher, transport};
use super::streams::Streams;
use super::v2x::{V2xLayer, V2xReport, cam_state};
use super::wire::{Reply, SceneEnd, Truth, controls_of};
use super::{Role, SceneError, SceneSetup};
use risktwin_common::scenario::ScenarioSpec;
use risktwin_common::telemetry::{DetectedObject, Frame, Header, ObjectList, RoadMap, VehicleStateSample};
use risktwin_common::vehicle::Controls;
use risktwin_protos::{WireMessage, encode};
use risktwin_transport::keyexpr::{
    SCENE_CHUNK, SceneTopic, scene_ground_truth, scene_replies, scene_reply, scene_topic, scene_truth,
};
use risktwin_transport::sync::{CondvarExt, LockExt};
use risktwin_transport::wall_clock::unix_ns;
use risktwin_transport::zenoh::pubsub::{Publisher, Subscriber};
use risktwin_transport::zenoh::sample::Sample;
use risktwin_transport::zenoh::{Session, Wait};
use risktwin_transport::{SiteId, SourceId, protobuf};
use serde::Serialize;
use std::collections::BTreeMap;
use std::sync::mpsc::RecvTimeoutError;
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

/// How long the plane waits before it names who failed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Timeouts {
    /// For every participant to join (processes starting), and for a participant the first truth.
    pub join: Duration,
    /// For every answer to one step (authority); a participant waits twice this for the next
    /// truth, so that the authority names a failed participant before the others give up.
    pub step: Duration,
}

impl Default for Timeouts {
    /// 30 s to start; 1.5 s per step, so a dead or stalled participant is named within 2 s.
    fn default() -> Self {
        Timeouts { join: Duration::from_secs(30), step: Duration::from_millis(1500) }
    }
}

/// Physics steps between two publications of the scene's road map (1 s of scene).
const MAP_EVERY_STEPS: u64 = 20;

/// How often a participant repeats its join until the first truth arrives.
const JOIN_REPEAT: Duration = Duration::from_millis(200);

/// The road map of a scene's world, as the authority publishes it (the same bytes each time):
/// the road, and a recording's lanelets.
fn scene_road_map(world: &SceneWorld<'_>) -> RoadMap {
    let header =
        Header { source: SCENE_CHUNK.into(), seq: 0, capture_time_ns: 0, publish_time_ns: 0, frame: Frame::World };
    let (road, lanelets) = world.road_map();
    RoadMap { header, road, lanelets }
}

/// The authority's side: truth out, replies in.
pub struct ZenohAuthority {
    /// The replies' subscriber: its callback tallies the answers into `tally`, so the stepping
    /// thread wakes once per step, when the last answer is in (not once per answer).
    _replies: Subscriber<()>,
    tally: Arc<Tally>,
    truth: Publisher<'static>,
    /// The scene's road map (`RoadMap`, protobuf) and its publisher: the cloud twin's risk runs
    /// on it. The same bytes every time, republished every [`MAP_EVERY_STEPS`].
    map: (Publisher<'static>, Vec<u8>),
    /// Each connected vehicle's role and ground-truth publisher (`scene/gt/<id>`).
    ground_truth: Vec<(String, Role, Publisher<'static>)>,
    /// Every other object's true state (`scene/objects`).
    objects: Publisher<'static>,
    /// Wall time at the scene's t = 0 by the authority's clock, ns since the Unix epoch: the
    /// ground truth's stamps, on the same clock as the participants' streams.
    epoch_ns: Option<i64>,
    timeouts: Timeouts,
    bytes: Vec<u8>,
    realtime: Option<RealTime>,
}

/// The answers to the step being handed out, and the joins, as the replies' callback counts them.
struct Tally {
    state: Mutex<Answers>,
    /// Signalled when the last answer to the current step arrives, and on every join.
    ready: Condvar,
    participants: Vec<String>,
}

#[derive(Default)]
struct Answers {
    /// The step whose answers count; `None` while the participants join.
    step: Option<u64>,
    /// Joins are taken until stepping starts; later ones (repeats in flight) are dropped.
    joining: bool,
    answered: Vec<bool>,
    /// Participants yet to answer `step`.
    missing: usize,
    /// The ego's controls for `step`.
    ego: Option<Controls>,
    /// Joins not yet looked at: participant, scene digest, scene description.
    joins: Vec<(String, u64, String)>,
    /// Replies that did not decode, counted and dropped.
    malformed: u64,
}

impl Tally {
    fn on_reply(&self, payload: &[u8]) {
        let reply = Reply::decode(payload);
        let mut answers = self.state.locked();
        match reply {
            Ok(Reply::Join { participant, scene, describe, .. }) if answers.joining => {
                answers.joins.push((participant, scene, describe));
                self.ready.notify_one();
            }
            Ok(Reply::Join { .. }) => {}
            Ok(Reply::Step { participant, step, controls }) if answers.step == Some(step) => {
                let Some(k) = self.participants.iter().position(|p| *p == participant) else { return };
                if std::mem::replace(&mut answers.answered[k], true) {
                    return;
                }
                if k == 0 {
                    answers.ego = controls.map(controls_of);
                }
                answers.missing = answers.missing.saturating_sub(1);
                if answers.missing == 0 {
                    self.ready.notify_one();
                }
            }
            // Answers to other steps: nothing to do.
            Ok(Reply::Step { .. }) => {}
            Err(e) => {
                answers.malformed += 1;
                tracing::warn!("scene: dropped a reply: {e}");
            }
        }
    }
}

/// Deadline accounting of a real-time scene: every participant's answer to step k is due when
/// step k+1 starts on the wall clock.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Deadlines {
    /// Answers due (participants × steps).
    pub due: u64,
    /// Answers that missed their deadline (a late answer is not used).
    pub missed: u64,
    /// Steps the ego's previous controls were held because its answer was late.
    pub ego_controls_held: u64,
}

/// The wall clock of a real-time scene.
struct RealTime {
    period: Duration,
    start: Option<Instant>,
    /// When each participant last answered in time (a stall is named after `Timeouts::step`).
    last_answer: Vec<Instant>,
    held: Controls,
    deadlines: Deadlines,
}

impl ZenohAuthority {
    /// Declares the plane on `physics` (truth out, answers in) and the scene's data for the
    /// cloud on `data` (road map, ground truth; the same session when the scene has one), and
    /// waits until every participant of `setup` has joined with the same scene; on a mismatch
    /// or a timeout every joined participant is told, and the error names who.
    pub fn open(
        physics: &Session,
        data: &Session,
        site: &SiteId,
        setup: &SceneSetup,
        timeouts: Timeouts,
    ) -> Result<Self, SceneError> {
        let participants = setup.participants();
        let answers = Answers { answered: vec![false; participants.len()], joining: true, ..Answers::default() };
        let tally = Arc::new(Tally { state: Mutex::new(answers), ready: Condvar::new(), participants });
        let replies_key = scene_replies(site);
        let replies = physics
            .declare_subscriber(replies_key.clone())
            .callback({
                let tally = Arc::clone(&tally);
                move |sample: Sample| tally.on_reply(&sample.payload().to_bytes())
            })
            .wait()
            .map_err(transport(&replies_key))?;
        let truth = reliable_publisher(physics, scene_truth(site))?;
        let declare = |key: String, message: &str| {
            data.declare_publisher(key.clone()).encoding(protobuf(message)).wait().map_err(transport(&key))
        };
        let map_publisher = declare(scene_topic(Some(site), SceneTopic::Map), RoadMap::PROTO_NAME)?;
        let objects = declare(scene_topic(Some(site), SceneTopic::Objects), ObjectList::PROTO_NAME)?;
        let mut world = setup.world()?;
        let map = scene_road_map(&world);
        let mut ground_truth = Vec::new();
        for id in tally.participants.iter().filter(|id| !id.starts_with("rsu")) {
            let source = SourceId::new(id.clone()).map_err(|e| SceneError::Failed { reason: e.to_string() })?;
            let publisher = declare(scene_ground_truth(site, &source), VehicleStateSample::PROTO_NAME)?;
            ground_truth.push((id.clone(), setup.role_of(id)?, publisher));
        }
        let mut plane = ZenohAuthority {
            _replies: replies,
            tally,
            truth,
            map: (map_publisher, encode(&map)),
            ground_truth,
            objects,
            epoch_ns: None,
            timeouts,
            bytes: Vec::new(),
            realtime: None,
        };
        if let Err(e) = plane.await_joins(setup) {
            let mut abort = world.truth(setup.digest(), 0);
            abort.end = Some(SceneEnd::Failed(e.to_string()));
            // The error is what matters; a failure to tell the participants adds nothing.
            let _ = plane.publish(&abort);
            return Err(e);
        }
        Ok(plane)
    }

    fn await_joins(&mut self, setup: &SceneSetup) -> Result<(), SceneError> {
        let joined = self.take_joins(setup);
        let mut answers = self.tally.state.locked();
        answers.joining = false;
        answers.joins.clear();
        joined
    }

    fn take_joins(&mut self, setup: &SceneSetup) -> Result<(), SceneError> {
        let (digest, ours) = (setup.digest(), setup.describe());
        let deadline = Instant::now() + self.timeouts.join;
        let mut joined = vec![false; self.tally.participants.len()];
        let mut answers = self.tally.state.locked();
        while joined.iter().any(|j| !j) {
            for (participant, scene, describe) in std::mem::take(&mut answers.joins) {
                let Some(k) = self.tally.participants.iter().position(|p| *p == participant) else {
                    let known = self.tally.participants.join(", ");
                    return Err(SceneError::UnknownParticipant { id: participant, known });
                };
                if scene != digest {
                    return Err(SceneError::Mismatch { id: participant, theirs: describe, ours });
                }
                joined[k] = true;
            }
            let now = Instant::now();
            if joined.iter().all(|j| *j) {
                break;
            }
            if now >= deadline {
                let missing = self.tally.participants.iter().zip(&joined).filter(|(_, j)| !**j);
                let ids = missing.map(|(p, _)| p.as_str()).collect::<Vec<_>>().join(", ");
                return Err(SceneError::NotJoined { ids, waited_s: self.timeouts.join.as_secs() });
            }
            answers = self.tally.ready.waited_for(answers, deadline - now);
        }
        Ok(())
    }

    /// Steps on the wall clock from now on, one every `period`; answers are due before the next
    /// step, and a late one is counted, not waited for.
    pub fn realtime(mut self, period: Duration) -> Self {
        let last_answer = vec![Instant::now(); self.tally.participants.len()];
        let deadlines = Deadlines::default();
        self.realtime = Some(RealTime { period, start: None, last_answer, held: Controls::default(), deadlines });
        self
    }

    /// The deadline accounting of a real-time scene.
    pub fn deadlines(&self) -> Option<&Deadlines> {
        self.realtime.as_ref().map(|rt| &rt.deadlines)
    }

    /// Replies that did not decode, counted and dropped.
    pub fn malformed(&self) -> u64 {
        self.tally.state.locked().malformed
    }

    fn publish(&mut self, truth: &Truth) -> Result<(), SceneError> {
        if truth.step.is_multiple_of(MAP_EVERY_STEPS) {
            let (publisher, bytes) = &self.map;
            publisher.put(bytes.as_slice()).wait().map_err(transport("map"))?;
        }
        truth.encode_into(&mut self.bytes);
        self.truth.put(self.bytes.as_slice()).wait().map_err(transport("truth"))?;
        if truth.end.is_some() {
            return Ok(());
        }
        let epoch = *self.epoch_ns.get_or_insert_with(|| unix_ns() - (truth.time_s * 1e9).round() as i64);
        let time_ns = epoch + (truth.time_s * 1e9).round() as i64;
        for (id, role, publisher) in &self.ground_truth {
            let header = Header {
                source: id.clone(),
                seq: truth.step,
                capture_time_ns: time_ns,
                publish_time_ns: time_ns,
                frame: Frame::World,
            };
            if let Some(state) = vehicle_state(truth, *role, header) {
                publisher.put(encode(&state)).wait().map_err(transport("ground truth"))?;
            }
        }
        let header = Header {
            source: SCENE_CHUNK.into(),
            seq: truth.step,
            capture_time_ns: time_ns,
            publish_time_ns: time_ns,
            frame: Frame::World,
        };
        let list = ObjectList { header, objects: truth.objects.iter().map(DetectedObject::from).collect() };
        self.objects.put(encode(&list)).wait().map_err(transport("ground-truth objects"))?;
        Ok(())
    }
}

impl Plane for ZenohAuthority {
    fn exchange(&mut self, truth: &Truth) -> Result<Controls, SceneError> {
        let start = match &mut self.realtime {
            Some(rt) => {
                let due = *rt.start.get_or_insert_with(Instant::now) + rt.period * truth.step as u32;
                if let Some(wait) = due.checked_duration_since(Instant::now()) {
                    std::thread::sleep(wait);
                }
                due
            }
            None => Instant::now(),
        };
        let deadline = self.realtime.as_ref().map_or(start + self.timeouts.step, |rt| start + rt.period);
        {
            let mut answers = self.tally.state.locked();
            answers.step = Some(truth.step);
            answers.answered.fill(false);
            answers.missing = self.tally.participants.len();
            answers.ego = None;
        }
        self.publish(truth)?;
        // A handle of its own, so that the answers can be read while `self` concludes the step.
        let tally = Arc::clone(&self.tally);
        let mut answers = tally.state.locked();
        loop {
            let now = Instant::now();
            if answers.missing == 0 || now >= deadline {
                break;
            }
            answers = tally.ready.waited_for(answers, deadline - now);
        }
        answers.step = None;
        let ego = answers.ego;
        self.conclude(truth.step, start, &answers.answered, ego)
    }

    fn finish(&mut self, last: &Truth) -> Result<(), SceneError> {
        self.publish(last)
    }
}

impl ZenohAuthority {
    /// The ego's controls once step `step`'s answers are in or its deadline has passed.
    fn conclude(
        &mut self,
        step: u64,
        start: Instant,
        answered: &[bool],
        ego: Option<Controls>,
    ) -> Result<Controls, SceneError> {
        if self.realtime.is_some() {
            return self.past_deadline(step, answered, ego);
        }
        if answered.iter().any(|a| !a) {
            let silent = self.tally.participants.iter().zip(answered).filter(|(_, a)| !**a);
            let ids = silent.map(|(p, _)| p.as_str()).collect::<Vec<_>>().join(", ");
            return Err(SceneError::Stalled { ids, step, waited_ms: start.elapsed().as_millis() as u64 });
        }
        ego.ok_or_else(|| SceneError::Failed { reason: "the ego (v0) answered without controls".into() })
    }

    /// A real-time step's deadline has come: counts the late answers, names a participant silent
    /// for longer than `Timeouts::step`, and holds the ego's controls if its answer is late.
    fn past_deadline(&mut self, step: u64, answered: &[bool], ego: Option<Controls>) -> Result<Controls, SceneError> {
        let now = Instant::now();
        let rt = self.realtime.as_mut().expect("a real-time scene");
        rt.deadlines.due += answered.len() as u64;
        for (k, answered) in answered.iter().enumerate() {
            if *answered {
                rt.last_answer[k] = now;
            } else {
                rt.deadlines.missed += 1;
            }
        }
        let silent =
            rt.last_answer.iter().zip(&self.tally.participants).filter(|(t, _)| now - **t > self.timeouts.step);
        let silent: Vec<&str> = silent.map(|(_, p)| p.as_str()).collect();
        if !silent.is_empty() {
            let waited_ms = self.timeouts.step.as_millis() as u64;
            return Err(SceneError::Stalled { ids: silent.join(", "), step, waited_ms });
        }
        match ego {
            Some(controls) => rt.held = controls,
            None => rt.deadlines.ego_controls_held += 1,
        }
        Ok(rt.held)
    }
}

/// What a participant did, printed on exit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ParticipantSummary {
    pub participant: String,
    pub scene: String,
    /// Steps answered.
    pub steps: u64,
    /// Objects perceived, summed over the steps.
    pub perceived: u64,
    /// Truth messages that did not decode, counted and dropped.
    pub malformed: u64,
    /// Messages made for the cloud, per edge stream.
    pub sent: BTreeMap<String, u64>,
    /// Of `sent`, those never put on the wire: made while no cloud had yet subscribed, beyond
    /// what the stream's cache holds, or still waiting for one when the scene ended.
    pub unsent: BTreeMap<String, u64>,
    /// The V2X layer's counts, when the scene has V2X.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub v2x: Option<V2xReport>,
}

/// A participant's stack, driven by the truth subscriber's callback: it answers each step as
/// the truth arrives, on Zenoh's receiving thread, with no hand-over to another thread; except
/// a vehicle that waits for RSU warnings, which must not wait on that thread (the warnings may
/// come on it) and answers on a thread of its own.
struct Answering {
    stack: Onboard,
    streams: Streams,
    /// The V2X layer, when the scene has V2X; finished by the participant's thread once the
    /// scene is over (its end waits for messages, never on a Zenoh callback).
    v2x: Option<V2xLayer>,
    outbox: Publisher<'static>,
    digest: u64,
    describe: String,
    /// The ego's scenario, whose outcome it reports when the scene ends (see
    /// [`SceneSetup::reported_spec`]).
    reported: Option<ScenarioSpec>,
    summary: ParticipantSummary,
    /// The last step answered and when: shared with the thread that watches for silence, which
    /// must not wait on this stack's lock (held while a step is answered and published).
    last: Arc<Mutex<Option<(u64, Instant)>>>,
    /// Set once the scene is over for this participant: later truths are ignored.
    over: bool,
}

impl Answering {
    /// Answers one truth message; the participant's end once the scene is over for it.
    fn on_truth(&mut self, payload: &[u8]) -> Option<Result<ParticipantSummary, SceneError>> {
        let truth = match Truth::decode(payload) {
            Ok(truth) => truth,
            Err(e) => {
                self.summary.malformed += 1;
                tracing::warn!("scene {}: dropped a truth message: {e}", self.summary.participant);
                return None;
            }
        };
        if let Some(SceneEnd::Failed(reason)) = truth.end {
            // Said by whichever authority failed: the reason names the scene.
            return Some(Err(SceneError::Failed { reason }));
        }
        if truth.scene != self.digest {
            let theirs = format!("scene {:016x}", truth.scene);
            let ours = self.describe.clone();
            return Some(Err(SceneError::Mismatch { id: "the authority".into(), theirs, ours }));
        }
        // Only this scene's end: another scene's outcome must never be reported as this one's.
        if let Some(SceneEnd::Done { ref metrics, risk }) = truth.end {
            let published = self.streams.publish_state(&self.stack, &truth).and_then(|()| self.streams.flush());
            let reported = published.and_then(|()| match &self.reported {
                Some(spec) => self.streams.report(spec, self.digest, metrics.clone(), risk),
                None => Ok(()),
            });
            if let Err(e) = reported {
                return Some(Err(e));
            }
            let (sent, unsent) = (self.streams.sent(), self.streams.unsent());
            return Some(Ok(ParticipantSummary { sent, unsent, ..self.summary.clone() }));
        }
        // A vehicle out of the world perceives nothing and hears nothing (as embedded).
        let controls = self.stack.perceive(&truth).and_then(|pose| {
            let warned = match &mut self.v2x {
                Some(v2x) => v2x.warned(&truth, self.stack.perceived()),
                None => &[],
            };
            self.stack.act(&truth, pose, warned)
        });
        self.summary.steps += 1;
        self.summary.perceived += self.stack.perceived().len() as u64;
        // The step's V2X messages go out before the answer: once every answer to the last step
        // is in, the authority may end the scene, and every message of it must be on its way by
        // then; and a vehicle's next step needs the RSUs' warnings of this one.
        if let Some(v2x) = &mut self.v2x
            && let Err(e) = v2x.on_step(&truth, cam_state(&truth, &self.stack), self.stack.perceived())
        {
            return Some(Err(e));
        }
        let reply = Reply::step(&self.summary.participant, truth.step, controls).encode();
        if let Err(e) = self.outbox.put(reply).wait().map_err(transport("reply")) {
            return Some(Err(e));
        }
        *self.last.locked() = Some((truth.step, Instant::now()));
        self.streams.publish(&self.stack, &truth).err().map(Err)
    }
}

/// Runs participant `id` of `setup` until the authority ends the scene: the plane on `physics`
/// (truth in, answers out), its edge streams on `data` (the same session when the scene has one),
/// and when the scene has V2X its V2X layer on `physics` (the scene's radio paths, not the
/// backhaul).
pub fn run_participant(
    physics: &Session,
    data: &Session,
    site: &SiteId,
    setup: &SceneSetup,
    id: &str,
    timeouts: Timeouts,
) -> Result<ParticipantSummary, SceneError> {
    let stack = Onboard::new(setup, id)?;
    let participant =
        risktwin_transport::SourceId::new(id).map_err(|e| SceneError::Failed { reason: e.to_string() })?;
    let outbox = reliable_publisher(physics, scene_reply(site, &participant))?;
    let digest = setup.digest();
    let join = Reply::Join {
        schema: super::wire::SCHEMA_VERSION,
        participant: id.to_owned(),
        scene: digest,
        describe: setup.describe(),
    }
    .encode();
    let reported = setup.reported_spec().filter(|_| stack.role() == Role::Ego).cloned();
    let streams =
        Streams::open(data, site, &participant, matches!(stack.role(), Role::Rsu { .. }), reported.is_some())?;
    let summary = ParticipantSummary {
        participant: id.to_owned(),
        scene: format!("{digest:016x}"),
        steps: 0,
        perceived: 0,
        malformed: 0,
        sent: BTreeMap::new(),
        unsent: BTreeMap::new(),
        v2x: None,
    };
    let waits_for_warnings = setup.rsus_send() && !matches!(stack.role(), Role::Rsu { .. });
    let v2x = setup.v2x().map(|&channel| V2xLayer::open(physics, site, setup, &participant, channel)).transpose()?;
    let last = Arc::new(Mutex::new(None));
    let answering = Answering {
        stack,
        streams,
        v2x,
        outbox,
        digest,
        describe: setup.describe(),
        reported,
        summary,
        last: Arc::clone(&last),
        over: false,
    };
    let answering = Arc::new(Mutex::new(answering));
    let (end_tx, end) = std::sync::mpsc::sync_channel(1);
    let answer = {
        let answering = Arc::clone(&answering);
        move |payload: &[u8]| {
            let mut answering = answering.locked();
            if answering.over {
                return;
            }
            if let Some(ended) = answering.on_truth(payload) {
                answering.over = true;
                // The channel holds one end and only one is sent.
                let _ = end_tx.try_send(ended);
            }
        }
    };
    let on_truth: Box<dyn Fn(Sample) + Send + Sync> = if waits_for_warnings {
        let (steps, handed) = std::sync::mpsc::channel::<Vec<u8>>();
        // Ends when the subscriber (and with it the sender) is gone.
        std::thread::Builder::new()
            .name(format!("scene-{id}"))
            .spawn(move || handed.iter().for_each(|payload| answer(&payload)))
            .map_err(|e| SceneError::Failed { reason: format!("cannot start the stepping thread: {e}") })?;
        Box::new(move |sample: Sample| {
            // Fails only once the thread is gone with the scene.
            let _ = steps.send(sample.payload().to_bytes().into_owned());
        })
    } else {
        Box::new(move |sample: Sample| answer(&sample.payload().to_bytes()))
    };
    let truth_key = scene_truth(site);
    let _truth =
        physics.declare_subscriber(truth_key.clone()).callback(on_truth).wait().map_err(transport(&truth_key))?;

    // This thread repeats the join until the first truth arrives and watches for silence.
    let join_deadline = Instant::now() + timeouts.join;
    let mut next_join = Instant::now();
    loop {
        let now = Instant::now();
        let last_step = *last.locked();
        let wake = match last_step {
            None if now >= join_deadline => {
                let waited_s = timeouts.join.as_secs();
                let unheard = answering.locked().v2x.as_ref().map(V2xLayer::unheard).unwrap_or_default();
                if !unheard.is_empty() {
                    return Err(SceneError::V2xUnheard { ids: unheard.join(", "), waited_s });
                }
                return Err(SceneError::NoAuthority { waited_s });
            }
            None => {
                if now >= next_join {
                    let answering = answering.locked();
                    // With V2X, the join waits until every V2X sender of the scene is heard.
                    let ready = answering.v2x.as_ref().map_or(Ok(true), V2xLayer::hello)?;
                    if ready {
                        answering.outbox.put(join.as_slice()).wait().map_err(transport("join"))?;
                    }
                    next_join = now + JOIN_REPEAT;
                }
                next_join.min(join_deadline)
            }
            Some((step, at)) if now - at >= 2 * timeouts.step => {
                let waited_ms = 2 * timeouts.step.as_millis() as u64;
                return Err(SceneError::AuthoritySilent { step, waited_ms });
            }
            Some((_, at)) => at + 2 * timeouts.step,
        };
        match end.recv_timeout(wake.saturating_duration_since(now)) {
            Ok(mut ended) => {
                if let Ok(summary) = &mut ended {
                    let started = Instant::now();
                    // Here, not on the truth's callback: the V2X end waits for the last messages.
                    let v2x = answering.locked().v2x.take();
                    summary.v2x = v2x.map(V2xLayer::finish);
                    // The streams' caches stay a while for the cloud to fetch what the link lost last.
                    let linger = answering.locked().streams.linger();
                    std::thread::sleep(linger.saturating_sub(started.elapsed()));
                }
                return ended;
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => {
                return Err(SceneError::Transport("the truth subscriber closed".into()));
            }
        }
    }
}

#[cfg(test)]
#[path = "net_tests.rs"]
mod tests;
