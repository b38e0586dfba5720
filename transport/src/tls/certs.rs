//! The deployment's certificate authority and the certificates it issues (`risktwin certs`).
//!
//! A directory holds the CA (`ca.pem`, `ca-key.pem`) and, per identity, `<common name>.pem`
//! and `<common name>-key.pem`. Keys are ECDSA P-256, written owner-readable only; files are
//! created new, never overwritten, so issuing one more identity leaves every other file as it
//! was. A router reads the certificates of its directory to know which identities exist
//! (`known_identities`): the access rules of an edge name it.

use super::{Identity, TlsError};
use rcgen::{
    BasicConstraints, CertificateParams, DistinguishedName, DnType, ExtendedKeyUsagePurpose, IsCa, Issuer, KeyPair,
    KeyUsagePurpose,
};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The CA's certificate in a certificates directory.
pub const CA_CERT_FILE: &str = "ca.pem";
/// The CA's private key: keep it on the machine that issues certificates only.
pub const CA_KEY_FILE: &str = "ca-key.pem";
/// The CA's common name.
const CA_NAME: &str = "risktwin-ca";
/// The names every router certificate answers to, so that `tls/127.0.0.1:…` and
/// `tls/localhost:…` verify on one host; other addresses come from `--san`.
pub const LOOPBACK_NAMES: [&str; 3] = ["localhost", "127.0.0.1", "::1"];

/// Makes a CA in `dir` (created if missing; refused if it already holds one) and a certificate
/// for each identity; routers answer to `LOOPBACK_NAMES` plus their extra names. Returns the
/// files written.
pub fn init(dir: &Path, identities: &[(Identity, Vec<String>)]) -> Result<Vec<PathBuf>, TlsError> {
    let write_err =
        |path: &Path, e: &dyn std::fmt::Display| TlsError::Write { path: path.to_owned(), reason: e.to_string() };
    std::fs::create_dir_all(dir).map_err(|e| write_err(dir, &e))?;
    let generate = |e: rcgen::Error| TlsError::Generate { name: CA_NAME.to_owned(), reason: e.to_string() };
    let mut params = CertificateParams::default();
    params.distinguished_name = common_name(CA_NAME);
    params.is_ca = IsCa::Ca(BasicConstraints::Unconstrained);
    params.key_usages = vec![KeyUsagePurpose::KeyCertSign, KeyUsagePurpose::CrlSign, KeyUsagePurpose::DigitalSignature];
    let key = KeyPair::generate().map_err(generate)?;
    let cert = params.self_signed(&key).map_err(generate)?;
    let mut written = vec![dir.join(CA_CERT_FILE), dir.join(CA_KEY_FILE)];
    for path in &written {
        if path.exists() {
            return Err(TlsError::Exists { path: path.clone() });
        }
    }
    create_new(&written[1], &key.serialize_pem(), true)?;
    create_new(&written[0], &cert.pem(), false)?;
    let issuer = Issuer::new(params, key);
    for (identity, sans) in identities {
        written.extend(issue_with(dir, &issuer, identity, sans)?);
    }
    Ok(written)
}

/// Issues one more certificate in `dir` with its CA; every other file stays as it was.
pub fn issue(dir: &Path, identity: &Identity, sans: &[String]) -> Result<Vec<PathBuf>, TlsError> {
    let ca_cert = read(&dir.join(CA_CERT_FILE))?;
    let key_path = dir.join(CA_KEY_FILE);
    let bad = |path: &Path, e: rcgen::Error| TlsError::BadCertificate { path: path.to_owned(), reason: e.to_string() };
    let key = KeyPair::from_pem(&read(&key_path)?).map_err(|e| bad(&key_path, e))?;
    let issuer = Issuer::from_ca_cert_pem(&ca_cert, key).map_err(|e| bad(&dir.join(CA_CERT_FILE), e))?;
    issue_with(dir, &issuer, identity, sans)
}

fn issue_with(
    dir: &Path,
    issuer: &Issuer<'_, KeyPair>,
    identity: &Identity,
    sans: &[String],
) -> Result<Vec<PathBuf>, TlsError> {
    let name = identity.common_name();
    let generate = |e: rcgen::Error| TlsError::Generate { name: name.clone(), reason: e.to_string() };
    let mut names: Vec<String> = sans.to_vec();
    if matches!(identity, Identity::Router { .. }) {
        names.extend(LOOPBACK_NAMES.map(str::to_owned));
    }
    let mut params = CertificateParams::new(names).map_err(generate)?;
    params.distinguished_name = common_name(&name);
    params.key_usages = vec![KeyUsagePurpose::DigitalSignature];
    // Routers accept links and open them to other routers; the others only open them.
    params.extended_key_usages = vec![ExtendedKeyUsagePurpose::ServerAuth, ExtendedKeyUsagePurpose::ClientAuth];
    params.use_authority_key_identifier_extension = true;
    let key = KeyPair::generate().map_err(generate)?;
    let cert = params.signed_by(&key, issuer).map_err(generate)?;
    let (cert_path, key_path) = (dir.join(format!("{name}.pem")), dir.join(format!("{name}-key.pem")));
    for path in [&cert_path, &key_path] {
        if path.exists() {
            return Err(TlsError::Exists { path: path.clone() });
        }
    }
    create_new(&key_path, &key.serialize_pem(), true)?;
    create_new(&cert_path, &cert.pem(), false)?;
    Ok(vec![cert_path, key_path])
}

/// The identities of the certificates in `dir` (every `*.pem` but the CA's and the keys),
/// read from each certificate's subject common name, sorted.
pub fn known_identities(dir: &Path) -> Result<Vec<Identity>, TlsError> {
    let read_err = |e: std::io::Error| TlsError::Read { path: dir.to_owned(), reason: e.to_string() };
    let mut identities = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(read_err)? {
        let path = entry.map_err(read_err)?.path();
        let Some(file) = path.file_name().and_then(|f| f.to_str()) else { continue };
        if !file.ends_with(".pem") || file.ends_with("-key.pem") || file == CA_CERT_FILE {
            continue;
        }
        identities.push(certificate_identity(&path)?);
    }
    identities.sort();
    identities.dedup();
    Ok(identities)
}

/// The identity a certificate file's subject common name names.
pub fn certificate_identity(path: &Path) -> Result<Identity, TlsError> {
    let bad = |reason: String| TlsError::BadCertificate { path: path.to_owned(), reason };
    let bytes = std::fs::read(path).map_err(|e| TlsError::Read { path: path.to_owned(), reason: e.to_string() })?;
    let (_, pem) = x509_parser::pem::parse_x509_pem(&bytes).map_err(|e| bad(e.to_string()))?;
    let cert = pem.parse_x509().map_err(|e| bad(e.to_string()))?;
    let name = cert.subject().iter_common_name().next().and_then(|cn| cn.as_str().ok());
    let name = name.ok_or_else(|| bad("no subject common name".to_owned()))?;
    name.parse().map_err(|e: TlsError| bad(e.to_string()))
}

fn common_name(name: &str) -> DistinguishedName {
    let mut dn = DistinguishedName::new();
    dn.push(DnType::CommonName, name);
    dn
}

fn read(path: &Path) -> Result<String, TlsError> {
    std::fs::read_to_string(path).map_err(|e| TlsError::Read { path: path.to_owned(), reason: e.to_string() })
}

/// Writes a file that must not exist yet; a private key is readable by its owner only.
fn create_new(path: &Path, text: &str, private: bool) -> Result<(), TlsError> {
    use std::os::unix::fs::OpenOptionsExt;
    let write_err = |e: std::io::Error| TlsError::Write { path: path.to_owned(), reason: e.to_string() };
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create_new(true).mode(if private { 0o600 } else { 0o644 });
    let mut file = options.open(path).map_err(|e| match e.kind() {
        std::io::ErrorKind::AlreadyExists => TlsError::Exists { path: path.to_owned() },
        _ => write_err(e),
    })?;
    file.write_all(text.as_bytes()).map_err(write_err)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::keyexpr::{SiteId, SourceId};

    fn edge(id: &str) -> Identity {
        Identity::Edge { site: SiteId::new("s1").unwrap(), id: SourceId::new(id).unwrap() }
    }

    #[test]
    fn init_then_issue_adds_one_identity_and_touches_nothing_else() {
        let dir = tempfile::tempdir().unwrap();
        let router = Identity::Router { name: "r1".into() };
        init(dir.path(), &[(router.clone(), vec![]), (edge("v1"), vec![])]).unwrap();
        let before: Vec<(PathBuf, Vec<u8>)> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().path())
            .map(|p| (p.clone(), std::fs::read(&p).unwrap()))
            .collect();
        assert_eq!(known_identities(dir.path()).unwrap(), vec![edge("v1"), router.clone()]);
        issue(dir.path(), &edge("v2"), &[]).unwrap();
        for (path, bytes) in &before {
            assert_eq!(&std::fs::read(path).unwrap(), bytes, "{}", path.display());
        }
        assert_eq!(known_identities(dir.path()).unwrap(), vec![edge("v1"), edge("v2"), router]);
        assert!(matches!(issue(dir.path(), &edge("v2"), &[]), Err(TlsError::Exists { .. })));
        assert!(matches!(init(dir.path(), &[]), Err(TlsError::Exists { .. })));
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(dir.path().join("edge:s1:v2-key.pem")).unwrap().permissions().mode();
        assert_eq!(mode & 0o077, 0, "a private key is the owner's only");
    }
}
