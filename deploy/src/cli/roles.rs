//! The grammar of the distributed roles: `risktwin router`, `edge …` and `cloud`, and how each
//! joins the Zenoh network.

use clap::{Args, Subcommand};
use risktwin_transport::recovery::DEFAULT_OUTAGE;
use std::path::PathBuf;

/// How a distributed role joins the Zenoh network.
#[derive(Debug, Args)]
pub struct ZenohArgs {
    /// Zenoh locator to connect to (`tcp/127.0.0.1:7447`); repeatable.
    #[arg(long = "connect", value_name = "ENDPOINT")]
    pub connect: Vec<String>,
    /// Zenoh locator to listen on; repeatable (default: a peer on loopback, a port the OS
    /// picks; none under TLS, where only routers listen).
    #[arg(long = "listen", value_name = "ENDPOINT")]
    pub listen: Vec<String>,
    /// `peer` or `client`.
    #[arg(long, default_value = "peer")]
    pub mode: String,
    /// Turn on UDP multicast scouting (off by default, see docs/keyexpr.md).
    #[arg(long)]
    pub multicast_scouting: bool,
    #[command(flatten)]
    pub tls: TlsArgs,
}

/// A rotating recording (docs/recordings.md): `cloud --record-dir`, `bench ingest --record-dir`.
#[derive(Debug, Args, Default, Clone)]
pub struct RecordDirArgs {
    /// Record as --record does, into MCAP segments in this folder (created if missing), each
    /// finished when the next opens, with a catalogue (catalogue.db; docs/recordings.md).
    #[arg(long, value_name = "DIR")]
    pub record_dir: Option<PathBuf>,
    /// A segment closes once its file reaches this many MiB (checked every 250 ms; default 256).
    #[arg(long, value_name = "MIB", requires = "record_dir")]
    pub segment_mb: Option<f64>,
    /// A segment closes once it is this many seconds old (default 600; at least 0.25).
    #[arg(long, value_name = "S", requires = "record_dir")]
    pub segment_s: Option<f64>,
    /// Delete closed segments closed longer ago than this many seconds.
    #[arg(long, value_name = "S", requires = "record_dir")]
    pub retain_s: Option<f64>,
    /// Delete the oldest closed segments while the folder's segments hold more than this many MiB.
    #[arg(long, value_name = "MIB", requires = "record_dir")]
    pub retain_mb: Option<f64>,
}

/// The role's Prometheus endpoint (docs/metrics.md).
#[derive(Debug, Args, Default, Clone)]
pub struct MetricsArgs {
    /// Serve Prometheus metrics at http://ADDR/metrics: `IP:PORT`, `localhost:PORT` or a port
    /// (on loopback); port 0 picks a free one. Unauthenticated: a non-loopback address warns.
    #[arg(long, value_name = "ADDR")]
    pub metrics_listen: Option<String>,
}

/// TLS with mutual authentication (docs/security.md); without these flags links are plain TCP.
#[derive(Debug, Args, Default, Clone)]
pub struct TlsArgs {
    /// A `risktwin certs` folder: use its CA and the certificate of --identity.
    #[arg(long, value_name = "DIR")]
    pub tls_dir: Option<PathBuf>,
    /// The identity to present from --tls-dir: `edge:<site>:<id>`, `cloud:<name>` or
    /// `router:<name>` (its certificate's common name).
    #[arg(long, value_name = "NAME", requires = "tls_dir")]
    pub identity: Option<String>,
    /// The CA certificate (PEM), instead of --tls-dir; with --tls-cert and --tls-key.
    #[arg(long, value_name = "FILE", conflicts_with = "tls_dir", requires_all = ["tls_cert", "tls_key"])]
    pub tls_ca: Option<PathBuf>,
    /// This process's certificate (PEM), signed by the CA.
    #[arg(long, value_name = "FILE", requires = "tls_ca")]
    pub tls_cert: Option<PathBuf>,
    /// This process's private key (PEM, PKCS#8).
    #[arg(long, value_name = "FILE", requires = "tls_ca")]
    pub tls_key: Option<PathBuf>,
}

#[derive(Debug, Args)]
pub struct RouterArgs {
    /// Zenoh locator to listen on (`tcp/127.0.0.1:0` picks a free port); repeatable (default:
    /// `tcp/127.0.0.1:7447`, `tls/…` under TLS: loopback only).
    #[arg(long = "listen", value_name = "ENDPOINT")]
    pub listen: Vec<String>,
    /// Another router to connect to; repeatable.
    #[arg(long = "connect", value_name = "ENDPOINT")]
    pub connect: Vec<String>,
    /// Under TLS the router enforces access rules for the identities whose certificates lie
    /// beside the CA certificate when it starts (docs/security.md).
    #[command(flatten)]
    pub tls: TlsArgs,
    #[command(flatten)]
    pub metrics: MetricsArgs,
}

#[derive(Debug, Subcommand)]
pub enum EdgeCommand {
    /// A vehicle: state at the rate, CAN at twice it, perception at a fifth of it.
    Vehicle(EdgeArgs),
    /// A roadside unit: object lists and signal phases at the rate.
    Rsu(EdgeArgs),
    /// Republish a recording's edge streams (fleet data) on their recorded keys.
    Replay(ReplayArgs),
    /// A vehicle's sensor producer: the `vehicle` world and streams, published zero-copy into
    /// iceoryx2 shared memory for the vehicle's `gateway` on this host (Zenoh flags unused).
    Sensor(EdgeArgs),
    /// A vehicle's gateway: forwards its `sensor`'s shared-memory samples to Zenoh on the
    /// vehicle's keys, until the sensor ends its stream or a signal (`--kind`/`--seed` name the
    /// vehicle model, as for the sensor; rate, count and duration are the sensor's).
    Gateway(EdgeArgs),
}

#[derive(Debug, Args)]
pub struct ReplayArgs {
    /// An MCAP recording (e.g. from `risktwin cloud --record`), or a `cloud --record-dir`
    /// folder: its segments in order, across files.
    pub recording: PathBuf,
    /// Replay only this span (log times in [--from, --to), one source's streams).
    #[command(flatten)]
    pub span: super::SpanArgs,
    /// Replay speed relative to the recording; 0 replays as fast as the transport allows.
    #[arg(long, default_value_t = 1.0)]
    pub speed: f64,
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    #[command(flatten)]
    pub metrics: MetricsArgs,
    /// Seconds to wait for a subscriber before publishing anyway.
    #[arg(long, default_value_t = 10.0)]
    pub wait_for_cloud_s: f64,
    /// Publish without waiting for (or reporting) the cloud's delivery acknowledgements of the
    /// replayed sources (as `edge vehicle --no-ack`).
    #[arg(long)]
    pub no_ack: bool,
}

#[derive(Debug, Args)]
pub struct EdgeArgs {
    #[arg(long)]
    pub id: String,
    #[arg(long, default_value = "default")]
    pub site: String,
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    #[command(flatten)]
    pub metrics: MetricsArgs,
    /// Base rate, Hz (default: 50 for a vehicle's state, 10 for an RSU).
    #[arg(long)]
    pub rate_hz: Option<f64>,
    /// Stop after this many seconds.
    #[arg(long)]
    pub duration: Option<f64>,
    /// Stop each stream after this many messages.
    #[arg(long)]
    pub count: Option<u64>,
    /// Edge clock offset, ns.
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    pub clock_offset_ns: i64,
    /// Edge clock drift, parts per million.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub clock_drift_ppm: f64,
    /// Capture-stamp jitter, ± ns.
    #[arg(long, default_value_t = 0)]
    pub clock_jitter_ns: u32,
    /// Seed of the scenario sample (and of the clock jitter).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Scenario kind the edge's world is sampled from.
    #[arg(long, default_value = "cut-in")]
    pub kind: String,
    /// Seconds to wait for a subscriber before publishing anyway.
    #[arg(long, default_value_t = 10.0)]
    pub wait_for_cloud_s: f64,
    /// Seconds of each stream kept for the cloud to recover after an outage (router restart,
    /// partition): a longer outage loses its oldest samples, counted by the cloud as `lost`.
    #[arg(long, default_value_t = DEFAULT_OUTAGE.as_secs_f64())]
    pub cache_s: f64,
    /// A file of clock steps, one signed number of ms per line: those in it at the start and
    /// each one appended later (looked for on a tick, at most every 100 ms) step the edge
    /// clock (a deployment's `clock_step` events write it).
    #[arg(long)]
    pub clock_steps: Option<std::path::PathBuf>,
    /// `edge vehicle`: the cloud's verifying key (`risktwin keys generate`); a policy update
    /// is driven with only when signed by it for this vehicle. Without it, every policy from
    /// the network is refused (`unverifiable`).
    #[arg(long)]
    pub trust_key: Option<std::path::PathBuf>,
    /// `edge vehicle`: the driver it starts with, `idm` (default), `PATH.safetensors` or
    /// `PATH.onnx` (docs/driver-interface.md), checked in full before the vehicle starts; a
    /// signed policy update replaces it.
    #[arg(long, value_name = "SPEC")]
    pub driver: Option<risktwin_policy::spec::DriverSpec>,
    /// Publish without waiting for (or reporting) the cloud's delivery acknowledgements: for an
    /// edge with no RiskTwin cloud on purpose (another subscriber, a capture). Without it, an
    /// edge whose messages were not all acknowledged exits 1 (docs/keyexpr.md).
    #[arg(long)]
    pub no_ack: bool,
}

#[derive(Debug, Args)]
pub struct CloudArgs {
    /// Comma-separated roles: ingest, union (the twin's input from sharded ingest workers, in
    /// place of ingest), twin (needs ingest or union), risk (needs twin), library (needs --db),
    /// criticality (needs --criticality-out or --db: the replayed drive stored as a recorded
    /// case), loop (needs twin and --db), trainer (needs loop), warning (needs ingest: a hazard
    /// warning to both vehicles of a critical pair on every state message), viz (needs twin: the
    /// live twin for the Foxglove app, docs/viz.md).
    #[arg(long, default_value = "ingest", value_delimiter = ',')]
    pub roles: Vec<String>,
    /// The viz role serves the Foxglove WebSocket protocol on this IP:PORT (default
    /// 127.0.0.1:8765; port 0 picks a free one). Unauthenticated: a non-loopback address is
    /// warned about.
    #[arg(long, value_name = "ADDR")]
    pub viz_listen: Option<String>,
    /// Serve one site only (default: every site).
    #[arg(long)]
    pub site: Option<String>,
    /// Ingest as one of several workers sharing the site (needs --site and role ingest alone):
    /// each edge is owned by one live worker, a departed worker's edges move to the others, and
    /// what each accepts goes on to the union role (docs/sharding.md).
    #[arg(long)]
    pub shard: bool,
    /// When live states wait at least this long (the least over a second), shed CAN, then every
    /// stream but states, and have the edges hold them back (docs/keyexpr.md, "Overload");
    /// default: never (the wait is still measured and reported).
    #[arg(long, value_name = "MS")]
    pub shed_after_ms: Option<f64>,
    /// Record every accepted message (and the twin's scene and risk outputs) into this MCAP
    /// file (closed cleanly on SIGINT/SIGTERM).
    #[arg(long, conflicts_with = "record_dir")]
    pub record: Option<std::path::PathBuf>,
    #[command(flatten)]
    pub rotation: RecordDirArgs,
    /// Ingest `risktwin edge replay` output at the recorded receive times it attaches, instead
    /// of this cloud's clock (messages without one are dropped as `no-replay-time`).
    #[arg(long)]
    pub replay_time: bool,
    /// The scenario library the library role serves, the loop role works on and the criticality
    /// role stores replayed drives in.
    #[arg(long)]
    pub db: Option<PathBuf>,
    /// The loop role sends a pushed scenario again when its result has not come back within
    /// this many seconds (and gives it up after 3 sends).
    #[arg(long, default_value_t = 60.0)]
    pub push_timeout_s: f64,
    /// The loop role writes its report here on shutdown (Markdown).
    #[arg(long, value_name = "FILE.md")]
    pub loop_report: Option<PathBuf>,
    /// The loop role mutates this many children around each failure.
    #[arg(long, default_value_t = 4)]
    pub mutants_per_failure: u64,
    /// The trainer role trains the next policy version once this many new fleet failures are
    /// in the library.
    #[arg(long, default_value_t = 5)]
    pub retrain_failures: u64,
    /// The trainer role also trains the next version on this schedule, seconds after the last
    /// run began (or the role started), when at least one new fleet failure is in.
    #[arg(long, value_name = "S")]
    pub retrain_every_s: Option<f64>,
    /// Environment steps of each training run of the trainer role.
    #[arg(long, default_value_t = 200_000)]
    pub train_steps: u64,
    /// Held-out scenarios per kind the trainer's regression gate drives.
    #[arg(long, default_value_t = 6)]
    pub held_out_per_kind: usize,
    /// Seed of the trainer's held-out set and runs (version V trains with seed + V).
    #[arg(long, default_value_t = 1)]
    pub train_seed: u64,
    /// The loop role signs every policy update it pushes with this key, for the vehicle it goes
    /// to (`risktwin keys generate`; vehicles trust its public half with `--trust-key`). Without
    /// it the updates go unsigned and every vehicle refuses them.
    #[arg(long)]
    pub signing_key: Option<std::path::PathBuf>,
    /// The warning role warns about a pair whose time to collision lies below this, s (default
    /// 2; needs the warning role).
    #[arg(long)]
    pub warning_ttc_s: Option<f64>,
    /// The warning role warns about one pair at most once per this much message time, ms (0:
    /// on every critical message; default 500; needs the warning role).
    #[arg(long)]
    pub warning_repeat_ms: Option<f64>,
    /// The risk role evaluates on the road of this scenario kind (the edges' `--kind`); so does
    /// the warning role's lane TTC.
    #[arg(long, default_value = "cut-in")]
    pub road: String,
    /// The criticality role writes the CommonRoad criticality of the replayed scenario here on
    /// shutdown: FILE.csv or FILE.json, as `risktwin criticality` prints them.
    #[arg(long)]
    pub criticality_out: Option<PathBuf>,
    /// Write the twin's fidelity against a scene's ground truth here on shutdown: fidelity.md
    /// (table) and fidelity.png (plot); needs the twin role (the risk columns the risk role).
    #[arg(long, value_name = "DIR")]
    pub fidelity_report: Option<PathBuf>,
    /// The ego obstacle of the criticality role (default: the first dynamic obstacle).
    #[arg(long)]
    pub ego: Option<u64>,
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    #[command(flatten)]
    pub metrics: MetricsArgs,
}
