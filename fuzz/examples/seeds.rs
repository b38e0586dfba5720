//! Writes the seed corpora of the binary-input targets (`fuzz/corpus/<target>/`) from real
//! values, encoded by the same code the binary encodes them with: edge-stream messages as an
//! edge publishes them, pushes as the cloud sends them (a policy update signed with the key the
//! `edge_push` target trusts), scene wire messages, policy files as the trainer saves them,
//! recordings as the recorder and `risktwin import commonroad` write them, and configuration
//! files as their defaults serialise. Text seeds (CommonRoad, topology) are files in the
//! corpus. Run from `fuzz/`: `cargo +nightly run --release --example seeds` (docs/fuzzing.md).

// Built with the fuzz targets' flags (to share their build), the code calls the coverage hooks
// that libFuzzer defines.
extern crate libfuzzer_sys;

use risktwin_cloud::commonroad_recording::write_scenario;
use risktwin_commonroad::parse_scenario;
use risktwin_common::geometry::{Footprint, Pose, Vec2};
use risktwin_policy::signature::PolicySigningKey;
use risktwin_common::rng::Rng;
use risktwin_common::road::Road;
use risktwin_common::scenario::{ScenarioKind, sample};
use risktwin_common::sensor::ObjectKind;
use risktwin_common::telemetry::{
    CanFrame, DetectedObject, Frame, HazardKind, HazardWarning, Header, ObjectList, Phase, PolicyUpdate, RoadMap,
    RsuObservation, ScenarioPush, SignalPhase, VehicleStateSample,
};
use risktwin_v2x::sweep::SweepConfig;
use risktwin_edge::fleet::wire::{EgoTruth, Reply, Truth, TruthObject};
use risktwin_edge::vehicle::push::{PolicyTrust, PushSummary};
use risktwin_fuzz::{
    INGEST_SITES, PUSH_KEY_SEED, PUSH_TARGET, PUSH_VEHICLE_ID, ingest_tag, push_tag, scene_tag, write_record,
};
use risktwin_learn::{Algo, PolicyNet};
use risktwin_pipeline::RunConfig;
use risktwin_protos::recording::{Recorder, encode_replay_time};
use risktwin_protos::{WireMessage, encode, encoding_of};
use risktwin_transport::EdgeStream;
use std::io::Cursor;
use std::path::Path;

type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

/// The CommonRoad seed the recordings are made of (also a seed of `commonroad`).
const COMMONROAD_SEED: &str = "corpus/commonroad/DEU_Crit-1_1_T-1.xml";

fn header(source: &str, seq: u64, t_ns: i64) -> Header {
    Header { source: source.into(), seq, capture_time_ns: t_ns, publish_time_ns: t_ns, frame: Frame::World }
}

fn state(source: &str, seq: u64, t_ns: i64) -> VehicleStateSample {
    let x_m = 20.0 * t_ns as f64 * 1e-9;
    VehicleStateSample {
        header: header(source, seq, t_ns),
        pose: Pose::new(x_m, 0.0, 0.0),
        velocity: Vec2::new(20.0, 0.0),
        speed_mps: 20.0,
        accel_mps2: 0.0,
        yaw_rate_radps: 0.0,
        steer_rad: 0.0,
        footprint: Footprint::new(4.5, 1.8),
    }
}

fn objects() -> Vec<DetectedObject> {
    let car = DetectedObject {
        id: 7,
        kind: ObjectKind::Vehicle,
        pose: Pose::new(30.0, 3.5, 0.0),
        footprint: Footprint::new(4.5, 1.8),
        velocity: Vec2::new(15.0, 0.0),
        accel_mps2: -0.5,
    };
    let walker = DetectedObject {
        id: 8,
        kind: ObjectKind::Pedestrian,
        pose: Pose::new(40.0, -4.0, 1.57),
        footprint: Footprint::new(0.5, 0.5),
        velocity: Vec2::new(0.0, 1.2),
        accel_mps2: 0.0,
    };
    vec![car, walker]
}

/// The payload of `stream` from `source`, message `seq` at `t_ns`.
fn edge_message(stream: EdgeStream, source: &str, seq: u64, t_ns: i64) -> Vec<u8> {
    let h = header(source, seq, t_ns);
    match stream {
        EdgeStream::State => encode(&state(source, seq, t_ns)),
        EdgeStream::Can => encode(&CanFrame { header: h, can_id: 0x100, data: [1, 2, 3, 4, 0, 0, 0, 0], dlc: 8 }),
        EdgeStream::Perception => encode(&ObjectList { header: h, objects: objects() }),
        EdgeStream::Rsu => encode(&RsuObservation {
            header: h,
            rsu_pose: Pose::new(50.0, 10.0, 0.0),
            range_m: 80.0,
            objects: objects(),
        }),
        EdgeStream::Signal => {
            encode(&SignalPhase { header: h, signal_id: 1, phase: Phase::Green, time_to_change_s: 4.0 })
        }
    }
}

/// Writes `bytes` as `corpus/<target>/<name>`.
fn seed(target: &str, name: &str, bytes: &[u8]) -> Result<()> {
    let dir = Path::new("corpus").join(target);
    std::fs::create_dir_all(&dir)?;
    std::fs::write(dir.join(name), bytes)?;
    Ok(())
}

fn ingest_seeds() -> Result<()> {
    // Every stream from one vehicle (and the RSU's own), in time order, over 0.2 s.
    let mut all = Vec::new();
    for step in 0..10u64 {
        let t_ns = 1_000_000_000 + step as i64 * 20_000_000;
        for (stream_index, &stream) in EdgeStream::ALL.iter().enumerate() {
            let source = if matches!(stream, EdgeStream::Rsu | EdgeStream::Signal) { 2 } else { 0 };
            let tag = ingest_tag::of(stream_index as u8, source, 0, 0);
            let payload = edge_message(stream, ["veh-1", "veh-2", "rsu-1"][usize::from(source)], step, t_ns);
            write_record(&mut all, tag, &[&encode_replay_time(t_ns), &payload]);
        }
    }
    seed("ingest", "all_streams", &all)?;
    // Two vehicles' states, the second a duplicate and a wrongly tagged one among them.
    let mut two = Vec::new();
    for step in 0..8u64 {
        let t_ns = 2_000_000_000 + step as i64 * 20_000_000;
        for source in 0..2u8 {
            let payload = edge_message(EdgeStream::State, ["veh-1", "veh-2"][usize::from(source)], step, t_ns);
            let encoding = u8::from(step == 5 && source == 1);
            write_record(&mut two, ingest_tag::of(0, source, 0, encoding), &[&encode_replay_time(t_ns), &payload]);
        }
    }
    let again = edge_message(EdgeStream::State, "veh-1", 3, 2_200_000_000);
    write_record(&mut two, ingest_tag::of(0, 0, 0, 0), &[&encode_replay_time(2_200_000_000), &again]);
    seed("ingest", "two_vehicles", &two)?;
    Ok(())
}

/// A policy file as the trainer saves it.
fn policy_file(algo: Algo, hidden: &[usize]) -> Result<Vec<u8>> {
    let net = PolicyNet::new(algo, hidden, &mut Rng::new(1))?;
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("policy.safetensors");
    net.save(&path)?;
    Ok(std::fs::read(path)?)
}

fn push_seeds() -> Result<()> {
    let cloud = header("cloud", 0, 1_000_000_000);
    let spec = sample(1, ScenarioKind::CutIn, 0);
    let push = ScenarioPush { header: cloud.clone(), spec_id: "cut-in-0".into(), spec };
    let warning = HazardWarning {
        header: cloud.clone(),
        warned_source: PUSH_VEHICLE_ID.into(),
        hazard_source: "veh-2".into(),
        hazard_pose: Pose::new(30.0, 0.0, 0.0),
        hazard_velocity: Vec2::new(10.0, 0.0),
        hazard_footprint: Footprint::new(4.5, 1.8),
        kind: HazardKind::LaneTtc,
        ttc_s: 2.5,
        distance_m: 25.0,
        trigger_source: "veh-1".into(),
        trigger_seq: 4,
        trigger_capture_time_ns: 1_000_000_000,
    };
    // The weights a vehicle loads: the actor of a trainer's policy file.
    let host = PolicyNet::new(Algo::Ppo, &[8], &mut Rng::new(2))?.host()?;
    let mut update = PolicyUpdate {
        header: cloud,
        policy_id: "p".into(),
        version: 1,
        algo: "ppo".into(),
        weights: host.to_safetensors()?,
        target: PUSH_TARGET.into(),
        signature: Vec::new(),
    };
    let key = PolicySigningKey::from_seed(PUSH_KEY_SEED);
    key.sign(&mut update);
    // The seeds must get through, or the fuzzer starts at the first refusal.
    let mut vehicle = PushSummary::default();
    let trust = PolicyTrust { key: Some(key.verifying_key()), target: PUSH_TARGET.into() };
    let accepted = (
        vehicle.scenario(&encoding_of(ScenarioPush::PROTO_NAME), &encode(&push)).is_some(),
        vehicle.warning(PUSH_VEHICLE_ID, &encoding_of(HazardWarning::PROTO_NAME), &encode(&warning)).is_some(),
        vehicle.policy(&encoding_of(PolicyUpdate::PROTO_NAME), &encode(&update), &trust).is_some(),
    );
    if accepted != (true, true, true) {
        return Err(format!("a push seed is refused (scenario, warning, policy accepted: {accepted:?})").into());
    }
    let mut all = Vec::new();
    write_record(&mut all, push_tag::SCENARIO, &[&encode(&push)]);
    write_record(&mut all, push_tag::WARNING, &[&encode(&warning)]);
    write_record(&mut all, push_tag::POLICY, &[&encode(&update)]);
    seed("edge_push", "scenario_warning_policy", &all)?;
    // The same update twice: the second is stale.
    let mut twice = Vec::new();
    write_record(&mut twice, push_tag::POLICY, &[&encode(&update)]);
    write_record(&mut twice, push_tag::POLICY, &[&encode(&update)]);
    seed("edge_push", "policy_twice", &twice)?;
    Ok(())
}

fn scene_seeds() -> Result<()> {
    let ego = EgoTruth {
        pose: [10.0, 0.0, 0.0],
        speed_mps: 12.0,
        accel_mps2: 0.5,
        yaw_rate_radps: 0.0,
        steer_rad: 0.01,
        velocity: [12.0, 0.0],
        footprint: [4.5, 1.8],
    };
    let other = TruthObject {
        id: 2,
        kind: ObjectKind::Vehicle,
        centre: [30.0, 3.5],
        axis: [1.0, 0.0],
        half_length_m: 2.25,
        half_width_m: 0.9,
        velocity: [10.0, 0.0],
        accel_mps2: 0.0,
    };
    let truth = Truth {
        schema: risktwin_edge::fleet::wire::SCHEMA_VERSION,
        scene: 0x1234_5678,
        step: 3,
        time_s: 0.15,
        ego,
        objects: vec![other],
        end: None,
    };
    let mut truth_bytes = Vec::new();
    truth.encode_into(&mut truth_bytes);
    let join = Reply::Join {
        schema: risktwin_edge::fleet::wire::SCHEMA_VERSION,
        participant: "veh-1".into(),
        scene: 0x1234_5678,
        describe: "cut-in seed 1".into(),
    };
    let step = Reply::step("veh-1", 3, Some(risktwin_common::vehicle::Controls::default()));
    let map = RoadMap {
        header: header("scene", 0, 0),
        road: Road::straight(2, 3.5, 200.0, 20.0),
        lanelets: Default::default(),
    };
    let mut all = Vec::new();
    write_record(&mut all, scene_tag::TRUTH, &[&truth_bytes]);
    write_record(&mut all, scene_tag::REPLY, &[&join.encode()]);
    write_record(&mut all, scene_tag::REPLY, &[&step.encode()]);
    write_record(&mut all, scene_tag::VEHICLE, &[&encode(&state("veh-1", 0, 0))]);
    write_record(
        &mut all,
        scene_tag::OBJECTS,
        &[&encode(&ObjectList { header: header("scene", 0, 0), objects: objects() })],
    );
    seed("scene_wire", "messages", &all)?;
    let mut road = Vec::new();
    write_record(&mut road, scene_tag::ROAD_MAP, &[&encode(&map)]);
    seed("scene_wire", "road_map", &road)?;
    Ok(())
}

fn recording_seeds() -> Result<()> {
    // What a cloud records: accepted edge messages under their keys.
    let mut rec = Recorder::new(Cursor::new(Vec::new()))?;
    for step in 0..5u64 {
        let t_ns = 1_000_000_000 + step as i64 * 20_000_000;
        for &stream in &EdgeStream::ALL {
            let key = format!("risktwin/v1/{}/veh-1/{}", INGEST_SITES[0], stream.as_str());
            let channel = rec.channel(&key, stream.message())?;
            rec.write(channel, t_ns as u64, t_ns as u64, &edge_message(stream, "veh-1", step, t_ns))?;
        }
    }
    let bytes = rec.finish_into_inner()?.into_inner();
    seed("mcap", "edge_streams.mcap", &bytes)?;
    // A recording cut short: no footer, the last chunk cut in half.
    seed("mcap", "edge_streams_cut.mcap", &bytes[..bytes.len() * 2 / 3])?;
    // `risktwin import commonroad`: what `criticality --mcap` rebuilds a scenario from.
    let scenario = parse_scenario(&std::fs::read_to_string(COMMONROAD_SEED)?)?;
    let mut import = Cursor::new(Vec::new());
    write_scenario(&scenario, &mut import)?;
    seed("mcap", "commonroad_import.mcap", &import.into_inner())?;
    Ok(())
}

fn policy_seeds() -> Result<()> {
    seed("policy_file", "ppo.safetensors", &policy_file(Algo::Ppo, &[8])?)?;
    seed("policy_file", "sac.safetensors", &policy_file(Algo::Sac, &[8, 4])?)?;
    seed("policy_file", "ppo_gru.safetensors", &policy_file(Algo::PpoGru, &[4])?)?;
    Ok(())
}

fn config_seeds() -> Result<()> {
    let run = serde_json::to_string_pretty(&RunConfig::quick())?;
    seed("config", "run_quick.json", format!("\0{run}").as_bytes())?;
    let sweep = serde_json::to_string_pretty(&SweepConfig::default())?;
    seed("config", "v2x_sweep_default.json", format!("\x01{sweep}").as_bytes())?;
    Ok(())
}

fn main() -> Result<()> {
    ingest_seeds()?;
    push_seeds()?;
    scene_seeds()?;
    recording_seeds()?;
    policy_seeds()?;
    config_seeds()?;
    Ok(())
}
