//! `risktwin recover IN.mcap --out OUT.mcap`: every readable message of an unfinished or damaged
//! recording (channels, schemas, metadata, attachments too) rewritten as a finished MCAP file;
//! and what the other readers of a recording share: opening one, and the warning for an
//! unfinished one.

use crate::cli::RecoverArgs;
use crate::error::{CliError, CliResult};
use crate::output::{Format, print_json, print_table};
use risktwin_protos::recording::{MessageCursor, RecordScanner, UnfinishedRecording, recover as rewrite};
use serde::Serialize;
use std::fs::File;
use std::io::BufReader;
use std::path::Path;

/// A recording opened for streaming, its length told to the reader (so that a length field past
/// the end of the file is named as such).
pub fn open_recording(path: &Path, buffer_bytes: usize) -> CliResult<MessageCursor<BufReader<File>>> {
    let (file, len) = open(path)?;
    Ok(MessageCursor::new(BufReader::with_capacity(buffer_bytes, file)).with_source_len(len))
}

fn open(path: &Path) -> CliResult<(File, u64)> {
    let cannot = |e: std::io::Error| CliError::input(format!("cannot read {}: {e}", path.display()));
    let file = File::open(path).map_err(cannot)?;
    let len = file.metadata().map_err(cannot)?.len();
    Ok((file, len))
}

/// What a reader of an unfinished recording says on stderr.
pub fn warn_unfinished(path: &Path, unfinished: &UnfinishedRecording) {
    eprintln!("warning: {}: {unfinished}", path.display());
}

/// The JSON document.
#[derive(Serialize)]
struct RecoverReport {
    input: String,
    output: String,
    /// False when the input was a finished file read to its end.
    unfinished: bool,
    messages: u64,
    schemas: u64,
    channels: u64,
    metadata: u64,
    attachments: u64,
    orphan_messages: u64,
    first_log_time_ns: Option<u64>,
    last_log_time_ns: Option<u64>,
    /// Where the unreadable part starts, how long it is and why (absent for a finished file).
    lost_at_byte: Option<u64>,
    lost_bytes: Option<u64>,
    lost_reason: Option<String>,
}

pub fn recover(args: RecoverArgs) -> CliResult {
    let (file, len) = open(&args.recording)?;
    let input = args.recording.display().to_string();
    let scanner = RecordScanner::new(BufReader::with_capacity(1 << 20, file)).with_source_len(len);
    let out =
        File::create(&args.out).map_err(|e| CliError::input(format!("cannot write {}: {e}", args.out.display())))?;
    let (recovery, _) = rewrite(scanner, std::io::BufWriter::new(out)).map_err(|e| match e {
        risktwin_protos::recording::RecordingError::NotMcap => CliError::input(format!("{input}: {e}")),
        other => CliError::runtime(format!("{}: {other}", args.out.display())),
    })?;
    if !recovery.kept_anything() {
        // Nothing to keep: no empty file is left behind to be taken for a recovery.
        let _ = std::fs::remove_file(&args.out);
        let why = recovery.lost.as_ref().map_or("an empty recording".to_owned(), |t| {
            format!("{} at byte {} ({} bytes unreadable)", t.reason, t.at_byte, t.unreadable_bytes)
        });
        return Err(CliError::input(format!("{input}: nothing readable: {why}")));
    }
    let lost = recovery.lost.clone();
    let report = RecoverReport {
        input,
        output: args.out.display().to_string(),
        unfinished: lost.is_some(),
        messages: recovery.messages,
        schemas: recovery.schemas,
        channels: recovery.channels,
        metadata: recovery.metadata,
        attachments: recovery.attachments,
        orphan_messages: recovery.orphan_messages,
        first_log_time_ns: recovery.log_time_ns.map(|t| t.0),
        last_log_time_ns: recovery.log_time_ns.map(|t| t.1),
        lost_at_byte: lost.as_ref().map(|t| t.at_byte),
        lost_bytes: lost.as_ref().map(|t| t.unreadable_bytes),
        lost_reason: lost.map(|t| t.reason),
    };
    match args.format {
        Format::Json => print_json(&report),
        Format::Table | Format::Csv => {
            let cell = |v: Option<u64>| v.map_or_else(|| "-".to_owned(), |v| v.to_string());
            let rows = vec![
                vec!["messages".into(), report.messages.to_string()],
                vec!["schemas".into(), report.schemas.to_string()],
                vec!["channels".into(), report.channels.to_string()],
                vec!["metadata".into(), report.metadata.to_string()],
                vec!["attachments".into(), report.attachments.to_string()],
                vec!["orphan_messages".into(), report.orphan_messages.to_string()],
                vec!["first_log_time_ns".into(), cell(report.first_log_time_ns)],
                vec!["last_log_time_ns".into(), cell(report.last_log_time_ns)],
                vec!["lost_at_byte".into(), cell(report.lost_at_byte)],
                vec!["lost_bytes".into(), cell(report.lost_bytes)],
                vec!["lost_reason".into(), report.lost_reason.clone().unwrap_or_else(|| "-".into())],
            ];
            print_table(&["kept", "value"], &rows)
        }
    }
}
