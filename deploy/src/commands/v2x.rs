//! `risktwin v2x channel`: the sidelink channel of `risktwin_v2x::channel` by distance;
//! `risktwin v2x sweep`: a grid of V2X experiments in virtual time (`risktwin_pipeline::v2x_sweep`).

use super::input_file::{MAX_CONFIG_BYTES, read_text_bounded};
use crate::cli::{V2xChannelArgs, V2xSweepArgs};
use crate::error::{CliError, CliResult};
use crate::output::{Format, csv_float, print_json, print_table};
use risktwin_pipeline::v2x_sweep;
use risktwin_v2x::channel::{ChannelPoint, LinkBudget, PathLoss};
use risktwin_v2x::sweep::SweepConfig;
use serde::Serialize;

#[derive(Serialize)]
struct ChannelReport {
    model: &'static str,
    parameters: LinkBudget,
    noise_dbm: f64,
    points: Vec<ChannelPoint>,
}

/// The path-loss model `name` given to `flag`.
pub(super) fn path_loss_of(flag: &str, name: &str) -> CliResult<PathLoss> {
    PathLoss::from_name(name).ok_or_else(|| {
        let names: Vec<&str> = PathLoss::ALL.iter().map(|m| m.name()).collect();
        CliError::input(format!("{flag} {name:?}: not one of {}", names.join(", ")))
    })
}

pub fn channel(args: V2xChannelArgs) -> CliResult {
    let model = path_loss_of("--model", &args.model)?;
    if let Some(d) = args.distance_m.iter().find(|d| !(d.is_finite() && **d >= 0.0)) {
        return Err(CliError::input(format!("--distance-m {d}: a distance is a finite number of metres ≥ 0")));
    }
    let d = LinkBudget::default();
    let budget = LinkBudget {
        carrier_ghz: args.carrier_ghz.unwrap_or(d.carrier_ghz),
        tx_power_dbm: args.tx_power_dbm.unwrap_or(d.tx_power_dbm),
        tx_antenna_gain_dbi: args.antenna_gain_dbi.unwrap_or(d.tx_antenna_gain_dbi),
        rx_antenna_gain_dbi: args.antenna_gain_dbi.unwrap_or(d.rx_antenna_gain_dbi),
        noise_figure_db: args.noise_figure_db.unwrap_or(d.noise_figure_db),
        bandwidth_hz: args.bandwidth_mhz.map_or(d.bandwidth_hz, |mhz| mhz * 1e6),
        sinr_threshold_db: args.sinr_threshold_db.unwrap_or(d.sinr_threshold_db),
    };
    budget.check().map_err(CliError::input)?;
    let points: Vec<ChannelPoint> = args.distance_m.iter().map(|&d| budget.at(model, d)).collect();
    match args.format {
        Format::Json => print_json(&ChannelReport {
            model: model.name(),
            parameters: budget,
            noise_dbm: budget.noise_dbm(),
            points,
        }),
        Format::Table | Format::Csv => {
            let header = ["distance_m", "path_loss_db", "shadowing_sigma_db", "snr_db", "pdr"];
            let rows: Vec<Vec<String>> = points
                .iter()
                .map(|p| {
                    let cells = [p.distance_m, p.path_loss_db, p.shadowing_sigma_db, p.snr_db, p.pdr];
                    cells
                        .iter()
                        .map(|&v| if args.format == Format::Csv { csv_float(v) } else { format!("{v:.4}") })
                        .collect()
                })
                .collect();
            if args.format == Format::Csv {
                println!("{}", header.join(","));
                rows.iter().for_each(|r| println!("{}", r.join(",")));
                Ok(())
            } else {
                print_table(&header, &rows)
            }
        }
    }
}

pub fn sweep(args: V2xSweepArgs) -> CliResult {
    let config = match &args.config {
        Some(path) => {
            let text = read_text_bounded(path, MAX_CONFIG_BYTES, "config ")?;
            serde_json::from_str::<SweepConfig>(&text)
                .map_err(|e| CliError::input(format!("config {}: {e}", path.display())))?
        }
        None => SweepConfig::default(),
    };
    let shown =
        args.config.as_ref().map_or_else(|| "the default grid".to_string(), |p| format!("config {}", p.display()));
    let grid = config.grid().map_err(|e| CliError::input(format!("{shown}: {e}")))?;
    eprintln!("v2x sweep: {} cells, {} episodes with V2X …", grid.cells.len(), grid.episodes());
    let started = std::time::Instant::now();
    let result = v2x_sweep::run(&config, grid, &args.out).map_err(CliError::runtime)?;
    let secs = started.elapsed().as_secs_f64();
    let episodes = result.episodes();
    println!(
        "{episodes} episodes with V2X in {secs:.1} s ({:.0} per minute); report: {}",
        episodes as f64 / secs.max(1e-9) * 60.0,
        args.out.join(v2x_sweep::REPORT_FILE).display()
    );
    Ok(())
}
