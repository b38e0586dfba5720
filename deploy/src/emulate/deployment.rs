//! One deployment from start to teardown: machines, relays on every hop, routers, clouds and
//! edges started in that order and supervised, the event schedule carried out, then everything
//! stopped in reverse (edges first, so that the clouds count all they sent) and removed.
//!
//! Whatever ends it — its time, every edge done, a signal, an error — the teardown runs
//! ([`Teardown`]), and a later `deploy down` finds anything a crash left by its tag.

use super::net::{Net, sweep};
use super::network_log::NetworkLog;
use super::options::{Options, tag_of};
use super::plan::{CLOCK_STEPS_FILE, Hop, Planned, argv, file_stem, is_edge, plan};
use super::relay::{self, HopView, LinkShape, LinkState, Relay, RelayCounts};
use super::report::{self, Report, TimelineEntry};
use super::supervise::Supervised;
use super::tls;
use crate::topology::{Action, Link, Target, Topology};
use std::cell::RefCell;
use std::collections::BTreeMap;
use std::io::Write as _;
use std::net::{IpAddr, Ipv4Addr, SocketAddr, TcpListener, TcpStream};
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};
use tokio::sync::watch;

/// The queue of a host's way into its site's network, bytes.
const LAN_QUEUE_BYTES: usize = 256 * 1024;
/// How long a router has to listen, and a cloud to say `ready`.
const START_TIMEOUT: Duration = Duration::from_secs(30);
/// How long each kind of process has to stop on SIGTERM before it is killed.
const EDGE_GRACE: Duration = Duration::from_secs(10);
const CLOUD_GRACE: Duration = Duration::from_secs(30);
const ROUTER_GRACE: Duration = Duration::from_secs(5);
/// How long a cloud may take to see the ended edges leave (their last data is behind that).
const EDGES_LEFT_TIMEOUT: Duration = Duration::from_secs(15);
/// How long routers that just connected are given to agree on their routes.
const MESH_SETTLE: Duration = Duration::from_millis(500);
/// How often the supervisor looks at its processes and the schedule.
const TICK: Duration = Duration::from_millis(20);
/// How often `status.json` is rewritten.
const STATUS_EVERY: Duration = Duration::from_millis(500);

/// Why a deployment failed (after a complete teardown): a process did not come up, a relay
/// could not listen, a file could not be written.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct DeployError(String);

fn runtime(what: impl std::fmt::Display) -> DeployError {
    DeployError(what.to_string())
}

/// Removes the namespaces of a deployment, however it ends (its processes go with their
/// supervisor: they are its children with a parent-death signal, and in their namespaces).
struct Teardown {
    tag: String,
    namespaces: bool,
}

impl Drop for Teardown {
    fn drop(&mut self) {
        if self.namespaces {
            sweep(&self.tag);
        }
    }
}

/// A hop's emulation: its configured shape, the state its relays follow, their counts.
struct HopRun {
    name: String,
    base: LinkShape,
    shape: LinkShape,
    /// Partitions in force (they may overlap).
    cut: u32,
    state: watch::Sender<LinkState>,
    counts: Arc<RelayCounts>,
}

impl HopRun {
    fn apply(&self) {
        let state = if self.cut > 0 { LinkState::Partitioned } else { LinkState::Up(self.shape) };
        self.state.send_replace(state);
    }
}

/// The shape of a link of the file.
pub fn shape_of(link: &Link) -> LinkShape {
    LinkShape {
        latency: Duration::from_secs_f64(link.latency_ms / 1e3),
        jitter: link.jitter,
        bandwidth_bps: link.bandwidth_mbps.map(|m| m * 1e6),
        queue_bytes: (link.queue_kib * 1024) as usize,
    }
}

/// Something to undo when a lasting event ends.
enum Undo {
    Heal(Vec<usize>),
    /// A degradation's end: back to the configured values of what it changed.
    Restore(usize, Restore),
}

struct Restore {
    latency: bool,
    bandwidth: bool,
}

/// The stage a role starts and stops in: routers, clouds, and every other role as an edge.
fn stage_of(role: &str) -> &'static str {
    match role {
        "router" => "router",
        "cloud" => "cloud",
        _ => "edge",
    }
}

/// How long a process of a stage (or role) has to stop on SIGTERM.
fn grace_of(role: &str) -> Duration {
    match stage_of(role) {
        "cloud" => CLOUD_GRACE,
        "router" => ROUTER_GRACE,
        _ => EDGE_GRACE,
    }
}

/// Runs the deployment until its time is up, every edge has ended, or `stop` is set.
pub fn run(t: &Topology, o: &Options, stop: &AtomicBool) -> Result<Report, DeployError> {
    let plan = plan(t);
    let tag = tag_of(&o.file);
    // What a crashed run of the same file left goes first (the caller holds its lock: no
    // supervisor of it runs), and so does an earlier run's output.
    sweep(&tag);
    for old in ["hosts", "status.json", "report.json", "report.md", "topology.toml", "network.mcap", tls::CERTS_DIR] {
        let path = o.out.join(old);
        let _ = if path.is_dir() { std::fs::remove_dir_all(path) } else { std::fs::remove_file(path) };
    }
    let begun = Instant::now();
    let network = RefCell::new(NetworkLog::create(&o.out.join("network.mcap")).map_err(runtime)?);
    let mut timeline: Vec<TimelineEntry> = Vec::new();
    let mut note = |what: String| {
        // stderr may be gone (a closed pipe): the deployment goes on and tears down all the same.
        let _ = writeln!(std::io::stderr(), "{:7.2} s  {what}", begun.elapsed().as_secs_f64());
        network.borrow_mut().note(&what);
        timeline.push(TimelineEntry { at_s: begun.elapsed().as_secs_f64(), what });
    };
    let names: Vec<String> = plan.machines.iter().map(|m| m.name.clone()).collect();
    let net = if o.loopback {
        Net::Loopback
    } else {
        match Net::namespaces(&tag, &names, &std::env::temp_dir()) {
            Ok(net) => net,
            Err(e) => {
                eprintln!("note: no network namespaces ({e}): the deployment runs on loopback, links emulated alike");
                Net::Loopback
            }
        }
    };
    let _teardown = Teardown { tag: tag.clone(), namespaces: matches!(net, Net::Namespaces { .. }) };
    note(format!("machines: {}", net.describe()));
    let rt = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().map_err(runtime)?;
    let mut hops: Vec<HopRun> = plan
        .hops
        .iter()
        .map(|hop| {
            let (name, base) = match *hop {
                Hop::Link(k) => (t.links[k].name.clone(), shape_of(&t.links[k])),
                Hop::Lan(h) => (format!("lan:{}", t.hosts[h].name), LinkShape::lan(LAN_QUEUE_BYTES)),
            };
            let (state, _) = watch::channel(LinkState::Up(base));
            HopRun { name, base, shape: base, cut: 0, state, counts: Arc::default() }
        })
        .collect();
    let hop_index = |hop: Hop| plan.hops.iter().position(|h| *h == hop).expect("every hop is planned");
    // Routers listen on their machine's own address.
    let mut router_addr: Vec<Option<SocketAddr>> = vec![None; plan.machines.len()];
    for p in plan.processes.iter().filter(|p| p.role == "router") {
        let port = match net {
            Net::Loopback => free_port(&router_addr).map_err(runtime)?,
            Net::Namespaces { .. } => 7447,
        };
        router_addr[p.machine] = Some(SocketAddr::new(net.own(p.machine).into(), port));
    }
    // Every route becomes a chain of relays, the last one forwarding to the router.
    let mut relays: Vec<Relay> = Vec::new();
    let mut route_addr: Vec<SocketAddr> = Vec::new();
    for (r, route) in plan.routes.iter().enumerate() {
        let mut upstream = router_addr[route.to].expect("a route leads to a router");
        for (k, hop) in route.hops.iter().enumerate().rev() {
            let listen = SocketAddr::new(if k == 0 { net.gateway(route.from) } else { Ipv4Addr::LOCALHOST }.into(), 0);
            let h = &hops[hop_index(*hop)];
            let seed = risktwin_common::rng::Rng::derive(o.seed, (r as u64) << 16 | k as u64).next_u64();
            let relay = rt
                .block_on(relay::start(listen, upstream, h.state.subscribe(), Arc::clone(&h.counts), seed))
                .map_err(|e| runtime(format!("relay of {} on {listen}: {e}", h.name)))?;
            upstream = relay.addr;
            relays.push(relay);
        }
        route_addr.push(upstream);
    }
    // Under TLS: a certificate per process, a router's naming every address it is dialled on.
    let certs_dir = o.out.join(tls::CERTS_DIR);
    let proto = if t.tls { "tls" } else { "tcp" };
    if t.tls {
        let mut identities: BTreeMap<String, Vec<IpAddr>> = BTreeMap::new();
        for p in &plan.processes {
            let sans = identities.entry(tls::identity(p, &plan.machines[p.machine].name)).or_default();
            if p.role == "router" {
                sans.extend(router_addr[p.machine].map(|a| a.ip()));
                let routes = plan.routes.iter().zip(&route_addr).filter(|(r, _)| r.to == p.machine);
                sans.extend(routes.map(|(_, a)| a.ip()));
                sans.sort();
                sans.dedup();
            }
        }
        tls::make(&certs_dir, &identities).map_err(runtime)?;
        note(format!("tls: {} certificates in {}", identities.len(), certs_dir.display()));
    }
    let mut processes: Vec<(Planned, Supervised)> = Vec::new();
    for p in &plan.processes {
        let machine = &plan.machines[p.machine];
        let dir = o.out.join("hosts").join(&machine.name);
        std::fs::create_dir_all(&dir).map_err(runtime)?;
        let connect: Vec<String> = p.routes.iter().map(|&r| format!("{proto}/{}", route_addr[r])).collect();
        let listen = router_addr[p.machine].filter(|_| p.role == "router").map(|a| format!("{proto}/{a}"));
        let mut command = net.exec_prefix(p.machine);
        command.push(o.exe.display().to_string());
        command.extend(argv(p, &connect, listen.as_deref()));
        if t.tls {
            let dir = std::path::absolute(&certs_dir).map_err(runtime)?.display().to_string();
            command.extend(["--tls-dir".to_owned(), dir, "--identity".to_owned(), tls::identity(p, &machine.name)]);
        }
        let stem = dir.join(file_stem(p));
        processes.push((p.clone(), Supervised::new(p.name.clone(), command, dir, stem, p.restart)));
    }
    // Routers, then clouds, then the rest.
    for stage in ["router", "cloud", "edge"] {
        let in_stage = |p: &Planned| stage_of(p.role) == stage;
        for (_, s) in processes.iter_mut().filter(|(p, _)| in_stage(p)) {
            std::fs::write(s.log_stem.with_extension("cmd"), s.command.join(" ") + "\n").map_err(runtime)?;
            s.start().map_err(runtime)?;
        }
        for (p, s) in processes.iter_mut().filter(|(p, _)| in_stage(p)) {
            match stage {
                "router" => wait_listening(router_addr[p.machine].expect("a router's address"), s)?,
                "cloud" => wait_ready(s)?,
                _ => {}
            }
        }
        if stage == "router" {
            let peerings: Vec<usize> = processes
                .iter()
                .filter(|(p, _)| p.role == "router")
                .flat_map(|(p, _)| p.routes.iter().flat_map(|&r| plan.routes[r].hops.iter().map(|&h| hop_index(h))))
                .collect();
            wait_mesh(&peerings, &hops)?;
        }
    }
    note(format!("up: {} processes, {} relays", processes.len(), relays.len()));
    let status_file = o.out.join("status.json");
    let mut events = t.events.iter().peekable();
    let mut undo: Vec<(Duration, Undo)> = Vec::new();
    let mut last_status = Instant::now() - STATUS_EVERY;
    let mut ended_by = "a signal";
    let edges = processes.iter().filter(|(p, _)| is_edge(p.role)).count();
    let started = Instant::now();
    loop {
        let now = Instant::now();
        let at = now - started;
        if stop.load(Ordering::Relaxed) {
            break;
        }
        if o.duration.is_some_and(|d| at >= d) {
            ended_by = "its time";
            break;
        }
        if !o.until_down && edges > 0 && processes.iter().filter(|(p, _)| is_edge(p.role)).all(|(_, s)| s.done()) {
            ended_by = "every edge process ending";
            break;
        }
        // The links are recorded when the status is due and whenever an event changes them.
        let status_due = now - last_status >= STATUS_EVERY;
        let mut changed = status_due;
        while let Some(e) = events.next_if(|e| e.at <= at) {
            changed = true;
            match &e.action {
                Action::Partition { links, hosts } => {
                    let cut: Vec<usize> = links
                        .iter()
                        .map(|&k| Hop::Link(k))
                        .chain(hosts.iter().map(|&h| Hop::Lan(h)))
                        .map(hop_index)
                        .collect();
                    for &k in &cut {
                        hops[k].cut += 1;
                        hops[k].apply();
                    }
                    let names: Vec<&str> = cut.iter().map(|&k| hops[k].name.as_str()).collect();
                    note(format!("partition: {}", names.join(", ")));
                    if let Some(d) = e.lasts {
                        undo.push((e.at + d, Undo::Heal(cut)));
                    }
                }
                Action::Degrade { link, latency_ms, bandwidth_mbps } => {
                    let k = hop_index(Hop::Link(*link));
                    let h = &mut hops[k];
                    if let Some(ms) = latency_ms {
                        h.shape.latency = Duration::from_secs_f64(ms / 1e3);
                    }
                    if let Some(m) = bandwidth_mbps {
                        h.shape.bandwidth_bps = Some(m * 1e6);
                    }
                    h.apply();
                    note(format!(
                        "degrade {}: latency {:?} ms, bandwidth {:?} Mbit/s",
                        h.name, latency_ms, bandwidth_mbps
                    ));
                    if let Some(d) = e.lasts {
                        let what = Restore { latency: latency_ms.is_some(), bandwidth: bandwidth_mbps.is_some() };
                        undo.push((e.at + d, Undo::Restore(k, what)));
                    }
                }
                Action::Kill(target) | Action::Restart(target) => {
                    let k = match target {
                        // Hosts are the first machines, their processes planned in their order.
                        Target::Hosted { host, process } => processes
                            .iter()
                            .enumerate()
                            .filter(|(_, (p, _))| p.machine == *host)
                            .nth(*process)
                            .map(|(k, _)| k),
                        Target::SiteRouter { site } => processes.iter().position(|(p, _)| {
                            let machine = &plan.machines[p.machine];
                            machine.host.is_none() && machine.site == *site && p.role == "router"
                        }),
                    }
                    .expect("the event names a planned process");
                    let s = &mut processes[k].1;
                    if matches!(e.action, Action::Kill(_)) {
                        s.kill();
                        note(format!("kill {}", s.name));
                    } else {
                        let (p, s) = &mut processes[k];
                        s.stop(grace_of(p.role));
                        s.restarts += 1;
                        match s.start() {
                            Ok(()) => note(format!("restart {}", s.name)),
                            Err(e) => note(format!("restart {}: {e}", s.name)),
                        }
                    }
                }
                Action::ClockStep { host, by_ms } => {
                    let name = &t.hosts[*host].name;
                    let file = o.out.join("hosts").join(name).join(CLOCK_STEPS_FILE);
                    match append_line(&file, &format!("{by_ms}")) {
                        Ok(()) => note(format!("clock_step {name}: {by_ms:+} ms")),
                        Err(e) => note(format!("clock_step {name}: {e}")),
                    }
                }
            }
        }
        undo.sort_by_key(|(t, _)| *t);
        while undo.first().is_some_and(|(t, _)| *t <= at) {
            changed = true;
            match undo.remove(0).1 {
                Undo::Heal(cut) => {
                    for &k in &cut {
                        hops[k].cut -= 1;
                        hops[k].apply();
                    }
                    let names: Vec<&str> = cut.iter().map(|&k| hops[k].name.as_str()).collect();
                    note(format!("heal: {}", names.join(", ")));
                }
                Undo::Restore(k, what) => {
                    let h = &mut hops[k];
                    if what.latency {
                        h.shape.latency = h.base.latency;
                    }
                    if what.bandwidth {
                        h.shape.bandwidth_bps = h.base.bandwidth_bps;
                    }
                    h.apply();
                    note(format!("{} restored", h.name));
                }
            }
        }
        for (_, s) in &mut processes {
            if let Some(what) = s.poll(now) {
                note(what);
            }
        }
        if changed {
            let views = hop_views(&hops);
            network.borrow_mut().links(&views);
            if status_due {
                last_status = now;
                let status = report::status(&tag, &net, at, &processes, &views);
                report::write_atomically(&status_file, &status).map_err(runtime)?;
            }
        }
        std::thread::sleep(TICK);
    }
    let ran = started.elapsed();
    note(format!("stopping: ended by {ended_by}"));
    for stage in ["edge", "cloud", "router"] {
        let in_stage = |p: &Planned| stage_of(p.role) == stage;
        if stage == "cloud" {
            let deadline = Instant::now() + EDGES_LEFT_TIMEOUT;
            for (_, s) in processes.iter().filter(|(p, _)| p.role == "cloud") {
                wait_edges_left(s, deadline);
            }
        }
        // Every process of the stage at once: SIGTERM to all, then the wait.
        let grace = grace_of(stage);
        let mut stopping: Vec<&mut Supervised> =
            processes.iter_mut().filter(|(p, _)| in_stage(p)).map(|(_, s)| s).collect();
        super::supervise::stop_all(&mut stopping, grace);
    }
    note("stopped".into());
    let views = hop_views(&hops);
    network.borrow_mut().links(&views);
    network.into_inner().finish();
    drop(relays);
    let report = Report::build(o, &net, begun, ran, &processes, &views, timeline);
    Ok(report)
}

/// Appends `line` to `file`: each of the host's edges reads what was appended (a host's clock
/// steps; `risktwin edge … --clock-steps`).
fn append_line(file: &Path, line: &str) -> std::io::Result<()> {
    let mut f = std::fs::OpenOptions::new().create(true).append(true).open(file)?;
    f.write_all(format!("{line}\n").as_bytes())
}

fn hop_views(hops: &[HopRun]) -> Vec<HopView> {
    hops.iter()
        .map(|h| HopView {
            name: h.name.clone(),
            base: h.base,
            shape: h.shape,
            counts: Arc::clone(&h.counts),
            partitioned: h.cut > 0,
        })
        .collect()
}

/// Where a loopback deployment's routers listen: below Linux's ephemeral range (32768 up), from
/// which the relays' and every client's port-0 binds come, so none of them can take it.
const ROUTER_PORTS: std::ops::Range<u16> = 20_000..32_000;

/// A port free on loopback now and not given to another router.
fn free_port(taken: &[Option<SocketAddr>]) -> std::io::Result<u16> {
    let start = ROUTER_PORTS.start + (std::process::id() % 997) as u16 * 12;
    (start..ROUTER_PORTS.end)
        .chain(ROUTER_PORTS.start..start)
        .find(|&p| !taken.iter().flatten().any(|a| a.port() == p) && TcpListener::bind(("127.0.0.1", p)).is_ok())
        .ok_or_else(|| std::io::Error::other("no free port for a router in 20000–31999"))
}

/// Waits until the router of `s` accepts connections on `addr`.
fn wait_listening(addr: SocketAddr, s: &mut Supervised) -> Result<(), DeployError> {
    let deadline = Instant::now() + START_TIMEOUT;
    while TcpStream::connect_timeout(&addr, Duration::from_millis(200)).is_err() {
        if s.poll(Instant::now()).is_some() || Instant::now() > deadline {
            return Err(runtime(format!("{} did not listen on {addr}: {}", s.name, log_tail(s))));
        }
        std::thread::sleep(TICK);
    }
    Ok(())
}

/// Waits until every hop between routers carries a connection, then lets the routers exchange
/// their routing state. An edge that sees the cloud's subscriber declared through a router that
/// has not finished computing its routes loses its first messages (seen: the first 80 ms of
/// every stream, on a second run of the same deployment, when everything starts fast).
fn wait_mesh(peerings: &[usize], hops: &[HopRun]) -> Result<(), DeployError> {
    let deadline = Instant::now() + START_TIMEOUT;
    while peerings.iter().any(|&k| hops[k].counts.connections.load(std::sync::atomic::Ordering::Relaxed) == 0) {
        if Instant::now() > deadline {
            return Err(runtime("the site routers did not connect to each other"));
        }
        std::thread::sleep(TICK);
    }
    if !peerings.is_empty() {
        std::thread::sleep(MESH_SETTLE);
    }
    Ok(())
}

/// Waits until the cloud of `s` says `ready` on stderr.
fn wait_ready(s: &mut Supervised) -> Result<(), DeployError> {
    let deadline = Instant::now() + START_TIMEOUT;
    let log = s.log_stem.with_extension("log");
    while !std::fs::read_to_string(&log).is_ok_and(|l| l.lines().any(|l| l == "ready")) {
        if s.poll(Instant::now()).is_some() || Instant::now() > deadline {
            return Err(runtime(format!("{} did not become ready: {}", s.name, log_tail(s))));
        }
        std::thread::sleep(TICK);
    }
    Ok(())
}

/// Waits until the cloud of `s` has seen every edge that joined it leave (liveliness): what an
/// edge sent before it left has then arrived, and stopping the cloud loses none of it.
fn wait_edges_left(s: &Supervised, deadline: Instant) {
    let log = s.log_stem.with_extension("log");
    loop {
        let text = std::fs::read_to_string(&log).unwrap_or_default();
        // An edge may join and leave many times (restarts, long partitions): count them.
        let mut inside: std::collections::BTreeMap<&str, i64> = std::collections::BTreeMap::new();
        for line in text.lines() {
            if let Some(edge) = line.strip_prefix("edge joined: ") {
                *inside.entry(edge).or_default() += 1;
            } else if let Some(edge) = line.strip_prefix("edge left: ") {
                *inside.entry(edge).or_default() -= 1;
            }
        }
        if inside.values().all(|&n| n <= 0) || Instant::now() > deadline {
            return;
        }
        std::thread::sleep(TICK);
    }
}

/// The last lines of a process's stderr, for an error.
fn log_tail(s: &Supervised) -> String {
    let text = std::fs::read_to_string(s.log_stem.with_extension("log")).unwrap_or_default();
    let lines: Vec<&str> = text.lines().collect();
    lines[lines.len().saturating_sub(3)..].join(" / ")
}
