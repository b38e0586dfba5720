//! Re-simulation and field tests on the CriMe fixture scenarios (tests/fixtures/crime).

use super::*;
use crate::criticality::scenario_criticality;
use crate::{Scenario, parse_scenario};
use risktwin_common::world::STEP_S;

/// (file stem, ego id) of the three fixture scenarios.
const FIXTURES: [(&str, u64); 3] = [("OSC_CutIn-1_2_T-1", 3), ("BEL_Putte-8_2_T-1", 33), ("HRV_Pula-27_3_T-1", 34)];

fn fixture(name: &str) -> Scenario {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../tests/fixtures/crime/{name}.xml"));
    let text = std::fs::read_to_string(&path).expect("fixture file present");
    parse_scenario(&text).expect("fixture parses")
}

#[test]
fn replayed_ego_passes_its_recorded_states_at_the_twin_step() {
    for (name, ego) in FIXTURES {
        let s = fixture(name);
        let r = resimulate(&s, Some(ego), EgoMode::Replay, STEP_S).expect("resimulates");
        let rec = s.dynamic_obstacle(ego).expect("ego present");
        let mut checked = 0;
        for st in rec.states() {
            let t = st.time_step as f64 * s.dt_s;
            let Some(sample) = r.trace.iter().find(|x| (x.time_s - t).abs() < 1e-6) else { continue };
            let err = (sample.ego.centre - st.position).norm();
            assert!(err < 1e-6, "{name}: ego at step {} off by {err} m", st.time_step);
            checked += 1;
        }
        // dt is a multiple of the twin step in every fixture: every recorded step is visited.
        assert_eq!(checked, rec.states().count(), "{name}");
        // Between recorded steps the ego moves on the chord: never farther from the recorded
        // polyline than the distance covered in one step.
        assert!(r.trace.len() > checked, "{name}: interpolated steps in between");
    }
}

#[test]
fn replay_min_distance_equals_the_criticality_module() {
    for (name, ego) in FIXTURES {
        let s = fixture(name);
        let crit = scenario_criticality(&s, Some(ego)).expect("criticality");
        let crit_min = crit.pairs.iter().map(|p| p.min_distance_m).fold(f64::INFINITY, f64::min);
        // At the scenario's own step the twin visits exactly the recorded states.
        let at_dt = resimulate(&s, Some(ego), EgoMode::Replay, s.dt_s).expect("resimulates");
        let trace_min = at_dt.trace.iter().map(|x| x.min_distance_m).fold(f64::INFINITY, f64::min);
        assert!((trace_min - crit_min).abs() < 1e-6, "{name}: twin {trace_min} vs criticality {crit_min}");
        assert_eq!(at_dt.metrics.collision, crit_min == 0.0, "{name}");
        // The twin step sees the recorded steps and the instants between: never farther.
        let fine = resimulate(&s, Some(ego), EgoMode::Replay, STEP_S).expect("resimulates");
        let fine_min = fine.trace.iter().map(|x| x.min_distance_m).fold(f64::INFINITY, f64::min);
        assert!(fine_min <= crit_min + 1e-9 && fine_min > crit_min - 1.0, "{name}: {fine_min} vs {crit_min}");
        assert!(fine.metrics.risk_score.is_finite() && fine.metrics.risk_score >= 0.0);
    }
}

#[test]
fn reference_driver_runs_closed_loop_on_every_fixture() {
    for (name, ego) in FIXTURES {
        let s = fixture(name);
        let r = resimulate(&s, Some(ego), EgoMode::ReferenceDriver, STEP_S).expect("resimulates");
        let m = &r.metrics;
        assert!(m.steps > 0, "{name}");
        assert!(m.avg_speed_mps.is_finite() && m.risk_score.is_finite(), "{name}: {m:?}");
        // It starts where the recording starts.
        let first = s.dynamic_obstacle(ego).expect("ego").initial_state.position;
        assert!((r.trace[0].ego.centre - first).norm() < 1e-6, "{name}");
        if !m.collision {
            assert_eq!(m.steps as usize, r.trace.len() - 1, "{name}: runs to the end of the recording");
        }
    }
}

#[test]
fn field_on_the_real_map_peaks_near_traffic_and_rejects_bad_times() {
    let s = fixture("OSC_CutIn-1_2_T-1");
    let f = field_at(&s, Some(3), 2.0, 0.5, 128).expect("field");
    let (max, mean, _) = f.stats();
    assert!(max > mean && mean > 0.0, "max {max} mean {mean}");
    assert!(!f.others.is_empty());
    let layers = lanelet_layers(&f, &s.lanelets);
    assert_eq!(layers.on_map.len(), 128 * 128);
    // The ego stands on a lanelet at the grid centre, and the map has bounds to draw.
    assert!(layers.is_on_map(64 * 128 + 64) && !layers.edges.is_empty());
    assert!(layers.scale_max as f64 <= max + 1e-6 && layers.scale_max > 0.0);
    assert!(matches!(field_at(&s, Some(3), 1e4, 0.5, 64), Err(TwinError::TimeOutOfRange { .. })));
    assert!(matches!(field_at(&s, Some(999_999), 0.0, 0.5, 64), Err(TwinError::UnknownEgo { .. })));
}

/// The field of [`field_at`] (road cropped around the grid) against the same grid over the whole
/// map: cropping must not change what the grid shows.
#[test]
fn cropping_the_map_keeps_the_field_of_the_whole_map() {
    use risktwin_common::risk::{EgoKinematics, FieldObject, GridEvaluator, RiskFieldParams, RiskGrid, RoadRaster};
    for (name, ego) in FIXTURES {
        let s = fixture(name);
        let scene = TwinScene::new(&s, Some(ego)).expect("scene");
        let t = scene.ego.start_s() + 0.5 * (scene.ego.end_s() - scene.ego.start_s());
        let cropped = field_at(&s, Some(ego), t, 0.5, 160).expect("field");
        let st = scene.ego.at(t).expect("ego at t");
        let kin = EgoKinematics {
            pose: st.pose,
            velocity: st.velocity(),
            lateral_accel_mps2: 0.0,
            jerk_mps3: 0.0,
            footprint: scene.ego.footprint,
        };
        let mut objects = Vec::new();
        scene.objects_at(t, &mut objects);
        let fo: Vec<FieldObject> = objects.iter().map(|o| FieldObject { obb: o.obb, velocity: o.velocity }).collect();
        let g = &cropped.grid;
        let mut whole = RiskGrid::new(g.origin_m, g.resolution_m, g.cols, g.rows).expect("grid");
        let params = RiskFieldParams::default();
        let raster = RoadRaster::covering(&scene.road, &params, &whole).expect("raster");
        GridEvaluator::new(params).fill(&mut whole, &raster, &scene.road, &fo, &kin);
        let worst = g.cells.iter().zip(&whole.cells).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
        assert!(worst < 1e-4, "{name}: cropped field differs from the whole map's by {worst}");
    }
}

/// Cost of one field over a real map (release: `cargo test --release -p risktwin-commonroad --lib
/// field_speed -- --ignored --nocapture`) over the scenarios of data/commonroad/.
#[test]
#[ignore = "timing, prints"]
fn field_speed_on_real_maps() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/commonroad");
    let Ok(entries) = std::fs::read_dir(&dir) else { return };
    let mut files: Vec<_> =
        entries.flatten().map(|e| e.path()).filter(|p| p.extension().is_some_and(|x| x == "xml")).collect();
    files.sort();
    for path in files {
        let Ok(s) = std::fs::read_to_string(&path).map_err(|_| ()).and_then(|t| parse_scenario(&t).map_err(|_| ()))
        else {
            continue;
        };
        let Ok(scene) = TwinScene::new(&s, None) else { continue };
        let t = scene.ego.start_s();
        let start = std::time::Instant::now();
        let n = 5;
        for _ in 0..n {
            let _ = field_at(&s, None, t, 0.5, 160);
        }
        let per_field_s = start.elapsed().as_secs_f64() / n as f64;
        let name = path.file_stem().map(|x| x.to_string_lossy().into_owned()).unwrap_or_default();
        println!("{name}: {} lanelets, {:.1} ms per 160x160 field", s.lanelets.len(), 1e3 * per_field_s);
    }
}
