//! The criticality report as `risktwin criticality` prints it and the cloud's `criticality` role
//! writes it: the CSV of docs/cli.md, or the JSON document with the pair summaries. One writer, so
//! the offline and the fleet outputs can be compared byte for byte.

use risktwin_commonroad::criticality::ScenarioCriticality;
use serde::Serialize;
use std::io::Write;
use std::path::Path;

/// The CSV header of docs/cli.md, exactly.
pub const CSV_HEADER: &str = "time_step,other_id,hw,thw,ttc,a_long_req";

/// The two file formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReportFormat {
    /// One line per (time step, other): [`CSV_HEADER`].
    Csv,
    /// The scenario id, the cells and the pair summaries (PET, minimum distance), pretty-printed.
    Json,
}

impl ReportFormat {
    /// The format a file name asks for: `.csv` or `.json`; `None` for anything else.
    pub fn from_path(path: &Path) -> Option<Self> {
        match path.extension()?.to_str()? {
            "csv" => Some(ReportFormat::Csv),
            "json" => Some(ReportFormat::Json),
            _ => None,
        }
    }
}

/// The JSON document: where the numbers come from, then the cells and the pair summaries.
#[derive(Serialize)]
struct Report<'a> {
    scenario: &'a str,
    #[serde(flatten)]
    measures: &'a ScenarioCriticality,
}

/// A float for CSV cells: `inf`, `-inf`, `nan` spelled out, otherwise shortest round-trip form.
pub fn csv_float(x: f64) -> String {
    if x.is_nan() {
        "nan".into()
    } else if x.is_infinite() {
        if x > 0.0 { "inf".into() } else { "-inf".into() }
    } else {
        format!("{x}")
    }
}

/// Writes the measures of `scenario` in `format` (a trailing newline either way).
pub fn write_report(
    mut out: impl Write,
    format: ReportFormat,
    scenario: &str,
    m: &ScenarioCriticality,
) -> std::io::Result<()> {
    match format {
        ReportFormat::Csv => {
            writeln!(out, "{CSV_HEADER}")?;
            for c in &m.cells {
                writeln!(
                    out,
                    "{},{},{},{},{},{}",
                    c.time_step,
                    c.other_id,
                    csv_float(c.hw_m),
                    csv_float(c.thw_s),
                    csv_float(c.ttc_s),
                    csv_float(c.a_long_req_mps2)
                )?;
            }
        }
        ReportFormat::Json => {
            serde_json::to_writer_pretty(&mut out, &Report { scenario, measures: m })?;
            writeln!(out)?;
        }
    }
    out.flush()
}
