//! `risktwin-pipeline`: the main job of RiskTwin, `risktwin run`, as a library. Named for what
//! it is — one pipeline that chains the other crates' roles — rather than for the command that
//! calls it, so that tests, benchmarks or another front end can run it too.
//!
//! The phases, in order: generate candidates of every scenario kind and score them with the
//! reference driver → mutate around the failures ([`search`]) → train the four variants (base /
//! risk-only / full / ttc; PPO, or SAC) over several seeds through the cloud's trainer and evaluate
//! them on a held-out set, next to its achievable floor (the privileged planner of
//! `common::planner`, [`floor`] in the report) → re-score the library's top scenarios with the trained policies
//! ([`rescore`]) → push the top scenarios and the `full` policy over Zenoh to an edge vehicle in
//! this process and compare what it reports ([`closed_loop`]) → draw the figures ([`figures`])
//! and write the report folder: report.md ([`report`]), metrics.json ([`RunMetrics`]: the same
//! seed gives the same bytes), training_curves.png, ablation.png, risk-field heatmaps,
//! library.db, one policy per variant, recording.mcap of the top scenario driven by the `full`
//! policy ([`recording`]) and loop.mcap of what the cloud ingested during the push phase.
//!
//! The caller chooses how progress is shown ([`Progress`]) and can stop the run between phases
//! through a [`Shutdown`] (the `risktwin` binary passes one that never fires: Ctrl-C ends the
//! process).
//!
//! ```no_run
//! use risktwin_pipeline::{RunConfig, RunRequest, Silent, run};
//!
//! let (_trigger, shutdown) = risktwin_transport::shutdown::channel();
//! let request = RunRequest { config: RunConfig::quick(), seed: 1, out_dir: "out".into() };
//! let done = run(&request, &mut Silent, &shutdown)?;
//! println!("{} scenarios ranked, report in {}", done.metrics.top.len(), done.report.display());
//! # Ok::<(), risktwin_pipeline::RunError>(())
//! ```

pub mod closed_loop;
mod config;
mod error;
pub mod fidelity;
pub mod figures;
pub mod floor;
mod metrics;
pub mod push_loop;
pub mod recording;
pub mod report;
pub mod rescore;
pub mod search;
pub mod v2x_sweep;
pub mod verdict;

pub use config::{ConfigError, RunConfig};
pub use error::RunError;
pub use metrics::RunMetrics;
pub use risktwin_transport::Shutdown;

use closed_loop::ClosedLoop;
use figures::HeatmapScene;
use risktwin_cloud::generate::{generate, store};
use risktwin_cloud::trainer::{HeldOut, evaluate_floor, run_ablation};
use risktwin_common::env::Variant;
use risktwin_common::episode::field_snapshot;
use risktwin_common::rng::Rng;
use risktwin_common::scenario::ScenarioKind;
use risktwin_common::world::STEP_S;
use risktwin_learn::PolicyNet;
use risktwin_store::library::{RankedScenario, ScenarioLibrary};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What to run: the knobs, the seed every random stream derives from, the report folder.
#[derive(Debug, Clone, PartialEq)]
pub struct RunRequest {
    pub config: RunConfig,
    pub seed: u64,
    /// Created if missing; refused if it holds a library.db already.
    pub out_dir: PathBuf,
}

/// How a run reports its progress: the phase lines (`[k/7] …`), a phase's steps, and the
/// events of the closed loop.
pub trait Progress {
    /// A phase begins (or, for `[5/7]`, is skipped): one line.
    fn phase(&mut self, line: &str);
    /// `done` of `total` steps of the long phase named `label`.
    fn advance(&mut self, label: &str, done: u64, total: u64);
    /// One event inside the current phase.
    fn detail(&mut self, line: &str);
}

/// A [`Progress`] that shows nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct Silent;

impl Progress for Silent {
    fn phase(&mut self, _line: &str) {}
    fn advance(&mut self, _label: &str, _done: u64, _total: u64) {}
    fn detail(&mut self, _line: &str) {}
}

/// What a finished run leaves: its metrics (also in metrics.json) and the report's path.
#[derive(Debug)]
pub struct RunOutcome {
    pub metrics: RunMetrics,
    /// `report.md` in the report folder.
    pub report: PathBuf,
}

/// Name of the metrics file in the report folder.
pub const METRICS_FILE: &str = "metrics.json";
/// Name of the report in the report folder.
pub const REPORT_FILE: &str = "report.md";
/// Name of the scenario library in the report folder.
pub const LIBRARY_FILE: &str = "library.db";

fn prepare_out_dir(dir: &Path) -> Result<(), RunError> {
    std::fs::create_dir_all(dir).map_err(|source| RunError::Create { path: dir.to_path_buf(), source })?;
    let db = dir.join(LIBRARY_FILE);
    if db.exists() {
        return Err(RunError::UsedOutDir { path: db });
    }
    Ok(())
}

/// Fails with [`RunError::Stopped`] once `shutdown` has fired.
fn check(shutdown: &Shutdown) -> Result<(), RunError> {
    if shutdown.is_fired() { Err(RunError::Stopped) } else { Ok(()) }
}

/// Risk-field heatmaps of the top scenarios at the moment just before each episode's end.
fn draw_heatmaps(
    library: &ScenarioLibrary,
    top: &[RankedScenario],
    n: usize,
    out: &Path,
) -> Result<Vec<String>, RunError> {
    let mut heatmaps = Vec::new();
    for (i, r) in top.iter().take(n).enumerate() {
        let spec = library.get(&r.id)?.map(|s| s.spec);
        let Some(spec) = spec else { continue };
        let result = risktwin_common::episode::evaluate(&spec);
        // The moment just before the end: the collision, the closest approach or the finish.
        let t = (result.metrics.steps as f64 * STEP_S - 1.0).max(0.0);
        let snap = field_snapshot(&spec, t, 0.5, 160)?;
        let name = format!("risk_field_{}_{}.png", i + 1, r.kind);
        let title = format!("Risk field of scenario {} ({}) at t = {:.1} s", r.id, r.kind, snap.time_s);
        figures::write_png(&out.join(&name), &figures::heatmap::heatmap(&HeatmapScene::of_snapshot(&snap, title))?)?;
        heatmaps.push(name);
    }
    Ok(heatmaps)
}

/// Runs the whole pipeline into `request.out_dir`. The config is taken as it is: validate it
/// first ([`RunConfig::validate`]).
pub fn run(request: &RunRequest, progress: &mut dyn Progress, shutdown: &Shutdown) -> Result<RunOutcome, RunError> {
    let RunRequest { config, seed, out_dir: out } = request;
    let (seed, algo, threads) = (*seed, config.training.algo, config.training.threads);
    prepare_out_dir(out)?;
    let started = Instant::now();
    let mut library = ScenarioLibrary::open(out.join(LIBRARY_FILE))?;
    let mut timings: Vec<(String, f64)> = Vec::new();
    let mut lap = Instant::now();
    let mut mark = |what: &str, lap: &mut Instant| {
        timings.push((what.to_string(), lap.elapsed().as_secs_f64()));
        *lap = Instant::now();
    };

    progress.phase(&format!("[1/7] generating {} candidates per kind on {threads} threads", config.count_per_kind));
    let batch = generate(&ScenarioKind::ALL, config.count_per_kind, seed, threads);
    let generation = store(&mut library, &ScenarioKind::ALL, &batch)?;
    let mut rng = Rng::derive(seed, 0x4D55_5441);
    let mut rounds = Vec::new();
    for round in 1..=config.iterations {
        check(shutdown)?;
        progress.advance(
            "[2/7] mutation rounds (reference driver)",
            u64::from(round) - 1,
            u64::from(config.iterations),
        );
        rounds.push(search::mutation_round(&mut library, config, round, &mut rng)?);
    }
    progress.advance("[2/7] mutation rounds (reference driver)", 1, 1);
    mark("generate, score and mutate", &mut lap);
    check(shutdown)?;

    let seeds = search::training_seeds(seed, config.seeds);
    let held_out = HeldOut::new(seed, config.eval_per_kind);
    progress.phase(&format!(
        "[3/7] training {} variants × {} seeds × {} steps ({algo}); held-out set: {} scenarios",
        Variant::ALL.len(),
        seeds.len(),
        config.training.steps,
        held_out.specs.len()
    ));
    let ablation =
        run_ablation(&config.training, &Variant::ALL, &seeds, &mut library, &held_out, &mut |label, done, total| {
            progress.advance(label, done, total)
        })?;
    mark("train and evaluate", &mut lap);
    check(shutdown)?;
    progress
        .detail(&format!("achievable floor: privileged planner on the {} held-out scenarios", held_out.specs.len()));
    let floor = evaluate_floor(&held_out.specs, &ablation.reference_episodes, threads);
    mark("achievable floor (privileged planner)", &mut lap);
    check(shutdown)?;

    progress.phase(&format!("[4/7] re-scoring the top {} scenarios with the trained policies", config.top_k));
    let top = library.rank(Some(config.top_k), None)?;
    let rescore = rescore::rescore(&mut library, &top, &ablation.policies, algo.name(), threads)?;
    let mut files = vec![REPORT_FILE.to_string(), METRICS_FILE.to_string(), LIBRARY_FILE.to_string()];
    for (variant, policy) in &ablation.policies {
        let name = format!("policy_{variant}.safetensors");
        policy.save(&out.join(&name))?;
        files.push(name);
    }

    let recorded = recording::record_top(&library, &top, &ablation.policies, out)?;
    if recorded.is_some() {
        files.push(recording::FILE.to_string());
    }
    mark("re-score and recording", &mut lap);
    check(shutdown)?;

    let (closed_loop, traffic) = push_phase(&library, &top, &ablation.policies, config, out, shutdown, progress)?;
    if closed_loop.is_some() {
        files.push(closed_loop::FILE.to_string());
        mark("closed loop over Zenoh", &mut lap);
    }
    check(shutdown)?;

    progress.phase("[6/7] drawing risk fields and charts");
    let heatmaps = draw_heatmaps(&library, &top, config.heatmaps, out)?;
    figures::write_png(&out.join(figures::TRAINING_CURVES_FILE), &figures::training_curves(&ablation)?)?;
    figures::write_png(&out.join(figures::ABLATION_FILE), &figures::ablation(&ablation)?)?;
    files.extend([figures::TRAINING_CURVES_FILE.to_string(), figures::ABLATION_FILE.to_string()]);
    files.extend(heatmaps.iter().cloned());
    mark("heatmaps and charts", &mut lap);

    progress.phase(&format!("[7/7] writing the report to {}", out.display()));
    let by_kind = search::summarise(&library)?;
    let verdict = verdict::judge(&ablation);
    let metrics = RunMetrics {
        seed,
        config: config.clone(),
        generation,
        rounds,
        by_kind,
        top,
        heatmaps,
        training_seeds: seeds,
        ablation,
        floor,
        verdict,
        rescore,
        recording: recorded,
        closed_loop,
        files,
    };
    let json = serde_json::to_string_pretty(&metrics)?;
    std::fs::write(out.join(METRICS_FILE), json + "\n")?;
    timings.push(("total".to_string(), started.elapsed().as_secs_f64()));
    let report = out.join(REPORT_FILE);
    std::fs::write(&report, report::markdown(&metrics, traffic.as_ref(), &timings))?;
    Ok(RunOutcome { metrics, report })
}

type PushPhase = (Option<ClosedLoop>, Option<push_loop::LoopOutput>);

/// Phase 5: the top scenarios and the `full` policy (as saved in the report folder) pushed to an
/// edge vehicle over Zenoh, in this process.
fn push_phase(
    library: &ScenarioLibrary,
    top: &[RankedScenario],
    policies: &[(Variant, PolicyNet)],
    config: &RunConfig,
    out: &Path,
    shutdown: &Shutdown,
    progress: &mut dyn Progress,
) -> Result<PushPhase, RunError> {
    let n = config.push_scenarios.min(top.len());
    let full = policies.iter().find(|(v, _)| *v == Variant::Full);
    let Some((variant, policy)) = full.filter(|_| n > 0) else {
        progress.phase(&format!(
            "[5/7] closed loop over Zenoh: skipped (push_scenarios {}, no full policy or no top scenario)",
            n
        ));
        return Ok((None, None));
    };
    progress.phase(&format!(
        "[5/7] closed loop over Zenoh: router, cloud ingest and edge vehicle {}/{} in this process; pushing {n} \
         scenario(s), then the {variant} policy, then the scenario(s) again",
        push_loop::SITE,
        push_loop::VEHICLE
    ));
    let weights_path = out.join(format!("policy_{variant}.safetensors"));
    let weights =
        std::fs::read(&weights_path).map_err(|source| RunError::Read { path: weights_path.clone(), source })?;
    let record = Some(out.join(closed_loop::FILE));
    let algo = config.training.algo.name();
    let mut detail = |line: &str| progress.detail(line);
    match closed_loop::push_phase(library, top, n, policy, weights, algo, record, shutdown, &mut detail)? {
        Some((closed, traffic)) => Ok((Some(closed), Some(traffic))),
        None => Ok((None, None)),
    }
}
