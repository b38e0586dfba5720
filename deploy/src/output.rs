//! Output formats shared by every subcommand: a table for people, one JSON document, or CSV.
//!
//! JSON and CSV follow docs/cli.md: infinities and NaN are `null` in JSON, `inf`/`nan` in CSV.

use crate::error::{CliError, CliResult};
use serde::Serialize;
use std::io::Write;

/// `--format`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Default)]
pub enum Format {
    #[default]
    Table,
    Json,
    Csv,
}

/// Writes `value` as one pretty JSON document on stdout. serde_json already writes non-finite
/// floats as `null`, which is the contract.
pub fn print_json<T: Serialize>(value: &T) -> CliResult {
    let text = serde_json::to_string_pretty(value).map_err(CliError::runtime)?;
    let mut out = std::io::stdout().lock();
    writeln!(out, "{text}").map_err(CliError::runtime)
}

/// CSV cells spell out `inf`, `-inf` and `nan` (shared with the cloud's criticality report).
pub use risktwin_cloud::criticality::report::csv_float;

/// Prints a left-aligned text table.
pub fn print_table(header: &[&str], rows: &[Vec<String>]) -> CliResult {
    let mut widths: Vec<usize> = header.iter().map(|h| h.len()).collect();
    for row in rows {
        for (w, cell) in widths.iter_mut().zip(row) {
            *w = (*w).max(cell.len());
        }
    }
    let mut out = std::io::stdout().lock();
    let line =
        |cells: Vec<&str>| cells.iter().zip(&widths).map(|(c, w)| format!("{c:<w$}")).collect::<Vec<_>>().join("  ");
    let write = |out: &mut std::io::StdoutLock, s: String| writeln!(out, "{}", s.trim_end()).map_err(CliError::runtime);
    write(&mut out, line(header.to_vec()))?;
    write(&mut out, widths.iter().map(|w| "-".repeat(*w)).collect::<Vec<_>>().join("  "))?;
    for row in rows {
        write(&mut out, line(row.iter().map(String::as_str).collect()))?;
    }
    Ok(())
}
