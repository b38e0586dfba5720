//! The key scheme's builders and parsers, against hand-written keys.

use super::*;

#[test]
fn sharding_keys_round_trip_and_refuse_strangers() {
    let (site, source) = (SiteId::new("s1").unwrap(), SourceId::new("v7").unwrap());
    assert_eq!(source_streams(&site, &source), "risktwin/v1/s1/v7/*");
    let token = worker_liveliness(&site, "w-01");
    assert_eq!(parse_worker_liveliness_key(&token), Some("w-01"));
    assert_eq!(parse_worker_liveliness_key("risktwin/v1/s1/alive/w-01"), None);
    assert_eq!(parse_worker_liveliness_key("risktwin/v1/s1/cloud/workers/w/x"), None);
    let edge = parse_edge_key("risktwin/v1/s1/v7/state").unwrap();
    let forwarded = ingested(&edge);
    assert_eq!(forwarded, "risktwin/v1/s1/cloud/ingested/v7/state");
    let mut buf = String::new();
    assert_eq!(edge_key_of_ingested(&forwarded, &mut buf), Some("risktwin/v1/s1/v7/state"));
    assert_eq!(edge_key_of_ingested("risktwin/v1/s1/cloud/ingested/v7/nope", &mut buf), None);
    assert_eq!(edge_key_of_ingested("risktwin/v1/s1/cloud/risk_field", &mut buf), None);
    assert_eq!(edge_key_of_ingested("risktwin/v1/s1/cloud/ingested/cloud/state", &mut buf), None);
}

#[test]
fn shard_groups_partition_the_sources_by_zenoh_s_own_matching() {
    use zenoh::key_expr::KeyExpr;
    let site = SiteId::new("s1").unwrap();
    let ids = ["v", "w", "v7", "veh-7", "veh-17", "car.ab", "ab", "b", "x-0001", "y-0001", "cloudy"];
    assert_eq!(shard_group("veh-17"), "17");
    assert_eq!(shard_group("v"), "v");
    for id in ids {
        let key = KeyExpr::new(format!("risktwin/v1/s1/{id}/state")).unwrap();
        for other in ids {
            let group = KeyExpr::new(shard_group_streams(&site, shard_group(other))).unwrap();
            let same = shard_group(id) == shard_group(other);
            assert_eq!(group.intersects(&key), same, "{group} and {key}");
        }
    }
}

fn ids() -> (SiteId, SourceId) {
    (SiteId::new("track-1").unwrap(), SourceId::new("veh_0.a").unwrap())
}

#[test]
fn ids_reject_separators_wildcards_and_empty() {
    assert_eq!(SourceId::new(""), Err(KeyError::EmptyId { what: "source" }));
    for (bad, ch) in [("a/b", '/'), ("a*", '*'), ("$x", '$'), ("a?b", '?'), ("a#", '#'), ("a b", ' ')] {
        assert_eq!(SourceId::new(bad), Err(KeyError::ForbiddenChar { what: "source", id: bad.into(), ch }), "{bad}");
    }
    assert!(matches!(SiteId::new("x".repeat(65)), Err(KeyError::IdTooLong { len: 65, .. })));
    assert_eq!(SourceId::new("cloud"), Err(KeyError::ReservedId { what: "source", id: "cloud".into() }));
    assert_eq!(SourceId::new("alive"), Err(KeyError::ReservedId { what: "source", id: "alive".into() }));
    // A site may be called "cloud": it sits at another level.
    assert!(SiteId::new("cloud").is_ok());
}

#[test]
fn keys_are_spelled_by_direction() {
    let (site, src) = ids();
    assert_eq!(edge_stream(&site, &src, EdgeStream::Can), "risktwin/v1/track-1/veh_0.a/can");
    assert_eq!(edge_stream_all(None, EdgeStream::State), "risktwin/v1/*/*/state");
    assert_eq!(edge_stream_all(Some(&site), EdgeStream::Rsu), "risktwin/v1/track-1/*/rsu");
    assert_eq!(edge_streams_all(None), "risktwin/v1/*/*/*");
    assert_eq!(cloud_to_edge(&site, &src, CloudToEdge::Policy), "risktwin/v1/track-1/veh_0.a/policy");
    assert_eq!(cloud_to_edge(&site, &src, CloudToEdge::Warning), "risktwin/v1/track-1/veh_0.a/warning");
    assert_eq!(parse_edge_key("risktwin/v1/track-1/veh_0.a/warning"), None, "a warning is no edge stream");
    assert_eq!(cloud_output(&site, CloudOutput::RiskField), "risktwin/v1/track-1/cloud/risk_field");
    assert_eq!(library_queryable(&site), "risktwin/v1/track-1/cloud/library/**");
    assert_eq!(library_ranked(&site), "risktwin/v1/track-1/cloud/library/ranked");
    assert_eq!(parse_library_ranked(&library_ranked(&site)), Some("track-1"));
    assert_eq!(parse_library_ranked("risktwin/v1/a/b/cloud/library/ranked"), None);
    assert_eq!(parse_library_ranked("risktwin/v1/a/cloud/library/other"), None);
    assert_eq!(library_queryable_all(None), "risktwin/v1/*/cloud/library/**");
    assert_eq!(cloud_output(&site, CloudOutput::Scene), "risktwin/v1/track-1/cloud/scene");
    assert_eq!(cloud_output(&site, CloudOutput::Road), "risktwin/v1/track-1/cloud/road");
    for output in [CloudOutput::Scene, CloudOutput::Road] {
        assert_eq!(parse_cloud_output_key(&cloud_output(&site, output), output), Some("track-1"));
    }
    assert_eq!(parse_cloud_output_key("risktwin/v1/track-1/cloud/scene", CloudOutput::Road), None);
    assert_eq!(parse_cloud_output_key("risktwin/v1/a/b/cloud/scene", CloudOutput::Scene), None);
    assert_eq!(parse_cloud_output_key("risktwin/v1/a/veh/scene", CloudOutput::Scene), None);
    assert_eq!(parse_cloud_output_key("risktwin/v1//cloud/scene", CloudOutput::Scene), None);
    let report = edge_report(&site, &src, EdgeReport::ScenarioResult);
    assert_eq!(report, "risktwin/v1/track-1/veh_0.a/scenario_result");
    assert_eq!(parse_edge_key(&report), None, "a report is not an ingest stream");
    assert_eq!(edge_report_all(None, EdgeReport::ScenarioResult), "risktwin/v1/*/*/scenario_result");
    assert_eq!(parse_edge_report_key(&report, EdgeReport::ScenarioResult), Some(("track-1", "veh_0.a")));
    for bad in ["risktwin/v1/s/cloud/scenario_result", "risktwin/v1/s/v/state", "risktwin/v1/s/v/scenario_result/x"] {
        assert_eq!(parse_edge_report_key(bad, EdgeReport::ScenarioResult), None, "{bad}");
    }
    assert_eq!(liveliness_token(&site, &src), "risktwin/v1/track-1/alive/veh_0.a");
    assert_eq!(liveliness_all(None), "risktwin/v1/*/alive/*");
}

#[test]
fn map_keys_round_trip_and_are_no_ingest_stream() {
    let (site, src) = ids();
    let key = edge_map(&site, &src);
    assert_eq!(key, "risktwin/v1/track-1/veh_0.a/map");
    assert_eq!(parse_edge_map_key(&key), Some(("track-1", "veh_0.a")));
    assert_eq!(parse_edge_key(&key), None, "the ingest does not take a map for a stream");
    for other in ["risktwin/v1/track-1/cloud/map", "risktwin/v1/track-1/veh/state", "risktwin/v1/s/v/map/x"] {
        assert_eq!(parse_edge_map_key(other), None, "{other}");
    }
}

#[test]
fn scene_keys_round_trip_and_are_no_ingest_stream() {
    let (site, src) = ids();
    for (topic, leaf) in
        [(SceneTopic::Map, "map"), (SceneTopic::Objects, "objects"), (SceneTopic::TruthBoxes, "truth_boxes")]
    {
        let key = scene_topic(Some(&site), topic);
        assert_eq!(key, format!("risktwin/v1/track-1/scene/{leaf}"));
        assert_eq!(parse_scene_topic_key(&key, topic), Some("track-1"));
        assert_eq!(parse_edge_key(&key), None, "{key} is no ingest stream");
        assert_eq!(scene_topic(None, topic), format!("risktwin/v1/*/scene/{leaf}"));
    }
    let objects = scene_topic(Some(&site), SceneTopic::Objects);
    assert_eq!(parse_scene_topic_key(&objects, SceneTopic::Map), None, "another topic");
    for other in ["risktwin/v1/a/b/scene/map", "risktwin/v1//scene/map", "risktwin/v1/track-1/scene_map"] {
        assert_eq!(parse_scene_topic_key(other, SceneTopic::Map), None, "{other}");
    }
    let gt = scene_ground_truth(&site, &src);
    assert_eq!(gt, "risktwin/v1/track-1/scene/gt/veh_0.a");
    assert_eq!(parse_scene_ground_truth_key(&gt), Some(("track-1", "veh_0.a")));
    assert_eq!(parse_edge_key(&gt), None, "the truth is no ingest stream");
    assert_eq!(scene_ground_truth_all(None), "risktwin/v1/*/scene/gt/*");
    let v2x = scene_v2x(&site, &src);
    assert_eq!(v2x, "risktwin/v1/track-1/scene/v2x/veh_0.a");
    assert_eq!(parse_edge_key(&v2x), None, "V2X broadcasts are no ingest stream");
    assert_eq!(scene_v2x_all(&site), "risktwin/v1/track-1/scene/v2x/*");
}

#[test]
fn edge_keys_round_trip_and_others_are_refused() {
    let (site, src) = ids();
    for stream in EdgeStream::ALL {
        let key = edge_stream(&site, &src, stream);
        assert_eq!(parse_edge_key(&key), Some(EdgeKey { site: "track-1", source: "veh_0.a", stream }));
        assert_eq!(EdgeStream::ALL[stream.index()], stream);
    }
    for bad in [
        "risktwin/v1/track-1/veh/scenario",
        "risktwin/v1/track-1/cloud/snapshot",
        "risktwin/v1/track-1/alive/state",
        "risktwin/v1/track-1/veh/state/extra",
        "risktwin/v2/track-1/veh/state",
        "risktwin/v1/track-1/state",
        "risktwin/v1//veh/state",
    ] {
        assert_eq!(parse_edge_key(bad), None, "{bad}");
    }
    assert_eq!(try_parse_edge_key("x/y"), Err(KeyError::NotEdgeStream { key: "x/y".into() }));
    assert_eq!(parse_liveliness_key(&liveliness_token(&site, &src)), Some(("track-1", "veh_0.a")));
    assert_eq!(parse_liveliness_key("risktwin/v1/track-1/veh/state"), None);
    assert_eq!(cloud_liveliness(Some(&site)), "risktwin/v1/track-1/alive/cloud");
    assert_eq!(cloud_liveliness(None), "risktwin/v1/*/alive/cloud");
    assert_eq!(parse_liveliness_key(&cloud_liveliness(Some(&site))), None, "the cloud is no edge");
    assert_eq!(cloud_to_edge(&site, &src, CloudToEdge::Ack), "risktwin/v1/track-1/veh_0.a/ack");
    assert_eq!(parse_edge_key(&cloud_to_edge(&site, &src, CloudToEdge::Ack)), None, "not an ingest stream");
}
