//! A self-drawn progress bar on stderr for the long phases (stdout stays for the summary).

use std::io::Write;

const WIDTH: u64 = 30;

/// Redraws one stderr line when the whole percentage changes.
#[derive(Debug, Default)]
pub struct ProgressBar {
    label: String,
    percent: Option<u64>,
}

impl ProgressBar {
    /// Shows `done` of `total` for `label`; a new label starts a new line.
    pub fn update(&mut self, label: &str, done: u64, total: u64) {
        let total = total.max(1);
        let percent = done.min(total) * 100 / total;
        if label != self.label {
            self.finish();
            self.label = label.to_string();
        } else if self.percent == Some(percent) {
            return;
        }
        self.percent = Some(percent);
        let filled = (done.min(total) * WIDTH / total) as usize;
        let bar = format!("{}{}", "#".repeat(filled), ".".repeat(WIDTH as usize - filled));
        let _ = write!(std::io::stderr(), "\r{label} [{bar}] {percent:3}% {done}/{total}");
    }

    /// Ends the current bar's line.
    pub fn finish(&mut self) {
        if self.percent.take().is_some() {
            let _ = writeln!(std::io::stderr());
        }
    }
}
