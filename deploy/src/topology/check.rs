//! From the file as written to a checked [`Topology`]: names resolved, values in range, every
//! host able to reach a router. The first mistake is reported with its line.

use super::checked::{
    Endpoint, Event, Host, Link, MAX_BANDWIDTH_MBPS, MAX_LATENCY_MS, MIN_BANDWIDTH_MBPS, Process, Site, Topology,
    TopologyError,
};
use super::events::check_event;
use super::model::{File, Jitter, ROLES, Restart};
use std::collections::HashMap;
use std::ops::Range;
use toml::Spanned;

/// Queue of a link without `queue_kib`, KiB.
const DEFAULT_QUEUE_KIB: u64 = 256;
/// The largest queue, KiB (1 GiB).
const MAX_QUEUE_KIB: u64 = 1 << 20;
/// Arguments the deployment gives: addresses are assigned, never written.
const GIVEN_ARGS: [&str; 12] = [
    "--connect",
    "--listen",
    "--router",
    "--data-router",
    "--mode",
    "--multicast-scouting",
    "--clock-steps",
    "--tls-dir",
    "--identity",
    "--tls-ca",
    "--tls-cert",
    "--tls-key",
];
/// Parses and checks the topology file `text`.
pub fn parse(text: &str) -> Result<Topology, TopologyError> {
    let at = |span: Range<usize>, message: String| TopologyError { line: line_of(text, span.start), message };
    let file: File = toml::from_str(text).map_err(|e| {
        let start = e.span().map_or(0, |s| s.start);
        at(start..start, e.message().to_owned())
    })?;
    let mut names: HashMap<String, (Endpoint, usize)> = HashMap::new();
    let mut claim = |name: &Spanned<String>, end: Endpoint| {
        let line = line_of(text, name.span().start);
        check_name(name.get_ref()).map_err(|m| at(name.span(), m))?;
        match names.insert(name.get_ref().clone(), (end, line)) {
            Some((_, first)) => {
                Err(at(name.span(), format!("duplicate name {:?} (first on line {first})", name.get_ref())))
            }
            None => Ok(()),
        }
    };
    let mut sites = Vec::new();
    for (k, s) in file.site.iter().enumerate() {
        claim(&s.name, Endpoint::Site(k))?;
        sites.push(Site { name: s.name.get_ref().clone(), router: s.router });
    }
    let site_index: HashMap<&str, usize> = sites.iter().enumerate().map(|(k, s)| (s.name.as_str(), k)).collect();
    let mut hosts = Vec::new();
    for (k, h) in file.host.iter().enumerate() {
        claim(&h.name, Endpoint::Host(k))?;
        let site = *site_index.get(h.site.get_ref().as_str()).ok_or_else(|| {
            at(h.site.span(), format!("host {:?}: unknown site {:?}", h.name.get_ref(), h.site.get_ref()))
        })?;
        let mut run = Vec::new();
        for p in &h.run {
            let role = ROLES.iter().find(|r| **r == p.role.get_ref()).ok_or_else(|| {
                at(p.role.span(), format!("unknown role {:?} (roles: {})", p.role.get_ref(), ROLES.join(", ")))
            })?;
            // Also given: an edge's site is its host's, its id its host's name; a scene's site.
            let also: &[&str] = match *role {
                "vehicle" | "rsu" => &["--id", "--site"],
                "scene" => &["--site", "--participant-summaries"],
                _ => &[],
            };
            let given = p.args.iter().find(|a| {
                let flag = a.split('=').next();
                GIVEN_ARGS.iter().chain(also).any(|g| flag == Some(*g))
            });
            if let Some(arg) = given {
                let message = format!("{arg}: the deployment gives this argument (addresses are assigned)");
                return Err(at(p.role.span(), message));
            }
            if file.tls && *role == "scene" {
                // A scene meets on its own plain loopback router and peers (docs/security.md).
                return Err(at(p.role.span(), "a scene does not run under `tls = true` yet".to_owned()));
            }
            let restart = p.restart.as_ref().map_or(Restart::default(), |r| *r.get_ref());
            run.push(Process { role, args: p.args.clone(), restart });
        }
        hosts.push(Host { name: h.name.get_ref().clone(), site, run });
    }
    for (k, h) in hosts.iter().enumerate() {
        let first = hosts[..k].iter().find(|o| o.site == h.site && o.run.iter().any(|p| p.role == "router"));
        let routers = h.run.iter().filter(|p| p.role == "router").count();
        let other = match (first, routers) {
            (Some(f), 1..) => Some(format!("and so does {:?}", f.name)),
            (None, 2..) => Some("twice".to_owned()),
            _ => None,
        };
        if let Some(other) = other {
            let message = format!("host {:?} runs its site's router {other}: one router per site", h.name);
            return Err(at(file.host[k].name.span(), message));
        }
    }
    let mut links = Vec::new();
    for l in &file.link {
        let between = l.between.get_ref();
        let [a, b] = between.as_slice() else {
            return Err(at(l.between.span(), format!("a link is between two names, got {}", between.len())));
        };
        if a == b {
            return Err(at(l.between.span(), format!("a link from {a:?} to itself")));
        }
        let end = |name: &String| {
            names
                .get(name)
                .map(|(end, _)| *end)
                .ok_or_else(|| at(l.between.span(), format!("link to {name:?}, which is neither a site nor a host")))
        };
        let ends = [end(a)?, end(b)?];
        let latency_ms = l.latency_ms.as_ref().map_or(0.0, |v| *v.get_ref());
        if let Some(v) = &l.latency_ms
            && !(0.0..=MAX_LATENCY_MS).contains(&latency_ms)
        {
            return Err(at(v.span(), format!("latency_ms {latency_ms} must lie in [0, {MAX_LATENCY_MS}]")));
        }
        let jitter = l.jitter.as_ref().map(|j| (j.span(), *j.get_ref()));
        if let Some((span, j)) = &jitter {
            let (Jitter::Normal { sd_ms: v } | Jitter::Uniform { max_ms: v }) = *j;
            if !(0.0..=MAX_LATENCY_MS).contains(&v) {
                return Err(at(span.clone(), format!("jitter {v} ms must lie in [0, {MAX_LATENCY_MS}]")));
            }
        }
        let bandwidth_mbps = l.bandwidth_mbps.as_ref().map(|b| (b.span(), *b.get_ref()));
        if let Some((span, b)) = &bandwidth_mbps
            && !(MIN_BANDWIDTH_MBPS..=MAX_BANDWIDTH_MBPS).contains(b)
        {
            let range = format!("[{MIN_BANDWIDTH_MBPS}, {MAX_BANDWIDTH_MBPS}]");
            return Err(at(span.clone(), format!("bandwidth_mbps {b} must lie in {range}")));
        }
        let queue_kib = match &l.queue_kib {
            Some(q) if !(1..=MAX_QUEUE_KIB).contains(q.get_ref()) => {
                return Err(at(q.span(), format!("queue_kib must lie in [1, {MAX_QUEUE_KIB}]")));
            }
            Some(q) => *q.get_ref(),
            None => DEFAULT_QUEUE_KIB,
        };
        let name = l.name.as_ref().map_or_else(|| format!("{a}-{b}"), |n| n.get_ref().clone());
        let name_span = l.name.as_ref().map_or_else(|| l.between.span(), |n| n.span());
        if l.name.is_some() {
            check_name(&name).map_err(|m| at(name_span.clone(), m))?;
        }
        if links.iter().any(|k: &Link| k.name == name) || names.contains_key(&name) {
            let message = format!("duplicate name {name:?} (a link's name differs from every site, host and link)");
            return Err(at(name_span, message));
        }
        links.push(Link {
            name,
            ends,
            latency_ms,
            jitter: jitter.map(|(_, j)| j),
            bandwidth_mbps: bandwidth_mbps.map(|(_, b)| b),
            queue_kib,
        });
    }
    let mut events = Vec::new();
    for e in &file.event {
        events.push(check_event(e, &names, &sites, &hosts, &links, &at)?);
    }
    events.sort_by_key(|e: &Event| e.at);
    let topology = Topology { tls: file.tls, sites, hosts, links, events };
    if let Some(k) = topology.unreachable_host() {
        let h = &file.host[k];
        let message =
            format!("host {:?} can reach no router (its site has none and no link leads to one)", h.name.get_ref());
        return Err(at(h.name.span(), message));
    }
    Ok(topology)
}

impl Topology {
    /// The site of an endpoint.
    fn site_of(&self, end: Endpoint) -> usize {
        match end {
            Endpoint::Site(s) => s,
            Endpoint::Host(h) => self.hosts[h].site,
        }
    }

    /// The first host whose site is joined to no site with a router, through links.
    fn unreachable_host(&self) -> Option<usize> {
        let mut reach: Vec<bool> = self.sites.iter().map(|s| s.router).collect();
        for h in self.hosts.iter().filter(|h| h.run.iter().any(|p| p.role == "router")) {
            reach[h.site] = true;
        }
        // Links join sites both ways; spread until nothing changes.
        let mut changed = true;
        while changed {
            changed = false;
            for l in &self.links {
                let (a, b) = (self.site_of(l.ends[0]), self.site_of(l.ends[1]));
                if reach[a] != reach[b] {
                    reach[a] = true;
                    reach[b] = true;
                    changed = true;
                }
            }
        }
        self.hosts.iter().position(|h| !reach[h.site])
    }
}

/// Names become Zenoh key chunks and namespace names: letters, digits, `-` and `_`, at most 32.
fn check_name(name: &str) -> Result<(), String> {
    let ok = !name.is_empty()
        && name.len() <= 32
        && name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_');
    if ok { Ok(()) } else { Err(format!("name {name:?}: use 1–32 letters, digits, '-' or '_'")) }
}

/// The 1-based line of byte offset `at` in `text`.
fn line_of(text: &str, at: usize) -> usize {
    text.as_bytes()[..at.min(text.len())].iter().filter(|&&b| b == b'\n').count() + 1
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    pub(in crate::topology) const TWO_SITES: &str = r#"
[[site]]
name = "cloud"

[[site]]
name = "north"

[[host]]
name = "cloud-0"
site = "cloud"
run = [{ role = "cloud", args = ["--roles", "ingest,twin"] }]

[[host]]
name = "car-1"
site = "north"
run = [{ role = "vehicle" }]

[[link]]
between = ["north", "cloud"]
latency_ms = 20
jitter = { dist = "normal", sd_ms = 2 }
bandwidth_mbps = 100
"#;

    #[test]
    fn a_two_site_topology_is_read_with_its_links_resolved() {
        let t = parse(TWO_SITES).expect("a valid topology");
        assert_eq!(
            t.sites.iter().map(|s| (s.name.as_str(), s.router)).collect::<Vec<_>>(),
            [("cloud", true), ("north", true)]
        );
        assert_eq!(t.hosts[1].site, 1);
        let cloud =
            Process { role: "cloud", args: vec!["--roles".into(), "ingest,twin".into()], restart: Restart::OnFailure };
        assert_eq!(t.hosts[0].run[0], cloud);
        let link = &t.links[0];
        assert_eq!(link.ends, [Endpoint::Site(1), Endpoint::Site(0)]);
        assert_eq!(
            (link.latency_ms, link.jitter, link.bandwidth_mbps),
            (20.0, Some(Jitter::Normal { sd_ms: 2.0 }), Some(100.0))
        );
        assert_eq!(link.queue_kib, DEFAULT_QUEUE_KIB);
    }

    #[test]
    fn each_mistake_is_refused_with_its_line() {
        let cases: [(&str, &str, usize, &str); 11] = [
            (
                "an address",
                r#"{ role = "vehicle" }"#,
                16,
                r#"{ role = "vehicle", args = ["--connect", "tcp/1.2.3.4:7447"] }"#,
            ),
            ("huge latency", "latency_ms = 20", 20, "latency_ms = 1e300"),
            ("tiny bandwidth", "bandwidth_mbps = 100", 22, "bandwidth_mbps = 1e-300"),
            ("unknown host", r#"between = ["north", "cloud"]"#, 19, r#"between = ["north", "nowhere"]"#),
            ("negative latency", "latency_ms = 20", 20, "latency_ms = -1"),
            ("duplicate", r#"name = "car-1""#, 14, r#"name = "cloud-0""#),
            ("unknown role", r#"run = [{ role = "vehicle" }]"#, 16, r#"run = [{ role = "teleporter" }]"#),
            ("unknown site", r#"site = "north""#, 15, r#"site = "south""#),
            ("bad jitter", "sd_ms = 2", 21, "sd_ms = -2"),
            ("unknown field", "bandwidth_mbps = 100", 22, "bandwidth_gbps = 100"),
            ("bad name", r#"name = "north""#, 6, r#"name = "no rth""#),
        ];
        for (what, from, line, to) in cases {
            let text = TWO_SITES.replacen(from, to, 1);
            assert_ne!(text, TWO_SITES, "{what}: the case changes the file");
            let e = parse(&text).expect_err(what);
            assert_eq!(e.line, line, "{what}: {e}");
        }
    }

    #[test]
    fn the_example_topologies_are_valid() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("topologies");
        let mut read = 0;
        for entry in std::fs::read_dir(&dir).expect("deploy/topologies") {
            let path = entry.expect("an entry").path();
            let text = std::fs::read_to_string(&path).expect("readable");
            parse(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            read += 1;
        }
        assert!(read >= 3, "the examples the docs name");
    }

    #[test]
    fn a_host_that_reaches_no_router_is_refused() {
        let routerless = TWO_SITES.replacen("name = \"north\"", "name = \"north\"\nrouter = false", 1);
        assert!(parse(&routerless).is_ok(), "through the link, north reaches the cloud's router");
        let isolated = routerless.replace("between = [\"north\", \"cloud\"]", "between = [\"car-1\", \"north\"]");
        let e = parse(&isolated).expect_err("car-1 reaches no router");
        assert!(e.message.contains("\"car-1\" can reach no router"), "{e}");
        assert_eq!(e.line, 15, "the host's name: {e}");
    }
}
