//! The event schedule of a topology: partitions, degraded links, killed and restarted
//! processes and stepped clocks, their names resolved against the checked hosts and links.

use super::checked::{
    Action, Endpoint, Event, Host, Link, MAX_BANDWIDTH_MBPS, MAX_LATENCY_MS, MIN_BANDWIDTH_MBPS, Site, Target,
    TopologyError, router_on_gateway,
};
use super::model::EventDef;
use std::collections::HashMap;
use std::ops::Range;
use std::time::Duration;
use toml::Spanned;

/// The latest an event may be scheduled, s (a day).
const MAX_EVENT_S: f64 = 86_400.0;

/// The largest clock step, ms (a day).
pub const MAX_CLOCK_STEP_MS: f64 = 86_400_000.0;

/// One event, its names resolved.
pub(super) fn check_event(
    e: &EventDef,
    names: &HashMap<String, (Endpoint, usize)>,
    sites: &[Site],
    hosts: &[Host],
    links: &[Link],
    at: &impl Fn(Range<usize>, String) -> TopologyError,
) -> Result<Event, TopologyError> {
    let seconds = |v: &Spanned<f64>, what: &str| {
        let s = *v.get_ref();
        match Duration::try_from_secs_f64(s) {
            Ok(d) if s <= MAX_EVENT_S => Ok(d),
            _ => Err(at(v.span(), format!("{what} {s} must lie in [0, {MAX_EVENT_S}] s"))),
        }
    };
    let start = seconds(&e.at_s, "at_s")?;
    let lasts = e.for_s.as_ref().map(|v| seconds(v, "for_s")).transpose()?;
    let actions = [&e.partition, &e.degrade, &e.kill, &e.restart, &e.clock_step];
    let given: Vec<&Spanned<String>> = actions.iter().filter_map(|a| a.as_ref()).collect();
    let [target] = given.as_slice() else {
        let message = "an event does one of partition, degrade, kill, restart, clock_step".to_owned();
        return Err(at(e.at_s.span(), format!("{message} (this one {})", given.len())));
    };
    let name = target.get_ref();
    let link_named = |name: &str| links.iter().position(|l| l.name == name);
    let process = |spec: &Spanned<String>| {
        let (host, role) = spec
            .get_ref()
            .split_once('/')
            .ok_or_else(|| at(spec.span(), format!("{:?}: write host/role or site/router", spec.get_ref())))?;
        if let Some(site) = sites.iter().position(|s| s.name == host) {
            return match (role, router_on_gateway(sites, hosts, site)) {
                ("router", true) => Ok(Target::SiteRouter { site }),
                ("router", false) => Err(at(
                    spec.span(),
                    format!("site {host:?} has no router of its own (a host of it runs the router, or none is run)"),
                )),
                _ => Err(at(spec.span(), format!("a site runs only its router: write {host}/router or host/role"))),
            };
        }
        let h = hosts
            .iter()
            .position(|x| x.name == host)
            .ok_or_else(|| at(spec.span(), format!("unknown host or site {host:?}")))?;
        let matching: Vec<usize> =
            hosts[h].run.iter().enumerate().filter(|(_, p)| p.role == role).map(|(k, _)| k).collect();
        match matching.as_slice() {
            [k] => Ok(Target::Hosted { host: h, process: *k }),
            [] => Err(at(spec.span(), format!("host {host:?} runs no {role:?}"))),
            _ => Err(at(spec.span(), format!("host {host:?} runs {role:?} more than once"))),
        }
    };
    let action = if e.partition.is_some() {
        let (cut, off): (Vec<usize>, Vec<usize>) = match (names.get(name), link_named(name)) {
            (Some((end, _)), _) => {
                // A site's partition cuts its hosts' own links too; a host's also its way into
                // its site's network.
                let touches = |e: &Endpoint| match (e, end) {
                    (Endpoint::Host(h), Endpoint::Site(s)) => hosts[*h].site == *s,
                    _ => e == end,
                };
                let cut = links.iter().enumerate().filter(|(_, l)| l.ends.iter().any(touches)).map(|(k, _)| k);
                let off = match end {
                    Endpoint::Host(h) => vec![*h],
                    Endpoint::Site(_) => Vec::new(),
                };
                (cut.collect(), off)
            }
            (None, Some(k)) => (vec![k], Vec::new()),
            (None, None) => {
                return Err(at(target.span(), format!("partition of {name:?}: no site, host or link of that name")));
            }
        };
        if cut.is_empty() && off.is_empty() {
            return Err(at(target.span(), format!("partition of {name:?}: it has no link to cut")));
        }
        Action::Partition { links: cut, hosts: off }
    } else if e.degrade.is_some() {
        let link = link_named(name).ok_or_else(|| at(target.span(), format!("degrade: no link named {name:?}")))?;
        let bad_latency = e.latency_ms.is_some_and(|v| !(0.0..=MAX_LATENCY_MS).contains(&v));
        let bad_bandwidth = e.bandwidth_mbps.is_some_and(|v| !(MIN_BANDWIDTH_MBPS..=MAX_BANDWIDTH_MBPS).contains(&v));
        if e.latency_ms.is_none() && e.bandwidth_mbps.is_none() || bad_latency || bad_bandwidth {
            let message = format!(
                "degrade needs latency_ms in [0, {MAX_LATENCY_MS}] and/or bandwidth_mbps in \
                 [{MIN_BANDWIDTH_MBPS}, {MAX_BANDWIDTH_MBPS}]"
            );
            return Err(at(target.span(), message));
        }
        Action::Degrade { link, latency_ms: e.latency_ms, bandwidth_mbps: e.bandwidth_mbps }
    } else if let Some(spec) = &e.kill {
        Action::Kill(process(spec)?)
    } else if let Some(spec) = &e.restart {
        Action::Restart(process(spec)?)
    } else {
        let host = hosts
            .iter()
            .position(|h| h.name == *name)
            .ok_or_else(|| at(target.span(), format!("clock_step: unknown host {name:?}")))?;
        let by_ms = e.by_ms.filter(|v| v.is_finite() && v.abs() <= MAX_CLOCK_STEP_MS).ok_or_else(|| {
            at(target.span(), format!("clock_step needs a finite by_ms within ± {MAX_CLOCK_STEP_MS}"))
        })?;
        // The clocks stepped are our edges' own (a Linux time namespace cannot shift the wall clock).
        if !hosts[host].run.iter().any(|p| matches!(p.role, "vehicle" | "rsu")) {
            return Err(at(
                target.span(),
                format!("clock_step: host {name:?} runs no vehicle or rsu, whose clocks it steps"),
            ));
        }
        Action::ClockStep { host, by_ms }
    };
    let lasting = matches!(action, Action::Partition { .. } | Action::Degrade { .. });
    if lasts.is_some() && !lasting {
        return Err(at(e.at_s.span(), "for_s belongs to a partition or a degradation".to_owned()));
    }
    Ok(Event { at: start, lasts, action })
}

#[cfg(test)]
mod tests {
    use super::super::check::parse;
    use super::super::check::tests::TWO_SITES;
    use super::*;

    #[test]
    fn events_are_resolved_and_ordered_and_their_mistakes_named() {
        let events = r#"
[[event]]
at_s = 12
restart = "cloud-0/cloud"

[[event]]
at_s = 5
partition = "north"
for_s = 3
"#;
        let t = parse(&format!("{TWO_SITES}{events}")).expect("valid events");
        assert_eq!(t.links[0].name, "north-cloud");
        let got: Vec<(f64, &Action)> = t.events.iter().map(|e| (e.at.as_secs_f64(), &e.action)).collect();
        let north = Action::Partition { links: vec![0], hosts: vec![] };
        assert_eq!(got, [(5.0, &north), (12.0, &Action::Restart(Target::Hosted { host: 0, process: 0 }))]);
        let gateway =
            parse(&format!("{TWO_SITES}\n[[event]]\nat_s = 1\nkill = \"north/router\"\n")).expect("a site's router");
        let north_site = gateway.sites.iter().position(|s| s.name == "north").expect("north");
        assert_eq!(gateway.events[0].action, Action::Kill(Target::SiteRouter { site: north_site }));
        assert_eq!(t.events[0].lasts, Some(Duration::from_secs(3)));
        for (bad, says) in [
            ("partition = \"south\"", "no site, host or link"),
            ("restart = \"car-1/cloud\"", "runs no \"cloud\""),
            ("kill = \"car-1\"", "write host/role"),
            ("kill = \"north/cloud\"", "a site runs only its router"),
            ("restart = \"south/router\"", "unknown host or site"),
            ("degrade = \"north-cloud\"", "degrade needs"),
            ("clock_step = \"car-1\"", "finite by_ms"),
            ("clock_step = \"car-1\"\nby_ms = 1e9", "within ± 86400000"),
            ("kill = \"car-1/vehicle\"\nrestart = \"car-1/vehicle\"", "one of"),
        ] {
            let text = format!("{TWO_SITES}\n[[event]]\nat_s = 1\n{bad}\n");
            let e = parse(&text).expect_err(bad);
            assert!(e.message.contains(says), "{bad}: {e}");
            assert!((25..=26).contains(&e.line), "{bad}: the event's line, {e}");
        }
        let far = format!("{TWO_SITES}\n[[event]]\nat_s = 1e20\npartition = \"north\"\n");
        assert!(parse(&far).expect_err("beyond a day").message.contains("at_s 100000000000000000000"));
    }
}
