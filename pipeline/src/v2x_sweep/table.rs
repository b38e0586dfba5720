//! The table of the latency at which cooperative warnings stop preventing crashes.

use risktwin_v2x::sweep::{Cell, SweepResult, mean_latency_ms};
use std::fmt::Write as _;

/// Warnings "still prevent crashes" while they prevent at least this share of the crashes the
/// driver has without them.
pub const STILL_PREVENTS_SHARE: f64 = 0.1;

/// Crashes of `cell` on `kind` summed over the seeds: without warnings, those the warnings
/// prevent and those they cause.
fn crashes(r: &SweepResult, cell: usize, kind: &str) -> (u32, u32, u32) {
    r.rows.iter().filter(|row| row.cell == cell && row.kind == kind).fold((0, 0, 0), |(u, p, i), row| {
        (u + row.crashes_unwarned, p + row.crashes_prevented, i + row.crashes_induced)
    })
}

/// Cells that differ from `c` in their latency only, in the grid's order.
pub(super) fn same_but_latency(r: &SweepResult, c: &Cell) -> Vec<usize> {
    (0..r.grid.cells.len())
        .filter(|&i| {
            let o = &r.grid.cells[i];
            o.model == c.model
                && o.rsu_offset_m == c.rsu_offset_m
                && o.bursts == c.bursts
                && o.warning_rate_hz == c.warning_rate_hz
        })
        .collect()
}

/// One line per kind and group of cells differing in latency only: the share of the unwarned
/// crashes prevented at the lowest latency, and the lowest mean latency at which warnings
/// prevent less than [`STILL_PREVENTS_SHARE`] of them.
pub(super) fn stop_table(r: &SweepResult) -> String {
    let mut s = format!(
        "Prevented: the share of the crashes without V2X that the warnings avoid, summed over the seeds; \
         caused: crashes with warnings in scenes without one unwarned. \
         Warnings stop preventing crashes at the lowest mean latency at which they avoid less than {:.0} % \
         of them.\n\n| kind | model | RSU offset (m) | bursts | warning rate (Hz) | crashes without V2X | prevented at {} | caused there | stop at mean latency |\n|---|---|---|---|---|---|---|---|---|\n",
        100.0 * STILL_PREVENTS_SHARE,
        "the lowest latency",
    );
    let mut done = vec![false; r.grid.cells.len()];
    for kind in &r.grid.kinds {
        done.iter_mut().for_each(|d| *d = false);
        for (i, c) in r.grid.cells.iter().enumerate() {
            if done[i] {
                continue;
            }
            let mut group = same_but_latency(r, c);
            group.iter().for_each(|&j| done[j] = true);
            group.sort_by(|&a, &b| {
                mean_latency_ms(&r.grid.cells[a].latency).total_cmp(&mean_latency_ms(&r.grid.cells[b].latency))
            });
            let (unwarned, _, induced) = crashes(r, group[0], kind.name());
            let prevented = |cell| {
                let (u, p, _) = crashes(r, cell, kind.name());
                f64::from(p) / f64::from(u)
            };
            let (first, stop) = if unwarned == 0 {
                ("—".to_string(), "no crashes to prevent".to_string())
            } else {
                let first = format!("{:.0} %", 100.0 * prevented(group[0]));
                let stop = if prevented(group[0]) < STILL_PREVENTS_SHARE {
                    "never prevented (not even at the lowest latency)".to_string()
                } else {
                    group.iter().find(|&&cell| prevented(cell) < STILL_PREVENTS_SHARE).map_or_else(
                        || {
                            format!(
                                "above {} ms",
                                mean_latency_ms(&r.grid.cells[*group.last().expect("a group")].latency)
                            )
                        },
                        |&cell| format!("{} ms", mean_latency_ms(&r.grid.cells[cell].latency)),
                    )
                };
                (first, stop)
            };
            let bursts = if c.bursts.share > 0.0 {
                format!("{:.0} % in bursts of {}", 100.0 * c.bursts.share, c.bursts.mean_burst)
            } else {
                "none".to_string()
            };
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                kind,
                c.model.name(),
                c.rsu_offset_m,
                bursts,
                c.warning_rate_hz,
                unwarned,
                first,
                induced,
                stop
            );
        }
    }
    s
}
