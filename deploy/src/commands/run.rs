//! `risktwin run`: the main job. Reads the config and flags, calls the pipeline
//! ([`risktwin_pipeline::run`]), shows its progress on stderr and prints the summary.

use super::input_file::{MAX_CONFIG_BYTES, read_text_bounded};
use super::run_progress::ProgressBar;
use crate::cli::RunArgs;
use crate::error::{CliError, CliResult};
use crate::output::{Format, print_json, print_table};
use risktwin_cloud::generate::all_cores;
use risktwin_cloud::trainer::{ReplayRule, Spread};
use risktwin_learn::Algo;
use risktwin_pipeline::{Progress, RunConfig, RunError, RunMetrics, RunRequest};
use std::path::PathBuf;

fn load_config(args: &RunArgs) -> CliResult<RunConfig> {
    let mut config = match &args.config {
        Some(path) => {
            let text = read_text_bounded(path, MAX_CONFIG_BYTES, "config ")?;
            RunConfig::from_json(&text).map_err(|e| CliError::input(format!("config {}: {e}", path.display())))?
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

/// `./risktwin-out/<UTC timestamp>` (`20261127-133700`).
fn default_out_dir() -> PathBuf {
    let stamp = risktwin_store::recordings::utc_stamp(std::time::SystemTime::now());
    PathBuf::from("risktwin-out").join(stamp.trim_end_matches('Z').replace('T', "-"))
}

/// The pipeline's progress on stderr: phase lines, a bar for the long phases, the closed loop's
/// events indented under its phase.
#[derive(Default)]
struct StderrProgress {
    bar: ProgressBar,
}

impl Progress for StderrProgress {
    fn phase(&mut self, line: &str) {
        self.bar.finish();
        eprintln!("{line}");
    }

    fn advance(&mut self, label: &str, done: u64, total: u64) {
        self.bar.update(label, done, total);
    }

    fn detail(&mut self, line: &str) {
        self.bar.finish();
        eprintln!("      {line}");
    }
}

pub fn run(args: RunArgs) -> CliResult {
    let mut config = load_config(&args)?;
    let algo: Algo = args.algo.parse().map_err(CliError::input)?;
    config.training.algo = algo;
    if config.training.warm_start && algo != Algo::Ppo {
        return Err(CliError::input(format!(
            "warm_start needs --algo ppo (it imitates with the feed-forward policy), not {algo}"
        )));
    }
    if config.training.cost_limit.is_some() && algo != Algo::Ppo {
        return Err(CliError::input(format!(
            "cost_limit needs --algo ppo (PPO-Lagrangian with the feed-forward policy), not {algo}"
        )));
    }
    if config.training.replay_rule == ReplayRule::Frontier && algo == Algo::Sac {
        return Err(CliError::input(
            "replay_rule \"frontier\" needs --algo ppo or ppo-gru (it samples with PPO's σ), not sac",
        ));
    }
    config.training.threads = all_cores();
    let request = RunRequest { config, seed: args.seed, out_dir: args.out.clone().unwrap_or_else(default_out_dir) };
    // Nothing fires it: Ctrl-C ends the process, as it always has for `run`.
    let (_trigger, shutdown) = risktwin_transport::shutdown::channel();
    let mut progress = StderrProgress::default();
    let done = risktwin_pipeline::run(&request, &mut progress, &shutdown)
        .map_err(|e: RunError| if e.is_input() { CliError::input(e) } else { CliError::runtime(e) })?;
    let metrics = &done.metrics;
    match args.format {
        Format::Json => print_json(metrics),
        _ => {
            print_table(&summary_header(), &summary_rows(metrics))?;
            if let Some(v) = &metrics.verdict {
                println!("{}", v.sentences[0]);
            }
            println!("report: {}", done.report.display());
            Ok(())
        }
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
