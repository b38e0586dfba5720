//! Where the emulated machines live: one Linux network namespace each, joined to the root
//! namespace by a veth pair (the relays listen on the root side, so every byte between two
//! machines crosses its links' relays: the root namespace forwards nothing itself), or, where
//! namespaces cannot be made, all on loopback with the same relays.
//!
//! Names carry the deployment's tag, so that a teardown finds everything by name even after a
//! crash: namespaces `rt-<tag>-<machine>`, veths `rt<tag><k>a` (root side) and `…b`. Addresses
//! come from a free /16 of 10.100.0.0–10.227.0.0, chosen under a lock: machine k gets the /30
//! 10.B.(4k / 256).(4k mod 256), `.1` the root side, `.2` its own.

use super::lock::Lock;
use std::io;
use std::net::Ipv4Addr;
use std::path::Path;
use std::process::{Command, Stdio};

/// The first and last second octets of the address blocks.
const BLOCKS: std::ops::RangeInclusive<u8> = 100..=227;
/// The most machines a /16 holds.
pub const MAX_MACHINES: usize = 16_384;

/// The machines' network.
#[derive(Debug)]
pub enum Net {
    Namespaces { block: u8, names: Vec<String> },
    Loopback,
}

/// Runs `ip` with `args`; its stderr becomes the error.
fn ip(args: &[&str]) -> io::Result<String> {
    let out = Command::new("ip").args(args).stdin(Stdio::null()).output()?;
    if out.status.success() {
        Ok(String::from_utf8_lossy(&out.stdout).into_owned())
    } else {
        let err = String::from_utf8_lossy(&out.stderr);
        Err(io::Error::other(format!("ip {}: {}", args.join(" "), err.trim())))
    }
}

/// The namespace of machine `name`.
pub fn namespace(tag: &str, name: &str) -> String {
    format!("rt-{tag}-{name}")
}

fn veth(tag: &str, k: usize, side: char) -> String {
    format!("rt{tag}{k}{side}")
}

/// The /30 of machine `k`: (root side, its own side).
fn addresses(block: u8, k: usize) -> (Ipv4Addr, Ipv4Addr) {
    let base = 4 * k as u32;
    let at = |last: u32| Ipv4Addr::new(10, block, ((base + last) >> 8) as u8, ((base + last) & 0xff) as u8);
    (at(1), at(2))
}

impl Net {
    /// Makes a namespace per machine, or says why it cannot (then nothing is left behind).
    pub fn namespaces(tag: &str, machines: &[String], lock_dir: &Path) -> io::Result<Net> {
        if unsafe { libc::geteuid() } != 0 {
            return Err(io::Error::other("network namespaces need root"));
        }
        if machines.len() > MAX_MACHINES {
            return Err(io::Error::other(format!("more than {MAX_MACHINES} machines")));
        }
        let _lock = Lock::take(&lock_dir.join("risktwin-deploy.lock"))?;
        let used = ip(&["-4", "-o", "addr", "show"])?;
        let block = BLOCKS
            .clone()
            .find(|b| !used.contains(&format!(" 10.{b}.")))
            .ok_or_else(|| io::Error::other("every address block 10.100–227.0.0/16 is in use"))?;
        let names: Vec<String> = machines.iter().map(|m| namespace(tag, m)).collect();
        let net = Net::Namespaces { block, names: names.clone() };
        let made = (|| {
            for (k, ns) in names.iter().enumerate() {
                let (outer, inner) = addresses(block, k);
                let (a, b) = (veth(tag, k, 'a'), veth(tag, k, 'b'));
                ip(&["netns", "add", ns])?;
                ip(&["link", "add", &a, "type", "veth", "peer", "name", &b, "netns", ns])?;
                ip(&["addr", "add", &format!("{outer}/30"), "dev", &a])?;
                ip(&["link", "set", &a, "up"])?;
                ip(&["-n", ns, "addr", "add", &format!("{inner}/30"), "dev", &b])?;
                ip(&["-n", ns, "link", "set", &b, "up"])?;
                ip(&["-n", ns, "link", "set", "lo", "up"])?;
            }
            Ok(())
        })();
        match made {
            Ok(()) => Ok(net),
            Err(e) => {
                sweep(tag);
                Err(e)
            }
        }
    }

    /// Where machine `k`'s relays listen (its side of the root namespace).
    pub fn gateway(&self, k: usize) -> Ipv4Addr {
        match self {
            Net::Namespaces { block, .. } => addresses(*block, k).0,
            Net::Loopback => Ipv4Addr::LOCALHOST,
        }
    }

    /// Machine `k`'s own address (where its router listens).
    pub fn own(&self, k: usize) -> Ipv4Addr {
        match self {
            Net::Namespaces { block, .. } => addresses(*block, k).1,
            Net::Loopback => Ipv4Addr::LOCALHOST,
        }
    }

    /// What a command of machine `k` is prefixed with.
    pub fn exec_prefix(&self, k: usize) -> Vec<String> {
        match self {
            Net::Namespaces { names, .. } => vec!["ip".into(), "netns".into(), "exec".into(), names[k].clone()],
            Net::Loopback => Vec::new(),
        }
    }

    pub fn describe(&self) -> String {
        match self {
            Net::Namespaces { block, names, .. } => {
                format!("{} network namespaces, addresses in 10.{block}.0.0/16", names.len())
            }
            Net::Loopback => "loopback (no network namespaces)".to_owned(),
        }
    }
}

/// Removes everything of deployment `tag`: the processes in its namespaces, the namespaces and
/// veths. Idempotent; what it cannot remove it says on stderr.
pub fn sweep(tag: &str) {
    for ns in namespaces(tag) {
        for pid in ip(&["netns", "pids", &ns]).unwrap_or_default().split_whitespace() {
            if let Ok(pid) = pid.parse::<i32>() {
                // SAFETY: a plain signal to a process of the deployment's namespace.
                unsafe { libc::kill(pid, libc::SIGKILL) };
            }
        }
        if let Err(e) = ip(&["netns", "del", &ns]) {
            eprintln!("warning: {e}");
        }
    }
    // Deleting a namespace takes its veth pair with it, a moment later.
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(2);
    while !veths(tag).is_empty() && std::time::Instant::now() < deadline {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    for name in veths(tag) {
        if let Err(e) = ip(&["link", "del", &name])
            && veths(tag).contains(&name)
        {
            eprintln!("warning: {e}");
        }
    }
}

/// The root-side veths of deployment `tag`.
fn veths(tag: &str) -> Vec<String> {
    let root_side = format!("rt{tag}");
    ip(&["-o", "link", "show"])
        .unwrap_or_default()
        .lines()
        .filter_map(|l| l.split(':').nth(1))
        .map(|n| n.trim().split('@').next().unwrap_or("").to_owned())
        .filter(|n| n.starts_with(&root_side))
        .collect()
}

/// Whether anything of deployment `tag` is left (namespaces or veths).
pub fn leftovers(tag: &str) -> Vec<String> {
    let mut left = namespaces(tag);
    left.extend(veths(tag));
    left
}

/// The namespaces of deployment `tag`.
fn namespaces(tag: &str) -> Vec<String> {
    let prefix = format!("rt-{tag}-");
    ip(&["netns", "list"])
        .unwrap_or_default()
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .filter(|n| n.starts_with(&prefix))
        .map(str::to_owned)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn machines_get_disjoint_slash_30s() {
        assert_eq!(addresses(100, 0), (Ipv4Addr::new(10, 100, 0, 1), Ipv4Addr::new(10, 100, 0, 2)));
        assert_eq!(addresses(100, 64), (Ipv4Addr::new(10, 100, 1, 1), Ipv4Addr::new(10, 100, 1, 2)));
        let last = addresses(227, MAX_MACHINES - 1);
        assert_eq!(last, (Ipv4Addr::new(10, 227, 255, 253), Ipv4Addr::new(10, 227, 255, 254)));
        assert!(veth("abcdef", 9999, 'a').len() <= 15, "an interface name has at most 15 bytes");
    }
}
