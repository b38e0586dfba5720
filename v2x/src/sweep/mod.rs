//! A V2X sweep in virtual time: every cell of a grid ([`config`]) run on the same critical
//! scenes of each kind for each seed, in parallel, reduced to one [`Row`] per cell, kind and
//! seed. Deterministic: rows depend only on the config (each episode's randomness is derived
//! from its scene's seed, the same in every cell, so cells differ by their parameters only).

pub mod config;

pub use config::{Bursts, Cell, Grid, SweepConfig, latency_label, mean_latency_ms};

use super::experiment::run_episode;
use super::twin::CRITICAL_TTC_S;
use rayon::prelude::*;
use risktwin_common::episode::evaluate;
use risktwin_common::histogram::Histogram;
use risktwin_common::scenario::{ScenarioKind, ScenarioSpec, sample};
use serde::Serialize;

/// Candidates drawn per scene wanted before a kind and seed give up looking.
pub const TRIES_PER_SCENE: u64 = 50;

/// The scenes of one kind and seed: sampled scenes in which the reference driver without V2X
/// crashes or comes within [`CRITICAL_TTC_S`] of a crash (warnings can matter only there).
#[derive(Debug, Clone)]
pub struct Scenes {
    pub kind: ScenarioKind,
    pub seed: u64,
    /// Candidates drawn.
    pub tried: u64,
    /// The critical ones, and whether the unwarned driver crashed in each.
    pub scenes: Vec<(ScenarioSpec, bool)>,
}

impl Scenes {
    pub fn crashes(&self) -> u32 {
        self.scenes.iter().filter(|(_, c)| *c).count() as u32
    }
}

/// Draws `wanted` critical scenes of `kind` under `seed` (fewer if [`TRIES_PER_SCENE`] × `wanted`
/// candidates hold fewer).
pub fn scenes(kind: ScenarioKind, seed: u64, wanted: usize) -> Scenes {
    let mut out = Scenes { kind, seed, tried: 0, scenes: Vec::with_capacity(wanted) };
    while out.scenes.len() < wanted && out.tried < TRIES_PER_SCENE * wanted as u64 {
        let spec = sample(seed, kind, out.tried);
        out.tried += 1;
        let m = evaluate(&spec).metrics;
        if m.collision || m.min_ttc_s.is_some_and(|t| t < CRITICAL_TTC_S) {
            out.scenes.push((spec, m.collision));
        }
    }
    out
}

/// A running mean.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Mean {
    sum: f64,
    n: u32,
}

impl Mean {
    fn add(&mut self, v: Option<f64>) {
        if let Some(v) = v.filter(|v| v.is_finite()) {
            self.sum += v;
            self.n += 1;
        }
    }
    fn get(&self) -> Option<f64> {
        (self.n > 0).then(|| self.sum / f64::from(self.n))
    }
}

/// One cell on the scenes of one kind and seed.
#[derive(Debug, Serialize)]
pub struct Row {
    /// Index into the grid's cells.
    pub cell: usize,
    pub kind: &'static str,
    pub seed: u64,
    pub episodes: u32,
    /// Episodes that crash without V2X, and with the cell's warnings.
    pub crashes_unwarned: u32,
    pub crashes_warned: u32,
    /// Episodes whose unwarned crash the warnings avoid, and crashes they cause (the driver's
    /// slowing for a warned hazard put it in another's way): warned = unwarned − prevented +
    /// induced.
    pub crashes_prevented: u32,
    pub crashes_induced: u32,
    /// CAMs among the vehicles: copies sent and passed by the channel.
    pub cam_copies: u64,
    pub cam_passed: u64,
    /// Means over the episodes: age of information among the vehicles, ms; the twin's position
    /// error, m, and the error of the risk it sees at the ego.
    pub aoi_mean_ms: Option<f64>,
    pub twin_position_error_m: Option<f64>,
    pub twin_risk_error: Option<f64>,
    /// Episodes with a critical event, those the twin never saw, and the mean lag of the seen.
    pub critical_events: u32,
    pub critical_missed: u32,
    pub critical_lag_mean_s: Option<f64>,
    pub warnings_made: u64,
    pub warnings_arrived: u64,
    /// Latencies of the CAM copies that arrived, µs.
    #[serde(skip)]
    pub latency_us: Histogram,
}

impl Row {
    pub fn pdr(&self) -> Option<f64> {
        (self.cam_copies > 0).then(|| self.cam_passed as f64 / self.cam_copies as f64)
    }
}

/// Runs `cell` (index `index`) on `scenes`.
fn run_row(index: usize, cell: &Cell, scenes: &Scenes) -> Row {
    let setup = cell.setup();
    let (mut aoi, mut position, mut risk, mut lag) =
        (Mean::default(), Mean::default(), Mean::default(), Mean::default());
    let mut row = Row {
        cell: index,
        kind: scenes.kind.name(),
        seed: scenes.seed,
        episodes: 0,
        crashes_unwarned: scenes.crashes(),
        crashes_warned: 0,
        crashes_prevented: 0,
        crashes_induced: 0,
        cam_copies: 0,
        cam_passed: 0,
        aoi_mean_ms: None,
        twin_position_error_m: None,
        twin_risk_error: None,
        critical_events: 0,
        critical_missed: 0,
        critical_lag_mean_s: None,
        warnings_made: 0,
        warnings_arrived: 0,
        latency_us: Histogram::default(),
    };
    for (spec, crashed_unwarned) in &scenes.scenes {
        let e = run_episode(spec, setup, spec.seed);
        let crashed = e.result.metrics.collision;
        row.episodes += 1;
        row.crashes_warned += u32::from(crashed);
        row.crashes_prevented += u32::from(*crashed_unwarned && !crashed);
        row.crashes_induced += u32::from(!*crashed_unwarned && crashed);
        if let Some(a) = &e.awareness {
            row.cam_copies += a.transmissions;
            row.cam_passed += a.passed;
            aoi.add(a.aoi_mean_ms);
        }
        row.latency_us.merge(&e.latency_us);
        position.add(e.twin.position_error_mean_m);
        risk.add(e.twin.risk_error_mean);
        if e.twin.critical_true_s.is_some() {
            row.critical_events += 1;
            match e.twin.critical_lag_s() {
                Some(s) => lag.add(Some(s)),
                None => row.critical_missed += 1,
            }
        }
        row.warnings_made += e.warnings.made;
        row.warnings_arrived += e.warnings.arrived;
    }
    row.aoi_mean_ms = aoi.get();
    row.twin_position_error_m = position.get();
    row.twin_risk_error = risk.get();
    row.critical_lag_mean_s = lag.get();
    row
}

/// What a sweep produced.
#[derive(Debug)]
pub struct SweepResult {
    pub grid: Grid,
    /// Per kind and seed, in the grid's order (kinds, then seeds).
    pub scenes: Vec<Scenes>,
    /// Per cell, kind and seed (cells, then kinds, then seeds).
    pub rows: Vec<Row>,
}

impl SweepResult {
    /// Episodes run with V2X.
    pub fn episodes(&self) -> u64 {
        self.rows.iter().map(|r| u64::from(r.episodes)).sum()
    }
}

/// Runs `grid` on rayon's pool.
pub fn run(grid: Grid) -> SweepResult {
    let pairs: Vec<(ScenarioKind, u64)> =
        grid.kinds.iter().flat_map(|&k| grid.seeds.iter().map(move |&s| (k, s))).collect();
    let scenes: Vec<Scenes> = pairs.par_iter().map(|&(k, s)| scenes(k, s, grid.scenes_per_kind)).collect();
    let jobs: Vec<(usize, usize)> =
        (0..grid.cells.len()).flat_map(|c| (0..scenes.len()).map(move |k| (c, k))).collect();
    let rows = jobs.par_iter().map(|&(c, k)| run_row(c, &grid.cells[c], &scenes[k])).collect();
    SweepResult { grid, scenes, rows }
}

#[cfg(test)]
mod tests;
