//! `simulate` and `risk-field`: the fields and types docs/cli.md promises, and a readable heatmap.

use crate::support::{GOOD_SPEC, SIMULATE_KEYS, keys, num, ok_json, ok_stdout, uint, write_file};
use tempfile::tempdir;

#[test]
fn simulate_json_has_the_contract_fields() {
    let dir = tempdir().unwrap();
    write_file(dir.path(), "s.json", GOOD_SPEC);
    let m = ok_json(dir.path(), &["simulate", "--spec", "s.json", "--format", "json"]);
    let mut expected = SIMULATE_KEYS.to_vec();
    expected.sort_unstable();
    assert_eq!(keys(&m), expected);
    for flag in ["collision", "offroad", "success"] {
        assert!(m[flag].is_boolean(), "{flag} is a bool: {m}");
    }
    for f in ["route_completion", "avg_speed_mps", "steering_smoothness", "longitudinal_smoothness", "min_distance_m"] {
        assert!(num(&m, f) >= 0.0, "{f} is a non-negative number: {m}");
    }
    assert!(num(&m, "route_completion") <= 1.0);
    assert!((0.0..=1.0).contains(&num(&m, "risk_score")));
    num(&m, "reward");
    assert!(uint(&m, "steps") > 0);
    // A lead braking at 6 m/s² from 30 m/s, 20 m ahead: the ego closes in, so TTC is finite;
    // braking within μ·g it stops short of contact.
    assert!(num(&m, "min_ttc_s") > 0.0);
    assert_eq!(m["collision"], false);
    assert!(num(&m, "min_distance_m") > 0.0);
    // Speed is bounded by the initial 30 m/s (the reference driver never speeds up past it here).
    assert!(num(&m, "avg_speed_mps") < 30.0);
}

#[test]
fn simulate_csv_is_a_header_and_one_row() {
    let dir = tempdir().unwrap();
    write_file(dir.path(), "s.json", GOOD_SPEC);
    let json = ok_json(dir.path(), &["simulate", "--spec", "s.json", "--format", "json"]);
    let csv = ok_stdout(dir.path(), &["simulate", "--spec", "s.json", "--format", "csv"]);
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 2, "{csv}");
    let header: Vec<&str> = lines[0].split(',').collect();
    let row: Vec<&str> = lines[1].split(',').collect();
    assert_eq!(header.len(), row.len());
    let mut sorted = header.clone();
    sorted.sort_unstable();
    assert_eq!(sorted, keys(&json), "CSV columns are the JSON fields");
    for (h, cell) in header.iter().zip(&row) {
        let v = &json[*h];
        match v {
            serde_json::Value::Bool(b) => assert_eq!(*cell, b.to_string(), "{h}"),
            // docs/cli.md: null in JSON (no time to collision) is `inf` in CSV.
            serde_json::Value::Null => assert_eq!(*cell, "inf", "{h}"),
            _ => assert_eq!(cell.parse::<f64>().ok(), v.as_f64(), "{h}"),
        }
    }
}

/// Width and height from a PNG's IHDR chunk, after checking the 8-byte signature.
fn png_size(bytes: &[u8]) -> (u32, u32) {
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "PNG signature");
    assert_eq!(&bytes[12..16], b"IHDR", "the first chunk is IHDR");
    let be = |i: usize| u32::from_be_bytes(bytes[i..i + 4].try_into().unwrap());
    (be(16), be(20))
}

#[test]
fn risk_field_json_and_png() {
    let dir = tempdir().unwrap();
    write_file(dir.path(), "s.json", GOOD_SPEC);
    let args = ["risk-field", "--spec", "s.json", "--time", "1.5", "--resolution", "0.5", "--cells", "40"];
    let f = ok_json(dir.path(), &[&args[..], &["--png", "field.png", "--format", "json"]].concat());
    let present = keys(&f);
    for key in ["cols", "rows", "resolution_m", "origin_m", "max", "mean", "argmax_m"] {
        assert!(present.contains(&key), "risk-field JSON lacks {key}: {f}");
    }
    let (cols, rows) = (uint(&f, "cols"), uint(&f, "rows"));
    assert_eq!((cols, rows), (40, 40), "--cells 40 gives a 40 × 40 grid");
    assert_eq!(num(&f, "resolution_m"), 0.5);
    let pair = |key: &str| -> [f64; 2] {
        let a = f[key].as_array().unwrap_or_else(|| panic!("{key} is an array: {f}"));
        assert_eq!(a.len(), 2, "{key} is [x, y]");
        [a[0].as_f64().unwrap(), a[1].as_f64().unwrap()]
    };
    let (origin, argmax) = (pair("origin_m"), pair("argmax_m"));
    let extent_m = 40.0 * 0.5;
    for axis in 0..2 {
        assert!(
            argmax[axis] >= origin[axis] && argmax[axis] <= origin[axis] + extent_m,
            "argmax {argmax:?} lies outside the grid from {origin:?} over {extent_m} m"
        );
    }
    let (max, mean) = (num(&f, "max"), num(&f, "mean"));
    assert!(max > 0.0 && mean > 0.0 && mean <= max, "max {max}, mean {mean}");

    let bytes = std::fs::read(dir.path().join("field.png")).expect("--png wrote the file");
    // The map (at least 4 pixels per cell), with metre axes, a title and a colour bar around it.
    let (w, h) = png_size(&bytes);
    assert!(w > 40 * 4 && h > 40 * 4 && w < 2000 && h < 2000, "{w}×{h}");
    // The whole file decodes (chunk CRCs, zlib stream) and is not a blank image.
    let mut reader = png::Decoder::new(std::io::Cursor::new(&bytes)).read_info().expect("a decodable PNG");
    let mut pixels = vec![0; reader.output_buffer_size().expect("a sane size")];
    let info = reader.next_frame(&mut pixels).expect("the image data decodes");
    let colours: std::collections::BTreeSet<&[u8]> =
        pixels[..info.buffer_size()].chunks(info.color_type.samples()).collect();
    assert!(colours.len() >= 10, "a heatmap with lanes and vehicles has many colours, got {}", colours.len());

    // Same question without --png: same numbers, and no file needed.
    let again = ok_json(dir.path(), &[&args[..], &["--format", "json"]].concat());
    assert_eq!(again, f);
}

#[test]
fn risk_field_grid_follows_cells_and_resolution() {
    let dir = tempdir().unwrap();
    write_file(dir.path(), "s.json", GOOD_SPEC);
    let f = ok_json(
        dir.path(),
        &["risk-field", "--spec", "s.json", "--resolution", "1", "--cells", "16", "--format", "json"],
    );
    assert_eq!((uint(&f, "cols"), uint(&f, "rows"), num(&f, "resolution_m")), (16, 16, 1.0));
}
