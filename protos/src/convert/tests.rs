//! Round trips (domain → wire → bytes → wire → domain, bit-exact), rejections and garbage input.

use super::*;
use crate::v1;
use risktwin_common::geometry::{Footprint, Pose, Vec2};
use risktwin_common::metrics::EpisodeMetrics;
use risktwin_common::risk::{RiskGrid, RiskTerms};
use risktwin_common::road::Road;
use risktwin_common::scenario::{ScenarioKind, content_id, sample};
use risktwin_common::sensor::ObjectKind;
use risktwin_common::telemetry::*;
use risktwin_common::vehicle::Controls;

pub(crate) fn hdr(seq: u64) -> Header {
    Header {
        source: "vehicle-7".into(),
        seq,
        capture_time_ns: 1_700_000_000_123_456_789,
        publish_time_ns: -42,
        frame: Frame::World,
    }
}

pub(crate) fn vehicle_state() -> VehicleStateSample {
    VehicleStateSample {
        header: hdr(3),
        pose: Pose::new(0.1 + 0.2, -1e-300, std::f64::consts::PI),
        velocity: Vec2::new(27.777_777_777_777_78, -1.5e-7),
        speed_mps: 27.8,
        accel_mps2: -9.81,
        yaw_rate_radps: 1.0 / 3.0,
        steer_rad: -0.05,
        footprint: Footprint::new(4.5, 1.8),
    }
}

fn warning(kind: HazardKind) -> HazardWarning {
    HazardWarning {
        header: Header { source: "cloud".into(), ..hdr(15) },
        warned_source: "vehicle-1".into(),
        hazard_source: "vehicle-2".into(),
        hazard_pose: Pose::new(12.5, -3.5, 0.25),
        hazard_velocity: Vec2::new(-4.0, 0.1),
        hazard_footprint: Footprint::new(4.5, 1.8),
        kind,
        ttc_s: 1.375,
        distance_m: 6.0,
        trigger_source: "vehicle-2".into(),
        trigger_seq: 81,
        trigger_capture_time_ns: 1_700_000_000_500_000_000,
    }
}

fn object(id: u32, kind: ObjectKind) -> DetectedObject {
    DetectedObject {
        id,
        kind,
        pose: Pose::new(12.5, 3.75, 0.01),
        footprint: Footprint::new(0.6, 0.6),
        velocity: Vec2::new(0.0, 1.4),
        accel_mps2: -0.5,
    }
}

fn terms() -> RiskTerms {
    RiskTerms { score: 0.61, ttc: 1.0, dist: 0.7, lane: 0.0, jerk: 0.123_456_789, collision: 1.0 }
}

fn metrics() -> EpisodeMetrics {
    EpisodeMetrics {
        collision: true,
        offroad: false,
        success: false,
        route_completion: 0.4,
        avg_speed_mps: 13.3,
        steering_smoothness: 0.02,
        longitudinal_smoothness: 1.7,
        min_ttc_s: None,
        min_distance_m: f64::INFINITY,
        risk_score: 0.9,
        reward: -120.5,
        steps: 900,
    }
}

fn road_map() -> RoadMap {
    RoadMap {
        header: hdr(1),
        road: Road::crossing(3.5, 200.0, 100.0, 80.0, 13.9).with_friction_patch(10.0, 50.0, 0.3),
        lanelets: Default::default(),
    }
}

/// Encodes, decodes and checks the value came back bit for bit (Debug prints the shortest
/// round-trip form of every f64, so equal Debug strings mean equal bits, -0.0 included).
fn round_trip<T: WireMessage + std::fmt::Debug>(value: &T) -> T {
    let bytes = encode(value);
    let mut appended = vec![0xAA];
    encode_into(value, &mut appended);
    assert_eq!(&appended[1..], &bytes[..], "encode_into appends the same bytes");
    let back: T = decode(&bytes).unwrap_or_else(|e| panic!("{} failed to decode: {e}", T::PROTO_NAME));
    assert_eq!(format!("{back:?}"), format!("{value:?}"), "{}", T::PROTO_NAME);
    back
}

#[test]
fn every_message_round_trips_bit_exactly() {
    let back = round_trip(&vehicle_state());
    assert_eq!(back.velocity.y.to_bits(), (-1.5e-7f64).to_bits());
    // The one documented loss: proto3 leaves out fields equal to 0.0, and -0.0 == 0.0.
    let zero = decode::<VehicleStateSample>(&encode(&VehicleStateSample { steer_rad: -0.0, ..vehicle_state() }));
    assert_eq!(zero.map(|s| s.steer_rad.to_bits()), Ok(0.0f64.to_bits()));
    let mut can = CanSignals { speed_mps: 12.0, ..Default::default() }.to_frames(hdr(1), hdr(2))[0].clone();
    round_trip(&can);
    can.dlc = 0;
    can.data = [0; 8];
    round_trip(&can);
    let objects =
        vec![object(1, ObjectKind::Vehicle), object(2, ObjectKind::Pedestrian), object(3, ObjectKind::Parked)];
    round_trip(&ObjectList { header: hdr(4), objects: objects.clone() });
    round_trip(&ObjectList { header: hdr(5), objects: vec![] });
    round_trip(&RsuObservation { header: hdr(6), rsu_pose: Pose::new(50.0, -5.0, 1.5), range_m: 80.0, objects });
    for phase in [Phase::Red, Phase::Amber, Phase::Green] {
        round_trip(&SignalPhase { header: hdr(7), signal_id: 9, phase, time_to_change_s: 2.5 });
    }
    let map = round_trip(&road_map());
    assert_eq!(map.road.lanes[0].cum_s, road_map().road.lanes[0].cum_s);
    let grid = RiskGrid {
        origin_m: Vec2::new(-10.0, 2.5),
        resolution_m: 0.5,
        cols: 3,
        rows: 2,
        cells: vec![0.0, 0.25, 1e-8, 3.5, 0.0, 7.0],
    };
    round_trip(&RiskField { header: Header { frame: Frame::Vehicle, ..hdr(8) }, grid });
    round_trip(&RiskReport {
        header: hdr(9),
        ego_source: "vehicle-1".into(),
        terms: terms(),
        min_ttc_s: Some(1.25),
        min_distance_m: 3.0,
    });
    round_trip(&RiskReport {
        header: hdr(9),
        ego_source: "vehicle-1".into(),
        terms: terms(),
        min_ttc_s: None,
        min_distance_m: f64::INFINITY,
    });
    round_trip(&ControlCommand { header: hdr(10), controls: Controls::new(-0.3, 0.25, 0.0) });
    round_trip(&PolicyUpdate {
        header: hdr(11),
        policy_id: "ppo-main".into(),
        version: 4,
        algo: "ppo".into(),
        weights: vec![1, 2, 3, 0, 255],
        target: "site0/veh-1".into(),
        signature: vec![7; 64],
    });
    for kind in ScenarioKind::ALL {
        round_trip(&ScenarioPush { header: hdr(12), spec_id: format!("{kind}-1"), spec: sample(7, kind, 3) });
    }
    round_trip(&ScenarioResult {
        header: hdr(13),
        spec_id: "cut-in-1".into(),
        metrics: metrics(),
        risk: terms(),
        policy: None,
        state_seqs: None,
        scene: None,
    });
    round_trip(&ScenarioResult {
        header: hdr(13),
        spec_id: "x".into(),
        metrics: EpisodeMetrics { min_ttc_s: Some(0.0), ..metrics() },
        risk: terms(),
        policy: Some(PolicyRef { policy_id: "ppo-main".into(), version: 7 }),
        state_seqs: Some((40, 240)),
        scene: None,
    });
    let spec = sample(7, ScenarioKind::CutIn, 3);
    round_trip(&ScenarioResult {
        header: hdr(14),
        spec_id: content_id(&spec),
        metrics: metrics(),
        risk: terms(),
        policy: None,
        state_seqs: Some((0, 120)),
        scene: Some(SceneRef { digest: "00ff00ff00ff00ff".into(), spec }),
    });
    for kind in [HazardKind::Contact, HazardKind::LaneTtc, HazardKind::PredictedContact] {
        round_trip(&warning(kind));
    }
}

#[test]
fn hazard_warnings_without_ids_or_with_bad_values_are_rejected() {
    let w = warning(HazardKind::LaneTtc);
    rejects(&w, |p| p.warned_source.clear(), missing("HazardWarning", "warned_source"));
    rejects(&w, |p| p.trigger_source.clear(), missing("HazardWarning", "trigger_source"));
    rejects(&w, |p| p.hazard_pose = None, missing("HazardWarning", "hazard_pose"));
    rejects(&w, |p| p.kind = 0, bad("HazardWarning", "kind", "value is UNSPECIFIED (0)"));
    rejects(&w, |p| p.kind = 9, bad("HazardWarning", "kind", "unknown enum value 9"));
    rejects(&w, |p| p.ttc_s = -0.5, bad("HazardWarning", "ttc_s", "-0.5 is not a finite number ≥ 0"));
    rejects(&w, |p| p.distance_m = f64::NAN, bad("HazardWarning", "distance_m", "NaN is not a finite number ≥ 0"));
}

#[test]
fn scenario_params_encode_deterministically() {
    let push = ScenarioPush { header: hdr(1), spec_id: "a".into(), spec: sample(1, ScenarioKind::CutIn, 0) };
    assert_eq!(encode(&push), encode(&push.clone()));
}

/// Asserts that mutating a valid wire message makes decoding fail with `expected`.
fn rejects<T: WireMessage>(value: &T, mutate: impl FnOnce(&mut T::Proto), expected: ConvertError) {
    let mut proto = value.to_proto();
    mutate(&mut proto);
    let bytes = prost::Message::encode_to_vec(&proto);
    match decode::<T>(&bytes) {
        Err(DecodeError::Invalid(e)) => assert_eq!(e, expected),
        Err(e) => panic!("{}: expected {expected:?}, got {e:?}", T::PROTO_NAME),
        Ok(_) => panic!("{}: expected {expected:?}, got Ok", T::PROTO_NAME),
    }
}

fn missing(message: &'static str, field: &'static str) -> ConvertError {
    ConvertError::MissingField { message, field }
}

fn bad(message: &'static str, field: &'static str, reason: &str) -> ConvertError {
    ConvertError::InvalidField { message, field, reason: reason.into() }
}

#[test]
fn missing_sub_messages_and_ids_are_rejected() {
    let s = vehicle_state();
    rejects(&s, |p| p.header = None, missing("VehicleState", "header"));
    rejects(&s, |p| p.pose = None, missing("VehicleState", "pose"));
    rejects(&s, |p| p.footprint = None, missing("VehicleState", "footprint"));
    rejects(&s, |p| p.velocity_mps = None, missing("VehicleState", "velocity_mps"));
    rejects(&s, |p| p.header.as_mut().map_or((), |h| h.source.clear()), missing("Header", "source"));
    let r = ScenarioResult {
        header: hdr(1),
        spec_id: "a".into(),
        metrics: metrics(),
        risk: terms(),
        policy: Some(PolicyRef { policy_id: "p".into(), version: 1 }),
        state_seqs: Some((3, 3)),
        scene: None,
    };
    rejects(&r, |p| p.metrics = None, missing("ScenarioResult", "metrics"));
    rejects(
        &r,
        |p| p.state_seqs = Some(crate::v1::SeqRange { first: 4, last: 3 }),
        bad("ScenarioResult", "state_seqs", "first 4 > last 3"),
    );
    rejects(&r, |p| p.policy.as_mut().map_or((), |q| q.policy_id.clear()), missing("PolicyRef", "policy_id"));
    rejects(&r, |p| p.risk = None, missing("ScenarioResult", "risk"));
    let spec = sample(1, ScenarioKind::CutIn, 0);
    let in_scene = ScenarioResult {
        spec_id: content_id(&spec),
        scene: Some(SceneRef { digest: "0123456789abcdef".into(), spec }),
        ..r.clone()
    };
    rejects(
        &in_scene,
        |p| scene_of(p).digest = "xyz".into(),
        bad("SceneRef", "digest", "\"xyz\" is not 16 lower-case hex digits"),
    );
    rejects(&in_scene, |p| scene_of(p).spec = None, missing("SceneRef", "spec"));
    let other = content_id(&sample(2, ScenarioKind::CutIn, 0));
    rejects(
        &in_scene,
        |p| p.spec_id = other.clone(),
        bad("SceneRef", "spec", &format!("its content id {} is not the result's spec_id {other}", in_scene.spec_id)),
    );
    let push = ScenarioPush { header: hdr(1), spec_id: "a".into(), spec: sample(1, ScenarioKind::LowFriction, 0) };
    rejects(&push, |p| p.spec = None, missing("ScenarioPush", "spec"));
    let pol = PolicyUpdate {
        header: hdr(1),
        policy_id: "p".into(),
        version: 1,
        algo: "sac".into(),
        weights: vec![1],
        target: String::new(),
        signature: Vec::new(),
    };
    rejects(&pol, |p| p.weights_safetensors.clear(), missing("PolicyUpdate", "weights_safetensors"));
    rejects(&road_map(), |p| p.lanes.clear(), missing("RoadMap", "lanes"));
}

#[test]
fn non_finite_numbers_are_rejected() {
    let s = vehicle_state();
    rejects(&s, |p| p.speed_mps = f64::NAN, bad("VehicleState", "speed_mps", "NaN is not finite"));
    rejects(&s, |p| p.accel_mps2 = f64::INFINITY, bad("VehicleState", "accel_mps2", "inf is not finite"));
    rejects(
        &s,
        |p| p.pose.as_mut().map_or((), |q| q.x_m = f64::NEG_INFINITY),
        bad("VehicleState", "pose", "-inf is not finite"),
    );
    let report =
        RiskReport { header: hdr(1), ego_source: "v".into(), terms: terms(), min_ttc_s: None, min_distance_m: 1.0 };
    rejects(&report, |p| p.min_distance_m = f64::NAN, bad("RiskReport", "min_distance_m", "NaN is not ≥ 0 or +inf"));
    rejects(
        &report,
        |p| p.min_ttc_s = Some(f64::INFINITY),
        bad("RiskReport", "min_ttc_s", "inf is not a finite number ≥ 0"),
    );
    let grid = RiskGrid { origin_m: Vec2::new(0.0, 0.0), resolution_m: 1.0, cols: 2, rows: 1, cells: vec![0.0, 1.0] };
    let field = RiskField { header: hdr(1), grid };
    rejects(&field, |p| p.cells[1] = f32::NAN, bad("RiskGrid", "cells", "cell 1 is NaN"));
    let push = ScenarioPush { header: hdr(1), spec_id: "a".into(), spec: sample(1, ScenarioKind::CutIn, 0) };
    let decoded = {
        let mut p = push.to_proto();
        if let Some(spec) = p.spec.as_mut() {
            spec.params.insert("ego_speed_mps".into(), f64::NAN);
        }
        decode::<ScenarioPush>(&prost::Message::encode_to_vec(&p))
    };
    assert!(
        matches!(decoded, Err(DecodeError::Invalid(ConvertError::InvalidField { field: "params", .. }))),
        "{decoded:?}"
    );
}

#[test]
fn negative_sizes_and_out_of_range_values_are_rejected() {
    let s = vehicle_state();
    rejects(
        &s,
        |p| p.footprint.as_mut().map_or((), |f| f.width_m = -1.8),
        bad("VehicleState", "footprint", "-1.8 is not a finite number > 0"),
    );
    let rsu = RsuObservation { header: hdr(1), rsu_pose: Pose::default(), range_m: 50.0, objects: vec![] };
    rejects(&rsu, |p| p.range_m = -1.0, bad("RsuObservation", "range_m", "-1 is not a finite number ≥ 0"));
    let cmd = ControlCommand { header: hdr(1), controls: Controls::new(0.0, 0.5, 0.0) };
    rejects(&cmd, |p| p.brake = 1.5, bad("ControlCommand", "brake", "1.5 is outside [0, 1]"));
    let report =
        RiskReport { header: hdr(1), ego_source: "v".into(), terms: terms(), min_ttc_s: None, min_distance_m: 1.0 };
    rejects(
        &report,
        |p| p.terms.as_mut().map_or((), |t| t.score = 1.01),
        bad("RiskTerms", "score", "1.01 is outside [0, 1]"),
    );
    let field = RiskField {
        header: hdr(1),
        grid: RiskGrid { origin_m: Vec2::new(0.0, 0.0), resolution_m: 1.0, cols: 2, rows: 1, cells: vec![0.0, 1.0] },
    };
    rejects(&field, |p| p.rows = 2, bad("RiskGrid", "cells", "2 values for 2×2 cells"));
    rejects(&field, |p| p.resolution_m = 0.0, bad("RiskGrid", "resolution_m", "0 is not a finite number > 0"));
    rejects(&field, |p| p.cols = 0, bad("RiskGrid", "cols", "0×1 cells, need at least 1×1"));
    rejects(
        &field,
        |p| (p.cols, p.rows) = (u32::MAX, u32::MAX),
        bad(
            "RiskGrid",
            "cols",
            &format!("{0}×{0} cells exceed the limit of {1}", u32::MAX, risktwin_common::risk::raster::MAX_CELLS),
        ),
    );
    let map = road_map();
    rejects(&map, |p| p.reference_lane = 5, bad("RoadMap", "reference_lane", "5, the map has 5 lanes"));
    rejects(&map, |p| p.lanes[0].left = Some(9), bad("Lane", "left", "lane 0 names neighbour 9, the map has 5 lanes"));
    rejects(
        &map,
        |p| p.lanes[1].centre_m.truncate(1),
        bad("Lane", "centre_m", "lane 1 has 1 vertices, needs at least 2"),
    );
    rejects(
        &map,
        |p| {
            let v = p.lanes[2].centre_m[0];
            p.lanes[2].centre_m.insert(0, v)
        },
        bad("Lane", "centre_m", "lane 2 repeats vertex 1 (zero-length segment)"),
    );
    rejects(&map, |p| p.friction_patches[0].s_end_m = 0.0, bad("FrictionPatch", "s_end_m", "0 is before s_start_m 10"));
    let r = ScenarioResult {
        header: hdr(1),
        spec_id: "a".into(),
        metrics: metrics(),
        risk: terms(),
        policy: None,
        state_seqs: None,
        scene: None,
    };
    rejects(
        &r,
        |p| p.metrics.as_mut().map_or((), |m| m.min_distance_m = -0.5),
        bad("EpisodeMetrics", "min_distance_m", "-0.5 is not ≥ 0 or +inf"),
    );
}

#[test]
fn unknown_and_unspecified_enums_are_rejected() {
    let s = vehicle_state();
    rejects(&s, |p| p.header.as_mut().map_or((), |h| h.frame = 0), bad("Header", "frame", "value is UNSPECIFIED (0)"));
    rejects(&s, |p| p.header.as_mut().map_or((), |h| h.frame = 17), bad("Header", "frame", "unknown enum value 17"));
    let list = ObjectList { header: hdr(1), objects: vec![object(1, ObjectKind::Vehicle)] };
    rejects(
        &list,
        |p| p.objects[0].kind = v1::ObjectKind::Unspecified as i32,
        bad("DetectedObject", "kind", "value is UNSPECIFIED (0)"),
    );
    rejects(&list, |p| p.objects[0].kind = -3, bad("DetectedObject", "kind", "unknown enum value -3"));
    let phase = SignalPhase { header: hdr(1), signal_id: 1, phase: Phase::Green, time_to_change_s: 0.0 };
    rejects(&phase, |p| p.phase = 0, bad("SignalPhase", "phase", "value is UNSPECIFIED (0)"));
    let push = ScenarioPush { header: hdr(1), spec_id: "a".into(), spec: sample(1, ScenarioKind::CutIn, 0) };
    rejects(
        &push,
        |p| p.spec.as_mut().map_or((), |s| s.kind = 0),
        bad("ScenarioSpec", "kind", "value is UNSPECIFIED (0)"),
    );
}

#[test]
fn can_frames_longer_than_eight_bytes_or_wider_than_29_bits_are_rejected() {
    let f = CanFrame { header: hdr(1), can_id: CAN_ID_MOTION, data: [1, 2, 3, 4, 5, 6, 0, 0], dlc: 6 };
    let back = round_trip(&f);
    assert_eq!((back.dlc, back.data), (6, [1, 2, 3, 4, 5, 6, 0, 0]));
    rejects(&f, |p| p.data = vec![0; 9], bad("CanFrame", "data", "9 bytes, a CAN frame carries at most 8"));
    rejects(
        &f,
        |p| p.can_id = 0x2000_0000,
        bad("CanFrame", "can_id", "0x20000000 exceeds the 29-bit maximum 0x1fffffff"),
    );
}

#[test]
fn garbage_bytes_are_errors_not_panics() {
    let err = decode::<VehicleStateSample>(&[0xff; 32]).expect_err("0xff… is not protobuf");
    assert_eq!(err.reason(), "malformed");
    // An empty buffer is a valid empty message, which lacks its header.
    let err = decode::<VehicleStateSample>(&[]).expect_err("empty message has no header");
    assert_eq!(err, DecodeError::Invalid(missing("VehicleState", "header")));
    assert_eq!(err.reason(), "missing-field");
    // Truncations of a valid message and pseudo-random bytes, through every decoder.
    let valid = encode(&vehicle_state());
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let mut inputs: Vec<Vec<u8>> = (0..valid.len()).map(|n| valid[..n].to_vec()).collect();
    for len in 0..400 {
        let bytes = (0..len % 97)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state >> 24) as u8
            })
            .collect();
        inputs.push(bytes);
    }
    let mut rejected = 0;
    for b in &inputs {
        rejected += usize::from(decode::<VehicleStateSample>(b).is_err());
        let _ = decode::<CanFrame>(b);
        let _ = decode::<ObjectList>(b);
        let _ = decode::<RsuObservation>(b);
        let _ = decode::<SignalPhase>(b);
        let _ = decode::<RoadMap>(b);
        let _ = decode::<RiskField>(b);
        let _ = decode::<RiskReport>(b);
        let _ = decode::<ControlCommand>(b);
        let _ = decode::<PolicyUpdate>(b);
        let _ = decode::<ScenarioPush>(b);
        let _ = decode::<ScenarioResult>(b);
        let _ = decode::<HazardWarning>(b);
    }
    assert_eq!(rejected, inputs.len(), "no truncation or random buffer is a valid vehicle state");
}

/// Encode + decode cost of one vehicle state. Run with
/// `cargo test -p risktwin-protos --release -- --ignored --nocapture measure_`.
#[test]
#[ignore]
fn measure_vehicle_state_encode_decode() {
    let s = vehicle_state();
    let n = 1_000_000u32;
    let mut buf = Vec::with_capacity(256);
    let t = std::time::Instant::now();
    let mut total = 0usize;
    for i in 0..n {
        let mut m = s.clone();
        m.header.seq = u64::from(i);
        buf.clear();
        encode_into(&m, &mut buf);
        let back: VehicleStateSample = decode(&buf).expect("valid");
        total += back.header.seq as usize & 1;
    }
    let per = t.elapsed().as_nanos() as f64 / f64::from(n);
    println!("VehicleState: {} bytes, encode+decode {per:.0} ns/message (checksum {total})", buf.len());
}

#[test]
fn lanelets_travel_with_their_bounds_and_links() {
    use risktwin_common::road::{Adjacency, Lanelet, LaneletNetwork};
    let mut a = Lanelet::new(
        10,
        vec![Vec2::new(0.0, 3.0), Vec2::new(50.0, 3.25)],
        vec![Vec2::new(0.0, 0.0), Vec2::new(50.0, 0.1)],
    );
    a.successors = vec![11, 99];
    a.predecessors = vec![7];
    a.adjacent_left = Some(Adjacency { id: 12, same_direction: false });
    a.lanelet_types = vec!["driveWay".into()];
    let b = Lanelet::new(
        11,
        vec![Vec2::new(50.0, 3.25), Vec2::new(90.0, 3.0)],
        vec![Vec2::new(50.0, 0.1), Vec2::new(90.0, 0.0)],
    );
    let mut map = road_map();
    map.lanelets = LaneletNetwork::new(vec![a.clone(), b]);
    let back: RoadMap = decode(&encode(&map)).expect("a valid map decodes");
    assert_eq!(back.lanelets.len(), 2);
    let l = back.lanelets.get(10).expect("lanelet 10 came back");
    assert_eq!((&l.left_bound, &l.right_bound), (&a.left_bound, &a.right_bound));
    assert_eq!((&l.centreline, &l.widths_m, &l.polygon), (&a.centreline, &a.widths_m, &a.polygon));
    assert_eq!((&l.predecessors, &l.successors), (&a.predecessors, &a.successors));
    assert_eq!((l.adjacent_left, l.adjacent_right), (a.adjacent_left, None));
    assert_eq!(l.lanelet_types, a.lanelet_types);
    assert_eq!(back.lanelets.lanelets[1].id, 11, "file order is kept");

    rejects(
        &map,
        |p| p.lanelets[1].right_bound_m.truncate(1),
        bad(
            "Lanelet",
            "right_bound_m",
            "lanelet 11: bounds need the same number of vertices (at least 2), left has 2, right has 1",
        ),
    );
    rejects(&map, |p| p.lanelets[1].id = 10, bad("RoadMap", "lanelets", "lanelet id 10 appears twice"));
    rejects(&map, |p| p.lanelets[0].left_bound_m[0].y = f64::NAN, bad("Lanelet", "left_bound_m", "NaN is not finite"));
}

#[test]
fn a_message_tagged_with_another_schema_is_refused_by_name() {
    let bytes = encode(&vehicle_state());
    let own = encoding_of("risktwin.v1.VehicleState");
    assert_eq!(own, "application/protobuf;risktwin.v1.VehicleState");
    assert_eq!(decode_tagged::<VehicleStateSample>(&own, &bytes).expect("its own schema"), vehicle_state());
    // The same bytes under another version, another type, another media type, or untagged:
    // never read.
    for tag in [
        "application/protobuf;risktwin.v2.VehicleState",
        "application/protobuf;risktwin.v1.ObjectList",
        "application/json;risktwin.v1.VehicleState",
        "application/protobuf",
        "zenoh/bytes",
    ] {
        let err = decode_tagged::<VehicleStateSample>(tag, &bytes).expect_err(tag);
        assert_eq!(err, DecodeError::WrongSchema { found: tag.to_owned(), expected: "risktwin.v1.VehicleState" });
        assert_eq!(err.reason(), "wrong-schema");
        assert!(err.to_string().contains(tag), "{err}");
    }
}

fn scene_of(p: &mut crate::v1::ScenarioResult) -> &mut crate::v1::SceneRef {
    p.scene.as_mut().expect("a scene")
}

#[test]
fn delivery_acks_round_trip_and_impossible_ones_are_rejected() {
    use risktwin_common::delivery::{DeliveryAck, StreamAck};
    let stream = |name: &str, next_seq, received, lost| StreamAck { stream: name.into(), next_seq, received, lost };
    let ack = DeliveryAck {
        header: hdr(3),
        edge_source: "veh-1".into(),
        edge_session: "a1b2".into(),
        cloud_session: "c3d4".into(),
        streams: vec![stream("state", 10, 9, 1), stream("can", 40, 40, 0)],
        shed: vec!["can".into()],
    };
    round_trip(&ack);
    rejects(&ack, |p| p.edge_session.clear(), missing("DeliveryAck", "edge_session"));
    rejects(&ack, |p| p.streams[0].stream.clear(), missing("StreamAck", "stream"));
    rejects(&ack, |p| p.streams[1].received = 41, bad("StreamAck", "received", "41 above next_seq 40"));
}

#[test]
fn the_header_sequence_number_is_read_without_decoding_the_rest() {
    let mut state = vehicle_state();
    state.header.seq = 123_456_789_012;
    assert_eq!(header_seq(&encode(&state)), Some(123_456_789_012));
    let frame = CanFrame { header: hdr(7), can_id: 0x123, data: [1, 2, 3, 4, 5, 6, 7, 8], dlc: 8 };
    assert_eq!(header_seq(&encode(&frame)), Some(7));
    assert_eq!(header_seq(&[]), None, "no header");
    assert_eq!(header_seq(&[0x0A, 0x05, 0x10]), None, "cut short");
}
