//! `risktwin run`: the main job, embedded. Generate → simulate → score → rank → mutate around
//! the failures (reference driver), then train the three variants (base / risk-only / full; PPO,
//! or SAC with `--algo sac`) over several seeds through the trainer role, evaluate them on a
//! held-out set, re-score the library's top scenarios with the trained policies, push the top
//! scenarios and the `full` policy over Zenoh to an edge vehicle in this process and compare
//! what it reports (`closed_loop`), and write the report folder (report.md, metrics.json,
//! training_curves.png, ablation.png, risk-field heatmaps, library.db, one policy per variant,
//! recording.mcap of the top scenario driven by the `full` policy, loop.mcap of what the cloud
//! ingested during the push phase).

use super::scenarios::worker_threads;
use crate::cli::RunArgs;
use crate::error::{CliError, CliResult};
use crate::output::{Format, print_json, print_table};
use crate::png_out::write_png;
use risktwin_cloud::generate::{GenerateReport, evaluate_all, generate, reference_outcome, store};
use risktwin_cloud::library::{RankedScenario, ScenarioLibrary, ScenarioRecord};
use risktwin_cloud::trainer::{AblationReport, HeldOut, Spread, TrainingPlan, run_ablation};
use risktwin_common::env::Variant;
use risktwin_common::episode::field_snapshot;
use risktwin_common::risk::render_heatmap;
use risktwin_common::rng::Rng;
use risktwin_common::scenario::{ScenarioKind, ScenarioSpec, mutate};
use risktwin_common::world::STEP_S;
use risktwin_learn::Algo;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

mod charts;
mod closed_loop;
mod config;
mod progress;
mod push_loop;
mod recording;
mod report;
mod rescore;
mod verdict;

use closed_loop::ClosedLoop;
pub use config::RunConfig;
use progress::ProgressBar;
use rescore::Rescore;
use verdict::Verdict;

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
#[derive(Debug, Clone, Serialize)]
pub struct RunMetrics {
    pub seed: u64,
    pub config: RunConfig,
    pub generation: GenerateReport,
    pub rounds: Vec<RoundReport>,
    pub by_kind: BTreeMap<ScenarioKind, KindSummary>,
    pub top: Vec<RankedScenario>,
    pub heatmaps: Vec<String>,
    /// The training seeds (derived from `seed`).
    pub training_seeds: Vec<u64>,
    pub ablation: AblationReport,
    /// The target checked against the ablation (absent when base or full was not trained).
    pub verdict: Option<Verdict>,
    /// The top scenarios driven again by each variant's policy.
    pub rescore: Vec<Rescore>,
    /// What `recording.mcap` holds (absent when nothing was recorded).
    pub recording: Option<String>,
    /// The push phase: what an edge vehicle reported over Zenoh, against the same episodes run
    /// here (absent when `push_scenarios` is 0).
    pub closed_loop: Option<ClosedLoop>,
    /// Files of the report folder.
    pub files: Vec<String>,
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

/// The training seeds of a run: a seed stream of their own.
fn training_seeds(seed: u64, n: u32) -> Vec<u64> {
    let mut rng = Rng::derive(seed, 0x5345_4544);
    (0..n).map(|_| rng.below(1_000_000)).collect()
}

fn plan(config: &RunConfig, algo: Algo, threads: usize) -> TrainingPlan {
    TrainingPlan {
        algo,
        steps: config.train_steps,
        n_envs: config.n_envs,
        phases: config.phases,
        curve_points: config.curve_points,
        replay_top: config.replay_top,
        background: config.background,
        replay_share: config.replay_share,
        mutations: config.failure_mutations,
        mutation_radius: config.mutation_radius,
        threads,
    }
}

/// Risk-field heatmaps of the top scenarios at the moment just before each episode's end.
fn draw_heatmaps(library: &ScenarioLibrary, top: &[RankedScenario], n: usize, out: &Path) -> CliResult<Vec<String>> {
    let mut heatmaps = Vec::new();
    for (i, r) in top.iter().take(n).enumerate() {
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
    Ok(heatmaps)
}

pub fn run(args: RunArgs) -> CliResult {
    let config = load_config(&args)?;
    let algo: Algo = args.algo.parse().map_err(CliError::input)?;
    if algo == Algo::PpoGru {
        return Err(CliError::input("--algo ppo-gru is not supported by run (expected ppo or sac)"));
    }
    let out = args.out.clone().unwrap_or_else(default_out_dir);
    prepare_out_dir(&out)?;
    let started = Instant::now();
    let mut library = ScenarioLibrary::open(out.join("library.db")).map_err(CliError::runtime)?;
    let threads = worker_threads();
    let mut timings: Vec<(String, f64)> = Vec::new();
    let mut lap = Instant::now();
    let mut mark = |what: &str, lap: &mut Instant| {
        timings.push((what.to_string(), lap.elapsed().as_secs_f64()));
        *lap = Instant::now();
    };

    eprintln!("[1/7] generating {} candidates per kind on {threads} threads", config.count_per_kind);
    let batch = generate(&ScenarioKind::ALL, config.count_per_kind, args.seed, threads);
    let generation = store(&mut library, &ScenarioKind::ALL, &batch).map_err(CliError::runtime)?;
    let mut rng = Rng::derive(args.seed, 0x4D55_5441);
    let mut rounds = Vec::new();
    let mut bar = ProgressBar::default();
    for round in 1..=config.iterations {
        bar.update("[2/7] mutation rounds (reference driver)", u64::from(round) - 1, u64::from(config.iterations));
        rounds.push(mutation_round(&mut library, &config, round, &mut rng).map_err(CliError::runtime)?);
    }
    bar.update("[2/7] mutation rounds (reference driver)", 1, 1);
    bar.finish();
    mark("generate, score and mutate", &mut lap);

    let seeds = training_seeds(args.seed, config.seeds);
    let held_out = HeldOut::new(args.seed, config.eval_per_kind);
    eprintln!(
        "[3/7] training {} variants × {} seeds × {} steps ({algo}); held-out set: {} scenarios",
        Variant::ALL.len(),
        seeds.len(),
        config.train_steps,
        held_out.specs.len()
    );
    let ablation = run_ablation(
        &plan(&config, algo, threads),
        &Variant::ALL,
        &seeds,
        &mut library,
        &held_out,
        &mut |label, done, total| bar.update(label, done, total),
    )
    .map_err(CliError::runtime)?;
    bar.finish();
    mark("train and evaluate", &mut lap);

    eprintln!("[4/7] re-scoring the top {} scenarios with the trained policies", config.top_k);
    let top = library.rank(Some(config.top_k), None).map_err(CliError::runtime)?;
    let rescore =
        rescore::rescore(&mut library, &top, &ablation.policies, algo.name(), threads).map_err(CliError::runtime)?;
    let mut files = vec!["report.md".to_string(), "metrics.json".to_string(), "library.db".to_string()];
    for (variant, policy) in &ablation.policies {
        let name = format!("policy_{variant}.safetensors");
        policy.save(&out.join(&name)).map_err(CliError::runtime)?;
        files.push(name);
    }

    let recorded = recording::record_top(&library, &top, &ablation.policies, &out)?;
    if recorded.is_some() {
        files.push(recording::FILE.to_string());
    }
    mark("re-score and recording", &mut lap);

    let (closed_loop, traffic) = push_phase(&library, &top, &ablation.policies, &config, algo, &out)?;
    if closed_loop.is_some() {
        files.push(closed_loop::FILE.to_string());
        mark("closed loop over Zenoh", &mut lap);
    }

    eprintln!("[6/7] drawing risk fields and charts");
    let heatmaps = draw_heatmaps(&library, &top, config.heatmaps, &out)?;
    write_png(&out.join("training_curves.png"), &charts::training_curves(&ablation))?;
    write_png(&out.join("ablation.png"), &charts::ablation(&ablation))?;
    files.extend(["training_curves.png".to_string(), "ablation.png".to_string()]);
    files.extend(heatmaps.iter().cloned());
    mark("heatmaps and charts", &mut lap);

    eprintln!("[7/7] writing the report to {}", out.display());
    let by_kind = summarise(&library).map_err(CliError::runtime)?;
    let verdict = verdict::judge(&ablation);
    let metrics = RunMetrics {
        seed: args.seed,
        config,
        generation,
        rounds,
        by_kind,
        top,
        heatmaps,
        training_seeds: seeds,
        ablation,
        verdict,
        rescore,
        recording: recorded,
        closed_loop,
        files,
    };
    let json = serde_json::to_string_pretty(&metrics).map_err(CliError::runtime)?;
    std::fs::write(out.join("metrics.json"), json + "\n").map_err(CliError::runtime)?;
    timings.push(("total".to_string(), started.elapsed().as_secs_f64()));
    std::fs::write(out.join("report.md"), report::markdown(&metrics, traffic.as_ref(), &timings))
        .map_err(CliError::runtime)?;

    match args.format {
        Format::Json => print_json(&metrics),
        _ => {
            print_table(&summary_header(), &summary_rows(&metrics))?;
            if let Some(v) = &metrics.verdict {
                println!("{}", v.sentences[0]);
            }
            println!("report: {}", out.join("report.md").display());
            Ok(())
        }
    }
}

type PushPhase = (Option<ClosedLoop>, Option<push_loop::LoopOutput>);

/// Phase 5: the top scenarios and the `full` policy (as saved in the report folder) pushed to an
/// edge vehicle over Zenoh, in this process.
fn push_phase(
    library: &ScenarioLibrary,
    top: &[RankedScenario],
    policies: &[(Variant, risktwin_learn::PolicyNet)],
    config: &RunConfig,
    algo: Algo,
    out: &Path,
) -> CliResult<PushPhase> {
    let n = config.push_scenarios.min(top.len());
    let full = policies.iter().find(|(v, _)| *v == Variant::Full);
    let Some((variant, policy)) = full.filter(|_| n > 0) else {
        eprintln!("[5/7] closed loop over Zenoh: skipped (push_scenarios {}, no full policy or no top scenario)", n);
        return Ok((None, None));
    };
    eprintln!(
        "[5/7] closed loop over Zenoh: router, cloud ingest and edge vehicle {}/{} in this process; pushing {n} \
         scenario(s), then the {variant} policy, then the scenario(s) again",
        push_loop::SITE,
        push_loop::VEHICLE
    );
    let weights_path = out.join(format!("policy_{variant}.safetensors"));
    let weights = std::fs::read(&weights_path)
        .map_err(|e| CliError::runtime(format!("cannot read {}: {e}", weights_path.display())))?;
    let record = Some(out.join(closed_loop::FILE));
    let mut progress = |line: &str| eprintln!("      {line}");
    match closed_loop::push_phase(library, top, n, policy, weights, algo.name(), record, &mut progress)
        .map_err(CliError::runtime)?
    {
        Some((closed, traffic)) => Ok((Some(closed), Some(traffic))),
        None => Ok((None, None)),
    }
}

fn summary_header() -> Vec<&'static str> {
    vec!["variant", "collision", "success", "completion", "speed_mps", "reward", "risk"]
}

/// One row per variant (mean ± std over seeds) and the reference driver.
fn summary_rows(m: &RunMetrics) -> Vec<Vec<String>> {
    let pm = |s: &Spread, p: usize| format!("{:.p$}±{:.p$}", s.mean, s.std);
    let mut rows: Vec<Vec<String>> = m
        .ablation
        .variants
        .iter()
        .map(|v| {
            let o = &v.overall;
            vec![
                v.variant.clone(),
                pm(&o.collision_rate, 2),
                pm(&o.success_rate, 2),
                pm(&o.route_completion, 2),
                pm(&o.avg_speed_mps, 1),
                pm(&o.reward, 0),
                pm(&o.risk_score, 3),
            ]
        })
        .collect();
    let r = &m.ablation.reference.overall;
    rows.push(vec![
        "idm (reference)".to_string(),
        format!("{:.2}", r.collision_rate),
        format!("{:.2}", r.success_rate),
        format!("{:.2}", r.route_completion),
        format!("{:.1}", r.avg_speed_mps),
        format!("{:.0}", r.reward),
        format!("{:.3}", r.risk_score),
    ]);
    rows
}
