//! The V2X layer of a scene's participants, in real time: each connected vehicle sends CAMs by
//! the ETSI generation rules from its own state in each step's truth, on
//! `risktwin/v1/<site>/scene/v2x/<participant>`; every other participant (vehicles and RSUs)
//! receives them and applies the channel per message and per receiver, from the distance
//! between the CAM's position and its own position in the truth of the step the CAM was made
//! in: the copy is lost or passed (`MessageChannel::passes`), and a passed copy is held until
//! its sent wall time plus the broadcast's latency (`MessageChannel::latency_ms`) by a delivery
//! thread, never by the physics. The decisions derive from (seed, sender, receiver, sequence),
//! so `risktwin_common::v2x::messages::VirtualScene`, which the embedded scene runs, makes the
//! same ones in virtual time.

use super::Role;
use super::SceneError;
use super::net::{lock, reliable_publisher};
use super::onboard::Onboard;
use super::streams::unix_ns;
use super::wire::Truth;
use risktwin_common::v2x::cam::{CamState, CamTrigger};
use risktwin_common::v2x::loss::BurstState;
use risktwin_common::v2x::messages::{MessageChannel, V2xSummary, V2xTally};
use risktwin_transport::keyexpr::{scene_v2x, scene_v2x_all};
use risktwin_transport::zenoh::pubsub::{Publisher, Subscriber};
use risktwin_transport::zenoh::sample::Sample;
use risktwin_transport::zenoh::{Session, Wait};
use risktwin_transport::{SiteId, SourceId};
use serde::{Deserialize, Serialize};
use std::cmp::Reverse;
use std::collections::{BTreeMap, BinaryHeap};
use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Version of the CAM message; bump on any change to it.
const CAM_SCHEMA: u32 = 1;

/// Steps of its own positions a receiver keeps for CAMs made in them (10 s of scene).
const OWN_HISTORY_STEPS: u64 = 200;

/// A CAM on the wire (postcard): who made it, when in the scene and on the wall clock, and the
/// state it carries (not ETSI's ASN.1 encoding).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WireCam {
    pub schema: u32,
    /// The scene's digest: another scene's CAMs on the same site are dropped.
    pub scene: u64,
    pub sender: String,
    /// The sender's CAM count before this one.
    pub seq: u64,
    /// The physics step whose truth it was made from, and its scene time, s.
    pub step: u64,
    pub made_s: f64,
    /// Wall clock when it was put on the wire, ns since the Unix epoch.
    pub sent_unix_ns: i64,
    /// Position, heading and speed: m, m, rad, m/s.
    pub state: [f64; 4],
}

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

/// What the receiving side holds, shared by the subscriber's callback, the stepping callback
/// and the delivery thread.
#[derive(Default)]
struct Receiving {
    /// This participant's position by step (`None`: not in the world then).
    own: BTreeMap<u64, Option<(f64, f64)>>,
    latest_step: Option<u64>,
    /// CAMs made in a step this participant has not seen yet.
    waiting: Vec<WireCam>,
    bursts: BTreeMap<String, BurstState>,
    /// Passed copies held until their due time: (due, sent wall ns).
    held: BinaryHeap<Reverse<(Instant, i64)>>,
    tally: V2xTally,
    malformed: u64,
    closed: bool,
}

struct Inbox {
    id: String,
    scene: u64,
    channel: MessageChannel,
    state: Mutex<Receiving>,
    /// Wakes the delivery thread: a copy held, or the layer closed.
    wake: Condvar,
}

impl Inbox {
    fn on_sample(&self, payload: &[u8]) {
        let mut state = lock(&self.state);
        let cam = match postcard::from_bytes::<WireCam>(payload) {
            Ok(cam) if cam.schema == CAM_SCHEMA => cam,
            Ok(_) | Err(_) => {
                state.malformed += 1;
                return;
            }
        };
        if cam.sender == self.id || cam.scene != self.scene {
            return;
        }
        if state.latest_step.is_some_and(|latest| cam.step <= latest) {
            self.decide(&mut state, &cam);
        } else {
            state.waiting.push(cam);
        }
    }

    /// Applies the channel to this participant's copy of `cam`: counted, and held if it passes.
    fn decide(&self, state: &mut Receiving, cam: &WireCam) {
        // A receiver not in the world when the CAM was made gets no copy.
        let Some(&Some((x_m, y_m))) = state.own.get(&cam.step) else { return };
        let distance_m = (cam.state[0] - x_m).hypot(cam.state[1] - y_m);
        let burst = state.bursts.entry(cam.sender.clone()).or_default();
        let passes = self.channel.passes(&cam.sender, &self.id, cam.seq, distance_m, burst);
        state.tally.copies += 1;
        if !passes {
            return;
        }
        state.tally.passed += 1;
        let latency_ns = (self.channel.latency_ms(&cam.sender, cam.seq) * 1e6).round() as i64;
        let wait_ns = (cam.sent_unix_ns + latency_ns - unix_ns()).max(0);
        state.held.push(Reverse((Instant::now() + Duration::from_nanos(wait_ns as u64), cam.sent_unix_ns)));
        self.wake.notify_one();
    }

    /// This participant's position in step `step`; decides the CAMs that waited for it.
    fn on_step(&self, step: u64, own: Option<(f64, f64)>) {
        let mut state = lock(&self.state);
        state.own.insert(step, own);
        state.own.retain(|&k, _| k + OWN_HISTORY_STEPS > step);
        state.latest_step = Some(step);
        let (ready, waiting): (Vec<WireCam>, Vec<WireCam>) =
            std::mem::take(&mut state.waiting).into_iter().partition(|cam| cam.step <= step);
        state.waiting = waiting;
        for cam in &ready {
            self.decide(&mut state, cam);
        }
    }

    /// Hands over each held copy at its due time, measuring its latency on the wall clock.
    fn deliver(&self) {
        let mut state = lock(&self.state);
        while !state.closed {
            let now = Instant::now();
            while let Some(&Reverse((due, sent_unix_ns))) = state.held.peek() {
                if due > now {
                    break;
                }
                state.held.pop();
                state.tally.delivered += 1;
                state.tally.latency_us.record(((unix_ns() - sent_unix_ns).max(0) / 1000) as u64);
            }
            state = match state.held.peek() {
                Some(&Reverse((due, _))) => {
                    let wait = due.saturating_duration_since(now);
                    self.wake.wait_timeout(state, wait).unwrap_or_else(PoisonError::into_inner).0
                }
                None => self.wake.wait(state).unwrap_or_else(PoisonError::into_inner),
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
}

impl V2xLayer {
    /// Declares participant `id`'s V2X publisher and its subscriber to every participant's
    /// broadcasts, and starts its delivery thread.
    pub fn open(
        session: &Session,
        site: &SiteId,
        id: &SourceId,
        scene: u64,
        channel: MessageChannel,
        sends: bool,
    ) -> Result<V2xLayer, SceneError> {
        let transport =
            |key: &str, e: Box<dyn std::error::Error + Send + Sync>| SceneError::Transport(format!("{key}: {e}"));
        // Reliable and blocking: every loss is the channel's, none the transport's.
        let publisher = reliable_publisher(session, scene_v2x(site, id))?;
        let inbox = Arc::new(Inbox {
            id: id.to_string(),
            scene,
            channel,
            state: Mutex::new(Receiving::default()),
            wake: Condvar::new(),
        });
        let all = scene_v2x_all(site);
        let subscriber = session
            .declare_subscriber(all.clone())
            .callback({
                let inbox = Arc::clone(&inbox);
                move |sample: Sample| inbox.on_sample(&sample.payload().to_bytes())
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
        let trigger = sends.then(CamTrigger::default);
        Ok(V2xLayer { inbox, _subscriber: subscriber, publisher, deliverer: Some(deliverer), trigger, seq: 0 })
    }

    /// After step `truth` was answered: records this participant's position for the CAMs made
    /// in it, and sends a CAM if the generation rules say so.
    pub fn on_step(&mut self, truth: &Truth, own: Option<CamState>) -> Result<(), SceneError> {
        self.inbox.on_step(truth.step, own.map(|s| (s.x_m, s.y_m)));
        let (Some(trigger), Some(state)) = (&mut self.trigger, own) else { return Ok(()) };
        if trigger.check(state).is_none() {
            return Ok(());
        }
        let cam = WireCam {
            schema: CAM_SCHEMA,
            scene: self.inbox.scene,
            sender: self.inbox.id.clone(),
            seq: self.seq,
            step: truth.step,
            made_s: truth.time_s,
            sent_unix_ns: unix_ns(),
            state: [state.x_m, state.y_m, state.heading_rad, state.speed_mps],
        };
        let bytes = postcard::to_allocvec(&cam).map_err(|e| SceneError::Failed { reason: e.to_string() })?;
        self.publisher.put(bytes).wait().map_err(|e| SceneError::Transport(format!("V2X CAM: {e}")))?;
        self.seq += 1;
        lock(&self.inbox.state).tally.cams_sent += 1;
        Ok(())
    }

    /// Stops the layer (copies still held are passed, not delivered); its counts.
    pub fn finish(mut self) -> V2xSummary {
        lock(&self.inbox.state).closed = true;
        self.inbox.wake.notify_one();
        if let Some(thread) = self.deliverer.take() {
            // The thread only counts; had it panicked, the counts it left are still reported.
            let _ = thread.join();
        }
        let state = lock(&self.inbox.state);
        if state.malformed > 0 {
            tracing::warn!("V2X {}: {} malformed CAMs dropped", self.inbox.id, state.malformed);
        }
        state.tally.summary()
    }
}

impl Drop for V2xLayer {
    fn drop(&mut self) {
        lock(&self.inbox.state).closed = true;
        self.inbox.wake.notify_one();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cam_round_trips_through_postcard() {
        let cam = WireCam {
            schema: CAM_SCHEMA,
            scene: 9,
            sender: "v1".into(),
            seq: 4,
            step: 17,
            made_s: 0.85,
            sent_unix_ns: 1_700_000_000_123_456_789,
            state: [1.5, -0.0, 3.0, 29.9],
        };
        let back: WireCam = postcard::from_bytes(&postcard::to_allocvec(&cam).expect("encodes")).expect("decodes");
        assert_eq!(back, cam);
        assert_eq!(back.state[1].to_bits(), (-0.0f64).to_bits());
    }
}
