//! `risktwin train`: trains a policy on the twin and writes it (safetensors, and its actor as
//! ONNX) and its training curves (CSV) into the output folder. Progress goes to stderr.
//!
//! `wall_s`, `env_steps_per_s` and `profile_s` (PPO's wall time in environment stepping, acting
//! and updates) are measurements and differ between runs; every other field
//! of the JSON is a function of the flags (same seed, same machine and thread count → same
//! values), which the CLI tests check.

use crate::cli::TrainArgs;
use crate::error::{CliError, CliResult};
use crate::output::{Format, print_json, print_table};
use risktwin_common::env::Variant;
use risktwin_learn::Algo;
use risktwin_learn::train::{TrainConfig, curves_csv, train as run_training};
use serde_json::json;
use std::io::Write;

pub fn train(args: TrainArgs) -> CliResult {
    let algo: Algo = args.algo.parse().map_err(CliError::input)?;
    let variant: Variant = args.variant.parse().map_err(CliError::input)?;
    if args.steps == 0 {
        return Err(CliError::input("--steps 0: must be positive"));
    }
    if args.warm_start && algo != Algo::Ppo {
        return Err(CliError::input(format!("--warm-start needs --algo ppo, not {algo}")));
    }
    std::fs::create_dir_all(&args.out)
        .map_err(|e| CliError::input(format!("cannot create {}: {e}", args.out.display())))?;
    let mut cfg = TrainConfig::new(algo, variant, args.steps, args.seed);
    cfg.benign_eval = args.benign;
    cfg.warm_start = args.warm_start;
    let mut last_pct = u64::MAX;
    let report = run_training(&cfg, &mut |done, total| {
        let pct = done * 100 / total.max(1);
        if pct / 5 != last_pct / 5 || done == total {
            last_pct = pct;
            let _ = write!(std::io::stderr(), "\rtrain {algo} {variant}: {done}/{total} steps ({pct}%)");
        }
    })
    .map_err(CliError::runtime)?;
    let _ = writeln!(std::io::stderr());
    let policy_path = args.out.join("policy.safetensors");
    report.policy.save(&policy_path).map_err(CliError::runtime)?;
    // The same actor as an ONNX model (docs/driver-interface.md), for other tools and runtimes.
    let onnx = report.policy.host().map_err(CliError::runtime)?.to_onnx();
    std::fs::write(args.out.join("policy.onnx"), onnx).map_err(CliError::runtime)?;
    std::fs::write(args.out.join("curves.csv"), curves_csv(&report.curve)).map_err(CliError::runtime)?;
    let doc = json!({
        "algo": algo.name(),
        "variant": variant.name(),
        "steps": report.steps,
        "wall_s": report.wall_s,
        "env_steps_per_s": report.env_steps_per_s,
        "benign_90_wall_s": report.benign_90_wall_s,
        "final": report.final_metrics,
        "profile_s": {
            "env": report.timings.env_s,
            "infer": report.timings.infer_s,
            "update": report.timings.update_s,
        },
    });
    match args.format {
        Format::Json => print_json(&doc),
        Format::Table | Format::Csv => {
            let f = &report.final_metrics;
            print_table(
                &[
                    "algo",
                    "variant",
                    "steps",
                    "wall_s",
                    "env_steps/s",
                    "success",
                    "collision",
                    "completion",
                    "speed_mps",
                ],
                &[vec![
                    algo.name().into(),
                    variant.name().into(),
                    report.steps.to_string(),
                    format!("{:.1}", report.wall_s),
                    format!("{:.0}", report.env_steps_per_s),
                    format!("{:.2}", f.success_rate),
                    format!("{:.2}", f.collision_rate),
                    format!("{:.2}", f.route_completion),
                    format!("{:.1}", f.avg_speed_mps),
                ]],
            )
        }
    }
}
