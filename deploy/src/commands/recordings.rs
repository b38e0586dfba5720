//! `risktwin recordings list|query|export DIR`: a `cloud --record-dir` folder read back through
//! its catalogue; the span reader that `edge replay` shares; and the cloud's `--record-dir`
//! flags turned into a rotation (docs/recordings.md).

use super::recover::{temp_next_to, warn_unfinished};
use crate::cli::{RecordDirArgs, RecordingsCommand, RecordingsExportArgs, RecordingsQueryArgs, SpanArgs};
use crate::error::{CliError, CliResult};
use crate::output::{Format, print_json, print_table};
use risktwin_protos::recording::{RecordingError, SpanCursor, export};
use risktwin_store::recordings::{Catalogue, CatalogueError, Provenance, RotationConfig, SegmentRow, StreamRow};
use risktwin_transport::SourceId;
use risktwin_transport::keyexpr::parse_edge_key;
use serde::Serialize;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::time::Duration;

const MIB: f64 = 1024.0 * 1024.0;

impl From<CatalogueError> for CliError {
    /// A folder or catalogue at fault is bad input (exit 2); a lock or a full disk exit 1.
    fn from(e: CatalogueError) -> Self {
        if e.blames_the_input() { CliError::input(e) } else { CliError::runtime(e) }
    }
}

/// The cloud's `--record-dir` and its bounds, checked; `None` without `--record-dir`.
pub fn rotation(args: &RecordDirArgs) -> CliResult<Option<RotationConfig>> {
    let Some(dir) = args.record_dir.clone() else { return Ok(None) };
    let positive = |flag: &str, v: f64, min: f64, max: f64| {
        if v.is_finite() && (min..=max).contains(&v) {
            Ok(v)
        } else {
            Err(CliError::input(format!("{flag} {v} must lie in [{min}, {max}]")))
        }
    };
    let segment_mb = positive("--segment-mb", args.segment_mb.unwrap_or(256.0), 0.001, 1_048_576.0)?;
    let segment_s = positive("--segment-s", args.segment_s.unwrap_or(600.0), 0.25, 604_800.0)?;
    let retain_s = args.retain_s.map(|s| positive("--retain-s", s, 1.0, 1e10)).transpose()?;
    let retain_mb = args.retain_mb.map(|mb| positive("--retain-mb", mb, 0.001, 1e12)).transpose()?;
    // A folder that cannot hold a catalogue, or a catalogue that is not one, fails now: before
    // the cloud joins the network, and as bad input.
    drop(Catalogue::create(&dir)?);
    let config = serde_json::json!({
        "argv": std::env::args().collect::<Vec<_>>(),
        "segment_mb": segment_mb,
        "segment_s": segment_s,
        "retain_s": retain_s,
        "retain_mb": retain_mb,
    });
    Ok(Some(RotationConfig {
        dir,
        segment_bytes: (segment_mb * MIB) as u64,
        segment_age: Duration::from_secs_f64(segment_s),
        retain_age: retain_s.map(Duration::from_secs_f64),
        retain_bytes: retain_mb.map(|mb| (mb * MIB) as u64),
        provenance: Provenance {
            risktwin_version: env!("CARGO_PKG_VERSION").to_owned(),
            git_commit: env!("RISKTWIN_COMMIT").to_owned(),
            config: config.to_string(),
        },
    }))
}

pub fn recordings(command: RecordingsCommand) -> CliResult {
    match command {
        RecordingsCommand::List(a) => list(&a.dir, a.format),
        RecordingsCommand::Query(a) => query(a),
        RecordingsCommand::Export(a) => export_span(a),
    }
}

/// `finished` or `unfinished` (a recorder killed, or still writing it).
fn status(row: &SegmentRow) -> &'static str {
    if row.closed { "finished" } else { "unfinished" }
}

#[derive(Serialize)]
struct Listed<'a> {
    #[serde(flatten)]
    row: &'a SegmentRow,
    status: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    streams: Option<Vec<StreamRow>>,
}

fn segment_table(segments: &[Listed<'_>]) -> CliResult {
    let cell = |v: Option<u64>| v.map_or_else(|| "-".to_owned(), |v| v.to_string());
    let rows: Vec<Vec<String>> = segments
        .iter()
        .map(|s| {
            vec![
                s.row.seq.to_string(),
                s.row.file.clone(),
                s.status.to_owned(),
                cell(s.row.start_log_ns),
                cell(s.row.end_log_ns),
                cell(s.row.messages),
                cell(s.row.bytes),
            ]
        })
        .collect();
    print_table(&["seq", "file", "status", "start_log_ns", "end_log_ns", "messages", "bytes"], &rows)
}

fn list(dir: &Path, format: Format) -> CliResult {
    let catalogue = Catalogue::open(dir)?;
    let rows = catalogue.all_segments()?;
    let segments: Vec<Listed<'_>> = rows.iter().map(|row| Listed { row, status: status(row), streams: None }).collect();
    match format {
        Format::Json => print_json(&serde_json::json!({
            "dir": dir.display().to_string(),
            "recordings": catalogue.recordings()?,
            "segments": segments,
        })),
        Format::Table | Format::Csv => segment_table(&segments),
    }
}

/// The span's log-time range and source, checked.
fn checked(span: &SpanArgs) -> CliResult<(std::ops::Range<u64>, Option<String>)> {
    let (from, to) = (span.from.unwrap_or(0), span.to.unwrap_or(u64::MAX));
    if from >= to {
        return Err(CliError::input(format!("--from {from} must be less than --to {to} (the span is [from, to))")));
    }
    if let Some(source) = &span.source {
        SourceId::new(source.clone()).map_err(|e| CliError::input(format!("--source: {e}")))?;
    }
    Ok((from..to, span.source.clone()))
}

fn query(args: RecordingsQueryArgs) -> CliResult {
    let (range, source) = checked(&args.span)?;
    let catalogue = Catalogue::open(&args.dir)?;
    let rows = catalogue.segments(source.as_deref(), range.clone())?;
    let mut segments = Vec::new();
    let mut messages = 0;
    for row in &rows {
        let streams: Vec<StreamRow> =
            catalogue.streams(row.seq)?.into_iter().filter(|s| source.is_none() || s.source == source).collect();
        messages += streams.iter().map(|s| s.messages).sum::<u64>();
        segments.push(Listed { row, status: status(row), streams: Some(streams) });
    }
    match args.format {
        Format::Json => print_json(&serde_json::json!({
            "dir": args.dir.display().to_string(),
            "source": source,
            "from_ns": range.start,
            "to_ns": range.end,
            "messages": messages,
            "segments": segments,
        })),
        Format::Table | Format::Csv => segment_table(&segments),
    }
}

/// The messages of `span` in `path` (a recording, or a `--record-dir` folder's segments that
/// may hold them, in order) and how many files that is.
pub(crate) fn span_cursor(path: &Path, span: &SpanArgs) -> CliResult<(SpanCursor, usize)> {
    let (range, source) = checked(span)?;
    let files: Vec<PathBuf> = if path.is_dir() {
        let rows = Catalogue::open(path)?.segments(source.as_deref(), range.clone())?;
        rows.iter().map(|r| path.join(&r.file)).collect()
    } else {
        // A lone file: refused now if it cannot be read, as every reader of one does.
        std::fs::File::open(path).map_err(|e| CliError::input(format!("cannot read {}: {e}", path.display())))?;
        vec![path.to_path_buf()]
    };
    let keep: risktwin_protos::recording::TopicFilter = match source {
        Some(s) => Box::new(move |topic| parse_edge_key(topic).is_some_and(|k| k.source == s)),
        None => Box::new(|_| true),
    };
    let count = files.len();
    Ok((SpanCursor::new(files, range, keep), count))
}

/// What a span reader says about each unfinished file it read.
pub(crate) fn warn_unfinished_files(cursor: &SpanCursor) {
    for (path, unfinished) in cursor.unfinished() {
        warn_unfinished(path, unfinished);
    }
}

#[derive(Serialize)]
struct ExportReport {
    dir: String,
    out: String,
    segments_read: usize,
    unfinished_segments: usize,
    messages: u64,
    first_log_time_ns: Option<u64>,
    last_log_time_ns: Option<u64>,
}

fn export_span(args: RecordingsExportArgs) -> CliResult {
    if !args.dir.is_dir() {
        return Err(CatalogueError::NotAFolder { dir: args.dir.clone() }.into());
    }
    let (mut cursor, segments_read) = span_cursor(&args.dir, &args.span)?;
    let output = args.out.display().to_string();
    let cannot_write = |e: std::io::Error| CliError::runtime(format!("cannot write {output}: {e}"));
    // Written under a temporary name beside OUT, renamed once finished (as `recover` does).
    let mut temp = temp_next_to(&args.out).map_err(cannot_write)?;
    let (written, exported) = export(&mut cursor, BufWriter::new(temp.as_file_mut())).map_err(|e| match e {
        // A segment that cannot be read is the folder's fault; a failing write is the run's.
        RecordingError::Corrupt { .. } => CliError::input(e),
        other => CliError::runtime(format!("{output}: {other}")),
    })?;
    written.into_inner().map_err(|e| cannot_write(e.into_error()))?;
    temp.persist(&args.out).map_err(|e| cannot_write(e.error))?;
    warn_unfinished_files(&cursor);
    let report = ExportReport {
        dir: args.dir.display().to_string(),
        out: output,
        segments_read,
        unfinished_segments: cursor.unfinished().len(),
        messages: exported.messages,
        first_log_time_ns: exported.log_time_ns.map(|t| t.0),
        last_log_time_ns: exported.log_time_ns.map(|t| t.1),
    };
    match args.format {
        Format::Json => print_json(&report),
        Format::Table | Format::Csv => {
            let cell = |v: Option<u64>| v.map_or_else(|| "-".to_owned(), |v| v.to_string());
            print_table(
                &["exported", "value"],
                &[
                    vec!["segments_read".into(), report.segments_read.to_string()],
                    vec!["unfinished_segments".into(), report.unfinished_segments.to_string()],
                    vec!["messages".into(), report.messages.to_string()],
                    vec!["first_log_time_ns".into(), cell(report.first_log_time_ns)],
                    vec!["last_log_time_ns".into(), cell(report.last_log_time_ns)],
                ],
            )
        }
    }
}
