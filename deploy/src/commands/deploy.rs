//! `risktwin deploy up|status|down|run FILE`: a topology file run as an emulated deployment
//! (`crate::emulate`). `run` is the deployment in the foreground; `up` starts `run` in the
//! background (its own session, so the terminal's signals do not reach it) and returns once
//! it is up; `down` signals it, waits until it has written its report and let go of its lock,
//! and sweeps whatever a crash left, by the file's tag.
//!
//! The supervisor holds the deployment's lock (`<state>/lock`) for its whole life: that, not a
//! pid file, says whether a deployment of FILE is up; the pid file only says whom to signal.

use crate::cli::{DeployFileArgs, DeployHow, DeployRunArgs, DeployUpArgs};
use crate::emulate::deployment;
use crate::emulate::lock::Lock;
use crate::emulate::net;
use crate::emulate::options::{Options, STATE_DIR_PREFIX, prepare_state_dir, state_dir, tag_of, topology_digest};
use crate::error::{CliError, CliResult};
use crate::output::print_json;
use crate::topology::{Topology, parse};
use serde_json::{Value, json};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// How long `up` waits for the deployment to come up, and `down` for it to stop and report.
const UP_TIMEOUT: Duration = Duration::from_secs(120);
const DOWN_TIMEOUT: Duration = Duration::from_secs(180);

/// Set by SIGINT, SIGTERM or SIGHUP: the deployment stops.
static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: libc::c_int) {
    STOP.store(true, Ordering::Relaxed);
}

/// Reads and checks the topology file; every mistake is the user's (exit 2).
fn topology(file: &Path) -> CliResult<(String, Topology)> {
    let text = super::input_file::read_text_bounded(file, super::input_file::MAX_CONFIG_BYTES, "")?;
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

fn state(tag: &str) -> CliResult<PathBuf> {
    prepare_state_dir(tag).map_err(|e| CliError::runtime(format!("the deployment's state folder: {e}")))
}

/// The folder `--out` names, made and absolute (so that `status` and `down` find it from
/// anywhere).
fn out_dir(out: &Path) -> CliResult<PathBuf> {
    std::fs::create_dir_all(out)
        .and_then(|()| std::fs::canonicalize(out))
        .map_err(|e| CliError::input(format!("--out {}: {e}", out.display())))
}

pub fn run(args: DeployRunArgs) -> CliResult {
    let (text, t) = topology(&args.file)?;
    let duration = args.duration.as_deref().map(duration).transpose()?;
    let out = out_dir(&args.out)?;
    let tag = tag_of(&args.file);
    let exe = exe()?;
    let (state, lock) = take_state(&tag)?;
    let Some(lock) = lock else {
        return Err(CliError::input(format!(
            "{} is up already (`risktwin deploy down` it first)",
            args.file.display()
        )));
    };
    let write = |name: &str, bytes: &[u8]| std::fs::write(state.join(name), bytes).map_err(CliError::runtime);
    write(PID_FILE, std::process::id().to_string().as_bytes())?;
    write(OUT_FILE, out.as_os_str().as_encoded_bytes())?;
    write(DIGEST_FILE, topology_digest(text.as_bytes()).as_bytes())?;
    let options = Options {
        file: args.file,
        text,
        out: out.clone(),
        duration,
        seed: args.how.seed,
        exe,
        loopback: args.how.loopback,
        until_down: args.until_down,
    };
    // SAFETY: the handler only stores to an atomic; a closed stdout or stderr must not kill the
    // supervisor before its teardown.
    unsafe {
        let handler = on_signal as *const () as libc::sighandler_t;
        libc::signal(libc::SIGINT, handler);
        libc::signal(libc::SIGTERM, handler);
        libc::signal(libc::SIGHUP, handler);
        libc::signal(libc::SIGPIPE, libc::SIG_IGN);
    }
    let report = deployment::run(&t, &options, &STOP).map_err(CliError::runtime).and_then(|report| {
        report.write(&out).map_err(|e| CliError::runtime(format!("writing the report: {e}")))?;
        Ok(report)
    });
    // The lock goes after the report is written (`down` waits for that), with the state folder.
    remove_state(&state, lock);
    print_json(&report?)
}

/// The state folder of `tag` and its lock, `None` if a supervisor holds it. Made again if the
/// last supervisor removed it between the two.
fn take_state(tag: &str) -> CliResult<(PathBuf, Option<Lock>)> {
    loop {
        let dir = state(tag)?;
        match Lock::try_take(&dir.join(LOCK_FILE)) {
            Ok(lock) => return Ok((dir, lock)),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(CliError::runtime(e)),
        }
    }
}

/// Removes a deployment's state folder once its supervisor is done: its pid, where its output
/// is, its topology's digest, then the lock (held here, see [`Lock::remove`]) and the folder.
fn remove_state(dir: &Path, lock: Lock) {
    for name in [PID_FILE, OUT_FILE, DIGEST_FILE] {
        let _ = std::fs::remove_file(dir.join(name));
    }
    if let Err(e) = lock.remove(&dir.join(LOCK_FILE)) {
        tracing::warn!("removing {}: {e}", dir.join(LOCK_FILE).display());
    }
    if let Err(e) = std::fs::remove_dir(dir) {
        tracing::warn!("removing {}: {e}", dir.display());
    }
}

pub fn up(args: DeployUpArgs) -> CliResult {
    topology(&args.file)?;
    let tag = tag_of(&args.file);
    if supervisor(&tag)?.is_some() {
        return Err(CliError::input(format!(
            "{} is up already (`risktwin deploy down` it first)",
            args.file.display()
        )));
    }
    let out = out_dir(&args.out.unwrap_or_else(|| std::env::temp_dir().join(format!("risktwin-out-{tag}"))))?;
    let _ = std::fs::remove_file(out.join("status.json"));
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
                // SIGTERM first: the supervisor tears down what it made.
                // SAFETY: a signal to the child this call started.
                unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
                let _ = child.wait();
            }
            let log = std::fs::read_to_string(out.join("supervisor.log")).unwrap_or_default();
            let why = log.lines().rev().find(|l| l.starts_with("error: ")).unwrap_or("it did not come up in time");
            let why = format!("the deployment did not come up: {}", why.trim_start_matches("error: "));
            return Err(if ended.and_then(|s| s.code()) == Some(2) {
                CliError::input(why)
            } else {
                CliError::runtime(why)
            });
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The pid of the running supervisor of `tag`: `None` when nobody holds its lock (or there is
/// none: the last supervisor removed it on its way out).
fn supervisor(tag: &str) -> CliResult<Option<i32>> {
    let dir = state_dir(tag);
    if !Lock::is_held(&dir.join(LOCK_FILE)).map_err(CliError::runtime)? {
        return Ok(None);
    }
    let pid = std::fs::read_to_string(dir.join(PID_FILE)).ok().and_then(|p| p.trim().parse::<i32>().ok());
    // Held but not yet named (the supervisor is starting): 0 stands for "up, pid unknown".
    Ok(Some(pid.filter(|&p| p > 1).unwrap_or(0)))
}

/// The files of a deployment's state folder: the lock its supervisor holds, the supervisor's
/// pid, the output folder's path and the topology's digest.
const LOCK_FILE: &str = "lock";
const PID_FILE: &str = "supervisor.pid";
const OUT_FILE: &str = "out";
const DIGEST_FILE: &str = "topology-digest";

/// The tag of `file`'s deployment: by the file's path, or, when nothing of one is there (the
/// file was moved, or is named by another path), the one deployment whose topology has the
/// file's bytes and that is up or left something behind.
fn find_tag(file: &Path) -> CliResult<String> {
    let tag = tag_of(file);
    let there = |tag: &str| supervisor(tag).ok().flatten().is_some() || !net::leftovers(tag).is_empty();
    if there(&tag) {
        return Ok(tag);
    }
    let Ok(text) = std::fs::read(file) else { return Ok(tag) };
    let digest = topology_digest(&text);
    let mut up = Vec::new();
    for entry in std::fs::read_dir(std::env::temp_dir()).into_iter().flatten().flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some(other) = name.strip_prefix(STATE_DIR_PREFIX) else { continue };
        let same = std::fs::read_to_string(entry.path().join(DIGEST_FILE)).is_ok_and(|d| d == digest);
        // Another user's folder, or one that cannot be read, is not this deployment's.
        if same && there(other) {
            up.push(other.to_owned());
        }
    }
    match up.len() {
        0 => Ok(tag),
        1 => Ok(up.remove(0)),
        _ => Err(CliError::input(format!(
            "nothing of {} is up by its path, and {} deployments of the same topology are: name the file they were started from",
            file.display(),
            up.len()
        ))),
    }
}

/// Where the deployment's output is.
fn out_of(tag: &str) -> Option<PathBuf> {
    std::fs::read(state_dir(tag).join(OUT_FILE)).ok().map(|b| PathBuf::from(String::from_utf8_lossy(&b).into_owned()))
}

pub fn status(args: DeployFileArgs) -> CliResult {
    topology(&args.file)?;
    let tag = find_tag(&args.file)?;
    if supervisor(&tag)?.is_none() {
        return Err(CliError::runtime(format!("no deployment of {} is up", args.file.display())));
    }
    let status = out_of(&tag)
        .and_then(|out| std::fs::read_to_string(out.join("status.json")).ok())
        .and_then(|t| serde_json::from_str::<Value>(&t).ok())
        .ok_or_else(|| CliError::runtime("the deployment is starting (no status yet)"))?;
    print_json(&status)
}

pub fn down(args: DeployFileArgs) -> CliResult {
    // A file that no longer parses can still be taken down: only its path (or bytes) matter here.
    let tag = find_tag(&args.file)?;
    // Read now: the supervisor removes its state folder on its way out.
    let report = out_of(&tag).map(|o| o.join("report.md"));
    let was_up = supervisor(&tag)?;
    if let Some(pid) = was_up.filter(|&p| p > 1) {
        // SAFETY: a signal to the process that holds this deployment's lock and named itself.
        unsafe { libc::kill(pid, libc::SIGTERM) };
        let deadline = Instant::now() + DOWN_TIMEOUT;
        while supervisor(&tag)?.is_some() && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(50));
        }
        if supervisor(&tag)?.is_some() {
            // SAFETY: as above; its processes die with it (parent-death signal).
            unsafe { libc::kill(pid, libc::SIGKILL) };
        }
    }
    net::sweep(&tag);
    // A supervisor killed (by this or anything else) left its state folder.
    let dir = state_dir(&tag);
    if let Ok(Some(lock)) = Lock::try_take(&dir.join(LOCK_FILE)) {
        remove_state(&dir, lock);
    }
    let left = net::leftovers(&tag);
    if !left.is_empty() {
        return Err(CliError::runtime(format!("could not remove: {}", left.join(", "))));
    }
    let report = report.filter(|r| r.exists());
    print_json(&json!({ "down": true, "was_up": was_up.is_some(), "report": report }))
}
