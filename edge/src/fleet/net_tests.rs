//! Unit tests of `net.rs`: the authority's tally and joins, the scene's road map on the wire.

use super::super::wire::SCHEMA_VERSION;
use super::*;
use risktwin_common::scenario::{ScenarioKind, build};
use risktwin_transport::sync::LockExt;

fn tally(step: u64) -> Tally {
    let answers = Answers { step: Some(step), answered: vec![false; 2], missing: 2, ..Answers::default() };
    Tally { state: Mutex::new(answers), ready: Condvar::new(), participants: vec!["v0".into(), "rsu0".into()] }
}

#[test]
fn the_tally_counts_each_participant_once_for_the_current_step_only() {
    let tally = tally(3);
    let brake = Controls { steer_rad: 0.0, throttle: 0.0, brake: 1.0 };
    tally.on_reply(&Reply::step("rsu0", 2, None).encode());
    tally.on_reply(&Reply::step("v9", 3, None).encode());
    tally.on_reply(&Reply::step("rsu0", 3, None).encode());
    tally.on_reply(&Reply::step("rsu0", 3, None).encode());
    assert_eq!(tally.state.locked().missing, 1, "another step, a stranger and a repeat do not count");
    tally.on_reply(&[0xFF, 0x00, 0x13]);
    tally.on_reply(&Reply::step("v0", 3, Some(brake)).encode());
    let answers = tally.state.locked();
    assert_eq!((answers.missing, answers.answered.as_slice()), (0, &[true, true][..]));
    assert_eq!((answers.ego, answers.malformed), (Some(brake), 1));
}

#[test]
fn joins_are_queued_for_the_stepping_thread_until_stepping_starts() {
    let tally = tally(0);
    {
        let mut answers = tally.state.locked();
        (answers.step, answers.joining) = (None, true);
    }
    let join =
        |id: &str| Reply::Join { schema: SCHEMA_VERSION, participant: id.into(), scene: 7, describe: "d".into() };
    tally.on_reply(&join("v0").encode());
    tally.on_reply(&join("v9").encode());
    let answers = tally.state.locked();
    let ids: Vec<&str> = answers.joins.iter().map(|(id, ..)| id.as_str()).collect();
    assert_eq!(ids, ["v0", "v9"], "an unknown participant is refused by the stepping thread, by name");
    assert_eq!(answers.missing, 2);
    drop(answers);
    tally.state.locked().joining = false;
    tally.on_reply(&join("v0").encode());
    assert_eq!(tally.state.locked().joins.len(), 2, "a join repeated after stepping started is dropped");
}

#[test]
fn every_kind_of_scene_map_decodes_as_the_cloud_decodes_it() {
    for kind in ScenarioKind::ALL {
        let spec = crate::scene::feasible_spec(3, kind).expect("feasible");
        let map = scene_road_map(&SceneWorld::Generated(build(&spec)));
        let back: RoadMap = risktwin_protos::decode(&encode(&map)).unwrap_or_else(|e| panic!("{kind:?}: {e}"));
        assert_eq!(back.road.lanes.len(), map.road.lanes.len());
    }
}
