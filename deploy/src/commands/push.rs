//! `risktwin push scenario|policy`: send one cloud→edge push to an edge vehicle and print what
//! came of it as JSON. A scenario comes from the library (`--db FILE --id ID`) or a spec file
//! (`--spec FILE`); the command waits for the edge's `ScenarioResult` and prints it. A policy
//! update (`--weights FILE.safetensors`) is delivered; the edge validates it and reports what it
//! holds in its own summary.

use super::input_file::read_bounded;
use super::router::{transport_config, with_signals};
use super::source;
use crate::cli::{PushCommand, PushPolicyArgs, PushScenarioArgs, PushTo};
use crate::error::{CliError, CliResult};
use crate::output::print_json;
use risktwin_cloud::network::push::{PushError, PushTarget, push_policy, push_scenario};
use risktwin_edge::vehicle::push::MAX_WEIGHTS_BYTES;
use risktwin_store::library::content_id;
use risktwin_transport::{SiteId, SourceId};
use std::time::Duration;

pub fn push(command: PushCommand) -> CliResult {
    match command {
        PushCommand::Scenario(a) => scenario(a),
        PushCommand::Policy(a) => policy(a),
    }
}

fn seconds(flag: &str, s: f64) -> CliResult<Duration> {
    Duration::try_from_secs_f64(s).map_err(|_| CliError::input(format!("{flag} {s} must be a non-negative number")))
}

fn target(to: PushTo) -> CliResult<PushTarget> {
    Ok(PushTarget {
        transport: transport_config(to.zenoh)?,
        site: SiteId::new(to.site).map_err(CliError::input)?,
        edge: SourceId::new(to.to).map_err(CliError::input)?,
        wait_for_edge: seconds("--wait-for-edge-s", to.wait_for_edge_s)?,
    })
}

fn runtime(e: PushError) -> CliError {
    CliError::runtime(e)
}

fn scenario(args: PushScenarioArgs) -> CliResult {
    let spec = source::load(&args.source)?;
    // The library id when it came from the library; the content id (the id it would have
    // there) for a spec file.
    let spec_id = args.source.id.clone().unwrap_or_else(|| content_id(&spec));
    let wait = seconds("--wait-for-result-s", args.wait_for_result_s)?;
    let target = target(args.to)?;
    let report = with_signals(|shutdown| async move {
        push_scenario(&target, &spec_id, &spec, wait, shutdown).await.map_err(runtime)
    })?;
    print_json(&report)
}

fn policy(args: PushPolicyArgs) -> CliResult {
    // Every vehicle refuses an unsigned update: sending one would report a delivery that
    // changes nothing.
    let Some(key_file) = args.signing_key.as_deref() else {
        return Err(CliError::input(
            "--signing-key FILE is required: vehicles refuse unsigned policy updates (make a key pair with \
             `risktwin keys generate`, docs/signing.md)",
        ));
    };
    let signer = super::keys::read_signing_key(key_file)?;
    // Refused (exit 2) when larger than a vehicle takes, before it is read whole.
    let weights = read_bounded(&args.weights, MAX_WEIGHTS_BYTES as u64, "weights ")?;
    let target = target(args.to)?;
    let (id, version, algo) = (args.policy_id, args.version, args.algo);
    let report = with_signals(|shutdown| async move {
        push_policy(&target, &id, version, &algo, weights, Some(&signer), shutdown).await.map_err(runtime)
    })?;
    print_json(&report)
}
