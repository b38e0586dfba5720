//! `risktwin simulate`: one episode of a scenario with the driver `--driver` names.

use super::driver::{load_model, warn_faults};
use super::recorded::commonroad_input;
use super::source;
use crate::cli::SimulateArgs;
use crate::error::{CliError, CliResult};
use crate::output::{Format, csv_float, print_json, print_table};
use risktwin_cloud::episode_recording::EpisodeRecorder;
use risktwin_common::driver::Policy;
use risktwin_common::episode;
use risktwin_common::metrics::{EpisodeMetrics, RewardWeights};
use risktwin_common::world::{StepReport, World};
use risktwin_policy::spec::DriverSpec;

pub fn simulate(args: SimulateArgs) -> CliResult {
    if let Some(mut input) = commonroad_input(&args.source)? {
        let run = super::simulate_commonroad::simulate(&args, &mut input)?;
        return match args.format {
            Format::Json => print_json(&run.metrics),
            Format::Table | Format::Csv => print_metrics(&run.metrics, args.format),
        };
    }
    let spec = source::load(&args.source)?;
    let mut trace = args.trace.as_ref().map(|_| String::from(TRACE_HEADER));
    let (mut world, reference) = episode::with_reference_driver(&spec);
    if args.driver == DriverSpec::Replay {
        return Err(CliError::input(
            "--driver replay plays a recording's ego: give --commonroad FILE or a recorded case (--db, --id)",
        ));
    }
    let model = load_model(&args.driver)?;
    let mut driver: Box<dyn Policy> = match &model {
        Some(file) => Box::new(file.model.driver(world.desired_speed_mps, world.dt_s)),
        None => Box::new(reference),
    };
    let mut recorder = match &args.record {
        None => None,
        Some(path) => {
            let file = std::fs::File::create(path)
                .map_err(|e| CliError::input(format!("cannot create {}: {e}", path.display())))?;
            let mut rec = EpisodeRecorder::new(std::io::BufWriter::new(file), &world).map_err(CliError::runtime)?;
            rec.record(&world).map_err(CliError::runtime)?;
            Some(rec)
        }
    };
    let mut record_error = None;
    let result = episode::run_observed(&mut world, driver.as_mut(), &RewardWeights::default(), &mut |w, r| {
        if let Some(rows) = trace.as_mut() {
            trace_row(rows, w, r);
        }
        if let (Some(rec), None) = (recorder.as_mut(), &record_error) {
            record_error = rec.record(w).err();
        }
    });
    if let Some(file) = &model {
        warn_faults(&file.label(), &file.model);
    }
    if let Some(e) = record_error {
        return Err(CliError::runtime(e));
    }
    if let Some(rec) = recorder {
        rec.finish().map_err(CliError::runtime)?;
    }
    if let (Some(path), Some(rows)) = (&args.trace, trace) {
        std::fs::write(path, rows).map_err(|e| CliError::input(format!("cannot write {}: {e}", path.display())))?;
    }
    match args.format {
        Format::Json => print_json(&result.metrics),
        Format::Table | Format::Csv => print_metrics(&result.metrics, args.format),
    }
}

const TRACE_HEADER: &str =
    "time_s,x_m,y_m,heading_rad,speed_mps,accel_mps2,steer_rad,lane,perceived,min_distance_m,collision,offroad\n";

fn trace_row(rows: &mut String, w: &World, r: &StepReport) {
    use std::fmt::Write;
    let p = w.ego.pose();
    let lane = w.road.locate_heading(p.position(), p.heading_rad).lane;
    let _ = writeln!(
        rows,
        "{:.2},{:.3},{:.3},{:.4},{:.3},{:.3},{:.4},{lane},{},{},{},{}",
        w.time_s,
        p.x_m,
        p.y_m,
        p.heading_rad,
        w.ego.state.speed_mps,
        w.ego.state.accel_mps2,
        w.ego.state.steer_rad,
        w.perceived().len(),
        csv_float(r.contacts.min_distance_m),
        r.contacts.collision,
        r.contacts.offroad
    );
}

fn print_metrics(m: &EpisodeMetrics, format: Format) -> CliResult {
    let rows: Vec<(&str, String)> = vec![
        ("collision", m.collision.to_string()),
        ("offroad", m.offroad.to_string()),
        ("success", m.success.to_string()),
        ("route_completion", csv_float(m.route_completion)),
        ("avg_speed_mps", csv_float(m.avg_speed_mps)),
        ("steering_smoothness", csv_float(m.steering_smoothness)),
        ("longitudinal_smoothness", csv_float(m.longitudinal_smoothness)),
        ("min_ttc_s", m.min_ttc_s.map_or("inf".into(), csv_float)),
        ("min_distance_m", csv_float(m.min_distance_m)),
        ("risk_score", csv_float(m.risk_score)),
        ("reward", csv_float(m.reward)),
        ("steps", m.steps.to_string()),
    ];
    if format == Format::Csv {
        println!("{}", rows.iter().map(|r| r.0).collect::<Vec<_>>().join(","));
        println!("{}", rows.iter().map(|r| r.1.as_str()).collect::<Vec<_>>().join(","));
        return Ok(());
    }
    print_table(&["metric", "value"], &rows.into_iter().map(|(k, v)| vec![k.to_string(), v]).collect::<Vec<_>>())
}
