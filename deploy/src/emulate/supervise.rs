//! Supervised processes: each runs in its own process group (so that a scene's participants go
//! with it), its stdout and stderr appended to its own files, and is started again by its
//! restart policy after a back-off (0.5 s, doubling to 8 s; back to 0.5 s after 10 s up).

use crate::error::BAD_INPUT_EXIT;
use crate::topology::Restart;
use std::fs::{File, OpenOptions};
use std::io;
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::PathBuf;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

const FIRST_BACKOFF: Duration = Duration::from_millis(500);
const MAX_BACKOFF: Duration = Duration::from_secs(8);
/// Up this long, a process's next failure starts the back-off over.
const STABLE: Duration = Duration::from_secs(10);

/// A process under supervision.
#[derive(Debug)]
pub struct Supervised {
    pub name: String,
    /// Program and arguments.
    pub command: Vec<String>,
    pub cwd: PathBuf,
    /// Where stdout (`.out`) and stderr (`.log`) go.
    pub log_stem: PathBuf,
    pub restart: Restart,
    child: Option<Child>,
    started: Instant,
    /// When to start it again (its policy wants it back).
    again_at: Option<Instant>,
    backoff: Duration,
    /// Starts after the first.
    pub restarts: u32,
    /// How each run ended (`exit 0`, `signal 9`, …), in order.
    pub ends: Vec<String>,
    /// Stopped by the supervisor: not started again.
    stopped: bool,
}

/// `status` in words.
fn ended(status: ExitStatus) -> String {
    match (status.code(), status.signal()) {
        (Some(c), _) => format!("exit {c}"),
        (None, Some(s)) => format!("signal {s}"),
        _ => "ended".to_owned(),
    }
}

impl Supervised {
    pub fn new(name: String, command: Vec<String>, cwd: PathBuf, log_stem: PathBuf, restart: Restart) -> Self {
        Supervised {
            name,
            command,
            cwd,
            log_stem,
            restart,
            child: None,
            started: Instant::now(),
            again_at: None,
            backoff: FIRST_BACKOFF,
            restarts: 0,
            ends: Vec::new(),
            stopped: false,
        }
    }

    fn log(&self, ext: &str) -> io::Result<File> {
        OpenOptions::new().create(true).append(true).open(self.log_stem.with_extension(ext))
    }

    /// Starts the process.
    pub fn start(&mut self) -> io::Result<()> {
        let (program, args) = self.command.split_first().ok_or_else(|| io::Error::other("an empty command"))?;
        let mut command = Command::new(program);
        command.args(args).current_dir(&self.cwd).stdin(Stdio::null()).stdout(self.log("out")?);
        command.stderr(self.log("log")?).process_group(0);
        // SAFETY: prctl between fork and exec touches no memory of this process. The signal
        // takes the child with the supervisor however it dies (kept across exec, also through
        // `ip netns exec`).
        unsafe {
            command.pre_exec(|| {
                if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL) != 0 {
                    return Err(io::Error::last_os_error());
                }
                Ok(())
            });
        }
        let child = command.spawn().map_err(|e| io::Error::other(format!("starting {}: {e}", self.name)))?;
        self.child = Some(child);
        self.started = Instant::now();
        self.again_at = None;
        self.stopped = false;
        Ok(())
    }

    pub fn pid(&self) -> Option<u32> {
        self.child.as_ref().map(Child::id)
    }

    pub fn running(&self) -> bool {
        self.child.is_some()
    }

    /// Ended for good: not running and not to be started again.
    pub fn done(&self) -> bool {
        self.child.is_none() && self.again_at.is_none()
    }

    /// Sees whether it ended, and starts it again when its policy and back-off say so. Returns
    /// what happened, for the timeline.
    pub fn poll(&mut self, now: Instant) -> Option<String> {
        if let Some(child) = &mut self.child
            && let Ok(Some(status)) = child.try_wait()
        {
            self.child = None;
            let how = ended(status);
            self.ends.push(how.clone());
            let failed = !status.success();
            // Exit 2 is a refused input (the CLI's contract): the same command would be refused again.
            let refused = status.code() == Some(i32::from(BAD_INPUT_EXIT));
            let again = !self.stopped
                && match self.restart {
                    Restart::Always => true,
                    Restart::OnFailure => failed && !refused,
                    Restart::Never => false,
                };
            if again {
                if now.duration_since(self.started) >= STABLE {
                    self.backoff = FIRST_BACKOFF;
                }
                self.again_at = Some(now + self.backoff);
                let note = format!("{} ended ({how}); restart in {:.1} s", self.name, self.backoff.as_secs_f64());
                self.backoff = (self.backoff * 2).min(MAX_BACKOFF);
                return Some(note);
            }
            if refused && failed && self.restart == Restart::OnFailure && !self.stopped {
                return Some(format!("{} ended ({how}: its input was refused, see its log; not restarted)", self.name));
            }
            return Some(format!("{} ended ({how})", self.name));
        }
        if self.again_at.is_some_and(|t| now >= t) {
            self.restarts += 1;
            return Some(match self.start() {
                Ok(()) => format!("{} restarted", self.name),
                Err(e) => {
                    self.again_at = Some(now + self.backoff);
                    format!("{e}")
                }
            });
        }
        None
    }

    /// Sends `signal` to its process group.
    pub fn signal(&self, signal: i32) {
        if let Some(pid) = self.pid() {
            signal_group(pid, signal);
        }
    }

    /// Kills it (a crash: its policy decides whether it comes back).
    pub fn kill(&mut self) {
        self.signal(libc::SIGKILL);
    }

    /// Stops it for good: SIGTERM, then SIGKILL after `grace`. Waits for it.
    pub fn stop(&mut self, grace: Duration) {
        stop_all(&mut [self], grace);
    }
}

/// Stops every process of `all` for good, at once: SIGTERM to each, then SIGKILL to those still
/// running after `grace`, then to whatever else their groups hold.
pub fn stop_all(all: &mut [&mut Supervised], grace: Duration) {
    let mut running: Vec<(usize, Child)> = Vec::new();
    for (k, s) in all.iter_mut().enumerate() {
        s.stopped = true;
        s.again_at = None;
        if let Some(child) = s.child.take() {
            signal_group(child.id(), libc::SIGTERM);
            running.push((k, child));
        }
    }
    let deadline = Instant::now() + grace;
    while !running.is_empty() {
        let past = Instant::now() >= deadline;
        running.retain_mut(|(k, child)| {
            let status = match child.try_wait() {
                Ok(Some(status)) => Some(status),
                Ok(None) if !past => return true,
                _ => {
                    signal_group(child.id(), libc::SIGKILL);
                    child.wait().ok()
                }
            };
            // Whatever else the group holds goes too (the exited leader's group stays
            // reserved while members live).
            signal_group(child.id(), libc::SIGKILL);
            all[*k].ends.push(status.map_or_else(|| "lost".to_owned(), ended));
            false
        });
        if !running.is_empty() {
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

/// Sends `signal` to the process group `pid` leads.
fn signal_group(pid: u32, signal: i32) {
    // SAFETY: a signal to a group this supervisor made for a child; a gone group just fails.
    unsafe { libc::kill(-(pid as i32), signal) };
}

impl Drop for Supervised {
    /// However the deployment ends, no process of it is left.
    fn drop(&mut self) {
        if let Some(mut child) = self.child.take() {
            signal_group(child.id(), libc::SIGKILL);
            let _ = child.wait();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sh(script: &str, restart: Restart, dir: &std::path::Path) -> Supervised {
        let command = vec!["sh".into(), "-c".into(), script.into()];
        Supervised::new("t/sh".into(), command, dir.into(), dir.join("sh"), restart)
    }

    fn poll_until(p: &mut Supervised, what: impl Fn(&Supervised) -> bool) {
        let deadline = Instant::now() + Duration::from_secs(10);
        while !what(p) {
            assert!(Instant::now() < deadline, "{p:?}");
            p.poll(Instant::now());
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    #[test]
    fn a_refused_input_is_not_restarted_on_failure() {
        let dir = tempfile::tempdir().expect("a temp dir");
        let mut p = sh("exit 2", Restart::OnFailure, dir.path());
        p.start().expect("starts");
        poll_until(&mut p, Supervised::done);
        assert_eq!((p.restarts, p.ends.as_slice()), (0, ["exit 2".to_owned()].as_slice()));
    }

    #[test]
    fn a_failure_is_restarted_and_a_success_is_not() {
        let dir = tempfile::tempdir().expect("a temp dir");
        let mut p = sh("echo run; exit 3", Restart::OnFailure, dir.path());
        p.start().expect("starts");
        poll_until(&mut p, |p| p.restarts == 1 && p.ends.len() == 2);
        p.stop(Duration::from_secs(1));
        assert!(p.ends.first().is_some_and(|e| e == "exit 3"), "{:?}", p.ends);
        let out = std::fs::read_to_string(dir.path().join("sh.out")).expect("stdout kept");
        assert!(out.starts_with("run\nrun"), "both runs' stdout appended: {out:?}");
        let mut q = sh("exit 0", Restart::OnFailure, dir.path());
        q.start().expect("starts");
        poll_until(&mut q, Supervised::done);
        assert_eq!((q.restarts, q.ends.as_slice()), (0, ["exit 0".to_owned()].as_slice()));
    }

    #[test]
    fn a_kill_is_a_failure_and_a_stop_takes_the_group() {
        let dir = tempfile::tempdir().expect("a temp dir");
        // A child of the process, as a scene's participants are.
        let mut p = sh("sleep 30 & echo $! > child; wait", Restart::OnFailure, dir.path());
        p.start().expect("starts");
        let pid_in = |dir: &std::path::Path| std::fs::read_to_string(dir.join("child")).ok();
        poll_until(&mut p, |_| pid_in(dir.path()).is_some_and(|s| s.ends_with('\n')));
        let first = pid_in(dir.path());
        p.kill();
        poll_until(&mut p, |_| pid_in(dir.path()).is_some_and(|s| s.ends_with('\n')) && pid_in(dir.path()) != first);
        assert_eq!((p.restarts, p.ends.as_slice()), (1, ["signal 9".to_owned()].as_slice()));
        let child: i32 = pid_in(dir.path()).expect("pid").trim().parse().expect("a pid");
        p.stop(Duration::from_secs(2));
        std::thread::sleep(Duration::from_millis(100));
        // SAFETY: signal 0 only asks whether the process exists.
        let alive = unsafe { libc::kill(child, 0) } == 0;
        let zombie = std::fs::read_to_string(format!("/proc/{child}/stat")).is_ok_and(|s| s.contains(") Z"));
        assert!(!alive || zombie, "the group's other processes are gone");
        assert!(p.done());
    }
}
