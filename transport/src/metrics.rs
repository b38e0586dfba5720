//! The roles' side of the live Prometheus metrics (`--metrics-listen`, docs/metrics.md): counts
//! go out through the `metrics` facade, and a role whose counts already live in its summary
//! registers an exporter that copies them at each scrape ([`on_scrape`]), so the metrics are the
//! summary's numbers by construction and the receive path pays nothing for them.
//!
//! The binary owns the recorder and the HTTP endpoint and calls [`refresh`] before rendering.
//! Without a recorder (no `--metrics-listen`) every facade call is a no-op and nothing is
//! registered here.

use crate::sync::LockExt;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

type Exporter = Box<dyn FnMut() -> bool + Send>;

static EXPORTERS: Mutex<Vec<Exporter>> = Mutex::new(Vec::new());

static ENABLED: AtomicBool = AtomicBool::new(false);

/// Says that this process serves metrics: called by the binary once it installed the recorder.
pub fn enable() {
    ENABLED.store(true, Ordering::Release);
}

/// Whether this process serves metrics: roles skip the work of exporting otherwise.
pub fn enabled() -> bool {
    ENABLED.load(Ordering::Acquire)
}

/// Registers `export`, run before each scrape is rendered until it returns `false` (its role
/// has ended; it should then have exported its final counts itself). Not registered when the
/// process serves no metrics.
pub fn on_scrape(export: impl FnMut() -> bool + Send + 'static) {
    if enabled() {
        EXPORTERS.locked().push(Box::new(export));
    }
}

/// Runs every registered exporter (the endpoint's scrape handler calls this), dropping those
/// whose role has ended.
pub fn refresh() {
    EXPORTERS.locked().retain_mut(|export| export());
}

#[cfg(test)]
mod tests {
    #[test]
    fn without_a_recorder_nothing_is_registered() {
        // No test of this crate enables metrics.
        assert!(!super::enabled());
        super::on_scrape(|| panic!("never run"));
        super::refresh();
    }
}
