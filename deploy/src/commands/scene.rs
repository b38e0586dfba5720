//! `risktwin scene run|authority|vehicle|rsu`: a scene shared by processes (edge::fleet).
//!
//! `scene run` is the one-host launcher: it starts a router process on a free loopback port,
//! one process per participant (`scene vehicle|rsu`), and acts as the physics authority itself.
//! Every role is a Zenoh peer listening on loopback only (the router introduces them). Every
//! child is killed and reaped however the run ends.

use super::driver::{LoadedDriver, warn_faults, warn_model};
use super::recorded::read_xml;
use super::router::transport_config;
use super::source::{parse_kinds, read_spec_file};
use crate::cli::{SceneArgs, SceneParticipantArgs, SceneRoleArgs, SceneRunArgs, ZenohArgs};
use crate::error::{CliError, CliResult};
use crate::output::{Format, print_json};
use risktwin_edge::fleet::authority::{Embedded, Paced, SceneOutcome, run_scene};
use risktwin_edge::fleet::net::{Deadlines, Timeouts, ZenohAuthority, run_participant};
use risktwin_edge::fleet::{EgoDriver, Recording, Role, SceneError, SceneSetup, SceneSource};
use risktwin_edge::scene::feasible_spec;
use risktwin_transport::zenoh::Session;
use risktwin_transport::{SiteId, TransportConfig, connect};
use risktwin_v2x::channel::LinkBudget;
use risktwin_v2x::latency::Latency;
use risktwin_v2x::link::V2xChannel;
use risktwin_v2x::loss::BurstLoss;
use risktwin_v2x::messages::{MessageChannel, V2xSummary};
use serde::Serialize;
use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Read, Write as _};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Where every role of `scene run` listens: loopback, a port the OS picks.
pub(super) const LOOPBACK: &str = "tcp/127.0.0.1:0";

/// The scene the arguments name (the scenario checked feasible, the roles checked present).
fn setup_of(args: &SceneArgs) -> CliResult<SceneSetup> {
    if args.ego.is_some() && args.commonroad.is_none() {
        return Err(CliError::input("--ego names the ego of a --commonroad recording"));
    }
    // clap's `requires` does not reach through the flattened arguments; checked here.
    if args.id.is_some() && args.db.is_none() {
        return Err(CliError::input("--id names a scenario of a --db library"));
    }
    let source = match (&args.spec, &args.db, &args.kind, &args.commonroad) {
        (Some(path), None, None, None) => SceneSource::Generated(read_spec_file(path)?),
        (None, Some(db), None, None) => {
            let lib = super::source::open_existing_library(db)?;
            let id = args.id.as_deref().unwrap_or_default();
            if let Some(stored) = lib.get(id).map_err(CliError::input)? {
                SceneSource::Generated(stored.spec)
            } else if let Some(stored) = lib.recorded(id).map_err(CliError::input)? {
                // A recorded case: its XML whole and the ego it was imported with.
                let shown = format!("{} case {id}", db.display());
                SceneSource::CommonRoad(recording(&stored.case.xml, Some(stored.case.ego_id), &shown)?)
            } else {
                return Err(CliError::input(format!("no scenario '{id}' in {}", db.display())));
            }
        }
        (None, None, Some(kind), None) => {
            let [kind] = parse_kinds(kind)?[..] else {
                return Err(CliError::input("--kind names one scenario kind for a scene, not `all`"));
            };
            SceneSource::Generated(feasible_spec(args.seed, kind).map_err(CliError::input)?)
        }
        (None, None, None, Some(path)) => {
            SceneSource::CommonRoad(recording(&read_xml(path)?, args.ego, &path.display().to_string())?)
        }
        _ => {
            return Err(CliError::input(
                "a scene needs one of --spec FILE, --db FILE --id ID, --kind KIND or --commonroad FILE",
            ));
        }
    };
    let setup = match source {
        SceneSource::Generated(spec) => SceneSetup::new(spec, args.connected, args.rsus),
        SceneSource::CommonRoad(recording) => SceneSetup::commonroad(recording, args.connected, args.rsus),
    };
    let setup = setup.and_then(|s| s.without(&args.without)).map_err(CliError::input)?;
    // The V2X channel is part of the scene (its digest): every role gets it, and a participant
    // started with other V2X flags is refused at the join, as one of another seed.
    let v2x = v2x_of(args, &setup)?;
    for (flag, on) in [("--v2x-warnings", args.v2x_warnings), ("--v2x-cpm", args.v2x_cpm)] {
        if on && v2x.is_none() {
            return Err(CliError::input(format!("{flag} needs --v2x-model")));
        }
    }
    let ego_driver = match &args.driver {
        Some(spec) => {
            // Quietly: every process of a scene loads it, the ego's own warns (`warn_ego_model`).
            let loaded = LoadedDriver::quietly(spec, "--driver")?;
            loaded.model.map(|file| EgoDriver { label: loaded.label, sha256: file.sha256, model: file.model })
        }
        None => None,
    };
    Ok(setup.with_v2x(v2x).with_warnings(args.v2x_warnings).with_cpm(args.v2x_cpm).with_ego_driver(ego_driver))
}

/// The ego model's load warnings on stderr, from the process that drives it.
fn warn_ego_model(setup: &SceneSetup) {
    if let Some(d) = setup.ego_driver() {
        warn_model(&d.label, &d.model);
    }
}

/// Says on stderr what the ego's model failed to decide in this process (only the ego's own
/// participant drives it; in the others the count stays 0).
fn warn_ego_faults(setup: &SceneSetup) {
    if let Some(d) = setup.ego_driver() {
        warn_faults(&d.label, &d.model);
    }
}

/// The V2X channel the arguments ask for, seeded by the scene (`None`: no V2X).
fn v2x_of(args: &SceneArgs, setup: &SceneSetup) -> CliResult<Option<MessageChannel>> {
    let Some(model) = &args.v2x_model else {
        if args.v2x_latency.is_some() || args.v2x_bursts.is_some() {
            return Err(CliError::input("--v2x-latency and --v2x-bursts need --v2x-model"));
        }
        return Ok(None);
    };
    let model = super::v2x::path_loss_of("--v2x-model", model)?;
    let latency = match &args.v2x_latency {
        Some(text) => Latency::parse(text).map_err(|e| CliError::input(format!("--v2x-latency: {e}")))?,
        None => Latency::SIDELINK,
    };
    let bursts = args.v2x_bursts.as_deref().map(bursts_of).transpose()?.flatten();
    let channel = V2xChannel { model, budget: LinkBudget::default(), latency, bursts };
    Ok(Some(MessageChannel { channel, seed: setup.seed() }))
}

/// `SHARE:MEAN_BURST`, both checked; a share of 0 is no burst loss.
fn bursts_of(text: &str) -> CliResult<Option<BurstLoss>> {
    let bad = |why: String| CliError::input(format!("--v2x-bursts {text:?}: {why}"));
    let (share, mean) = text.split_once(':').ok_or_else(|| bad("expected SHARE:MEAN_BURST".into()))?;
    let number = |v: &str| v.parse::<f64>().map_err(|e| bad(format!("{v:?}: {e}")));
    let (share, mean) = (number(share)?, number(mean)?);
    let chain = BurstLoss::from_share(share, mean).map_err(bad)?;
    Ok((share != 0.0).then_some(chain))
}

/// The recording of CommonRoad XML `xml` read from `shown`, with `ego` or its default ego.
fn recording(xml: &str, ego: Option<u64>, shown: &str) -> CliResult<Recording> {
    Recording::parse(xml, ego).map_err(|e| CliError::input(format!("{shown}: {e}")))
}

/// How the authority steps.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Clock {
    /// Virtual time: every step waits for every answer; paced at `speed`× the wall clock, or
    /// as fast as the answers come when 0.
    Lockstep { speed: f64 },
    /// The wall clock: one step per physics step of wall time; late answers counted.
    Realtime,
}

fn clock_of(clock: &str, speed: f64) -> CliResult<Clock> {
    if !(speed.is_finite() && speed >= 0.0) {
        return Err(CliError::input(format!("--speed {speed} must be a non-negative number (0: as fast as possible)")));
    }
    match clock {
        "lockstep" => Ok(Clock::Lockstep { speed }),
        "realtime" if speed != 0.0 => Err(CliError::input("--speed paces a lockstep scene; realtime runs at 1")),
        "realtime" => Ok(Clock::Realtime),
        other => Err(CliError::input(format!("--clock {other:?}: expected lockstep or realtime"))),
    }
}

/// What the authority prints: the outcome, and in real time how many answers were late.
#[derive(Debug, Serialize)]
struct SceneReport {
    #[serde(flatten)]
    outcome: SceneOutcome,
    #[serde(skip_serializing_if = "Option::is_none")]
    deadlines: Option<Deadlines>,
    /// An embedded scene's V2X counts per participant, in virtual time (with `--v2x-model`).
    #[serde(skip_serializing_if = "Option::is_none")]
    v2x: Option<BTreeMap<String, V2xSummary>>,
}

/// Setup and mismatch errors are the user's input (exit 2); a participant failing mid-run is a
/// runtime failure (exit 1), named.
fn scene_error(e: SceneError) -> CliError {
    match e {
        SceneError::NoEgo
        | SceneError::TooManyConnected { .. }
        | SceneError::Recording { .. }
        | SceneError::TooManyRsus { .. }
        | SceneError::UnknownParticipant { .. }
        | SceneError::Withdrawn { .. }
        | SceneError::CannotWithdraw { .. }
        | SceneError::Mismatch { .. } => CliError::input(e),
        _ => CliError::runtime(e),
    }
}

fn site_of(args: &SceneArgs) -> CliResult<SiteId> {
    SiteId::new(args.site.clone()).map_err(CliError::input)
}

/// Opens a Zenoh session on a runtime that lives as long as the session is used.
pub(super) fn open(transport: &TransportConfig) -> CliResult<(tokio::runtime::Runtime, Session)> {
    let runtime = tokio::runtime::Builder::new_multi_thread().enable_all().build().map_err(CliError::runtime)?;
    let session = runtime.block_on(connect(transport)).map_err(CliError::runtime)?;
    Ok((runtime, session))
}

/// The transport of the scene's data session, when `--data-router` asks for one: a detached
/// peer of that router, so that the scene's physics never waits for the network (a scene
/// started while its host is cut off drives on time; what its participants make before a
/// cloud subscribes waits in them, see `risktwin_edge::fleet::streams`).
fn data_transport(args: &SceneArgs) -> CliResult<Option<TransportConfig>> {
    let Some(router) = &args.data_router else { return Ok(None) };
    let config = TransportConfig {
        connect: vec![router.clone()],
        listen: vec![LOOPBACK.into()],
        detached: true,
        ..TransportConfig::default()
    };
    // A bad endpoint is the user's input: refused before anything starts.
    config.to_zenoh().map_err(CliError::input)?;
    Ok(Some(config))
}

/// The physics session on `physics`, and the data session: its own when `data` says so, else
/// the physics session again.
fn open_planes(
    physics: &TransportConfig,
    data: Option<&TransportConfig>,
) -> CliResult<(tokio::runtime::Runtime, Session, Session)> {
    let (runtime, session) = open(physics)?;
    let data = match data {
        Some(d) => {
            let data = runtime.block_on(connect(d)).map_err(CliError::runtime)?;
            runtime.spawn(say_when_reached(data.clone(), d.connect.join(", ")));
            data
        }
        None => session.clone(),
    };
    Ok((runtime, session, data))
}

/// How long a scene's data router may take to answer before the scene says it has not.
const DATA_ROUTER_PATIENCE: Duration = Duration::from_secs(5);

/// Warns once the data session has had no router for [`DATA_ROUTER_PATIENCE`] (a wrong address
/// or a host cut off: the scene drives on, its data waits), and says when one answers after that.
async fn say_when_reached(data: Session, router: String) {
    let started = Instant::now();
    let mut warned = false;
    loop {
        let reached = data.info().routers_zid().await.next().is_some();
        if reached {
            if warned {
                tracing::info!("data router {router} answered after {:.1} s", started.elapsed().as_secs_f64());
            }
            return;
        }
        if !warned && started.elapsed() >= DATA_ROUTER_PATIENCE {
            tracing::warn!(
                "data router {router} has not answered in {} s: the scene drives on, its data waits",
                DATA_ROUTER_PATIENCE.as_secs()
            );
            warned = true;
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
}

/// Steps `setup` as the authority on `session` until the episode ends.
fn authority_on(
    physics: &Session,
    data: &Session,
    site: &SiteId,
    setup: &SceneSetup,
    clock: Clock,
) -> CliResult<SceneReport> {
    let plane = ZenohAuthority::open(physics, data, site, setup, Timeouts::default()).map_err(scene_error)?;
    tracing::info!("scene {setup}: all {} participants joined, stepping", setup.participants().len());
    let started = Instant::now();
    let report = match clock {
        Clock::Lockstep { speed } if speed > 0.0 => {
            let mut paced = Paced::new(plane, speed, setup.step_s());
            let outcome = run_scene(setup, &mut paced).map_err(scene_error)?;
            if paced.late_steps > 0 {
                tracing::warn!("scene: {} of {} steps were handed out late", paced.late_steps, outcome.steps);
            }
            report_malformed(&paced.inner);
            SceneReport { outcome, deadlines: None, v2x: None }
        }
        Clock::Lockstep { .. } => {
            let mut plane = plane;
            let outcome = run_scene(setup, &mut plane).map_err(scene_error)?;
            report_malformed(&plane);
            SceneReport { outcome, deadlines: None, v2x: None }
        }
        Clock::Realtime => {
            let mut plane = plane.realtime(Duration::from_secs_f64(setup.step_s()));
            let outcome = run_scene(setup, &mut plane).map_err(scene_error)?;
            report_malformed(&plane);
            let deadlines = plane.deadlines().cloned();
            if let Some(d) = &deadlines {
                let share = 100.0 * d.missed as f64 / d.due.max(1) as f64;
                tracing::info!(
                    "scene deadlines: {} of {} answers late ({share:.2} %), ego controls held {} steps",
                    d.missed,
                    d.due,
                    d.ego_controls_held
                );
            }
            SceneReport { outcome, deadlines, v2x: None }
        }
    };
    log_pace(&report.outcome, started.elapsed());
    Ok(report)
}

/// How fast the scene ran: its steps, wall time per step and the multiple of real time (what
/// `deploy/bench/scene-lockstep.sh` reads).
fn log_pace(outcome: &SceneOutcome, wall: Duration) {
    let scene_s = outcome.steps as f64 * outcome.step_s;
    let wall_s = wall.as_secs_f64().max(1e-9);
    let per_step_ms = 1e3 * wall_s / (outcome.steps.max(1) as f64);
    tracing::info!(
        "scene pace: {} steps ({scene_s:.2} s of scene) in {wall_s:.3} s: {:.1}x real time, {per_step_ms:.3} ms per step",
        outcome.steps,
        scene_s / wall_s
    );
}

fn report_malformed(plane: &ZenohAuthority) {
    let malformed = plane.malformed();
    if malformed > 0 {
        tracing::warn!("scene: {malformed} malformed replies dropped");
    }
}

pub fn authority(args: SceneRoleArgs) -> CliResult {
    let clock = clock_of(&args.clock, args.speed)?;
    let setup = setup_of(&args.scene)?;
    let site = site_of(&args.scene)?;
    let data = data_transport(&args.scene)?;
    let transport = transport_config(args.zenoh)?;
    let _metrics = crate::metrics_endpoint::start(&args.metrics, "scene-authority")?;
    let (_runtime, physics, data) = open_planes(&transport, data.as_ref())?;
    let report = authority_on(&physics, &data, &site, &setup, clock)?;
    print_json(&report)
}

pub fn participant(args: SceneParticipantArgs, as_role: &str) -> CliResult {
    let setup = setup_of(&args.scene)?;
    let site = site_of(&args.scene)?;
    let role = setup.role_of(&args.participant).map_err(scene_error)?;
    let is_rsu = matches!(role, Role::Rsu { .. });
    if is_rsu != (as_role == "rsu") {
        let other = if is_rsu { "rsu" } else { "vehicle" };
        return Err(CliError::input(format!(
            "participant {} is a {other}: start it with `scene {other}`",
            args.participant
        )));
    }
    let data = data_transport(&args.scene)?;
    let transport = transport_config(args.zenoh)?;
    let _metrics = crate::metrics_endpoint::start(&args.metrics, &format!("scene-{as_role}"))?;
    let (_runtime, physics, data) = open_planes(&transport, data.as_ref())?;
    if role == Role::Ego {
        warn_ego_model(&setup);
    }
    let summary = run_participant(&physics, &data, &site, &setup, &args.participant, Timeouts::default());
    warn_ego_faults(&setup);
    print_json(&summary.map_err(scene_error)?)
}

pub fn run(args: SceneRunArgs) -> CliResult {
    let clock = clock_of(&args.clock, args.speed)?;
    let setup = setup_of(&args.scene)?;
    if args.format != Format::Json {
        return Err(CliError::input("scene outcomes are JSON only (--format json)"));
    }
    if args.embedded {
        if args.scene.data_router.is_some() {
            return Err(CliError::input(
                "--embedded runs in one process with no network; --data-router needs the processes",
            ));
        }
        if clock == Clock::Realtime {
            return Err(CliError::input("--embedded runs in virtual time; --clock realtime needs the processes"));
        }
        let mut plane = Embedded::new(&setup).map_err(scene_error)?;
        warn_ego_model(&setup);
        let started = Instant::now();
        let outcome = run_scene(&setup, &mut plane);
        warn_ego_faults(&setup);
        let outcome = outcome.map_err(scene_error)?;
        log_pace(&outcome, started.elapsed());
        return print_json(&SceneReport { outcome, deadlines: None, v2x: plane.v2x_summaries() });
    }
    let site = site_of(&args.scene)?;
    // Checked before anything starts: a bad endpoint or file is the user's input.
    let data = data_transport(&args.scene)?;
    let open_summaries = |path: &std::path::PathBuf| {
        let file = std::fs::OpenOptions::new().create(true).append(true).open(path);
        file.map_err(|e| CliError::input(format!("--participant-summaries {}: {e}", path.display())))
    };
    let mut summaries = args.participant_summaries.as_ref().map(open_summaries).transpose()?;
    let mut children = Children::default();
    let locator = match args.router {
        Some(locator) => locator,
        None => children.router()?,
    };
    for id in setup.participants() {
        let role = if id.starts_with("rsu") { "rsu" } else { "vehicle" };
        let mut argv = vec!["scene".to_owned(), role.to_owned(), "--participant".to_owned(), id.clone()];
        argv.extend(scene_argv(&args.scene));
        argv.extend(["--mode", "peer", "--listen", LOOPBACK, "--connect", &locator].map(str::to_owned));
        children.spawn(&id, &argv)?;
    }
    let zenoh = ZenohArgs {
        connect: vec![locator],
        listen: vec![LOOPBACK.into()],
        mode: "peer".into(),
        multicast_scouting: false,
        tls: Default::default(),
    };
    let (_runtime, physics, data) = open_planes(&transport_config(zenoh)?, data.as_ref())?;
    let report = authority_on(&physics, &data, &site, &setup, clock);
    let finished = children.finish_participants(Duration::from_secs(10));
    if let Some(file) = &mut summaries {
        for summary in &children.summaries {
            writeln!(file, "{summary}").map_err(CliError::runtime)?;
        }
    }
    let report = report?;
    finished?;
    print_json(&report)
}

/// The arguments that give a child the same scene.
fn scene_argv(args: &SceneArgs) -> Vec<String> {
    let mut argv = Vec::new();
    let path = |p: &std::path::Path| p.to_string_lossy().into_owned();
    if let Some(spec) = &args.spec {
        argv.extend(["--spec".to_owned(), path(spec)]);
    }
    if let (Some(db), Some(id)) = (&args.db, &args.id) {
        argv.extend(["--db".to_owned(), path(db), "--id".to_owned(), id.clone()]);
    }
    if let Some(kind) = &args.kind {
        argv.extend(["--kind".to_owned(), kind.clone(), "--seed".to_owned(), args.seed.to_string()]);
    }
    if let Some(file) = &args.commonroad {
        argv.extend(["--commonroad".to_owned(), path(file)]);
    }
    if let Some(ego) = args.ego {
        argv.extend(["--ego".to_owned(), ego.to_string()]);
    }
    argv.extend(["--connected".to_owned(), args.connected.to_string(), "--rsus".to_owned(), args.rsus.to_string()]);
    for id in &args.without {
        argv.extend(["--without".to_owned(), id.clone()]);
    }
    argv.extend(["--site".to_owned(), args.site.clone()]);
    if let Some(router) = &args.data_router {
        argv.extend(["--data-router".to_owned(), router.clone()]);
    }
    let v2x =
        [("--v2x-model", &args.v2x_model), ("--v2x-latency", &args.v2x_latency), ("--v2x-bursts", &args.v2x_bursts)];
    for (flag, value) in v2x {
        if let Some(value) = value {
            argv.extend([flag.to_owned(), value.clone()]);
        }
    }
    for (flag, on) in [("--v2x-warnings", args.v2x_warnings), ("--v2x-cpm", args.v2x_cpm)] {
        if on {
            argv.push(flag.to_owned());
        }
    }
    if let Some(driver) = &args.driver {
        // One argument: a path that starts with `-` is not read as a flag.
        argv.push(format!("--driver={driver}"));
    }
    argv
}

/// The launcher's child processes: killed and reaped on drop, whatever happened.
#[derive(Default)]
struct Children {
    router: Option<Child>,
    participants: Vec<(String, Child)>,
    /// The summaries the participants that ended well printed, one JSON object each.
    summaries: Vec<String>,
}

impl Children {
    /// Starts a router on a free loopback port; its locator.
    fn router(&mut self) -> CliResult<String> {
        let exe = std::env::current_exe().map_err(CliError::runtime)?;
        let mut child = Command::new(exe)
            .args(["router", "--listen", LOOPBACK])
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| CliError::runtime(format!("cannot start the router: {e}")))?;
        let stderr = child.stderr.take().ok_or_else(|| CliError::runtime("router stderr"))?;
        self.router = Some(child);
        let mut lines = BufReader::new(stderr).lines();
        let locator = lines
            .by_ref()
            .map_while(Result::ok)
            .find_map(|l| l.strip_prefix("listening on ").map(str::to_owned))
            .ok_or_else(|| CliError::runtime("the router exited before it listened"))?;
        // Keep draining the router's stderr so it never blocks on a full pipe.
        std::thread::spawn(move || lines.for_each(drop));
        Ok(locator)
    }

    fn spawn(&mut self, id: &str, argv: &[String]) -> CliResult {
        let exe = std::env::current_exe().map_err(CliError::runtime)?;
        let child = Command::new(exe)
            .args(argv)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .map_err(|e| CliError::runtime(format!("cannot start participant {id}: {e}")))?;
        self.participants.push((id.to_owned(), child));
        Ok(())
    }

    /// Waits for every participant to exit (they do once the authority ends the scene); the
    /// first that failed or did not exit within `limit` is named.
    fn finish_participants(&mut self, limit: Duration) -> CliResult {
        let deadline = Instant::now() + limit;
        let mut failed = Vec::new();
        for (id, child) in &mut self.participants {
            let status = loop {
                match child.try_wait().map_err(CliError::runtime)? {
                    Some(status) => break Some(status),
                    None if Instant::now() >= deadline => break None,
                    None => std::thread::sleep(Duration::from_millis(10)),
                }
            };
            let mut out = String::new();
            // Only an exited participant's pipe reaches its end: reading a stalled one's would
            // wait for ever. The summary is informational; a read failure loses only that.
            if let (Some(_), Some(stdout)) = (status, child.stdout.as_mut()) {
                let _ = stdout.read_to_string(&mut out);
            }
            match status {
                // Printed pretty by `print_json`; kept on one line.
                Some(s) if s.success() => match serde_json::from_str::<serde_json::Value>(&out) {
                    Ok(summary) => self.summaries.push(summary.to_string()),
                    Err(e) => tracing::warn!("participant {id} printed no summary ({e})"),
                },
                Some(s) => failed.push(format!("{id} ({s})")),
                None => failed.push(format!("{id} (did not exit within {} s)", limit.as_secs())),
            }
        }
        if failed.is_empty() {
            Ok(())
        } else {
            Err(CliError::runtime(format!("participant(s) failed: {}", failed.join(", "))))
        }
    }
}

impl Drop for Children {
    fn drop(&mut self) {
        let all = self.participants.iter_mut().map(|(_, c)| c).chain(self.router.as_mut());
        for child in all {
            // Already exited is fine: kill then reap, errors mean there is nothing left to do.
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}
