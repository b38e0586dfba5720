//! A TLS deployment's certificates (`tls = true` in the topology): one CA per run and a
//! certificate per process, in the run's `certs/` folder, which every process reads with
//! `--tls-dir` (the routers build their access rules from it; docs/security.md).

use super::plan::{Planned, file_stem};
use risktwin_transport::tls::certs;
use risktwin_transport::{Identity, TlsError};
use std::collections::BTreeMap;
use std::net::IpAddr;
use std::path::Path;

/// The folder of the run's certificates.
pub const CERTS_DIR: &str = "certs";

/// The identity process `p` on machine `machine` runs as: a router by its machine, an edge by
/// its site and id, and every other role (cloud, replay) as a cloud named after its machine
/// and process.
pub fn identity(p: &Planned, machine: &str) -> String {
    match (p.role, &p.edge_id) {
        ("router", _) => format!("router:{machine}"),
        (_, Some(id)) => format!("edge:{}:{id}", p.site),
        _ => format!("cloud:{machine}.{}", file_stem(p)),
    }
}

/// Makes the CA and one certificate per identity in `dir`; a router's answers to `sans`
/// (the addresses its clients dial: its own and its relays').
pub fn make(dir: &Path, identities: &BTreeMap<String, Vec<IpAddr>>) -> Result<(), TlsError> {
    let mut issued = Vec::new();
    for (name, sans) in identities {
        let identity: Identity = name.parse()?;
        issued.push((identity, sans.iter().map(ToString::to_string).collect()));
    }
    certs::init(dir, &issued)?;
    Ok(())
}
