use super::*;
use crate::latency::Latency;

/// A small grid: two latencies, one kind, two seeds.
fn small() -> SweepConfig {
    SweepConfig {
        models: vec!["3gpp-urban-los".into()],
        rsu_offsets_m: vec![10.0],
        latencies: vec![
            Latency::Sidelink { t1_ms: 4.0, t2_ms: 20.0 },
            Latency::Gamma { offset_ms: 1500.0, shape: 4.0, scale_ms: 25.0 },
        ],
        bursts: vec![Bursts { share: 0.0, mean_burst: 1.0 }],
        kinds: vec!["pedestrian-crossing".into()],
        seeds: vec![1, 2],
        scenes_per_kind: 6,
        ..SweepConfig::default()
    }
}

#[test]
fn a_sweep_is_its_config_to_the_last_bit() {
    let a = run(small().grid().expect("valid"));
    let b = run(small().grid().expect("valid"));
    let bytes = |r: &SweepResult| serde_json::to_string(&r.rows).expect("rows serialise");
    assert_eq!(bytes(&a), bytes(&b));
    assert_eq!(a.rows.len(), 2 * 2, "cells × seeds");
    // Both cells drive the same scenes: the unwarned crashes are the same.
    assert_eq!(a.rows[0].crashes_unwarned, a.rows[2].crashes_unwarned);
    let crashes = |cell| a.rows.iter().filter(|r| r.cell == cell).map(|r| r.crashes_warned).sum::<u32>();
    let unwarned: u32 = a.rows.iter().filter(|r| r.cell == 0).map(|r| r.crashes_unwarned).sum();
    assert!(unwarned > 0, "critical pedestrian crossings hold crashes");
    for r in &a.rows {
        assert_eq!(r.crashes_warned + r.crashes_prevented, r.crashes_unwarned + r.crashes_induced, "{r:?}");
    }
    // Warnings in about 12 ms prevent crashes; 1.6 s late they prevent fewer.
    assert!(crashes(0) < unwarned && crashes(0) < crashes(1), "{} / {} of {unwarned}", crashes(0), crashes(1));
    // Moved on at constant velocity, the twin is within centimetres at 12 ms, and over ten
    // times further off at 1.6 s (the ego brakes, the pedestrian's vehicles stand).
    let position =
        |cell| a.rows.iter().filter(|r| r.cell == cell).filter_map(|r| r.twin_position_error_m).fold(0.0f64, f64::max);
    assert!(position(0) < 0.05 && position(1) > 10.0 * position(0), "{} m against {} m", position(0), position(1));
}

#[test]
fn the_default_grid_has_every_kind_three_seeds_and_bad_values_are_named() {
    let grid = SweepConfig::default().grid().expect("the default is valid");
    assert_eq!((grid.kinds.len(), grid.seeds.len()), (5, 3));
    let refused = |c: SweepConfig| c.grid().expect_err("refused");
    assert!(
        refused(SweepConfig { models: vec!["free-space".into()], ..small() }).contains("unknown model 'free-space'")
    );
    assert!(refused(SweepConfig { rsu_offsets_m: vec![-5.0], ..small() }).contains("RSU offset -5 m"));
    assert!(refused(SweepConfig { kinds: vec!["merge".into()], ..small() }).contains("unknown scenario kind 'merge'"));
    assert!(refused(SweepConfig { seeds: vec![], ..small() }).contains("seeds: the list is empty"));
    assert!(refused(SweepConfig { seeds: vec![1, 2, 1], ..small() }).contains("seeds: 1 is listed twice"));
    // Refused by its count alone (10^13 episodes), before a single cell is built.
    let huge = SweepConfig { rsu_offsets_m: (0..1_000_000).map(f64::from).collect(), ..SweepConfig::default() };
    let huge = SweepConfig {
        warning_rates_hz: (1..=20).map(|r| r as f64 / 2.0).collect(),
        seeds: (0..1000).collect(),
        ..huge
    };
    assert!(refused(huge).contains("at most 2000000 in one sweep"));
    let bursts = vec![Bursts { share: 1.5, mean_burst: 2.0 }];
    assert!(refused(SweepConfig { bursts, ..small() }).contains("bursts: burst loss 1.5"));
    let latencies = vec![Latency::Sidelink { t1_ms: 50.0, t2_ms: 10.0 }];
    assert!(refused(SweepConfig { latencies, ..small() }).contains("sidelink window [50, 10]"));
    assert!(refused(SweepConfig { warning_rates_hz: vec![0.0], ..small() }).contains("warning rate 0 Hz"));
    let unknown = serde_json::from_str::<SweepConfig>(r#"{"modles": []}"#).expect_err("unknown key");
    assert!(unknown.to_string().contains("unknown field `modles`"), "{unknown}");
    let extra = r#"{"latencies": [{"model": "sidelink", "t1_ms": 4, "t2_ms": 20, "t3_ms": 1}]}"#;
    assert!(serde_json::from_str::<SweepConfig>(extra).is_err(), "unknown latency field");
}
