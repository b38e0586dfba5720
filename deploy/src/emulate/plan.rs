//! From a checked topology to what runs: the emulated machines (the hosts, and a gateway for
//! each site whose router no host runs), the processes with their command lines, and the hops
//! each connection crosses on its way to a router.
//!
//! The network is a graph of sites and hosts: every host is joined to its site by the site's
//! network (a [`Hop::Lan`]) and the file's links join sites and hosts ([`Hop::Link`]). A
//! process joins the nearest router (fewest hops, ties to the earlier hop); routers peer with
//! every router they reach without crossing another one. Each hop becomes a relay.

use crate::topology::{Endpoint, Restart, Topology, router_on_gateway};
use std::collections::VecDeque;

/// What a hop is: a link of the file, or a host's way into its site's network.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Hop {
    Link(usize),
    Lan(usize),
}

/// An emulated machine.
#[derive(Debug, Clone, PartialEq)]
pub struct Machine {
    pub name: String,
    pub site: usize,
    /// The host it is (`None`: its site's gateway, which runs the site's router).
    pub host: Option<usize>,
}

/// One process of the deployment.
#[derive(Debug, Clone, PartialEq)]
pub struct Planned {
    pub machine: usize,
    /// `host/role`, or `host/role#k` for the k-th of a role the host runs more than once.
    pub name: String,
    pub role: &'static str,
    pub args: Vec<String>,
    pub restart: Restart,
    /// The site whose Zenoh keys an edge or scene uses.
    pub site: String,
    /// An edge's id: its host's name (`host.k` for the k-th edge of a host with several: no
    /// name of a topology has a dot, so no id can be another host's).
    pub edge_id: Option<String>,
    /// Routes to the routers it connects to (a client's one router, a router's peers).
    pub routes: Vec<usize>,
}

/// A way from a machine to a router.
#[derive(Debug, Clone, PartialEq)]
pub struct Route {
    pub from: usize,
    /// The machine whose router it reaches.
    pub to: usize,
    /// In order from `from`; empty when the router is on the same machine.
    pub hops: Vec<Hop>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    pub machines: Vec<Machine>,
    pub processes: Vec<Planned>,
    pub routes: Vec<Route>,
    /// Every hop, links first (in file order), then the hosts' LANs.
    pub hops: Vec<Hop>,
}

/// The roles that publish edge data (ended for good, they end a deployment run).
pub fn is_edge(role: &str) -> bool {
    matches!(role, "vehicle" | "rsu" | "replay" | "scene")
}

/// A vertex of the network graph: sites first, then hosts.
type Vertex = usize;

pub fn plan(t: &Topology) -> Plan {
    let sites = t.sites.len();
    let vertex = |e: Endpoint| match e {
        Endpoint::Site(s) => s,
        Endpoint::Host(h) => sites + h,
    };
    let mut adjacent: Vec<Vec<(Vertex, Hop)>> = vec![Vec::new(); sites + t.hosts.len()];
    for (h, host) in t.hosts.iter().enumerate() {
        adjacent[sites + h].push((host.site, Hop::Lan(h)));
        adjacent[host.site].push((sites + h, Hop::Lan(h)));
    }
    for (k, l) in t.links.iter().enumerate() {
        let (a, b) = (vertex(l.ends[0]), vertex(l.ends[1]));
        adjacent[a].push((b, Hop::Link(k)));
        adjacent[b].push((a, Hop::Link(k)));
    }
    let mut machines: Vec<Machine> = t
        .hosts
        .iter()
        .enumerate()
        .map(|(k, h)| Machine { name: h.name.clone(), site: h.site, host: Some(k) })
        .collect();
    // Each site's router: on the host that runs one, else on the site's gateway.
    let mut router_at: Vec<Option<Vertex>> = vec![None; sites + t.hosts.len()];
    let mut machine_of: Vec<Option<usize>> = vec![None; sites + t.hosts.len()];
    for (h, host) in t.hosts.iter().enumerate() {
        machine_of[sites + h] = Some(h);
        if host.run.iter().any(|p| p.role == "router") {
            router_at[sites + h] = Some(sites + h);
        }
    }
    let mut processes = Vec::new();
    for (s, site) in t.sites.iter().enumerate() {
        if router_on_gateway(&t.sites, &t.hosts, s) {
            machine_of[s] = Some(machines.len());
            router_at[s] = Some(s);
            processes.push(Planned {
                machine: machines.len(),
                name: format!("{}/router", site.name),
                role: "router",
                args: Vec::new(),
                restart: Restart::Always,
                site: site.name.clone(),
                edge_id: None,
                routes: Vec::new(),
            });
            machines.push(Machine { name: site.name.clone(), site: s, host: None });
        }
    }
    for (h, host) in t.hosts.iter().enumerate() {
        let edges = host.run.iter().filter(|p| matches!(p.role, "vehicle" | "rsu")).count();
        let mut edge_k = 0;
        for (k, p) in host.run.iter().enumerate() {
            let same = host.run.iter().filter(|q| q.role == p.role).count();
            let before = host.run[..k].iter().filter(|q| q.role == p.role).count();
            let name = if same > 1 {
                format!("{}/{}#{before}", host.name, p.role)
            } else {
                format!("{}/{}", host.name, p.role)
            };
            let edge_id = matches!(p.role, "vehicle" | "rsu").then(|| {
                edge_k += 1;
                if edges > 1 { format!("{}.{}", host.name, edge_k - 1) } else { host.name.clone() }
            });
            processes.push(Planned {
                machine: h,
                name,
                role: p.role,
                args: p.args.clone(),
                restart: p.restart,
                site: t.sites[host.site].name.clone(),
                edge_id,
                routes: Vec::new(),
            });
        }
    }
    let mut routes: Vec<Route> = Vec::new();
    let mut route_to = |from: usize, to: usize, hops: Vec<Hop>| {
        if let Some(k) = routes.iter().position(|r| r.from == from && r.to == to) {
            return k;
        }
        routes.push(Route { from, to, hops });
        routes.len() - 1
    };
    let is_router = |v: Vertex| router_at[v] == Some(v);
    for p in &mut processes {
        let start = if p.machine < t.hosts.len() { sites + p.machine } else { machines[p.machine].site };
        if p.role == "router" {
            // Peers: every router reached without crossing another; of two, the one whose
            // vertex comes first (sites before hosts, in file order) connects.
            for (v, hops) in reach(&adjacent, start, &is_router, true) {
                if v > start {
                    p.routes.push(route_to(p.machine, machine_of[v].expect("a router vertex has a machine"), hops));
                }
            }
        } else if let Some((v, hops)) = reach(&adjacent, start, &is_router, false).into_iter().next() {
            p.routes.push(route_to(p.machine, machine_of[v].expect("a router vertex has a machine"), hops));
        }
    }
    let hops = (0..t.links.len()).map(Hop::Link).chain((0..t.hosts.len()).map(Hop::Lan)).collect();
    Plan { machines, processes, routes, hops }
}

/// The router vertices reachable from `start` by breadth-first search (not through another
/// router), nearest first, with their hops; `start` itself when it is one (with no hops),
/// unless `beyond` (a router looking for its peers).
fn reach(
    adjacent: &[Vec<(Vertex, Hop)>],
    start: Vertex,
    is_router: &impl Fn(Vertex) -> bool,
    beyond: bool,
) -> Vec<(Vertex, Vec<Hop>)> {
    let mut came: Vec<Option<(Vertex, Hop)>> = vec![None; adjacent.len()];
    let mut seen = vec![false; adjacent.len()];
    let mut queue = VecDeque::from([start]);
    seen[start] = true;
    let mut found = Vec::new();
    while let Some(v) = queue.pop_front() {
        if is_router(v) && (v != start || !beyond) {
            let mut hops = Vec::new();
            let mut at = v;
            while let Some((prev, hop)) = came[at] {
                hops.push(hop);
                at = prev;
            }
            hops.reverse();
            found.push((v, hops));
            continue;
        }
        for &(w, hop) in &adjacent[v] {
            if !seen[w] {
                seen[w] = true;
                came[w] = Some((v, hop));
                queue.push_back(w);
            }
        }
    }
    found
}

/// The `risktwin` arguments of process `p`: `connect` are the addresses of its routes (in
/// order), `listen` a router's own address.
/// A host's clock steps (one signed number of ms per line), in the host's folder.
pub const CLOCK_STEPS_FILE: &str = "clock-steps";

/// The extension of the file, beside a scene's logs, its participants' summaries are appended to.
pub const PARTICIPANTS_EXT: &str = "participants";

/// The name a process's files in its host's folder start with (`vehicle-1.log`, …).
pub fn file_stem(p: &Planned) -> String {
    p.name.rsplit('/').next().unwrap_or(p.role).replace('#', "-")
}

pub fn argv(p: &Planned, connect: &[String], listen: Option<&str>) -> Vec<String> {
    let s = |v: &str| v.to_owned();
    let mut argv: Vec<String> = match p.role {
        "router" => vec![s("router")],
        "cloud" => vec![s("cloud")],
        "vehicle" | "rsu" => vec![s("edge"), s(p.role)],
        "replay" => vec![s("edge"), s("replay")],
        _ => vec![s("scene"), s("run")],
    };
    if let Some(id) = &p.edge_id {
        argv.extend([s("--id"), id.clone()]);
    }
    if matches!(p.role, "vehicle" | "rsu" | "scene") {
        argv.extend([s("--site"), p.site.clone()]);
    }
    argv.extend(p.args.iter().cloned());
    match p.role {
        "router" => {
            argv.extend(listen.map(|l| [s("--listen"), s(l)]).into_iter().flatten());
            argv.extend(connect.iter().flat_map(|c| [s("--connect"), c.clone()]));
        }
        "scene" => {
            // Deployments run scenes in real time, unless told otherwise (a clock, or a lockstep
            // scene's pace: `scene run` refuses `--speed` with the real-time clock).
            if !p.args.iter().any(|a| a.starts_with("--clock") || a.starts_with("--speed")) {
                argv.extend([s("--clock"), s("realtime")]);
            }
            // Its data goes through the host's route; its physics stays on the host, on the
            // scene's own loopback router: no emulated link or partition touches it.
            argv.extend(connect.first().map(|c| [s("--data-router"), c.clone()]).into_iter().flatten());
            // Relative to the host's folder, the process's working directory: what each
            // participant sent, for the report.
            argv.extend([s("--participant-summaries"), format!("{}.{PARTICIPANTS_EXT}", file_stem(p))]);
        }
        _ => {
            if matches!(p.role, "vehicle" | "rsu") {
                // Relative to the host's folder, the process's working directory: one file per
                // host, so that a clock_step steps every edge of the host, restarted ones too.
                argv.extend([s("--clock-steps"), s(CLOCK_STEPS_FILE)]);
            }
            argv.extend([s("--mode"), s("client")]);
            argv.extend(connect.iter().flat_map(|c| [s("--connect"), c.clone()]));
        }
    }
    argv
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::topology::parse;

    const CORRIDOR: &str = r#"
[[site]]
name = "cloud"

[[site]]
name = "road"
router = false

[[host]]
name = "cloud-0"
site = "cloud"
run = [{ role = "cloud", args = ["--roles", "ingest"] }]

[[host]]
name = "car"
site = "road"
run = [{ role = "vehicle" }, { role = "vehicle" }]

[[link]]
between = ["road", "cloud"]
latency_ms = 20
"#;

    #[test]
    fn a_routerless_site_reaches_the_cloud_router_over_its_link() {
        let t = parse(CORRIDOR).expect("valid");
        let plan = plan(&t);
        let names: Vec<&str> = plan.machines.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names, ["cloud-0", "car", "cloud"], "hosts, then the cloud site's gateway");
        let car: Vec<&Planned> = plan.processes.iter().filter(|p| p.machine == 1).collect();
        assert_eq!(car.iter().map(|p| p.name.as_str()).collect::<Vec<_>>(), ["car/vehicle#0", "car/vehicle#1"]);
        assert_eq!(car[1].edge_id.as_deref(), Some("car.1"));
        let route = &plan.routes[car[0].routes[0]];
        assert_eq!((route.from, route.to), (1, 2));
        assert_eq!(route.hops, [Hop::Lan(1), Hop::Link(0)], "into the road's network, then the link");
        let cloud = plan.processes.iter().find(|p| p.role == "cloud").expect("the cloud");
        assert_eq!(plan.routes[cloud.routes[0]].hops, [Hop::Lan(0)]);
        let argv = argv(car[1], &["tcp/10.0.0.1:4000".into()], None);
        assert_eq!(
            argv.join(" "),
            "edge vehicle --id car.1 --site road --clock-steps clock-steps --mode client --connect tcp/10.0.0.1:4000"
        );
    }

    #[test]
    fn routers_of_linked_sites_peer_once() {
        let two = CORRIDOR.replace("router = false\n", "");
        let plan = plan(&parse(&two).expect("valid"));
        let routers: Vec<&Planned> = plan.processes.iter().filter(|p| p.role == "router").collect();
        assert_eq!(routers.len(), 2);
        let peerings: usize = routers.iter().map(|r| r.routes.len()).sum();
        assert_eq!(peerings, 1, "one connection between the two routers");
        let route = routers.iter().flat_map(|r| &r.routes).map(|&k| &plan.routes[k]).next().expect("a peering");
        assert_eq!(route.hops, [Hop::Link(0)]);
        let car = plan.processes.iter().find(|p| p.name == "car/vehicle#0").expect("the car");
        assert_eq!(plan.routes[car.routes[0]].hops, [Hop::Lan(1)], "its own site's router now");
    }

    #[test]
    fn a_router_on_a_host_serves_its_site() {
        let hosted = CORRIDOR.replace(
            r#"run = [{ role = "cloud", args = ["--roles", "ingest"] }]"#,
            r#"run = [{ role = "router" }, { role = "cloud", args = ["--roles", "ingest"] }]"#,
        );
        let plan = plan(&parse(&hosted).expect("valid"));
        assert_eq!(plan.machines.len(), 2, "no gateway: cloud-0 runs the router");
        let cloud = plan.processes.iter().find(|p| p.role == "cloud").expect("the cloud");
        assert_eq!(plan.routes[cloud.routes[0]].hops, [], "the router on its own machine");
        let car = plan.processes.iter().find(|p| p.name == "car/vehicle#0").expect("the car");
        assert_eq!(plan.routes[car.routes[0]].hops, [Hop::Lan(1), Hop::Link(0), Hop::Lan(0)]);
    }
}
