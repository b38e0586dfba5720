//! `risktwin scenarios regress`: the regression gate by hand ([`risktwin_cloud::trainer::gate`]).

use super::driver::LoadedDriver;
use super::source::open_existing_library;
use crate::cli::RegressArgs;
use crate::error::{CliError, CliResult};
use crate::output::{Format, print_json, print_table};
use risktwin_cloud::generate::all_cores;
use risktwin_cloud::trainer::HeldOut;
use risktwin_cloud::trainer::gate::{GateReport, SetComparison, gate};
use serde::Serialize;

/// The gate's report and the drivers it compared, in the documented key order.
#[derive(Serialize)]
struct Labelled<'a> {
    #[serde(flatten)]
    report: &'a GateReport,
    candidate: &'a str,
    deployed: &'a str,
}

pub fn regress(args: RegressArgs) -> CliResult {
    if args.per_kind == 0 || args.per_kind > 1000 {
        return Err(CliError::input(format!("--per-kind {} is out of range [1, 1000]", args.per_kind)));
    }
    let library = open_existing_library(&args.db)?;
    let candidate = LoadedDriver::load(&args.driver, "--driver")?;
    let deployed = LoadedDriver::load(&args.against, "--against")?;
    let held_out = HeldOut::new(args.seed, args.per_kind as usize);
    let report =
        gate(&library, candidate.driver(), deployed.driver(), &held_out, all_cores()).map_err(CliError::runtime)?;
    candidate.warn_faults();
    deployed.warn_faults();
    match args.format {
        Format::Json => {
            print_json(&Labelled { report: &report, candidate: &candidate.label, deployed: &deployed.label })
        }
        _ => {
            let row = |set: &str, c: &SetComparison| {
                vec![
                    set.to_owned(),
                    c.scenarios.to_string(),
                    format!("{} / {}", c.candidate.collisions, c.deployed.collisions),
                    format!("{} / {}", c.candidate.successes, c.deployed.successes),
                    format!("{:.3} / {:.3}", c.candidate.mean_route_completion, c.deployed.mean_route_completion),
                ]
            };
            let header =
                ["set", "scenarios", "collisions (candidate / deployed)", "successes", "mean route completion"];
            println!("candidate: {}\ndeployed: {}", candidate.label, deployed.label);
            print_table(&header, &[row("regression", &report.regression), row("held-out", &report.held_out)])?;
            println!("decision: {:?}", report.decision);
            for reason in &report.reasons {
                println!("  {reason}");
            }
            Ok(())
        }
    }
}
