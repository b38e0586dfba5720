//! The sweep's figures: PDR against distance, the latency CDF, age of information, the twin's
//! staleness and collision rates with and without warnings, each against the latency.

use super::table::same_but_latency;
use crate::figures::{Bitmap, FigureError, Panel, Series, line_panels};
use risktwin_common::histogram::Histogram;
use risktwin_v2x::channel::{LinkBudget, PathLoss};
use risktwin_v2x::sps_reference::published_curve;
use risktwin_v2x::sweep::{Cell, Row, SweepResult, latency_label, mean_latency_ms};

pub const PDR_FILE: &str = "pdr_vs_distance.png";
pub const LATENCY_FILE: &str = "latency_cdf.png";
pub const AOI_FILE: &str = "age_of_information.png";
pub const TWIN_FILE: &str = "twin_staleness.png";
pub const COLLISIONS_FILE: &str = "collisions.png";

/// The palette's grey, for the rate without V2X.
const WITHOUT_COLOUR: usize = 7;
/// Distances of the PDR curves, m.
const PDR_DISTANCES_M: std::ops::RangeInclusive<u32> = 0..=100;
const PDR_STEP_M: f64 = 20.0;

/// Every figure with its file name.
pub(super) fn draw(r: &SweepResult, reproduced: &[f64]) -> Result<Vec<(&'static str, Bitmap)>, FigureError> {
    let pdr = [pdr_panel(r), published_panel(reproduced)];
    Ok(vec![
        (PDR_FILE, line_panels("Packet delivery ratio against distance", &pdr, 2, (900, 620))?),
        (LATENCY_FILE, line_panels("Latency of the CAMs that arrived", &[latency_panel(r)], 1, (1100, 620))?),
        (AOI_FILE, line_panels("Age of information among the vehicles", &[aoi_panel(r)], 1, (1100, 620))?),
        (
            TWIN_FILE,
            line_panels(
                "The twin, fed by CAMs through the RSU, against the ground truth",
                &twin_panels(r),
                3,
                (640, 560),
            )?,
        ),
        (
            COLLISIONS_FILE,
            line_panels(
                "Collision rate of critical scenes with and without warnings (band: min–max over seeds)",
                &collision_panels(r),
                3,
                (640, 560),
            )?,
        ),
    ])
}

fn models(r: &SweepResult) -> Vec<PathLoss> {
    let mut out: Vec<PathLoss> = Vec::new();
    for c in &r.grid.cells {
        if !out.contains(&c.model) {
            out.push(c.model);
        }
    }
    out
}

/// The lines drawn against latency: per model and RSU offset, on the grid's first burst
/// setting and warning rate, its label and its cells by mean latency.
fn lines(r: &SweepResult) -> Vec<(String, Vec<usize>)> {
    let first = r.grid.cells[0];
    let mut out: Vec<(String, Vec<usize>)> = Vec::new();
    for c in &r.grid.cells {
        let probe = Cell { model: c.model, rsu_offset_m: c.rsu_offset_m, ..first };
        let label = format!("{} @ {} m", c.model.name(), c.rsu_offset_m);
        if out.iter().any(|(l, _)| *l == label) {
            continue;
        }
        let mut cells = same_but_latency(r, &probe);
        cells.sort_by(|&a, &b| {
            mean_latency_ms(&r.grid.cells[a].latency).total_cmp(&mean_latency_ms(&r.grid.cells[b].latency))
        });
        out.push((label, cells));
    }
    out
}

fn mean(values: impl Iterator<Item = f64>) -> Option<f64> {
    let (sum, n) = values.fold((0.0, 0u32), |(s, n), v| (s + v, n + 1));
    (n > 0).then(|| sum / f64::from(n))
}

/// Per line, `metric`'s mean over a cell's rows against the cell's mean latency.
fn per_line(r: &SweepResult, metric: fn(&Row) -> Option<f64>) -> Vec<Series> {
    lines(r)
        .into_iter()
        .enumerate()
        .map(|(colour, (label, cells))| Series {
            label,
            points: cells
                .into_iter()
                .filter_map(|c| {
                    let v = mean(r.rows.iter().filter(|row| row.cell == c).filter_map(metric))?;
                    Some((mean_latency_ms(&r.grid.cells[c].latency), v))
                })
                .collect(),
            band: Vec::new(),
            dashed: false,
            colour,
        })
        .collect()
}

fn panel(title: &str, x_desc: &str, y_desc: &str, share: bool, series: Vec<Series>) -> Panel {
    Panel { title: title.to_string(), x_desc: x_desc.to_string(), y_desc: y_desc.to_string(), share, series }
}

fn pdr_panel(r: &SweepResult) -> Panel {
    let budget = LinkBudget::default();
    let series = models(r)
        .into_iter()
        .enumerate()
        .map(|(colour, model)| Series {
            label: model.name().to_string(),
            points: PDR_DISTANCES_M.map(|k| f64::from(k) * PDR_STEP_M).map(|d| (d, budget.at(model, d).pdr)).collect(),
            band: Vec::new(),
            dashed: false,
            colour,
        })
        .collect();
    panel("The sweep's channels: Φ((SNR − threshold) / σ), no interference", "distance (m)", "PDR", true, series)
}

/// The published LTE-V2X Mode 4 curve under load and ours for its configuration.
fn published_panel(reproduced: &[f64]) -> Panel {
    let published = published_curve();
    let line = |label: &str, colour, dashed, pdr: &dyn Fn(usize) -> f64| Series {
        label: label.to_string(),
        points: published.iter().enumerate().map(|(k, p)| (p.distance_m, pdr(k))).collect(),
        band: Vec::new(),
        dashed,
        colour,
    };
    let series = vec![
        line("Gonzalez-Martín et al. 2019, analytical", 7, true, &|k| published[k].analytical_pdr),
        line("Gonzalez-Martín et al. 2019, simulated", 5, true, &|k| published[k].simulated_pdr),
        line("RiskTwin SB-SPS Monte Carlo", 0, false, &|k| reproduced[k]),
    ];
    panel("LTE-V2X Mode 4, 0.2 veh/m, 10 Hz, 190 B (half-duplex, interference)", "distance (m)", "PDR", true, series)
}

fn latency_panel(r: &SweepResult) -> Panel {
    let mut latencies = Vec::new();
    for c in &r.grid.cells {
        if !latencies.contains(&c.latency) {
            latencies.push(c.latency);
        }
    }
    let series = latencies
        .iter()
        .enumerate()
        .map(|(colour, latency)| {
            let pooled = Histogram::default();
            for row in r.rows.iter().filter(|row| r.grid.cells[row.cell].latency == *latency) {
                pooled.merge(&row.latency_us);
            }
            let points = (1..=99)
                .filter_map(|q| Some((pooled.quantile(f64::from(q) / 100.0)? / 1e3, f64::from(q) / 100.0)))
                .collect();
            Series { label: latency_label(latency), points, band: Vec::new(), dashed: false, colour }
        })
        .collect();
    panel("CDF over every cell with the latency model", "latency (ms)", "share of copies", true, series)
}

fn aoi_panel(r: &SweepResult) -> Panel {
    panel(
        "Mean age of the newest CAM a vehicle holds from another",
        "mean latency (ms)",
        "age (ms)",
        false,
        per_line(r, |row| row.aoi_mean_ms),
    )
}

fn twin_panels(r: &SweepResult) -> Vec<Panel> {
    vec![
        panel("Position error", "mean latency (ms)", "error (m)", false, per_line(r, |row| row.twin_position_error_m)),
        panel(
            "Error of the risk at the ego",
            "mean latency (ms)",
            "|R twin − R true|",
            false,
            per_line(r, |row| row.twin_risk_error),
        ),
        panel(
            "Critical-event lag (TTC < 2 s)",
            "mean latency (ms)",
            "lag (s)",
            false,
            per_line(r, |row| row.critical_lag_mean_s),
        ),
    ]
}

fn collision_panels(r: &SweepResult) -> Vec<Panel> {
    let lines = lines(r);
    r.grid
        .kinds
        .iter()
        .map(|kind| {
            let rows = |c: usize| {
                r.rows.iter().filter(move |row| row.cell == c && row.kind == kind.name() && row.episodes > 0)
            };
            let x = |c: usize| mean_latency_ms(&r.grid.cells[c].latency);
            let mut series = Vec::new();
            for (colour, (label, cells)) in lines.iter().enumerate() {
                let rates = |c: usize| -> Vec<f64> {
                    rows(c).map(|row| f64::from(row.crashes_warned) / f64::from(row.episodes)).collect()
                };
                // Pooled over the seeds, as the rate without V2X is; the band is per seed.
                let pooled = |c: usize| {
                    let (w, e) = rows(c).fold((0, 0), |(w, e), row| (w + row.crashes_warned, e + row.episodes));
                    (e > 0).then(|| f64::from(w) / f64::from(e))
                };
                let points = cells.iter().filter_map(|&c| Some((x(c), pooled(c)?))).collect();
                let band = cells
                    .iter()
                    .filter_map(|&c| {
                        let v = rates(c);
                        let lo = v.iter().copied().reduce(f64::min)?;
                        Some((x(c), lo, v.iter().copied().fold(lo, f64::max)))
                    })
                    .collect();
                series.push(Series { label: format!("{label}, warned"), points, band, dashed: false, colour });
            }
            // Every cell drives the same scenes: the rate without V2X is one number per kind.
            if let Some((_, cells)) = lines.first() {
                let (unwarned, episodes) =
                    rows(cells[0]).fold((0, 0), |(u, e), row| (u + row.crashes_unwarned, e + row.episodes));
                if episodes > 0 {
                    let rate = f64::from(unwarned) / f64::from(episodes);
                    let ends = [cells.first(), cells.last()].into_iter().flatten().map(|&c| (x(c), rate)).collect();
                    series.push(Series {
                        label: "without V2X".to_string(),
                        points: ends,
                        band: Vec::new(),
                        dashed: true,
                        colour: WITHOUT_COLOUR,
                    });
                }
            }
            panel(kind.name(), "mean latency (ms)", "collision rate", true, series)
        })
        .collect()
}
