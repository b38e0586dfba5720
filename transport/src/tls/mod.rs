//! Who may speak on the Zenoh network: mutual TLS on every link and the routers' access rules
//! (docs/security.md).
//!
//! Every process holds a certificate signed by the deployment's CA (`certs`); its subject
//! common name is its [`Identity`], by role: `edge:<site>:<id>`, `cloud:<name>`,
//! `router:<name>`. A router admits only links whose certificate the CA signed, and its access
//! rules (`acl`), built from the certificates it knows, say what each identity may publish,
//! subscribe to, query and answer: an edge only its own keys. Plain TCP stays available as
//! [`Security::Insecure`] for local experiments.

pub mod acl;
pub mod certs;

use crate::keyexpr::{KeyError, SiteId, SourceId};
use std::fmt;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// How a session's links are secured.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum Security {
    /// Plain TCP: no encryption, no authentication, no access control. For experiments on one
    /// host; a role that reaches beyond loopback this way says so once (`insecure_endpoint`).
    #[default]
    Insecure,
    /// TLS with mutual authentication on every link (`tls/` endpoints only).
    Tls(TlsFiles),
}

/// The PEM files of one TLS identity.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TlsFiles {
    /// The CA every peer's certificate must chain to.
    pub ca_cert: PathBuf,
    /// This process's certificate (signed by the CA).
    pub cert: PathBuf,
    /// This process's private key (PKCS#8).
    pub key: PathBuf,
}

impl TlsFiles {
    /// The files of `identity` in a directory made by `risktwin certs`: `ca.pem`,
    /// `<common name>.pem`, `<common name>-key.pem`.
    pub fn in_dir(dir: &Path, identity: &str) -> TlsFiles {
        TlsFiles {
            ca_cert: dir.join(certs::CA_CERT_FILE),
            cert: dir.join(format!("{identity}.pem")),
            key: dir.join(format!("{identity}-key.pem")),
        }
    }

    /// Each file must be readable and hold a PEM block of its kind: a wrong path is the
    /// user's mistake, told before any link is tried.
    pub fn check(&self) -> Result<(), TlsError> {
        for (path, label) in [(&self.ca_cert, "CERTIFICATE"), (&self.cert, "CERTIFICATE"), (&self.key, "PRIVATE KEY")] {
            let text = std::fs::read_to_string(path)
                .map_err(|e| TlsError::Read { path: path.clone(), reason: e.to_string() })?;
            if !text.contains(&format!("-----BEGIN {label}-----")) {
                return Err(TlsError::NotPem { path: path.clone(), expected: label });
            }
        }
        Ok(())
    }
}

/// What a certificate's common name says its holder is. Rules are by role; an edge's carry
/// its site and id because it may publish only under its own keys.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Identity {
    /// A vehicle, an RSU or another source publishing as `<site>/<id>`.
    Edge { site: SiteId, id: SourceId },
    /// A cloud (ingest, twin, loop, pusher): reads every edge, pushes to every edge.
    Cloud { name: String },
    /// A Zenoh router: forwards everything to its peer routers.
    Router { name: String },
}

/// The separator of a common name's parts: `:`, which no site or source id may hold (they
/// may hold `.`), so a name parses back to one identity only.
const SEP: char = ':';

impl Identity {
    /// The certificate subject's common name (and its files' stem).
    pub fn common_name(&self) -> String {
        self.to_string()
    }

    /// A cloud or router named `name` (the charset of a site id: letters, digits, `-_.`).
    pub fn named(role: &str, name: &str) -> Result<Identity, TlsError> {
        let name = SiteId::new(name).map_err(TlsError::BadName)?.as_str().to_owned();
        match role {
            "cloud" => Ok(Identity::Cloud { name }),
            "router" => Ok(Identity::Router { name }),
            other => Err(TlsError::BadRole { role: other.to_owned() }),
        }
    }
}

impl fmt::Display for Identity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Identity::Edge { site, id } => write!(f, "edge{SEP}{site}{SEP}{id}"),
            Identity::Cloud { name } => write!(f, "cloud{SEP}{name}"),
            Identity::Router { name } => write!(f, "router{SEP}{name}"),
        }
    }
}

impl std::str::FromStr for Identity {
    type Err = TlsError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let parts: Vec<&str> = s.split(SEP).collect();
        match parts.as_slice() {
            ["edge", site, id] => Ok(Identity::Edge {
                site: SiteId::new(*site).map_err(TlsError::BadName)?,
                id: SourceId::new(*id).map_err(TlsError::BadName)?,
            }),
            [role @ ("cloud" | "router"), name] => Identity::named(role, name),
            _ => Err(TlsError::BadIdentity { name: s.to_owned() }),
        }
    }
}

/// Why TLS files or identities could not be used.
#[derive(Debug, Error)]
pub enum TlsError {
    #[error("{path}: {reason}")]
    Read { path: PathBuf, reason: String },
    #[error("{path}: no PEM {expected} block")]
    NotPem { path: PathBuf, expected: &'static str },
    #[error("{path}: {reason}")]
    Write { path: PathBuf, reason: String },
    #[error("identity {name:?} is not edge:<site>:<id>, cloud:<name> or router:<name>")]
    BadIdentity { name: String },
    #[error("role {role:?} is not one of edge, cloud, router")]
    BadRole { role: String },
    #[error("{0}")]
    BadName(KeyError),
    #[error("{path}: already exists; `certs init` never overwrites a CA or a certificate")]
    Exists { path: PathBuf },
    #[error("{path}: not a certificate this tool can read: {reason}")]
    BadCertificate { path: PathBuf, reason: String },
    #[error("making a certificate for {name}: {reason}")]
    Generate { name: String, reason: String },
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identities_round_trip_through_their_common_names_even_with_dots_in_ids() {
        let edge = Identity::Edge { site: SiteId::new("a.b").unwrap(), id: SourceId::new("c.d").unwrap() };
        assert_eq!(edge.common_name(), "edge:a.b:c.d");
        assert_eq!("edge:a.b:c.d".parse::<Identity>().unwrap(), edge);
        assert_eq!("cloud:main".parse::<Identity>().unwrap(), Identity::Cloud { name: "main".into() });
        assert_eq!("router:r1".parse::<Identity>().unwrap(), Identity::Router { name: "r1".into() });
        for bad in ["edge:a", "edge:a:b:c", "vehicle:a:b", "cloud:", "cloud:a/b", "edge:s:cloud", ""] {
            assert!(bad.parse::<Identity>().is_err(), "{bad}");
        }
    }
}
