//! `risktwin v2x channel`: the TR 37.885 sidelink channel by distance, as docs/cli.md gives it;
//! `risktwin v2x sweep`: a small grid end to end, and its config refused where it is wrong.

use crate::support::{assert_input_error, ok_json, ok_stdout, write_file};

/// Φ(z) independently of the implementation under test: Zelen and Severo's approximation
/// (Abramowitz and Stegun 26.2.17), |error| < 7.5e-8.
fn normal_cdf(z: f64) -> f64 {
    let t = 1.0 / (1.0 + 0.231_641_9 * z.abs());
    let poly =
        t * (0.319_381_530 + t * (-0.356_563_782 + t * (1.781_477_937 + t * (-1.821_255_978 + t * 1.330_274_429))));
    let tail = (-0.5 * z * z).exp() / (2.0 * std::f64::consts::PI).sqrt() * poly;
    if z >= 0.0 { 1.0 - tail } else { tail }
}

#[test]
fn the_channel_prints_table_6_2_1_1_and_a_pdr_that_falls_with_distance() {
    let dir = tempfile::tempdir().expect("a temp dir");
    let lg = 5.9f64.log10();
    // (model, a, b, c, σ): a + b·log10 d + c·log10 f_c.
    let models = [
        ("3gpp-highway-los", 32.4, 20.0, 20.0, 3.0),
        ("3gpp-urban-los", 38.77, 16.7, 18.2, 3.0),
        ("3gpp-urban-nlos", 36.85, 30.0, 18.9, 4.0),
    ];
    for (model, a, b, c, sigma) in models {
        let args = ["v2x", "channel", "--model", model, "--distance-m", "5,50,200,800,3000", "--format", "json"];
        let out = ok_json(dir.path(), &args);
        assert_eq!(out["model"], model);
        assert_eq!(out["parameters"]["carrier_ghz"], 5.9, "{out}");
        // −174 dBm/Hz over the packet's 13 resource blocks (2.34 MHz), 9 dB noise figure.
        let noise = out["noise_dbm"].as_f64().expect("noise_dbm");
        assert!((noise - (-174.0 + 10.0 * 2.34e6f64.log10() + 9.0)).abs() < 1e-9, "{out}");
        let points = out["points"].as_array().expect("points");
        let mut last_pdr = 1.0;
        for p in points {
            let d = p["distance_m"].as_f64().expect("distance_m");
            let expected = a + b * d.log10() + c * lg;
            let got = p["path_loss_db"].as_f64().expect("path_loss_db");
            assert!((got - expected).abs() < 1e-9, "{model} at {d} m: {got} against {expected}");
            assert_eq!(p["shadowing_sigma_db"], sigma, "{p}");
            let snr = p["snr_db"].as_f64().expect("snr_db");
            assert!((snr - (23.0 + 6.0 - noise - got)).abs() < 1e-9, "{p}");
            let pdr = p["pdr"].as_f64().expect("pdr");
            assert!((pdr - normal_cdf((snr - 2.99) / sigma)).abs() < 1e-7, "Φ((snr − threshold)/σ): {p}");
            assert!((0.0..=1.0).contains(&pdr) && pdr <= last_pdr, "{model}: {points:?}");
            last_pdr = pdr;
        }
        assert!(points[0]["pdr"].as_f64().expect("pdr") > 0.999, "{model}: close by, every packet");
    }
    // A higher threshold loses packets sooner.
    let pdr_at = |threshold: &str| {
        let args = ["v2x", "channel", "--model", "3gpp-urban-nlos", "--distance-m", "200", "--format", "json"];
        let out = ok_json(dir.path(), &[&args[..], &["--sinr-threshold-db", threshold]].concat());
        out["points"][0]["pdr"].as_f64().expect("pdr")
    };
    assert!(pdr_at("10") < pdr_at("0"));
}

#[test]
fn bad_channel_parameters_are_refused_with_exit_2() {
    let dir = tempfile::tempdir().expect("a temp dir");
    let cases: [(&[&str], &str); 9] = [
        (&["--model", "3gpp-rural", "--distance-m", "10"], "--model \"3gpp-rural\""),
        (&["--model", "3gpp-urban-los", "--distance-m", "10,-5"], "--distance-m -5"),
        (&["--model", "3gpp-urban-los", "--distance-m", "ten"], "ten"),
        (&["--model", "3gpp-urban-los", "--distance-m", "10", "--carrier-ghz", "0"], "carrier 0 GHz"),
        (&["--model", "3gpp-urban-los", "--distance-m", "10", "--bandwidth-mhz", "-1"], "bandwidth"),
        (&["--model", "3gpp-urban-los", "--distance-m", "10", "--noise-figure-db", "-2"], "noise figure"),
        (&["--model", "3gpp-urban-los", "--distance-m", "nan"], "--distance-m NaN"),
        (&["--model", "3gpp-urban-los", "--distance-m", "10", "--carrier-ghz", "inf"], "carrier inf GHz"),
        (&["--model", "3gpp-urban-los", "--distance-m", "10", "--sinr-threshold-db", "nan"], "sinr_threshold_db"),
    ];
    for (args, needle) in cases {
        assert_input_error(dir.path(), &[&["v2x", "channel"][..], args].concat(), needle);
    }
}

#[test]
fn a_small_sweep_writes_its_report_and_a_wrong_config_is_refused_by_name() {
    let dir = tempfile::tempdir().expect("a temp dir");
    let small = r#"{"models": ["3gpp-urban-nlos"], "rsu_offsets_m": [10, 400],
        "latencies": [{"model": "sidelink", "t1_ms": 4, "t2_ms": 20}],
        "bursts": [{"share": 0, "mean_burst": 1}], "kinds": ["pedestrian-crossing"],
        "seeds": [1, 2, 3], "scenes_per_kind": 2}"#;
    let config = write_file(dir.path(), "small.json", small);
    let out = dir.path().join("sweep");
    let args = ["v2x", "sweep", "--config", config.to_str().expect("utf-8"), "--out", out.to_str().expect("utf-8")];
    let stdout = ok_stdout(dir.path(), &args);
    assert!(stdout.contains("12 episodes with V2X"), "2 cells × 3 seeds × 2 scenes: {stdout}");
    let report = std::fs::read_to_string(out.join("report.md")).expect("report.md");
    assert!(report.contains("## When warnings stop preventing crashes"), "{report}");
    for figure in
        ["pdr_vs_distance.png", "latency_cdf.png", "age_of_information.png", "twin_staleness.png", "collisions.png"]
    {
        assert!(out.join(figure).is_file() && report.contains(figure), "{figure}");
    }
    let bad = [
        (r#"{"models": ["free-space"]}"#, "unknown model 'free-space'"),
        (r#"{"rsu_offsets_m": [-10]}"#, "RSU offset -10 m"),
        (r#"{"bursts": [{"share": 1.5, "mean_burst": 3}]}"#, "burst loss 1.5"),
        (r#"{"latencies": [{"model": "sidelink", "t1_ms": 50, "t2_ms": 10}]}"#, "sidelink window [50, 10]"),
        (r#"{"seeds": []}"#, "seeds: the list is empty"),
        (r#"{"scenes": 3}"#, "unknown field `scenes`"),
        ("not json", "config"),
    ];
    for (text, needle) in bad {
        let path = write_file(dir.path(), "bad.json", text);
        let args = ["v2x", "sweep", "--config", path.to_str().expect("utf-8"), "--out", out.to_str().expect("utf-8")];
        assert_input_error(dir.path(), &args, needle);
    }
    assert_input_error(
        dir.path(),
        &["v2x", "sweep", "--config", "/nonexistent.json", "--out", "x"],
        "cannot read config",
    );
}
