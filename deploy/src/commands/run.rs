//! `risktwin run`: the main job, embedded. Today's loop: generate → simulate → score → rank →
//! mutate around the failures → re-score, then a report folder. Training, the ablation and the
//! MCAP recording join the loop with the pipeline and learning issues; the report says so.

use super::scenarios::worker_threads;
use crate::cli::RunArgs;
use crate::error::{CliError, CliResult};
use crate::output::{Format, print_json, print_table};
use crate::png_out::write_png;
use risktwin_cloud::generate::{GenerateReport, evaluate_all, generate, reference_outcome, store};
use risktwin_cloud::library::{RankedScenario, ScenarioLibrary, ScenarioRecord};
use risktwin_common::episode::field_snapshot;
use risktwin_common::risk::render_heatmap;
use risktwin_common::rng::Rng;
use risktwin_common::scenario::{ScenarioKind, ScenarioSpec, mutate};
use risktwin_common::world::STEP_S;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

mod report;

/// The knobs of a run; a `--config` JSON file may set any of them.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct RunConfig {
    /// Candidates sampled per kind in the first generation.
    pub count_per_kind: u64,
    /// Mutation rounds after the first generation.
    pub iterations: u32,
    /// Parents picked for mutation per round (failures first, then highest risk).
    pub mutations_per_iteration: usize,
    /// Mutation step as a share of each parameter's range.
    pub mutation_radius: f64,
    /// Scenarios listed in the report's ranking.
    pub top_k: usize,
    /// Risk-field heatmaps drawn for the top scenarios.
    pub heatmaps: usize,
}

impl Default for RunConfig {
    fn default() -> Self {
        Self {
            count_per_kind: 200,
            iterations: 4,
            mutations_per_iteration: 40,
            mutation_radius: 0.1,
            top_k: 10,
            heatmaps: 3,
        }
    }
}

impl RunConfig {
    fn quick() -> Self {
        Self { count_per_kind: 12, iterations: 1, mutations_per_iteration: 8, top_k: 5, heatmaps: 2, ..Self::default() }
    }

    fn validate(&self) -> Result<(), String> {
        if !(1..=100_000).contains(&self.count_per_kind) {
            return Err(format!("count_per_kind {} is out of range [1, 100000]", self.count_per_kind));
        }
        if self.iterations > 1000 || self.mutations_per_iteration > 100_000 {
            return Err("iterations (≤ 1000) or mutations_per_iteration (≤ 100000) too large".into());
        }
        if !(self.mutation_radius > 0.0 && self.mutation_radius <= 1.0) {
            return Err(format!("mutation_radius {} is out of range (0, 1]", self.mutation_radius));
        }
        if self.top_k > 1000 || self.heatmaps > 20 {
            return Err("top_k (≤ 1000) or heatmaps (≤ 20) too large".into());
        }
        Ok(())
    }
}

/// One mutation round's effect.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct RoundReport {
    pub round: u32,
    pub parents: usize,
    pub children: usize,
    pub infeasible_children: usize,
    pub parent_mean_risk: f64,
    pub child_mean_risk: f64,
    pub child_collisions: usize,
}

/// Aggregate over the library per kind.
#[derive(Debug, Clone, Default, Serialize, PartialEq)]
pub struct KindSummary {
    pub scenarios: u64,
    pub collisions: u64,
    pub collision_rate: f64,
    pub mean_risk: f64,
    pub max_risk: f64,
}

/// `metrics.json`: everything measured, nothing from the wall clock (same seed → same bytes).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct RunMetrics {
    pub seed: u64,
    pub config: RunConfig,
    pub generation: GenerateReport,
    pub rounds: Vec<RoundReport>,
    pub by_kind: BTreeMap<ScenarioKind, KindSummary>,
    pub top: Vec<RankedScenario>,
    pub heatmaps: Vec<String>,
}

fn load_config(args: &RunArgs) -> CliResult<RunConfig> {
    let mut config = match &args.config {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .map_err(|e| CliError::input(format!("cannot read config {}: {e}", path.display())))?;
            serde_json::from_str(&text).map_err(|e| CliError::input(format!("config {}: {e}", path.display())))?
        }
        None if args.quick => RunConfig::quick(),
        None => RunConfig::default(),
    };
    if let Some(n) = args.iterations {
        config.iterations = n;
    }
    config.validate().map_err(|e| match &args.config {
        Some(path) => CliError::input(format!("config {}: {e}", path.display())),
        None => CliError::input(e),
    })?;
    Ok(config)
}

/// `./risktwin-out/<UTC timestamp>`.
fn default_out_dir() -> PathBuf {
    let secs = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs());
    let (days, rem) = (secs / 86_400, secs % 86_400);
    // Civil date from days since 1970-01-01 (Howard Hinnant's algorithm).
    let z = days as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    PathBuf::from("risktwin-out").join(format!(
        "{year:04}{month:02}{day:02}-{:02}{:02}{:02}",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    ))
}

fn prepare_out_dir(dir: &Path) -> CliResult {
    std::fs::create_dir_all(dir).map_err(|e| CliError::input(format!("cannot create {}: {e}", dir.display())))?;
    let db = dir.join("library.db");
    if db.exists() {
        return Err(CliError::input(format!("{} already exists; choose a fresh --out", db.display())));
    }
    Ok(())
}

/// One round of neighbourhood search around the library's failures.
fn mutation_round(
    library: &mut ScenarioLibrary,
    config: &RunConfig,
    round: u32,
    rng: &mut Rng,
) -> Result<RoundReport, String> {
    let parents = library.select_for_mutation(config.mutations_per_iteration, rng).map_err(|e| e.to_string())?;
    let mut children: Vec<(String, ScenarioSpec)> = Vec::new();
    let mut infeasible_children = 0;
    let mut parent_risk = 0.0;
    for parent in &parents {
        parent_risk += parent.risk.score;
        let spec = library.get(&parent.id).map_err(|e| e.to_string())?.map(|s| s.spec);
        let Some(spec) = spec else { continue };
        match mutate(&spec, config.mutation_radius, rng) {
            Ok(child) => children.push((parent.id.clone(), child)),
            Err(_) => infeasible_children += 1,
        }
    }
    let (parent_ids, specs): (Vec<String>, Vec<ScenarioSpec>) = children.into_iter().unzip();
    let evaluated = evaluate_all(specs, worker_threads());
    let records: Vec<ScenarioRecord> = evaluated
        .iter()
        .zip(&parent_ids)
        .map(|(e, pid)| ScenarioRecord::mutated(e.spec.clone(), pid, reference_outcome(&e.result)))
        .collect();
    library.insert_batch(&records).map_err(|e| e.to_string())?;
    let n = evaluated.len().max(1) as f64;
    Ok(RoundReport {
        round,
        parents: parents.len(),
        children: evaluated.len(),
        infeasible_children,
        parent_mean_risk: parent_risk / parents.len().max(1) as f64,
        child_mean_risk: evaluated.iter().map(|e| e.result.risk.score).sum::<f64>() / n,
        child_collisions: evaluated.iter().filter(|e| e.result.metrics.collision).count(),
    })
}

fn summarise(library: &ScenarioLibrary) -> Result<BTreeMap<ScenarioKind, KindSummary>, String> {
    let mut out = BTreeMap::new();
    for kind in ScenarioKind::ALL {
        let all = library.rank(None, Some(kind)).map_err(|e| e.to_string())?;
        let n = all.len() as u64;
        let collisions = all.iter().filter(|r| r.outcome.collision).count() as u64;
        let mean_risk = all.iter().map(|r| r.risk.score).sum::<f64>() / (n.max(1) as f64);
        let max_risk = all.iter().map(|r| r.risk.score).fold(0.0, f64::max);
        let collision_rate = collisions as f64 / n.max(1) as f64;
        out.insert(kind, KindSummary { scenarios: n, collisions, collision_rate, mean_risk, max_risk });
    }
    Ok(out)
}

pub fn run(args: RunArgs) -> CliResult {
    let config = load_config(&args)?;
    let out = args.out.clone().unwrap_or_else(default_out_dir);
    prepare_out_dir(&out)?;
    let mut library = ScenarioLibrary::open(out.join("library.db")).map_err(CliError::runtime)?;
    let threads = worker_threads();

    eprintln!("[1/4] generating {} candidates per kind on {threads} threads", config.count_per_kind);
    let batch = generate(&ScenarioKind::ALL, config.count_per_kind, args.seed, threads);
    let generation = store(&mut library, &ScenarioKind::ALL, &batch).map_err(CliError::runtime)?;

    let mut rng = Rng::derive(args.seed, 0x4D55_5441);
    let mut rounds = Vec::new();
    for round in 1..=config.iterations {
        eprintln!("[2/4] mutation round {round}/{}", config.iterations);
        rounds.push(mutation_round(&mut library, &config, round, &mut rng).map_err(CliError::runtime)?);
    }

    eprintln!("[3/4] ranking and drawing risk fields");
    let top = library.rank(Some(config.top_k), None).map_err(CliError::runtime)?;
    let mut heatmaps = Vec::new();
    for (i, r) in top.iter().take(config.heatmaps).enumerate() {
        let spec = library.get(&r.id).map_err(CliError::runtime)?.map(|s| s.spec);
        let Some(spec) = spec else { continue };
        let result = risktwin_common::episode::evaluate(&spec);
        // The moment just before the end: the collision, the closest approach or the finish.
        let t = (result.metrics.steps as f64 * STEP_S - 1.0).max(0.0);
        let snap = field_snapshot(&spec, t, 0.5, 160).map_err(CliError::runtime)?;
        let name = format!("risk_field_{}_{}.png", i + 1, r.kind);
        write_png(&out.join(&name), &render_heatmap(&snap.grid, &snap.road, &snap.others, &snap.ego, 4))?;
        heatmaps.push(name);
    }

    eprintln!("[4/4] writing the report to {}", out.display());
    let by_kind = summarise(&library).map_err(CliError::runtime)?;
    let metrics = RunMetrics { seed: args.seed, config, generation, rounds, by_kind, top, heatmaps };
    let json = serde_json::to_string_pretty(&metrics).map_err(CliError::runtime)?;
    std::fs::write(out.join("metrics.json"), json + "\n").map_err(CliError::runtime)?;
    std::fs::write(out.join("report.md"), report::markdown(&metrics)).map_err(CliError::runtime)?;

    match args.format {
        Format::Json => print_json(&metrics),
        _ => {
            let rows: Vec<Vec<String>> = metrics
                .by_kind
                .iter()
                .map(|(k, s)| {
                    vec![
                        k.to_string(),
                        s.scenarios.to_string(),
                        s.collisions.to_string(),
                        format!("{:.2}", s.collision_rate),
                        format!("{:.3}", s.mean_risk),
                        format!("{:.3}", s.max_risk),
                    ]
                })
                .collect();
            print_table(&["kind", "scenarios", "collisions", "collision_rate", "mean_risk", "max_risk"], &rows)?;
            println!("report: {}", out.join("report.md").display());
            Ok(())
        }
    }
}
