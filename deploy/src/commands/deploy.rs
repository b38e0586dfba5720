//! `risktwin deploy up|status|down|run FILE`: a topology file run as an emulated deployment
//! (`crate::emulate`). `run` is the deployment in the foreground; `up` starts `run` in the
//! background (its own session, so the terminal's signals do not reach it) and returns once
//! it is up; `down` signals it, waits for its report, and sweeps whatever is left by the tag.

use crate::cli::{DeployFileArgs, DeployHow, DeployRunArgs, DeployUpArgs};
use crate::emulate::deployment::{self, DeployError, Options, state_dir, tag_of};
use crate::emulate::net;
use crate::error::{CliError, CliResult};
use crate::output::print_json;
use crate::topology::{Topology, parse};
use serde_json::{Value, json};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// How long `up` waits for the deployment to come up, and `down` for it to stop.
const UP_TIMEOUT: Duration = Duration::from_secs(90);
const DOWN_TIMEOUT: Duration = Duration::from_secs(90);

/// Set by SIGINT or SIGTERM: the deployment stops.
static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: libc::c_int) {
    STOP.store(true, Ordering::Relaxed);
}

/// Reads and checks the topology file; every mistake is the user's (exit 2).
fn topology(file: &Path) -> CliResult<(String, Topology)> {
    let text = std::fs::read_to_string(file).map_err(|e| CliError::input(format!("{}: {e}", file.display())))?;
    let t = parse(&text).map_err(|e| CliError::input(format!("{}: {e}", file.display())))?;
    Ok((text, t))
}

/// `90s`, `500ms`, `2m`, `1h` or plain seconds.
fn duration(text: &str) -> CliResult<Duration> {
    let bad = || CliError::input(format!("--for {text:?}: write a duration such as 90s, 500ms, 2m or 1h"));
    let (number, unit) = text.find(|c: char| c.is_ascii_alphabetic()).map_or((text, "s"), |k| text.split_at(k));
    let value: f64 = number.trim().parse().map_err(|_| bad())?;
    let seconds = match unit {
        "ms" => value / 1e3,
        "s" => value,
        "m" => value * 60.0,
        "h" => value * 3600.0,
        _ => return Err(bad()),
    };
    Duration::try_from_secs_f64(seconds).ok().filter(|d| !d.is_zero()).ok_or_else(bad)
}

fn exe() -> CliResult<PathBuf> {
    std::env::current_exe().map_err(|e| CliError::runtime(format!("finding the risktwin binary: {e}")))
}

pub fn run(args: DeployRunArgs) -> CliResult {
    let (text, t) = topology(&args.file)?;
    let duration = args.duration.as_deref().map(duration).transpose()?;
    std::fs::create_dir_all(&args.out).map_err(|e| CliError::input(format!("--out {}: {e}", args.out.display())))?;
    let options = Options {
        file: args.file,
        text,
        out: args.out.clone(),
        duration,
        seed: args.how.seed,
        exe: exe()?,
        loopback: args.how.loopback,
        until_down: args.until_down,
    };
    // SAFETY: the handler only stores to an atomic.
    unsafe {
        libc::signal(libc::SIGINT, on_signal as *const () as libc::sighandler_t);
        libc::signal(libc::SIGTERM, on_signal as *const () as libc::sighandler_t);
    }
    let report = deployment::run(&t, &options, &STOP).map_err(|e| match e {
        DeployError::Input(m) => CliError::input(m),
        DeployError::Runtime(m) => CliError::runtime(m),
    })?;
    report.write(&args.out).map_err(|e| CliError::runtime(format!("writing the report: {e}")))?;
    print_json(&report)
}

pub fn up(args: DeployUpArgs) -> CliResult {
    topology(&args.file)?;
    let tag = tag_of(&args.file);
    if supervisor(&tag).is_some() {
        return Err(CliError::input(format!(
            "{} is up already (`risktwin deploy down` it first)",
            args.file.display()
        )));
    }
    let state = state_dir(&tag);
    let out = args.out.unwrap_or_else(|| state.join("out"));
    std::fs::create_dir_all(&out).map_err(|e| CliError::input(format!("--out {}: {e}", out.display())))?;
    let _ = std::fs::remove_file(out.join("status.json"));
    std::fs::create_dir_all(&state).map_err(CliError::runtime)?;
    std::fs::write(state.join("out"), out.as_os_str().as_encoded_bytes()).map_err(CliError::runtime)?;
    let log = |name: &str| std::fs::File::create(out.join(name)).map_err(CliError::runtime);
    let DeployHow { seed, loopback } = args.how;
    let mut command = Command::new(exe()?);
    command.args(["deploy", "run", "--until-down", "--seed", &seed.to_string(), "--out"]).arg(&out).arg(&args.file);
    if loopback {
        command.arg("--loopback");
    }
    // SAFETY: setsid between fork and exec touches no memory of this process.
    let mut child = unsafe {
        command.stdin(Stdio::null()).stdout(log("supervisor.out")?).stderr(log("supervisor.log")?).pre_exec(|| {
            libc::setsid();
            Ok(())
        })
    }
    .spawn()
    .map_err(|e| CliError::runtime(format!("starting the supervisor: {e}")))?;
    let deadline = Instant::now() + UP_TIMEOUT;
    loop {
        if let Ok(text) = std::fs::read_to_string(out.join("status.json"))
            && let Ok(status) = serde_json::from_str::<Value>(&text)
        {
            return print_json(&json!({ "out": out, "status": status }));
        }
        let ended = child.try_wait().map_err(CliError::runtime)?;
        if ended.is_some() || Instant::now() > deadline {
            if ended.is_none() {
                let _ = child.kill();
                let _ = child.wait();
            }
            net::sweep(&tag);
            let log = std::fs::read_to_string(out.join("supervisor.log")).unwrap_or_default();
            let why = log.lines().rev().find(|l| l.starts_with("error: ")).unwrap_or("it did not come up in time");
            return Err(CliError::runtime(format!(
                "the deployment did not come up: {}",
                why.trim_start_matches("error: ")
            )));
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The pid of the running supervisor of `tag`, if one runs.
fn supervisor(tag: &str) -> Option<i32> {
    let pid: i32 = std::fs::read_to_string(state_dir(tag).join("supervisor.pid")).ok()?.trim().parse().ok()?;
    // SAFETY: signal 0 only asks whether the process exists.
    let alive = unsafe { libc::kill(pid, 0) } == 0;
    let zombie = std::fs::read_to_string(format!("/proc/{pid}/stat")).is_ok_and(|s| s.contains(") Z "));
    (alive && !zombie).then_some(pid)
}

/// Where `up` put the deployment's output.
fn out_of(tag: &str) -> Option<PathBuf> {
    std::fs::read(state_dir(tag).join("out")).ok().map(|b| PathBuf::from(String::from_utf8_lossy(&b).into_owned()))
}

pub fn status(args: DeployFileArgs) -> CliResult {
    topology(&args.file)?;
    let tag = tag_of(&args.file);
    let Some(_) = supervisor(&tag) else {
        return Err(CliError::runtime(format!("no deployment of {} is up", args.file.display())));
    };
    let status = out_of(&tag)
        .and_then(|out| std::fs::read_to_string(out.join("status.json")).ok())
        .and_then(|t| serde_json::from_str::<Value>(&t).ok())
        .ok_or_else(|| CliError::runtime("the deployment is starting (no status yet)"))?;
    print_json(&status)
}

pub fn down(args: DeployFileArgs) -> CliResult {
    // A file that no longer parses can still be taken down: only its path matters here.
    let tag = tag_of(&args.file);
    let out = out_of(&tag);
    let mut stopped = false;
    if let Some(pid) = supervisor(&tag) {
        // SAFETY: a signal to the supervisor this deployment's state names.
        unsafe { libc::kill(pid, libc::SIGTERM) };
        let deadline = Instant::now() + DOWN_TIMEOUT;
        while supervisor(&tag).is_some() && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(50));
        }
        if supervisor(&tag).is_some() {
            // SAFETY: as above.
            unsafe { libc::kill(pid, libc::SIGKILL) };
        }
        stopped = true;
    }
    // Processes a killed supervisor left (their process groups, by the last status).
    let status = out.as_ref().and_then(|o| std::fs::read_to_string(o.join("status.json")).ok());
    let pids = status
        .and_then(|t| serde_json::from_str::<Value>(&t).ok())
        .map(|v| v["processes"].as_array().into_iter().flatten().filter_map(|p| p["pid"].as_i64()).collect::<Vec<_>>());
    for pid in pids.unwrap_or_default() {
        // SAFETY: a signal to a process group the supervisor made; gone groups just fail.
        unsafe { libc::kill(-(pid as i32), libc::SIGKILL) };
    }
    net::sweep(&tag);
    let left = net::leftovers(&tag);
    let _ = std::fs::remove_file(state_dir(&tag).join("supervisor.pid"));
    if !left.is_empty() {
        return Err(CliError::runtime(format!("could not remove: {}", left.join(", "))));
    }
    print_json(&json!({ "down": true, "was_up": stopped, "report": out.map(|o| o.join("report.md")) }))
}
