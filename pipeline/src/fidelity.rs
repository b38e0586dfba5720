//! The cloud twin's fidelity report (`risktwin cloud --fidelity-report DIR`): fidelity.md, a
//! table per connected vehicle of how well the twin mirrored the scene's ground truth, and
//! fidelity.png, the same over time ([`figures::fidelity`]).

use crate::figures::{self, FigureError};
use risktwin_cloud::twin::fidelity::{ASSOCIATION_M, CRITICAL_TTC_S, ErrorStats, TTC_COMPARED_S, VehicleFidelity};
use risktwin_cloud::twin::outputs::TwinSummary;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// File names in the report folder.
pub const FIDELITY_MD: &str = "fidelity.md";
pub const FIDELITY_PNG: &str = "fidelity.png";

/// Why the report could not be written.
#[derive(Debug, thiserror::Error)]
pub enum FidelityReportError {
    #[error("cannot write {}: {source}", path.display())]
    Write { path: PathBuf, source: std::io::Error },
    #[error(transparent)]
    Figure(#[from] FigureError),
}

/// Writes fidelity.md and fidelity.png of `twin` into `dir` (created if missing).
pub fn write_fidelity_report(dir: &Path, twin: &TwinSummary) -> Result<(), FidelityReportError> {
    let write_err = |path: &Path| {
        let path = path.to_path_buf();
        move |source| FidelityReportError::Write { path, source }
    };
    std::fs::create_dir_all(dir).map_err(write_err(dir))?;
    let md = dir.join(FIDELITY_MD);
    std::fs::write(&md, markdown(twin)).map_err(write_err(&md))?;
    figures::write_png(&dir.join(FIDELITY_PNG), &figures::fidelity(&twin.fidelity_series)?)?;
    Ok(())
}

fn stats(s: &ErrorStats, digits: usize) -> String {
    if s.n == 0 { "–".into() } else { format!("{:.digits$} / {:.digits$} / {:.digits$}", s.mean, s.p95, s.max) }
}

/// The report's text: one row per connected vehicle (`site/source`).
pub fn markdown(twin: &TwinSummary) -> String {
    let mut md = String::from("# Twin fidelity against the scene's ground truth\n\n");
    if twin.fidelity.is_empty() {
        md.push_str("No ground truth was received: no scene published on this cloud's sites.\n");
        return md;
    }
    let _ = writeln!(
        md,
        "Per connected vehicle, every twin tick compared with the truth at the tick's time \
         (mean / p95 / max). Risk columns compare the same risk code run on the twin and on the \
         truth (they need the risk role). TTC: pairs the truth has closing in below {TTC_COMPARED_S} s; \
         a twin object stands for a true one within {ASSOCIATION_M} m. A critical event is a true \
         pair's TTC falling below {CRITICAL_TTC_S} s; its lag is how much later the twin saw it.\n"
    );
    md.push_str(
        "| vehicle | ticks | position error (m) | S_risk abs. error | risk at vehicle abs. error | TTC abs. error (s) | TTC pairs compared / unseen | critical events truth / seen / missed | lag (s) |\n",
    );
    md.push_str("|---|---:|---|---|---|---|---|---|---|\n");
    for (name, v) in &twin.fidelity {
        md.push_str(&row(name, v));
    }
    md.push_str("\nFigure: fidelity.png (solid: twin, dashed: truth).\n");
    md
}

fn row(name: &str, v: &VehicleFidelity) -> String {
    let mut cells = vec![name.to_owned(), v.ticks.to_string(), stats(&v.position_error_m, 3)];
    match &v.risk {
        Some(r) => {
            let e = &r.critical_events;
            cells.extend([
                stats(&r.s_risk_abs_error, 4),
                stats(&r.risk_at_ego_abs_error, 4),
                stats(&r.ttc_abs_error_s, 2),
                format!("{} / {}", r.ttc_abs_error_s.n, r.ttc_pairs_unseen),
                format!("{} / {} / {}", e.truth, e.seen, e.missed),
                stats(&e.lag_s, 2),
            ]);
        }
        None => cells.extend(std::iter::repeat_n("–".to_owned(), 6)),
    }
    format!("| {} |\n", cells.join(" | "))
}
