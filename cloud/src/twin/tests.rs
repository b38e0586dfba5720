//! The twin fed by a real ingest worker, and risk assessed on it.

use super::risk::{RiskAssessor, RiskConfig};
use super::*;
use crate::ingest::IngestWorker;
use crate::test_fixtures::state;
use risktwin_align::IngestConfig;
use risktwin_common::road::Road;
use risktwin_protos::encode;
use std::io::Cursor;

/// `veh-a` at 20 m/s and `veh-b` 12 m ahead in the same lane at 10 m/s, 50 Hz for 1 s; the
/// last twin state is returned.
fn twin_of_two() -> Twin {
    let mut worker: IngestWorker<Cursor<Vec<u8>>> = IngestWorker::new(IngestConfig::default(), None);
    let mut twin = Twin::new();
    for seq in 0..50u64 {
        let t = 1_000_000_000 + seq as i64 * 20_000_000;
        let a = state("veh-a", seq, t);
        let mut b = state("veh-b", seq, t);
        b.pose.x_m += 12.0;
        b.velocity.x = 10.0;
        b.speed_mps = 10.0;
        for (source, sample) in [("veh-a", a), ("veh-b", b)] {
            let topic = format!("risktwin/v1/site/{source}/state");
            let mut snapshots = Vec::new();
            worker
                .handle(source, EdgeStream::State, &topic, &encode(&sample), t + 2_000_000, |s| {
                    snapshots.push(s.clone())
                })
                .expect("no recorder");
            for i in 0..2 {
                if let Some(name) = worker.source_name(i) {
                    twin.name_source(i, name, "site");
                }
            }
            for s in &snapshots {
                twin.update(s);
            }
        }
    }
    twin
}

#[test]
fn snapshots_make_vehicles_of_their_site() {
    let twin = twin_of_two();
    assert!(twin.ticks() > 10, "ticks: {}", twin.ticks());
    let site = twin.site("site").expect("the site is known");
    let names: Vec<&str> = site.vehicles.iter().map(|v| &*v.source).collect();
    assert_eq!(names, ["veh-a", "veh-b"]);
    let (a, b) = (&site.vehicles[0].kinematics, &site.vehicles[1].kinematics);
    // Interpolated at the same tick: b stays 12 m ahead of a.
    assert!((b.pose.x_m - a.pose.x_m - 12.0).abs() < 1e-6, "{} vs {}", a.pose.x_m, b.pose.x_m);
    assert_eq!(site.vehicles[0].jerk_mps3, 0.0, "constant acceleration, no jerk");
    assert!(twin.tick_ns().is_some_and(|t| t > 1_000_000_000));
}

#[test]
fn risk_of_an_ego_closing_in_on_a_slower_car() {
    let twin = twin_of_two();
    let site = twin.site("site").expect("the site is known");
    let road = Road::straight(2, 3.5, 2000.0, 30.0);
    let mut assessor = RiskAssessor::new(road, RiskConfig::default()).expect("valid config");
    let tick = twin.tick_ns().expect("a tick");
    let out = assessor.assess(site, 0, tick).expect("vehicle 0 exists");
    let grid = &out.field.grid;
    assert_eq!((grid.cols, grid.rows), (160, 160));
    let max = grid.cells.iter().copied().fold(f32::MIN, f32::max);
    assert!(max > 0.0 && max.is_finite(), "max {max}");
    // The slower car ahead raises the field; the same road 12 m behind the ego stays low.
    let a = site.vehicles[0].kinematics.pose.position();
    let ahead = grid.value_at(site.vehicles[1].kinematics.pose.position()).expect("inside the grid");
    let behind = grid.value_at(a - (site.vehicles[1].kinematics.pose.position() - a)).expect("inside the grid");
    assert!(ahead > behind + 0.1, "ahead {ahead}, behind {behind}");
    // Gap 12 − 4.5 = 7.5 m closing at 10 m/s: TTC 0.75 s.
    let ttc = out.report.min_ttc_s.expect("closing in");
    assert!((ttc - 0.75).abs() < 0.05, "ttc {ttc}");
    assert!((out.report.min_distance_m - 7.5).abs() < 0.05, "{}", out.report.min_distance_m);
    assert!(out.report.terms.ttc > 0.5 && out.report.terms.score > 0.0, "{:?}", out.report.terms);
    assert_eq!(out.report.ego_source, "veh-a");
    assert_eq!(out.report.header.capture_time_ns, tick);
    // The car ahead sees nothing closing in from the front: no TTC, same distance.
    let back = assessor.assess(site, 1, tick).expect("vehicle 1 exists");
    assert!((back.report.min_distance_m - 7.5).abs() < 0.05);
    assert!(assessor.assess(site, 2, tick).is_none());
}

#[test]
fn a_held_state_is_moved_on_to_the_tick() {
    // 20 Hz states received 2 ms after capture, 10 ms before each tick's successor would
    // bracket it in time: the next sample comes 40 ms after the tick, beyond the 30 ms of
    // lateness, so every tick holds the sample from 10 ms before it.
    let mut worker: IngestWorker<Cursor<Vec<u8>>> = IngestWorker::new(IngestConfig::default(), None);
    let mut twin = Twin::new();
    let mut held = 0;
    for seq in 0..40u64 {
        let capture_ns = 1_038_000_000 + seq as i64 * 50_000_000;
        let sample = state("veh-a", seq, capture_ns);
        let mut snapshots = Vec::new();
        let topic = "risktwin/v1/site/veh-a/state";
        worker
            .handle("veh-a", EdgeStream::State, topic, &encode(&sample), capture_ns + 2_000_000, |s| {
                snapshots.push(s.clone())
            })
            .expect("no recorder");
        if let Some(name) = worker.source_name(0) {
            twin.name_source(0, name, "site");
        }
        for s in &snapshots {
            let aligned = s.get(SourceIndex(0), aligner_index(EdgeStream::State)).expect("the source");
            held += usize::from(aligned.status == ValueStatus::AsOf);
            twin.update(s);
            let Some(v) = twin.site("site").and_then(|site| site.vehicles.first()) else { continue };
            // The tick maps back to capture time tick − 2 ms (the minimum delay), where the
            // vehicle was at 20 m/s · t.
            let expected_m = 20.0 * (s.tick_ns - 2_000_000) as f64 * 1e-9;
            assert!((v.kinematics.pose.x_m - expected_m).abs() < 1e-6, "{} vs {expected_m}", v.kinematics.pose.x_m);
        }
    }
    assert!(held > 20, "the ticks held their state ({held})");
}
