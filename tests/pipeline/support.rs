//! Child processes (of the `risktwin` binary, or a peer's program) with their output read on threads, so that a test
//! can wait for a line or for the exit with a timeout instead of sleeping.

use serde_json::Value;
use std::io::{BufRead, BufReader, Read};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError, channel};
use std::time::{Duration, Instant};

/// A running child process.
pub struct Proc {
    pub name: String,
    child: Child,
    stderr_lines: Receiver<String>,
    stderr_seen: Vec<String>,
    stdout: Receiver<String>,
}

impl Proc {
    /// Starts `risktwin args…`.
    pub fn spawn(name: &str, args: &[&str]) -> Proc {
        let mut risktwin = Command::new(env!("CARGO_BIN_EXE_risktwin"));
        risktwin.args(args);
        Proc::spawn_command(name, risktwin)
    }

    /// Starts `command` (a peer's program as well as ours).
    pub fn spawn_command(name: &str, mut command: Command) -> Proc {
        let mut child = command
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| panic!("{name}: {command:?} does not start: {e}"));
        let (line_tx, stderr_lines) = channel();
        let stderr = child.stderr.take().expect("stderr is piped");
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                if line_tx.send(line).is_err() {
                    break;
                }
            }
        });
        let (out_tx, stdout) = channel();
        let mut out = child.stdout.take().expect("stdout is piped");
        // stdout is read to its end, which comes when the process exits: that is the exit signal.
        std::thread::spawn(move || {
            let mut text = String::new();
            let _ = out.read_to_string(&mut text);
            let _ = out_tx.send(text);
        });
        Proc { name: name.to_owned(), child, stderr_lines, stderr_seen: Vec::new(), stdout }
    }

    /// The first stderr line (seen before or arriving within `timeout`) that `matches`.
    pub fn wait_line(&mut self, timeout: Duration, matches: impl Fn(&str) -> bool) -> String {
        if let Some(line) = self.stderr_seen.iter().find(|l| matches(l)) {
            return line.clone();
        }
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.stderr_lines.recv_timeout(left) {
                Ok(line) => {
                    self.stderr_seen.push(line.clone());
                    if matches(&line) {
                        return line;
                    }
                }
                Err(RecvTimeoutError::Timeout) => {
                    panic!("{}: no matching stderr line in {timeout:?}:\n{}", self.name, self.stderr_seen.join("\n"))
                }
                Err(RecvTimeoutError::Disconnected) => {
                    panic!("{}: exited without the expected stderr line:\n{}", self.name, self.stderr_seen.join("\n"))
                }
            }
        }
    }

    /// Waits until `n` stderr lines (seen before or arriving within `timeout`) have matched.
    pub fn wait_count(&mut self, timeout: Duration, n: usize, matches: impl Fn(&str) -> bool) {
        let deadline = Instant::now() + timeout;
        while self.stderr_seen.iter().filter(|l| matches(l)).count() < n {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.stderr_lines.recv_timeout(left) {
                Ok(line) => self.stderr_seen.push(line),
                Err(e) => {
                    panic!("{}: {n} matching lines not seen ({e:?}):\n{}", self.name, self.stderr_seen.join("\n"))
                }
            }
        }
    }

    /// How many stderr lines seen so far (and already arrived) match.
    pub fn count_lines(&mut self, matches: impl Fn(&str) -> bool) -> usize {
        while let Ok(line) = self.stderr_lines.try_recv() {
            self.stderr_seen.push(line);
        }
        self.stderr_seen.iter().filter(|l| matches(l)).count()
    }

    /// Sends SIGTERM (through the `kill` command, which keeps the tests free of a libc binding).
    pub fn terminate(&self) {
        let status = Command::new("kill").args(["-TERM", &self.child.id().to_string()]).status().expect("kill runs");
        assert!(status.success(), "{}: kill -TERM failed", self.name);
    }

    /// Waits up to `timeout` for the exit; returns the status and stdout.
    pub fn wait_exit(&mut self, timeout: Duration) -> (ExitStatus, String) {
        let stdout = match self.stdout.recv_timeout(timeout) {
            Ok(text) => text,
            Err(_) => {
                let stderr = self.drain_stderr();
                panic!("{}: still running after {timeout:?}:\n{stderr}", self.name)
            }
        };
        let status = self.child.wait().expect("the child is waited for");
        (status, stdout)
    }

    /// Waits for a clean exit (status 0) and parses stdout as one JSON document.
    pub fn exit_json(&mut self, timeout: Duration) -> Value {
        let (status, stdout) = self.wait_exit(timeout);
        let stderr = self.drain_stderr();
        assert_eq!(status.code(), Some(0), "{} failed:\nstdout:\n{stdout}\nstderr:\n{stderr}", self.name);
        assert!(!stderr.contains("panicked"), "{} panicked:\n{stderr}", self.name);
        serde_json::from_str(&stdout).unwrap_or_else(|e| panic!("{}: stdout is not JSON ({e}):\n{stdout}", self.name))
    }

    /// The process id.
    pub fn id(&self) -> u32 {
        self.child.id()
    }

    /// Sends SIGKILL: the process dies without a word, as in a crash.
    pub fn kill(&mut self) {
        self.child.kill().expect("the child is killed");
    }

    /// Everything on stderr so far; once the process has exited, to the end (the reader thread
    /// may still hold the last lines when the exit is seen).
    pub fn drain_stderr(&mut self) -> String {
        let exited = matches!(self.child.try_wait(), Ok(Some(_)));
        let deadline = Instant::now() + Duration::from_secs(5);
        loop {
            let line = if exited {
                self.stderr_lines.recv_timeout(deadline.saturating_duration_since(Instant::now())).ok()
            } else {
                self.stderr_lines.try_recv().ok()
            };
            let Some(line) = line else { break };
            self.stderr_seen.push(line);
        }
        self.stderr_seen.join("\n")
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        // A failed test must not leave processes behind.
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// Starts a router on a free port and returns it with the locator it listens on.
pub fn start_router() -> (Proc, String) {
    start_router_at("tcp/127.0.0.1:0")
}

/// Starts a router listening on `listen` (`:0`: a free port) and returns it with the locator
/// it listens on, once it does.
pub fn start_router_at(listen: &str) -> (Proc, String) {
    start_router_with(listen, &[])
}

/// Starts a router listening on `listen` (`tcp/…` or `tls/…`) with `extra` arguments (its TLS
/// flags) and returns it with the locator it listens on, once it does.
pub fn start_router_with(listen: &str, extra: &[&str]) -> (Proc, String) {
    let mut args = vec!["router", "--listen", listen];
    args.extend(extra);
    let mut router = Proc::spawn("router", &args);
    let protocol = listen.split('/').next().expect("a protocol");
    let prefix = format!("listening on {protocol}/127.0.0.1:");
    let line = router.wait_line(Duration::from_secs(30), |l| l.starts_with(&prefix));
    let locator = line.trim_start_matches("listening on ").to_owned();
    assert!(!locator.ends_with(":0"), "the router reported port 0: {line}");
    (router, locator)
}

/// Runs `risktwin args…` to its exit (within a minute) and returns its JSON output.
pub fn run_json(args: &[&str]) -> Value {
    Proc::spawn(args[0], args).exit_json(Duration::from_secs(60))
}

/// A library of `count` generated cut-ins in `dir`: its path and the ranking as `scenarios rank`
/// prints it (best first).
pub fn cut_in_library(dir: &std::path::Path, count: usize) -> (String, Value) {
    let db = dir.join("lib.db").to_str().expect("a UTF-8 path").to_owned();
    let count = count.to_string();
    run_json(&["scenarios", "generate", "--kind", "cut-in", "--count", &count, "--db", &db, "--format", "json"]);
    let ranked = run_json(&["scenarios", "rank", "--db", &db, "--kind", "cut-in", "--format", "json"]);
    (db, ranked)
}

/// A TLS deployment's certificates (`risktwin certs init`) in a temporary folder.
pub struct Certs {
    pub dir: tempfile::TempDir,
}

impl Certs {
    /// A CA and a certificate for each of `identities` (`edge:<site>:<id>`, `cloud:<name>`, …).
    pub fn init(identities: &[&str]) -> Certs {
        let dir = tempfile::tempdir().expect("a temporary directory");
        let mut args = vec!["certs", "init", dir.path().to_str().expect("a UTF-8 path")];
        for identity in identities {
            args.extend(["--identity", identity]);
        }
        run_json(&args);
        Certs { dir }
    }

    /// The folder as an argument.
    pub fn path(&self) -> &str {
        self.dir.path().to_str().expect("a UTF-8 path")
    }

    /// `--tls-dir DIR --identity NAME`.
    pub fn flags<'a>(&'a self, identity: &'a str) -> [&'a str; 4] {
        ["--tls-dir", self.path(), "--identity", identity]
    }

    /// The files of `identity`, for a test's own session.
    pub fn security(&self, identity: &str) -> risktwin_transport::Security {
        risktwin_transport::Security::Tls(risktwin_transport::TlsFiles::in_dir(self.dir.path(), identity))
    }

    /// A router under TLS with the access rules of every identity here, on a free port.
    pub fn start_router(&self, identity: &str) -> (Proc, String) {
        start_router_with("tls/127.0.0.1:0", &self.flags(identity))
    }
}

/// A runtime for a test's own Zenoh session.
pub fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().expect("a tokio runtime")
}

/// The test's own Zenoh session, a peer connected to the router at `router`.
pub async fn session(router: &str) -> risktwin_transport::zenoh::Session {
    let config = risktwin_transport::TransportConfig { connect: vec![router.to_owned()], ..Default::default() };
    risktwin_transport::connect(&config).await.expect("the test session joins the router")
}

/// The test's own Zenoh session as a client of the router at `router`, secured by `security`.
pub async fn session_as(
    router: &str,
    security: risktwin_transport::Security,
) -> Result<risktwin_transport::zenoh::Session, risktwin_transport::TransportError> {
    let config = risktwin_transport::TransportConfig {
        mode: risktwin_transport::Mode::Client,
        connect: vec![router.to_owned()],
        connect_timeout: Duration::from_secs(5),
        security,
        ..Default::default()
    };
    risktwin_transport::connect(&config).await
}

/// `risktwin keys generate --out dir/name`: (signing key file, verifying key file).
pub fn keys(dir: &std::path::Path, name: &str) -> (String, String) {
    let out = dir.join(name);
    let printed = run_json(&["keys", "generate", "--out", out.to_str().expect("a UTF-8 path")]);
    let file = |k: &str| printed[k].as_str().expect("a key path").to_owned();
    (file("signing_key"), file("verifying_key"))
}
