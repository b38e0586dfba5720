use super::*;
use risktwin_v2x::latency::Latency;
use risktwin_v2x::sweep::Bursts;

#[test]
fn a_sweep_folder_is_byte_identical_for_the_same_config() {
    let config = SweepConfig {
        models: vec!["3gpp-urban-los".into(), "3gpp-urban-nlos".into()],
        rsu_offsets_m: vec![10.0],
        latencies: vec![
            Latency::Sidelink { t1_ms: 4.0, t2_ms: 20.0 },
            Latency::Gamma { offset_ms: 1500.0, shape: 4.0, scale_ms: 25.0 },
        ],
        bursts: vec![Bursts { share: 0.0, mean_burst: 1.0 }],
        kinds: vec!["pedestrian-crossing".into(), "cut-in".into()],
        seeds: vec![1, 2, 3],
        scenes_per_kind: 2,
        ..SweepConfig::default()
    };
    let (a, b) = (tempfile::tempdir().expect("temp"), tempfile::tempdir().expect("temp"));
    run(&config, config.grid().expect("valid"), a.path()).expect("runs");
    run(&config, config.grid().expect("valid"), b.path()).expect("runs");
    let mut names: Vec<_> =
        std::fs::read_dir(a.path()).expect("folder").map(|e| e.expect("entry").file_name()).collect();
    names.sort();
    assert_eq!(names.len(), 9, "{names:?}");
    for name in names {
        let bytes = |dir: &Path| std::fs::read(dir.join(&name)).expect("file");
        assert!(bytes(a.path()) == bytes(b.path()), "{name:?} differs");
    }
    let report = std::fs::read_to_string(a.path().join(REPORT_FILE)).expect("report");
    assert!(report.contains("| pedestrian-crossing | 3gpp-urban-los | 10 | none | 10 |"), "{report}");
    let rows = std::fs::read_to_string(a.path().join(ROWS_FILE)).expect("rows");
    assert_eq!(rows.lines().count(), 1 + 4 * 2 * 3, "header + cells × kinds × seeds");
}
