//! `risktwin recover IN.mcap --out OUT.mcap`: every readable message of an unfinished or damaged
//! recording (channels, schemas, metadata, attachments too) rewritten as a finished MCAP file;
//! and what the other readers of a recording share: opening one, and the warning for an
//! unfinished one.

use crate::cli::RecoverArgs;
use crate::error::{CliError, CliResult};
use crate::output::{Format, print_json, print_table};
use risktwin_protos::recording::{
    MessageCursor, RecordScanner, RecordingError, UnfinishedRecording, recover as rewrite,
};
use serde::Serialize;
use std::fs::File;
use std::io::{BufReader, BufWriter};
use std::os::unix::fs::{MetadataExt, PermissionsExt};
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
    let output = args.out.display().to_string();
    refuse_same_file(&file, &args.out, &input)?;
    // OUT is written under a temporary name in its own folder (so the rename cannot cross file
    // systems) and takes OUT's name only once finished: a refused input, a failed write or a
    // kill never leaves a partial OUT, nor clobbers one that was there.
    let cannot_write = |e: std::io::Error| CliError::runtime(format!("cannot write {output}: {e}"));
    let mut temp = temp_next_to(&args.out).map_err(cannot_write)?;
    let scanner = RecordScanner::new(BufReader::with_capacity(1 << 20, file)).with_source_len(len);
    let (recovery, written) = rewrite(scanner, BufWriter::new(temp.as_file_mut())).map_err(|e| match e {
        RecordingError::NotMcap => CliError::input(format!("{input}: {e}")),
        // A read that fails (a disk error) is no damage to recover around: exit 1.
        RecordingError::Io(_) => CliError::runtime(format!("{input}: {e}")),
        other => CliError::runtime(format!("{output}: {other}")),
    })?;
    written.into_inner().map_err(|e| cannot_write(e.into_error()))?;
    if !recovery.kept_anything() {
        // Nothing to keep: no empty file is left to be taken for a recovery (`temp` is removed).
        let why = recovery.lost.as_ref().map_or("an empty recording".to_owned(), |t| {
            format!("{} at byte {} ({} bytes unreadable)", t.reason, t.at_byte, t.unreadable_bytes)
        });
        return Err(CliError::input(format!("{input}: nothing readable: {why}")));
    }
    temp.persist(&args.out).map_err(|e| cannot_write(e.error))?;
    let lost = recovery.lost.clone();
    let report = RecoverReport {
        input,
        output,
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

/// Refuses an OUT that is IN itself (the same device and inode: another name, a hard link or a
/// symbolic link to it included), which the rename would replace by what was readable of it.
fn refuse_same_file(input: &File, out: &Path, input_name: &str) -> CliResult {
    let cannot = |e: std::io::Error| CliError::input(format!("cannot read {input_name}: {e}"));
    let read = input.metadata().map_err(cannot)?;
    // An OUT that does not exist (or cannot be looked at: creating it fails later) is not IN.
    let Ok(written) = std::fs::metadata(out) else { return Ok(()) };
    if (read.dev(), read.ino()) == (written.dev(), written.ino()) {
        return Err(CliError::input(format!(
            "--out {} is the recording itself ({input_name}): recover into another file",
            out.display()
        )));
    }
    Ok(())
}

/// An empty temporary file in `out`'s folder, removed when dropped unless persisted.
pub(crate) fn temp_next_to(out: &Path) -> std::io::Result<tempfile::NamedTempFile> {
    let folder = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    tempfile::Builder::new()
        .prefix(".recover-")
        .suffix(".mcap.part")
        // What `File::create` gives (0666 less the umask), not tempfile's private 0600.
        .permissions(std::fs::Permissions::from_mode(0o666))
        .tempfile_in(folder)
}
