//! The grid of a V2X sweep, read from a JSON file whose keys are all optional (the default grid
//! is [`SweepConfig::default`]); an unknown key or a value out of range is refused with a message
//! that names it.

use crate::channel::{LinkBudget, PathLoss};
use crate::latency::Latency;
use crate::link::V2xChannel;
use crate::loss::BurstLoss;
use crate::warning::WarningSetup;
use risktwin_common::scenario::ScenarioKind;
use serde::{Deserialize, Serialize};

/// The most episodes one sweep may ask for (about an hour on two cores).
pub const MAX_EPISODES: u64 = 2_000_000;

/// Correlated loss of one grid point: the long-run share lost and the mean burst, in messages.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Bursts {
    pub share: f64,
    pub mean_burst: f64,
}

/// The axes of a sweep: every combination of a channel model, an RSU offset, a latency model, a
/// burst loss and a warning rate is one cell, run on `scenes_per_kind` critical scenes of each
/// kind for each seed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SweepConfig {
    /// Path-loss models by name (`3gpp-highway-los`, `3gpp-urban-los`, `3gpp-urban-nlos`,
    /// `winner-b1-los`).
    pub models: Vec<String>,
    /// The RSU's distance beside the ego's lane, level with the point of conflict, m.
    pub rsu_offsets_m: Vec<f64>,
    /// Latency models (`{"model": "sidelink", "t1_ms", "t2_ms"}` or
    /// `{"model": "gamma", "offset_ms", "shape", "scale_ms"}`).
    pub latencies: Vec<Latency>,
    /// Burst losses; a share of 0 is none.
    pub bursts: Vec<Bursts>,
    /// Warning repetitions per second while a hazard lasts, Hz.
    pub warning_rates_hz: Vec<f64>,
    /// Scenario kinds by name.
    pub kinds: Vec<String>,
    /// Each seed draws its own scenes and its own channel randomness.
    pub seeds: Vec<u64>,
    /// Critical scenes per kind and seed (see `sweep::scenes`).
    pub scenes_per_kind: usize,
}

impl Default for SweepConfig {
    fn default() -> Self {
        let sidelink = |t2_ms| Latency::Sidelink { t1_ms: 4.0, t2_ms };
        let late = |offset_ms| Latency::Gamma { offset_ms, shape: 4.0, scale_ms: 25.0 };
        SweepConfig {
            models: [PathLoss::HighwayLos, PathLoss::UrbanLos, PathLoss::UrbanNlos]
                .map(|m| m.name().to_string())
                .to_vec(),
            rsu_offsets_m: vec![10.0, 400.0],
            latencies: vec![
                sidelink(20.0),
                sidelink(100.0),
                sidelink(300.0),
                sidelink(1000.0),
                Latency::CELLULAR_LTE_ROUND_TRIP,
                late(1000.0),
                late(2000.0),
            ],
            bursts: vec![Bursts { share: 0.0, mean_burst: 1.0 }, Bursts { share: 0.3, mean_burst: 5.0 }],
            warning_rates_hz: vec![10.0],
            kinds: ScenarioKind::ALL.iter().map(|k| k.name().to_string()).collect(),
            seeds: vec![1, 2, 3],
            scenes_per_kind: 20,
        }
    }
}

/// One grid point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cell {
    pub model: PathLoss,
    pub rsu_offset_m: f64,
    pub latency: Latency,
    pub bursts: Bursts,
    pub warning_rate_hz: f64,
}

impl Cell {
    pub fn setup(&self) -> WarningSetup {
        let bursts = (self.bursts.share > 0.0).then(|| {
            BurstLoss::from_share(self.bursts.share, self.bursts.mean_burst).expect("checked with the config")
        });
        WarningSetup {
            channel: V2xChannel { model: self.model, budget: LinkBudget::default(), latency: self.latency, bursts },
            rsu_offset_m: self.rsu_offset_m,
            repeat_hz: self.warning_rate_hz,
        }
    }
}

/// A checked config: its cells in grid order (model, offset, latency, bursts, rate; the last
/// varies fastest) and its kinds.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    pub cells: Vec<Cell>,
    pub kinds: Vec<ScenarioKind>,
    pub seeds: Vec<u64>,
    pub scenes_per_kind: usize,
}

impl Grid {
    /// Episodes the sweep runs (besides the unwarned ones that pick its scenes).
    pub fn episodes(&self) -> u64 {
        (self.cells.len() * self.kinds.len() * self.seeds.len() * self.scenes_per_kind) as u64
    }
}

fn nonempty<T>(name: &str, v: &[T]) -> Result<(), String> {
    if v.is_empty() { Err(format!("{name}: the list is empty")) } else { Ok(()) }
}

/// A repeated value would run the same cells twice and count them twice in every share.
/// Quadratic: called once the grid's size is known to be bounded.
fn no_repeats<T: PartialEq + std::fmt::Debug>(name: &str, v: &[T]) -> Result<(), String> {
    match v.iter().enumerate().find(|(i, x)| v[..*i].contains(x)) {
        Some((_, x)) => Err(format!("{name}: {x:?} is listed twice")),
        None => Ok(()),
    }
}

impl SweepConfig {
    /// The grid, or why this config has none.
    pub fn grid(&self) -> Result<Grid, String> {
        nonempty("models", &self.models)?;
        nonempty("rsu_offsets_m", &self.rsu_offsets_m)?;
        nonempty("latencies", &self.latencies)?;
        nonempty("bursts", &self.bursts)?;
        nonempty("warning_rates_hz", &self.warning_rates_hz)?;
        nonempty("kinds", &self.kinds)?;
        nonempty("seeds", &self.seeds)?;
        if !(1..=10_000).contains(&self.scenes_per_kind) {
            return Err(format!("scenes_per_kind {}: need 1 to 10000", self.scenes_per_kind));
        }
        // Counted before any cell is built: a short file can ask for 10^12 cells.
        let lengths = [
            self.models.len(),
            self.rsu_offsets_m.len(),
            self.latencies.len(),
            self.bursts.len(),
            self.warning_rates_hz.len(),
            self.kinds.len(),
            self.seeds.len(),
            self.scenes_per_kind,
        ];
        let episodes = lengths.iter().fold(1u128, |n, &l| n.saturating_mul(l as u128));
        if episodes > u128::from(MAX_EPISODES) {
            return Err(format!("{episodes} episodes: at most {MAX_EPISODES} in one sweep"));
        }
        no_repeats("models", &self.models)?;
        no_repeats("rsu_offsets_m", &self.rsu_offsets_m)?;
        no_repeats("latencies", &self.latencies)?;
        no_repeats("bursts", &self.bursts)?;
        no_repeats("warning_rates_hz", &self.warning_rates_hz)?;
        no_repeats("kinds", &self.kinds)?;
        no_repeats("seeds", &self.seeds)?;
        let models = self
            .models
            .iter()
            .map(|m| {
                PathLoss::from_name(m).ok_or_else(|| {
                    let names: Vec<&str> = PathLoss::ALL.iter().map(|m| m.name()).collect();
                    format!("models: unknown model '{m}' (expected one of {})", names.join(", "))
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let kinds = self
            .kinds
            .iter()
            .map(|k| k.parse::<ScenarioKind>().map_err(|e| format!("kinds: {e}")))
            .collect::<Result<Vec<_>, _>>()?;
        for l in &self.latencies {
            l.check().map_err(|e| format!("latencies: {e}"))?;
        }
        for b in &self.bursts {
            if b.share != 0.0 {
                BurstLoss::from_share(b.share, b.mean_burst).map_err(|e| format!("bursts: {e}"))?;
            }
        }
        let mut cells = Vec::new();
        for &model in &models {
            for &rsu_offset_m in &self.rsu_offsets_m {
                for &latency in &self.latencies {
                    for &bursts in &self.bursts {
                        for &warning_rate_hz in &self.warning_rates_hz {
                            let cell = Cell { model, rsu_offset_m, latency, bursts, warning_rate_hz };
                            cell.setup().check()?;
                            cells.push(cell);
                        }
                    }
                }
            }
        }
        Ok(Grid { cells, kinds, seeds: self.seeds.clone(), scenes_per_kind: self.scenes_per_kind })
    }
}

/// The mean of a latency model, ms: the x axis of the sweep's plots.
pub fn mean_latency_ms(latency: &Latency) -> f64 {
    match *latency {
        Latency::Sidelink { t1_ms, t2_ms } => 0.5 * (t1_ms + t2_ms),
        Latency::Gamma { offset_ms, shape, scale_ms } => offset_ms + shape * scale_ms,
    }
}

/// A short label of a latency model for tables, legends and CSV fields (no comma).
pub fn latency_label(latency: &Latency) -> String {
    match *latency {
        Latency::Sidelink { t1_ms, t2_ms } => format!("sidelink {t1_ms}–{t2_ms} ms"),
        Latency::Gamma { offset_ms, shape, scale_ms } => format!("gamma {offset_ms} + Γ(k {shape} θ {scale_ms}) ms"),
    }
}
