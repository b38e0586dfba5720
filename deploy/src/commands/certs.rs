//! `risktwin certs init|issue`: the CA and certificates of a TLS deployment
//! (docs/security.md). Prints the files written as JSON.

use crate::cli::{CertsInitArgs, CertsIssueArgs};
use crate::error::{CliError, CliResult};
use crate::output::print_json;
use risktwin_transport::tls::certs;
use risktwin_transport::{Identity, SiteId, SourceId, TlsError};
use std::path::PathBuf;

pub fn init(args: CertsInitArgs) -> CliResult {
    let mut identities = Vec::new();
    for name in &args.identities {
        let identity: Identity = name.parse().map_err(CliError::input)?;
        let sans = if matches!(identity, Identity::Router { .. }) { args.router_sans.clone() } else { Vec::new() };
        identities.push((identity, sans));
    }
    let written = certs::init(&args.dir, &identities).map_err(blame)?;
    print_written(written)
}

pub fn issue(args: CertsIssueArgs) -> CliResult {
    let identity = match (args.role.as_str(), &args.site, &args.id, &args.name) {
        ("edge", Some(site), Some(id), None) => Identity::Edge {
            site: SiteId::new(site.as_str()).map_err(CliError::input)?,
            id: SourceId::new(id.as_str()).map_err(CliError::input)?,
        },
        ("edge", ..) => return Err(CliError::input("--role edge takes --site and --id (not --name)")),
        (role @ ("cloud" | "router"), None, None, Some(name)) => {
            Identity::named(role, name).map_err(CliError::input)?
        }
        ("cloud" | "router", ..) => return Err(CliError::input("--role cloud|router takes --name (not --site/--id)")),
        (other, ..) => return Err(CliError::input(format!("--role {other:?} is not one of edge, cloud, router"))),
    };
    if !args.sans.is_empty() && !matches!(identity, Identity::Router { .. }) {
        return Err(CliError::input("--san is for routers, the only role that accepts links"));
    }
    let written = certs::issue(&args.dir, &identity, &args.sans).map_err(blame)?;
    print_written(written)
}

/// A missing, existing or unreadable file is the user's; a failed write or generation is not.
fn blame(e: TlsError) -> CliError {
    match e {
        TlsError::Write { .. } | TlsError::Generate { .. } => CliError::runtime(e),
        _ => CliError::input(e),
    }
}

fn print_written(written: Vec<PathBuf>) -> CliResult {
    let files: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
    print_json(&serde_json::json!({ "written": files }))
}
