//! The grammar of `risktwin recordings …`: a `cloud --record-dir` folder read back
//! (docs/recordings.md).

use crate::output::Format;
use clap::{Args, Subcommand};
use std::path::PathBuf;

#[derive(Debug, Subcommand)]
pub enum RecordingsCommand {
    /// Every recording and segment of a folder, from its catalogue.
    List(RecordingsListArgs),
    /// The segments (and their counts per topic) that may hold messages of a span.
    Query(RecordingsQueryArgs),
    /// The messages of a span, across segments, as one finished MCAP file.
    Export(RecordingsExportArgs),
}

#[derive(Debug, Args)]
pub struct RecordingsListArgs {
    /// A `risktwin cloud --record-dir` folder.
    pub dir: PathBuf,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

/// A span of a recording: log times in [from, to), optionally one source's edge streams.
#[derive(Debug, Args, Clone, Default)]
pub struct SpanArgs {
    /// Only this edge source's streams (its id, as in the keys).
    #[arg(long)]
    pub source: Option<String>,
    /// From this log time on, ns since the Unix epoch (default: the start).
    #[arg(long, value_name = "NS")]
    pub from: Option<u64>,
    /// Up to (not including) this log time, ns since the Unix epoch (default: the end).
    #[arg(long, value_name = "NS")]
    pub to: Option<u64>,
}

#[derive(Debug, Args)]
pub struct RecordingsQueryArgs {
    pub dir: PathBuf,
    #[command(flatten)]
    pub span: SpanArgs,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

#[derive(Debug, Args)]
pub struct RecordingsExportArgs {
    pub dir: PathBuf,
    #[command(flatten)]
    pub span: SpanArgs,
    /// The finished MCAP file to write.
    #[arg(long, value_name = "FILE.mcap")]
    pub out: PathBuf,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}
