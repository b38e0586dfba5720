//! The collector on hand-made messages: a scenario rebuilt from its map and states gives the
//! criticality of the scenario itself; bad messages are rejected by reason and change nothing.

use super::*;
use risktwin_common::geometry::Pose;
use risktwin_common::telemetry::{Frame, Header, RoadMap, VehicleStateSample};
use risktwin_commonroad::criticality::scenario_criticality;
use risktwin_commonroad::twin::{footprint_of, road_from_lanelets};
use risktwin_commonroad::{Scenario, parse_scenario};
use risktwin_protos::encode;

const MAP_KEY: &str = "risktwin/v1/two/map/map";

/// A 200 m lanelet along +x; cars 1 (x = 10 m, 20 m/s) and 2 (x = 40 m, 10 m/s), 21 steps of 0.1 s
/// (the fixture common's criticality tests use too).
pub(crate) fn two_cars() -> Scenario {
    parse_scenario(include_str!("../../../tests/fixtures/two_cars.xml")).expect("the test scenario parses")
}

fn header(source: &str, seq: u64, time_ns: i64) -> Header {
    Header { source: source.into(), seq, capture_time_ns: time_ns, publish_time_ns: time_ns, frame: Frame::World }
}

/// The scenario as (key, payload) messages, in the order `risktwin import commonroad` writes.
pub(crate) fn messages(s: &Scenario) -> Vec<(String, Vec<u8>)> {
    let (road, _) = road_from_lanelets(&s.lanelets).expect("the lanelet converts");
    let map = RoadMap { header: header("map", 0, 0), road, lanelets: s.lanelets.clone() };
    let mut out = vec![(MAP_KEY.to_owned(), encode(&map))];
    for step in 0..=20 {
        for o in &s.dynamic_obstacles {
            let st = o.states().nth(step).expect("21 states");
            let source = format!("dyn-{}", o.id);
            let pose = Pose::new(st.position.x, st.position.y, st.orientation_rad);
            let speed_mps = st.velocity_mps.unwrap_or(0.0);
            let sample = VehicleStateSample {
                header: header(&source, step as u64, st.time_step * 100_000_000),
                pose,
                velocity: pose.forward() * speed_mps,
                speed_mps,
                accel_mps2: 0.0,
                yaw_rate_radps: 0.0,
                steer_rad: 0.0,
                footprint: footprint_of(&o.shape),
            };
            out.push((format!("risktwin/v1/two/{source}/state"), encode(&sample)));
        }
    }
    out
}

#[test]
fn a_rebuilt_scenario_has_the_criticality_of_the_original() {
    let original = two_cars();
    let mut c = ScenarioCollector::new();
    for (key, payload) in messages(&original) {
        let pushed = c.push(&key, &payload).expect("a valid message");
        assert_eq!(pushed, if key == MAP_KEY { Pushed::Map } else { Pushed::State });
    }
    assert_eq!(c.push("risktwin/v1/two/dyn-1/can", b"\x01"), Ok(Pushed::Skipped), "other streams are skipped");
    let rebuilt = c.finish().expect("the scenario rebuilds");
    assert_eq!(rebuilt.benchmark_id, "two");
    assert!((rebuilt.dt_s - 0.1).abs() < 1e-12);
    let ids: Vec<u64> = rebuilt.dynamic_obstacles.iter().map(|o| o.id).collect();
    assert_eq!(ids, [1, 2], "first-appearance order");
    let a = scenario_criticality(&original, Some(1)).expect("measures");
    let b = scenario_criticality(&rebuilt, Some(1)).expect("measures");
    let mut csv_a = Vec::new();
    let mut csv_b = Vec::new();
    write_report(&mut csv_a, ReportFormat::Csv, "x", &a).expect("in memory");
    write_report(&mut csv_b, ReportFormat::Csv, "x", &b).expect("in memory");
    assert_eq!(String::from_utf8_lossy(&csv_a), String::from_utf8_lossy(&csv_b));
    assert!(csv_a.starts_with(CSV_HEADER.as_bytes()) && a.cells.len() == 21, "{}", a.cells.len());
}

#[test]
fn bad_messages_are_rejected_by_reason_and_change_nothing() {
    let msgs = messages(&two_cars());
    let mut c = ScenarioCollector::new();
    let reject =
        |c: &mut ScenarioCollector, key: &str, payload: &[u8]| c.push(key, payload).expect_err("rejected").reason;
    assert_eq!(reject(&mut c, MAP_KEY, b"\xff\xff\xff"), "malformed");
    assert!(!c.has_map(), "a map that does not decode is not taken");
    let (_, state) = &msgs[1];
    assert_eq!(reject(&mut c, "risktwin/v1/two/veh-1/state", state), "source-mismatch");
    let mut renamed: VehicleStateSample = risktwin_protos::decode(state).expect("a valid state");
    renamed.header.source = "veh-1".into();
    assert_eq!(reject(&mut c, "risktwin/v1/two/veh-1/state", &encode(&renamed)), "bad-source");
    for (key, payload) in &msgs {
        c.push(key, payload).expect("a valid message");
    }
    assert_eq!(reject(&mut c, &msgs[1].0, &msgs[1].1), "stale-seq", "a duplicate is dropped");
    assert_eq!(reject(&mut c, "risktwin/v1/other/dyn-1/state", state), "other-site");
    c.finish().expect("the rejected messages left the collector intact");
}

#[test]
fn a_missing_map_or_state_is_an_error_naming_it() {
    let msgs = messages(&two_cars());
    let mut no_map = ScenarioCollector::new();
    for (key, payload) in &msgs[1..] {
        no_map.push(key, payload).expect("a valid message");
    }
    assert!(matches!(no_map.finish(), Err(RebuildError::NoMap)));
    // Step 5 of car 2 lost (index: map, then two states per step).
    let mut gap = ScenarioCollector::new();
    for (i, (key, payload)) in msgs.iter().enumerate() {
        if i != 1 + 5 * 2 + 1 {
            gap.push(key, payload).expect("a valid message");
        }
    }
    let err = gap.finish().expect_err("a state is missing");
    assert!(err.to_string().contains("obstacle id 2") && err.to_string().contains("missing"), "{err}");
}
