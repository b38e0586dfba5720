//! `risktwin bench fanout`: raw Zenoh's floor under a lockstep step ([`risktwin_bench::fanout`]);
//! its echo processes are children of this binary (`bench fanout --echo-connect …`, hidden).

use super::scene::{LOOPBACK, open};
use crate::cli::BenchFanoutArgs;
use crate::error::{CliError, CliResult};
use crate::output::{Format, print_json, print_table};
use risktwin_bench::fanout::{FanoutConfig, coordinate, echo};
use risktwin_transport::{Mode, TransportConfig, listening_locators};
use std::process::{Child, Command, Stdio};

pub fn fanout(args: BenchFanoutArgs) -> CliResult {
    if let Some(locator) = args.echo_connect {
        let transport = TransportConfig { mode: Mode::Peer, connect: vec![locator], ..TransportConfig::default() };
        let (_runtime, session) = open(&transport)?;
        return echo(&session, args.echo_id, args.reply_bytes).map_err(CliError::from);
    }
    let config = FanoutConfig {
        echoes: args.echoes,
        rounds: args.rounds,
        out_bytes: args.out_bytes,
        reply_bytes: args.reply_bytes,
    };
    config.check()?;
    let transport = TransportConfig { mode: Mode::Peer, listen: vec![LOOPBACK.into()], ..TransportConfig::default() };
    let (runtime, session) = open(&transport)?;
    let locator = runtime
        .block_on(listening_locators(&session))
        .into_iter()
        .next()
        .ok_or_else(|| CliError::runtime("the coordinator listens nowhere"))?;
    let exe = std::env::current_exe().map_err(CliError::runtime)?;
    let mut echoes = Echoes(Vec::new());
    for id in 0..args.echoes {
        let child = Command::new(&exe)
            .args(["bench", "fanout", "--echo-connect", &locator, "--echo-id", &id.to_string()])
            .args(["--reply-bytes", &args.reply_bytes.to_string()])
            // Its input stays open while this process lives: the echo exits when it ends.
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .spawn()
            .map_err(|e| CliError::runtime(format!("cannot start echo {id}: {e}")))?;
        echoes.0.push(child);
    }
    let report = coordinate(&session, config)?;
    match args.format {
        Format::Json => print_json(&report),
        _ => print_table(
            &["echoes", "rounds", "out bytes", "reply bytes", "ms/round"],
            &[vec![
                report.echoes.to_string(),
                report.rounds.to_string(),
                report.out_bytes.to_string(),
                report.reply_bytes.to_string(),
                format!("{:.3}", report.ms_per_round),
            ]],
        ),
    }
}

/// The echo processes: they run until their input ends, and are killed and reaped on drop.
struct Echoes(Vec<Child>);

impl Drop for Echoes {
    fn drop(&mut self) {
        for child in &mut self.0 {
            // Killing an exited child fails harmlessly; the wait reaps it either way.
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}
