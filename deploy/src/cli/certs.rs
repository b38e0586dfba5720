//! The grammar of `risktwin certs init|issue`: the deployment's CA and its certificates.

use clap::{Args, Subcommand};
use std::path::PathBuf;

#[derive(Debug, Subcommand)]
pub enum CertsCommand {
    /// A new CA in DIR and a certificate per --identity (refused if DIR holds a CA already).
    Init(CertsInitArgs),
    /// One more certificate from DIR's CA (a worker or vehicle joins); other files untouched.
    Issue(CertsIssueArgs),
}

#[derive(Debug, Args)]
pub struct CertsInitArgs {
    /// The certificates folder (created if needed).
    pub dir: PathBuf,
    /// `edge:<site>:<id>`, `cloud:<name>` or `router:<name>`; repeatable.
    #[arg(long = "identity", value_name = "NAME")]
    pub identities: Vec<String>,
    /// Another host name or address the routers' certificates answer to (besides localhost,
    /// 127.0.0.1 and ::1); repeatable.
    #[arg(long = "router-san", value_name = "HOST")]
    pub router_sans: Vec<String>,
}

#[derive(Debug, Args)]
pub struct CertsIssueArgs {
    /// The certificates folder holding the CA (`ca.pem`, `ca-key.pem`).
    pub dir: PathBuf,
    /// `edge`, `cloud` or `router`.
    #[arg(long)]
    pub role: String,
    /// An edge's site.
    #[arg(long)]
    pub site: Option<String>,
    /// An edge's source id.
    #[arg(long)]
    pub id: Option<String>,
    /// A cloud's or router's name.
    #[arg(long)]
    pub name: Option<String>,
    /// A router: another host name or address its certificate answers to; repeatable.
    #[arg(long = "san", value_name = "HOST")]
    pub sans: Vec<String>,
}
