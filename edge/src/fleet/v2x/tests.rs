//! The real-time V2X layer's receiving side, message by message.

use super::*;
use risktwin_common::geometry::{Obb, Vec2};
use risktwin_common::sensor::ObjectKind;
use risktwin_transport::sync::LockExt;
use risktwin_v2x::channel::{LinkBudget, PathLoss};
use risktwin_v2x::latency::Latency;
use risktwin_v2x::link::V2xChannel;

const SCENE: u64 = 9;

/// Receiver `rsu0` of a scene whose vehicles `v0` and `v1` send.
fn inbox() -> Inbox {
    let channel = V2xChannel {
        model: PathLoss::HighwayLos,
        budget: LinkBudget::default(),
        latency: Latency::SIDELINK,
        bursts: None,
    };
    let peers = ["v0", "v1"].map(|p| (p.to_owned(), Peer::default())).into_iter().collect();
    Inbox {
        id: "rsu0".into(),
        scene: SCENE,
        channel: MessageChannel { channel, seed: 1 },
        warners: Vec::new(),
        state: Mutex::new(Receiving { peers, ..Receiving::default() }),
        wake: Condvar::new(),
        taken: Condvar::new(),
    }
}

fn message(sender: &str, body: V2xBody) -> Vec<u8> {
    let message = WireV2x { schema: V2X_SCHEMA, scene: SCENE, sender: sender.into(), body };
    postcard::to_allocvec(&message).expect("encodes")
}

/// CAM `seq` of step `step`, made 10 m from the receiver's position, sent now.
fn cam(seq: u64, step: u64) -> V2xBody {
    V2xBody::Cam(WireCam { seq, step, made_s: 0.0, sent_unix_ns: unix_ns(), state: [10.0, 0.0, 0.0, 0.0] })
}

fn key(sender: &str) -> String {
    format!("risktwin/v1/site/scene/v2x/{sender}")
}

#[test]
fn every_cam_is_decided_counted_or_waits_and_none_is_dropped_silently() {
    let inbox = inbox();
    inbox.on_step(0, Some((0.0, 0.0)));
    inbox.on_sample(&key("v0"), &message("v0", cam(0, 0)));
    inbox.on_sample(&key("v0"), &message("v0", cam(0, 0)));
    inbox.on_sample(&key("v1"), &message("v0", cam(1, 0)));
    inbox.on_sample(&key("v9"), &message("v9", cam(0, 0)));
    inbox.on_sample(&key("rsu1"), &message("rsu1", cam(0, 0)));
    inbox.on_sample(&key("v1"), &[0xFF, 0x13]);
    let mut nan = cam(5, 0);
    if let V2xBody::Cam(c) = &mut nan {
        c.state[0] = f64::NAN;
    }
    inbox.on_sample(&key("v1"), &message("v1", nan));
    let other_scene = WireV2x { schema: V2X_SCHEMA, scene: SCENE + 1, sender: "v1".into(), body: cam(0, 0) };
    inbox.on_sample(&key("v1"), &postcard::to_allocvec(&other_scene).expect("encodes"));
    {
        let state = inbox.state.locked();
        assert_eq!(state.tally.copies, 1, "the first CAM only");
        let why = "a repeat, a sender on another's key, a stranger, an RSU, garbage, NaN";
        assert_eq!((state.malformed, state.foreign), (6, 1), "{why}");
    }
    // Not in the world at step 1: no copy, as in virtual time. Ahead of the own steps: waits,
    // or beyond the bound, dropped and counted.
    inbox.on_step(1, None);
    inbox.on_sample(&key("v0"), &message("v0", cam(1, 1)));
    inbox.on_sample(&key("v0"), &message("v0", cam(2, 3)));
    inbox.on_sample(&key("v0"), &message("v0", cam(3, 1 + AHEAD_STEPS + 1)));
    {
        let state = inbox.state.locked();
        assert_eq!((state.tally.copies, state.waiting.len(), state.ahead), (1, 1, 1));
        assert!(!state.settled(), "a CAM waits, and no sender announced its end");
        assert_eq!(state.undecided(), 1, "the waiting CAM; the sequence numbers are all there");
    }
    inbox.on_step(3, Some((0.0, 0.0)));
    // v1's CAMs 0 to 2 were never taken (its NaN one was refused): its end announces 4.
    inbox.on_sample(&key("v0"), &message("v0", V2xBody::End { cams: 4 }));
    inbox.on_sample(&key("v1"), &message("v1", V2xBody::End { cams: 4 }));
    let state = inbox.state.locked();
    assert_eq!((state.tally.copies, state.waiting.len()), (2, 0), "the waiting CAM decided at its step");
    assert!(!state.settled());
    assert_eq!(state.undecided(), 4, "v1's four: announced, none taken");
}

#[test]
fn a_cam_of_a_step_no_longer_held_is_stale_and_hostile_times_neither_panic_nor_hold_for_ever() {
    let inbox = inbox();
    for step in 0..=OWN_HISTORY_STEPS + 10 {
        inbox.on_step(step, Some((0.0, 0.0)));
    }
    inbox.on_sample(&key("v0"), &message("v0", cam(0, 3)));
    assert_eq!(inbox.state.locked().stale, 1);
    for (seq, sent_unix_ns) in [(1, i64::MAX), (2, i64::MIN), (3, unix_ns() - 1_000_000_000)] {
        let body = V2xBody::Cam(WireCam { seq, step: 20, made_s: 0.0, sent_unix_ns, state: [1.0, 0.0, 0.0, 0.0] });
        inbox.on_sample(&key("v0"), &message("v0", body));
    }
    let state = inbox.state.locked();
    assert_eq!((state.tally.copies, state.tally.passed), (3, 3), "1 m on a highway");
    assert_eq!(state.late, 2, "sent long ago: their latency has passed");
    let latest = state.held.iter().map(|Reverse(h)| h.due).max().expect("held");
    assert!(latest <= Instant::now() + MAX_HOLD, "a sent time in the far future is held at most {MAX_HOLD:?}");
}

/// A pedestrian as an RSU perceives it.
fn pedestrian(id: u32) -> PerceivedObject {
    use risktwin_common::geometry::{Footprint, Pose};
    let obb = Obb::new(Pose::new(30.0, 0.0, 0.5), Footprint::new(0.5, 0.5));
    PerceivedObject { id, kind: ObjectKind::Pedestrian, obb, velocity: Vec2::new(0.0, 1.2), visible_fraction: 1.0 }
}

/// RSU `rsu`'s warnings of `step`: `objects` from warning `first_seq` on, made 10 m from
/// the receiver, sent now.
fn batch(step: u64, first_seq: u64, objects: Vec<PerceivedObject>) -> V2xBody {
    let made_s = step as f64 * 0.05;
    V2xBody::Rsu(RsuBatch { step, made_s, sent_unix_ns: unix_ns(), from: [10.0, 0.0], first_seq, objects, cpm: None })
}

/// `body` (an RSU batch) with a CPM of two pedestrians.
fn with_cpm(mut body: V2xBody) -> V2xBody {
    if let V2xBody::Rsu(batch) = &mut body {
        batch.cpm = Some(WireCpm { seq: 2, objects: vec![pedestrian(4), pedestrian(6)] });
    }
    body
}

/// Vehicle `v0` of a scene with RSUs `rsu0` and `rsu1` warning.
fn warned_vehicle() -> Inbox {
    let mut inbox = inbox();
    inbox.id = "v0".into();
    inbox.warners = vec!["rsu0".into(), "rsu1".into()];
    let state = inbox.state.get_mut().expect("not poisoned");
    state.peers = [("v1".to_owned(), Peer::default())].into_iter().collect();
    state.rsus = inbox
        .warners
        .iter()
        .map(|w| RsuBatches { id: w.clone(), hello: false, through: None, counted: None, batches: Vec::new() })
        .collect();
    inbox
}

#[test]
fn a_participant_is_ready_once_every_sender_it_decides_said_hello() {
    let inbox = warned_vehicle();
    for sender in ["v1", "rsu0", "rsu1"] {
        assert!(!inbox.state.locked().heard_everyone(), "before {sender}");
        inbox.on_sample(&key(sender), &message(sender, V2xBody::Hello));
    }
    assert!(inbox.state.locked().heard_everyone());
    inbox.on_sample(&key("v7"), &message("v7", V2xBody::Hello));
    assert_eq!(inbox.state.locked().malformed, 1, "not of the scene");
}

#[test]
fn a_hostile_rsu_batch_neither_panics_nor_shuts_out_the_genuine_ones() {
    let inbox = warned_vehicle();
    inbox.on_step(0, Some((0.0, 0.0)));
    for step in [u64::MAX, AHEAD_STEPS + 1] {
        inbox.on_sample(&key("rsu0"), &message("rsu0", batch(step, 0, vec![pedestrian(7)])));
    }
    inbox.on_sample(&key("rsu1"), &message("rsu1", batch(0, u64::MAX, vec![pedestrian(7)])));
    {
        let state = inbox.state.locked();
        assert_eq!((state.ahead, state.malformed), (2, 1), "far ahead twice; sequence numbers that overflow");
    }
    inbox.on_sample(&key("rsu0"), &message("rsu0", batch(0, 0, vec![pedestrian(7)])));
    inbox.on_sample(&key("rsu1"), &message("rsu1", batch(0, 0, Vec::new())));
    let state = inbox.decide_warnings_through(inbox.state.locked(), 0);
    assert_eq!((state.tally.warning_copies, state.warning_batches_lost), (1, 0), "the genuine batch decided");
}

#[test]
fn rsu_warnings_are_decided_in_step_order_and_bad_or_missing_batches_are_counted() {
    let inbox = warned_vehicle();
    for step in 0..3 {
        inbox.on_step(step, Some((0.0, 0.0)));
    }
    // rsu1's batch of step 0 comes before rsu0's; both say the step is done. Both warn of
    // pedestrian 7, seen a metre apart.
    let mut seen_by_rsu1 = pedestrian(7);
    seen_by_rsu1.obb.centre.x += 1.0;
    inbox.on_sample(&key("rsu1"), &message("rsu1", batch(0, 0, vec![seen_by_rsu1])));
    inbox.on_sample(&key("rsu0"), &message("rsu0", batch(0, 0, vec![pedestrian(7), pedestrian(8)])));
    inbox.on_sample(&key("rsu0"), &message("rsu0", batch(1, 2, Vec::new())));
    // Repeated, from a vehicle, of no RSU, not finite (a warning, a CPM): malformed; never
    // decided.
    inbox.on_sample(&key("rsu0"), &message("rsu0", batch(1, 2, vec![pedestrian(9)])));
    inbox.on_sample(&key("v1"), &message("v1", batch(0, 0, vec![pedestrian(9)])));
    inbox.on_sample(&key("rsu5"), &message("rsu5", batch(0, 0, vec![pedestrian(9)])));
    let mut nan = pedestrian(9);
    nan.velocity.x = f64::NAN;
    inbox.on_sample(&key("rsu1"), &message("rsu1", batch(1, 1, vec![nan])));
    let mut nan_cpm = with_cpm(batch(1, 1, Vec::new()));
    if let V2xBody::Rsu(b) = &mut nan_cpm {
        b.cpm.as_mut().expect("a CPM").objects[1].obb.half_width_m = f64::INFINITY;
    }
    inbox.on_sample(&key("rsu1"), &message("rsu1", nan_cpm));
    let state = inbox.decide_warnings_through(inbox.state.locked(), 0);
    assert_eq!(state.malformed, 5);
    assert_eq!((state.tally.warning_copies, state.warning_batches_late), (3, 0), "step 0's three copies");
    assert_eq!(state.rsus[0].batches.len(), 1, "rsu0's step 1 waits for the step that needs it");
    // Decided rsu0 first, as virtual time orders them: of two made at once, rsu1's is heard
    // last and kept.
    let mut state = state;
    let receiving = &mut *state;
    let warned = receiving.warnings.warned(0.5, &[], &mut receiving.tally);
    let seven = warned.iter().find(|o| o.id == 7).expect("heard: 10 m on a highway, made 0.5 s ago");
    assert_eq!(seven.obb.centre.x, 31.0, "{warned:?}");
    assert_eq!(warned.len(), 2);
    drop(state);
    // rsu1 never sends step 1: the wait ends, the batch is counted late once.
    let started = Instant::now();
    let state = inbox.decide_warnings_through(inbox.state.locked(), 1);
    assert!(started.elapsed() >= WARNING_WAIT, "waited for it");
    assert_eq!((state.tally.warning_copies, state.warning_batches_late), (3, 1));
    drop(state);
    let state = inbox.decide_warnings_through(inbox.state.locked(), 1);
    assert_eq!(state.warning_batches_late, 1, "not counted twice");
    drop(state);
    // rsu0's step 2 never comes, its step 3 does: one batch lost.
    inbox.on_sample(&key("rsu0"), &message("rsu0", batch(3, 2, Vec::new())));
    assert_eq!(inbox.state.locked().warning_batches_lost, 1);
}

#[test]
fn an_rsu_ignores_the_warnings_of_another_and_a_scene_without_warnings_refuses_them() {
    let rsu = inbox();
    rsu.on_sample(&key("v0"), &message("v0", batch(0, 0, vec![pedestrian(7)])));
    assert_eq!(rsu.state.locked().malformed, 1, "no warnings in this scene");
    let mut rsu = inbox();
    rsu.warners = vec!["rsu0".into(), "rsu1".into()];
    rsu.on_sample(&key("rsu1"), &message("rsu1", batch(0, 0, vec![pedestrian(7)])));
    let state = rsu.state.locked();
    assert_eq!((state.malformed, state.tally.warning_copies), (0, 0), "not for an RSU, and not malformed");
}

#[test]
fn a_v2x_message_round_trips_through_postcard() {
    let cam = WireCam {
        seq: 4,
        step: 17,
        made_s: 0.85,
        sent_unix_ns: 1_700_000_000_123_456_789,
        state: [1.5, -0.0, 3.0, 29.9],
    };
    for body in [V2xBody::Cam(cam), V2xBody::End { cams: 12 }, with_cpm(batch(3, 5, vec![pedestrian(4)]))] {
        let message = WireV2x { schema: V2X_SCHEMA, scene: 9, sender: "v1".into(), body };
        let bytes = postcard::to_allocvec(&message).expect("encodes");
        let back: WireV2x = postcard::from_bytes(&bytes).expect("decodes");
        assert_eq!(back, message);
        if let V2xBody::Cam(cam) = back.body {
            assert_eq!(cam.state[1].to_bits(), (-0.0f64).to_bits());
        }
    }
}
