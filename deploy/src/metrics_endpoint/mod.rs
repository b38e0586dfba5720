//! `--metrics-listen ADDR`: the process's Prometheus endpoint (docs/metrics.md).
//!
//! The recorder is `metrics-exporter-prometheus`'s; the endpoint is served here, on a thread of
//! its own, for two reasons the exporter's own listener cannot meet: the address it bound must
//! be printed (`:0` picks a free port), and each scrape first has the roles copy their summary
//! counts into the metrics ([`risktwin_transport::metrics::refresh`]), so a scrape shows the
//! numbers of that moment and the receive paths pay nothing for them.
//!
//! A role that ends (an edge whose count is sent, a stopped cloud) exports its final counts and,
//! when it has been scraped before, keeps serving them until one more scrape has taken them
//! ([`MetricsEndpoint::last_scrape`]), so a short run is not lost to Prometheus.

mod http;

use crate::cli::MetricsArgs;
use crate::error::{CliError, CliResult};
use metrics_exporter_prometheus::{Matcher, PrometheusBuilder, PrometheusHandle};
use risktwin_transport::sync::{CondvarExt, LockExt};
use risktwin_transport::wall_clock::unix_ns;
use std::net::{IpAddr, Ipv4Addr, SocketAddr, TcpListener};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

/// The longest a role that ends waits for its last scrape (Prometheus' default interval is 15 s).
const LAST_SCRAPE_MAX: Duration = Duration::from_secs(30);

/// Buckets of the twin's snapshot lag, s: the aligner waits 30 ms for late samples, so a
/// healthy twin lags tens of ms; the upper ones show a stalled one.
const LAG_BUCKETS_S: [f64; 12] = [0.005, 0.01, 0.02, 0.03, 0.05, 0.075, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0];

/// A served endpoint: its address and how often it was scraped.
pub struct MetricsEndpoint {
    scrapes: Arc<Scrapes>,
}

/// Scrapes served so far, for the wait for a last one.
#[derive(Default)]
struct Scrapes {
    seen: Mutex<ScrapeLog>,
    served: Condvar,
}

#[derive(Default, Clone, Copy)]
struct ScrapeLog {
    count: u64,
    last: Option<Instant>,
    /// The time between the last two scrapes.
    interval: Option<Duration>,
}

impl Scrapes {
    fn served(&self) {
        let mut log = self.seen.locked();
        let now = Instant::now();
        log.interval = log.last.map(|last| now.duration_since(last)).or(log.interval);
        log.last = Some(now);
        log.count += 1;
        self.served.notify_all();
    }
}

/// Starts the endpoint of `--metrics-listen` for a process running `role`, when the flag is
/// given; prints `metrics on http://ADDR/metrics` on stderr.
pub fn start(args: &MetricsArgs, role: &str) -> CliResult<Option<MetricsEndpoint>> {
    let Some(text) = args.metrics_listen.as_deref() else { return Ok(None) };
    let addr = parse_listen(text).map_err(|why| CliError::input(format!("--metrics-listen {text}: {why}")))?;
    if !addr.ip().is_loopback() {
        eprintln!(
            "warning: --metrics-listen {addr} serves beyond this host: the metrics are unauthenticated and \
             unencrypted; use a loopback address behind a proxy where that matters"
        );
    }
    let listener = TcpListener::bind(addr)
        .and_then(|l| l.set_nonblocking(true).map(|()| l))
        .map_err(|e| CliError::runtime(format!("--metrics-listen {text}: cannot listen: {e}")))?;
    let bound = listener.local_addr().map_err(CliError::runtime)?;
    let handle = install(role)?;
    let scrapes = Arc::new(Scrapes::default());
    let served = Arc::clone(&scrapes);
    std::thread::Builder::new()
        .name("metrics".into())
        .spawn(move || http::serve(listener, handle, move || served.served()))
        .map_err(CliError::runtime)?;
    eprintln!("metrics on http://{bound}/metrics");
    Ok(Some(MetricsEndpoint { scrapes }))
}

impl MetricsEndpoint {
    /// Once the role has ended and exported its final counts: when the endpoint has been
    /// scraped, waits for one more scrape (at most twice the last interval, never over
    /// [`LAST_SCRAPE_MAX`]) so that the final counts reach the scraper.
    pub fn last_scrape(self) {
        let log = *self.scrapes.seen.locked();
        if log.count == 0 {
            return;
        }
        let wait = log.interval.map_or(LAST_SCRAPE_MAX, |i| (i * 2).clamp(Duration::from_secs(1), LAST_SCRAPE_MAX));
        tracing::info!("metrics: serving the final counts until the next scrape (at most {:.1} s)", wait.as_secs_f64());
        let seen = self.scrapes.seen.locked();
        let (_seen, _) = self.scrapes.served.waited_while(seen, wait, |now| now.count == log.count);
    }
}

/// `--metrics-listen` as a socket address: `IP:PORT` (`[IPv6]:PORT`), `localhost:PORT` or a bare
/// `PORT` (on loopback, like every listener of ours without an explicit host).
fn parse_listen(text: &str) -> Result<SocketAddr, String> {
    let loopback = |port: &str| {
        port.parse::<u16>().map(|p| SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), p)).map_err(|e| e.to_string())
    };
    if !text.contains(':') {
        return loopback(text).map_err(|e| format!("not a port ({e})"));
    }
    if let Some(port) = text.strip_prefix("localhost:") {
        return loopback(port).map_err(|e| format!("not a port ({e})"));
    }
    text.parse::<SocketAddr>()
        .map_err(|_| "not an address: give IP:PORT ([IPv6]:PORT), localhost:PORT or a port".to_owned())
}

/// Installs the process's recorder (once) with the build's info; the handle renders scrapes.
fn install(role: &str) -> CliResult<PrometheusHandle> {
    let recorder = PrometheusBuilder::new()
        .set_buckets_for_metric(Matcher::Full("risktwin_twin_snapshot_lag_seconds".into()), &LAG_BUCKETS_S)
        .map_err(CliError::runtime)?
        .build_recorder();
    let handle = recorder.handle();
    metrics::set_global_recorder(recorder)
        .map_err(|_| CliError::runtime("a metrics recorder was already installed in this process"))?;
    risktwin_transport::metrics::enable();
    let version = env!("CARGO_PKG_VERSION");
    let commit = env!("RISKTWIN_COMMIT");
    metrics::gauge!("risktwin_build_info", "version" => version, "commit" => commit, "role" => role.to_owned())
        .set(1.0);
    let started_s = Duration::from_nanos(unix_ns() as u64).as_secs_f64();
    metrics::gauge!("process_start_time_seconds").set(started_s);
    Ok(handle)
}

#[cfg(test)]
mod tests {
    use super::parse_listen;

    #[test]
    fn listen_addresses_default_to_loopback_and_bad_ones_say_why() {
        assert_eq!(parse_listen("9464").unwrap().to_string(), "127.0.0.1:9464");
        assert_eq!(parse_listen("localhost:0").unwrap().to_string(), "127.0.0.1:0");
        assert_eq!(parse_listen("0.0.0.0:9464").unwrap().to_string(), "0.0.0.0:9464");
        assert_eq!(parse_listen("[::1]:9464").unwrap().to_string(), "[::1]:9464");
        for bad in ["", "70000", "host:9464", "127.0.0.1:", "127.0.0.1:x", "::1:9464", "tcp/127.0.0.1:9464"] {
            assert!(parse_listen(bad).is_err(), "{bad:?} accepted");
        }
    }
}
