//! `risktwin bench`: throughput of the traffic simulator and of the risk field.
//!
//! The timing loop lives here, at the binary edge, because the domain core has no clock. The
//! peers (highway-env) are timed side by side by `deploy/bench/sim-vs-highway-env.sh`.

use crate::cli::{BenchRiskFieldArgs, BenchSimArgs};
use crate::error::{CliError, CliResult};
use crate::output::{Format, csv_float, print_json, print_table};
use risktwin_common::risk::bench_scene;
use risktwin_common::traffic::bench_traffic;
use serde::Serialize;
use std::time::Instant;

#[derive(Serialize)]
struct SimReport {
    vehicles: usize,
    steps: u64,
    vehicle_steps_per_s: f64,
    threads: usize,
    wall_s: f64,
    collisions: u64,
}

pub fn sim(args: BenchSimArgs) -> CliResult {
    if args.vehicles == 0 || args.steps == 0 {
        return Err(CliError::input("--vehicles and --steps must be positive"));
    }
    let threads = args.threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    if threads == 0 {
        return Err(CliError::input("--threads must be positive"));
    }
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(CliError::runtime)?;
    pool.install(|| time_traffic(args, threads))
}

fn time_traffic(args: BenchSimArgs, threads: usize) -> CliResult {
    let (road, mut traffic) = bench_traffic(args.vehicles, args.seed);
    let dt_s = 0.05;
    // Warm-up: let the initial placement settle so the timed steps are steady-state traffic.
    for k in 0..20 {
        traffic.step_threads(&road, k as f64 * dt_s, dt_s, &[], threads);
    }
    let mut collisions = 0u64;
    let start = Instant::now();
    for k in 0..args.steps {
        traffic.step_threads(&road, (20 + k) as f64 * dt_s, dt_s, &[], threads);
        collisions += traffic.collisions().len() as u64;
    }
    let wall_s = start.elapsed().as_secs_f64();
    let report = SimReport {
        vehicles: args.vehicles,
        steps: args.steps,
        vehicle_steps_per_s: (args.vehicles as f64 * args.steps as f64) / wall_s,
        threads,
        wall_s,
        collisions,
    };
    match args.format {
        Format::Json => print_json(&report),
        _ => print_table(
            &["vehicles", "steps", "threads", "vehicle_steps_per_s", "wall_s", "collisions"],
            &[vec![
                report.vehicles.to_string(),
                report.steps.to_string(),
                report.threads.to_string(),
                format!("{:.3e}", report.vehicle_steps_per_s),
                format!("{:.3}", report.wall_s),
                report.collisions.to_string(),
            ]],
        ),
    }
}

#[derive(Serialize)]
struct FieldReport {
    fields_per_s: f64,
    cells: usize,
    agents: usize,
    fields: u64,
    wall_s: f64,
}

pub fn risk_field(args: BenchRiskFieldArgs) -> CliResult {
    if args.agents == 0 || args.cols == 0 || args.rows == 0 || args.cols * args.rows > 16_777_216 {
        return Err(CliError::input("--agents, --cols and --rows must be positive (at most 16 M cells)"));
    }
    if !(args.seconds > 0.0 && args.seconds <= 600.0) {
        return Err(CliError::input("--seconds must be in (0, 600]"));
    }
    let mut scene = bench_scene(args.agents, args.cols, args.rows, 1);
    scene.evaluate();
    let mut fields = 0u64;
    let mut checksum = 0.0f64;
    let start = Instant::now();
    while start.elapsed().as_secs_f64() < args.seconds {
        for _ in 0..16 {
            checksum += f64::from(scene.evaluate());
        }
        fields += 16;
    }
    let wall_s = start.elapsed().as_secs_f64();
    // The checksum keeps the optimiser from discarding the work.
    if !checksum.is_finite() {
        return Err(CliError::runtime("risk field produced a non-finite value"));
    }
    let report = FieldReport {
        fields_per_s: fields as f64 / wall_s,
        cells: args.cols * args.rows,
        agents: args.agents,
        fields,
        wall_s,
    };
    match args.format {
        Format::Json => print_json(&report),
        _ => print_table(
            &["agents", "cells", "fields_per_s", "wall_s"],
            &[vec![
                report.agents.to_string(),
                report.cells.to_string(),
                csv_float(report.fields_per_s.round()),
                format!("{:.3}", report.wall_s),
            ]],
        ),
    }
}
