//! `risktwin v2x sweep`: runs a sweep's grid in virtual time (`risktwin_v2x::sweep`) and
//! writes its folder: the config as run, one CSV row per cell, kind and seed, the scenes drawn,
//! the figures and `report.md`. Every file is a function of the config alone (no timings), so
//! the same config gives byte-identical files.

mod figures;
mod table;

use crate::figures::{FigureError, write_png};
use risktwin_v2x::sps_reference::{published_curve, reproduced_curve};
use risktwin_v2x::sweep::{self, Grid, SweepConfig, SweepResult, latency_label, mean_latency_ms};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Why a sweep's folder could not be written.
#[derive(Debug, thiserror::Error)]
pub enum SweepError {
    #[error("{}: {source}", path.display())]
    Io { path: PathBuf, source: std::io::Error },
    #[error(transparent)]
    Figure(#[from] FigureError),
}

/// File names in the sweep's folder.
pub const CONFIG_FILE: &str = "config.json";
pub const ROWS_FILE: &str = "rows.csv";
pub const SCENES_FILE: &str = "scenes.csv";
pub const REPORT_FILE: &str = "report.md";

fn write(path: PathBuf, text: &str) -> Result<(), SweepError> {
    std::fs::write(&path, text).map_err(|source| SweepError::Io { path, source })
}

/// Runs `grid` (checked from `config`, which is written beside the results) and writes `out`.
pub fn run(config: &SweepConfig, grid: Grid, out: &Path) -> Result<SweepResult, SweepError> {
    std::fs::create_dir_all(out).map_err(|source| SweepError::Io { path: out.to_path_buf(), source })?;
    let result = sweep::run(grid);
    let config_json = serde_json::to_string_pretty(config).expect("a config serialises");
    write(out.join(CONFIG_FILE), &(config_json + "\n"))?;
    write(out.join(ROWS_FILE), &rows_csv(&result))?;
    write(out.join(SCENES_FILE), &scenes_csv(&result))?;
    let reproduced = reproduced_curve(result.grid.seeds[0]);
    let figures = figures::draw(&result, &reproduced)?;
    for (name, image) in &figures {
        write_png(&out.join(name), image)?;
    }
    let names: Vec<&str> = figures.iter().map(|(n, _)| *n).collect();
    write(out.join(REPORT_FILE), &report(&result, &names, &reproduced))?;
    Ok(result)
}

/// An optional number as a CSV field (empty when none).
fn field(v: Option<f64>) -> String {
    v.map_or_else(String::new, |v| format!("{v}"))
}

fn rows_csv(r: &SweepResult) -> String {
    let mut s = String::from(
        "model,rsu_offset_m,latency,latency_mean_ms,burst_share,mean_burst,warning_rate_hz,kind,seed,episodes,\
         crashes_unwarned,crashes_warned,crashes_prevented,crashes_induced,cam_copies,cam_passed,pdr,latency_p50_ms,aoi_mean_ms,twin_position_error_m,\
         twin_risk_error,critical_events,critical_missed,critical_lag_mean_s,warnings_made,warnings_arrived\n",
    );
    for row in &r.rows {
        let c = &r.grid.cells[row.cell];
        let p50 = row.latency_us.quantile(0.5).map(|us| us / 1e3);
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            c.model.name(),
            c.rsu_offset_m,
            latency_label(&c.latency),
            mean_latency_ms(&c.latency),
            c.bursts.share,
            c.bursts.mean_burst,
            c.warning_rate_hz,
            row.kind,
            row.seed,
            row.episodes,
            row.crashes_unwarned,
            row.crashes_warned,
            row.crashes_prevented,
            row.crashes_induced,
            row.cam_copies,
            row.cam_passed,
            field(row.pdr()),
            field(p50),
            field(row.aoi_mean_ms),
            field(row.twin_position_error_m),
            field(row.twin_risk_error),
            row.critical_events,
            row.critical_missed,
            field(row.critical_lag_mean_s),
            row.warnings_made,
            row.warnings_arrived,
        );
    }
    s
}

fn scenes_csv(r: &SweepResult) -> String {
    let mut s = String::from("kind,seed,candidates,critical_scenes,crashes_unwarned\n");
    for sc in &r.scenes {
        let _ = writeln!(s, "{},{},{},{},{}", sc.kind, sc.seed, sc.tried, sc.scenes.len(), sc.crashes());
    }
    s
}

fn report(r: &SweepResult, figures: &[&str], reproduced: &[f64]) -> String {
    let g = &r.grid;
    let mut s = String::from("# V2X sweep\n\n");
    let _ = writeln!(
        s,
        "{} cells × {} kinds × {} seeds × up to {} critical scenes: {} episodes with V2X, in virtual time.\n",
        g.cells.len(),
        g.kinds.len(),
        g.seeds.len(),
        g.scenes_per_kind,
        r.episodes()
    );
    s.push_str(
        "A critical scene is a sampled scene in which the reference driver without V2X crashes or comes \
         within a 2 s time to collision; every cell drives the same scenes with the same random streams, \
         so cells differ by their parameters only. Files: `config.json` (the grid as run), `rows.csv` \
         (one row per cell, kind and seed), `scenes.csv` (the scenes drawn).\n\n",
    );
    s.push_str("## Scenes\n\n| kind | seed | candidates | critical | crash without V2X |\n|---|---|---|---|---|\n");
    for sc in &r.scenes {
        let _ = writeln!(s, "| {} | {} | {} | {} | {} |", sc.kind, sc.seed, sc.tried, sc.scenes.len(), sc.crashes());
    }
    s.push_str("\n## Figures\n\n");
    s.push_str(
        "Lines vs latency are drawn for the first RSU offset, burst setting and warning rate of the grid \
         (all cells are in `rows.csv`); x is the latency model's mean.\n\n",
    );
    for name in figures {
        let _ = writeln!(s, "![{name}]({name})\n");
    }
    s.push_str(&published_table(reproduced, r.grid.seeds[0]));
    s.push_str("## When warnings stop preventing crashes\n\n");
    s.push_str(&table::stop_table(r));
    s
}

/// The published LTE-V2X Mode 4 curve beside ours, with the largest gap.
fn published_table(reproduced: &[f64], seed: u64) -> String {
    let mut s = format!(
        "## A published PDR curve, reproduced\n\nLTE-V2X Mode 4 with sensing-based semi-persistent scheduling, \
         half-duplex and interference: Gonzalez-Martín, Sepulcre, Molina-Masegosa and Gozalvez, IEEE TVT 68(2), \
         2019 (0.2 vehicles/m, 10 Hz, 23 dBm, 4 sub-channels, 190 bytes, WINNER+ B1 LOS), their analytical model \
         and their simulator, against RiskTwin's Monte Carlo of the same configuration (seed {seed}; docs/v2x.md).\n\n\
         | distance (m) | analytical | simulated | RiskTwin | gap to analytical |\n|---|---|---|---|---|\n"
    );
    let mut worst = 0.0f64;
    for (p, ours) in published_curve().iter().zip(reproduced) {
        let gap = ours - p.analytical_pdr;
        worst = worst.max(gap.abs()).max((ours - p.simulated_pdr).abs());
        let _ = writeln!(
            s,
            "| {} | {:.3} | {:.3} | {:.3} | {:+.3} |",
            p.distance_m, p.analytical_pdr, p.simulated_pdr, ours, gap
        );
    }
    let _ = writeln!(s, "\nLargest gap to either published curve: {:.1} percentage points.\n", 100.0 * worst);
    s
}

#[cfg(test)]
mod tests;
