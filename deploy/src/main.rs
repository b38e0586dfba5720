//! `risktwin`: one binary, many roles. It parses arguments and calls library `run` functions;
//! everything it prints follows the contract in docs/cli.md.

mod cli;
mod commands;
mod emulate;
mod error;
mod logging;
mod metrics_endpoint;
mod output;
mod process_tuning;

// The topology parser lives in the library half of this package (see src/lib.rs).
use risktwin_deploy::topology;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    logging::init();
    // SAFETY: called once at start-up, before any other thread exists.
    unsafe {
        process_tuning::apply();
    }
    let args = match cli::Cli::try_parse() {
        Ok(args) => args,
        Err(e) => {
            use clap::error::ErrorKind;
            match e.kind() {
                ErrorKind::DisplayHelp | ErrorKind::DisplayVersion => {
                    let _ = e.print();
                    return ExitCode::SUCCESS;
                }
                ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => {
                    eprintln!("error: a subcommand is missing (see `risktwin --help`)");
                }
                _ => eprintln!("error: {}", one_line(&e.to_string())),
            }
            return ExitCode::from(error::BAD_INPUT_EXIT);
        }
    };
    if !args.command.uses_the_network() {
        // Like any Unix filter, stop quietly when the reader of stdout goes away (`| head`).
        // Never for a role with sockets: a TLS write to a peer that reset the connection
        // (`writev`, which has no MSG_NOSIGNAL) would kill it instead of failing the write.
        // SAFETY: still single-threaded (parsing arguments starts no thread).
        unsafe {
            libc::signal(libc::SIGPIPE, libc::SIG_DFL);
        }
    }
    match commands::dispatch(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}

/// Clap's message folded into the contract's single line: what is wrong and the argument it
/// names, without the usage and help hints.
fn one_line(text: &str) -> String {
    text.lines()
        .map(str::trim)
        .filter(|l| {
            !l.is_empty()
                && !l.starts_with("Usage:")
                && !l.starts_with("For more information")
                && !l.starts_with("tip:")
        })
        .map(|l| l.trim_start_matches("error: "))
        .collect::<Vec<_>>()
        .join(" ")
}
