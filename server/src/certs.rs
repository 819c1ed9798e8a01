//! Certificates for the secured deployment's TLS (`ricochet-server certs`): a certificate
//! authority of the deployment's own, and the router's certificate signed by it for the
//! host names and addresses clients reach it by. Host names flow in; PEM files flow out,
//! named as the shipped configurations of `assets/zenoh/` expect them.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use rcgen::{
    BasicConstraints, CertificateParams, DnType, ExtendedKeyUsagePurpose, IsCa, Issuer, KeyPair,
    KeyUsagePurpose,
};

/// The files `make` writes, as the shipped configurations name them.
pub const CA_CERT: &str = "ca.pem";
pub const CA_KEY: &str = "ca-key.pem";
pub const ROUTER_CERT: &str = "router.pem";
pub const ROUTER_KEY: &str = "router-key.pem";

fn validity(days: u32) -> (time::OffsetDateTime, time::OffsetDateTime) {
    let now = time::OffsetDateTime::now_utc();
    (
        now - time::Duration::days(1),
        now + time::Duration::days(days as i64),
    )
}

/// Writes a new authority and a router certificate for `hosts` (names or IP addresses)
/// valid `days` days into `out`; the keys are readable by their owner only. Returns the
/// files written.
pub fn make(out: &Path, hosts: &[String], days: u32) -> Result<Vec<PathBuf>> {
    anyhow::ensure!(!hosts.is_empty(), "the router needs at least one host name");
    anyhow::ensure!((1..=3650).contains(&days), "--days {days}: from 1 to 3650");
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let (from, until) = validity(days);

    let mut ca = CertificateParams::new(Vec::<String>::new())?;
    ca.is_ca = IsCa::Ca(BasicConstraints::Constrained(0));
    ca.distinguished_name
        .push(DnType::CommonName, "Ricochet deployment authority");
    ca.key_usages = vec![KeyUsagePurpose::KeyCertSign, KeyUsagePurpose::CrlSign];
    (ca.not_before, ca.not_after) = (from, until);
    let ca_key = KeyPair::generate()?;
    let ca_cert = ca.self_signed(&ca_key)?;
    let ca_pem = ca_cert.pem();
    let ca_key_pem = ca_key.serialize_pem();
    let issuer = Issuer::new(ca, ca_key);

    let mut router =
        CertificateParams::new(hosts.to_vec()).with_context(|| format!("host names {hosts:?}"))?;
    router
        .distinguished_name
        .push(DnType::CommonName, hosts[0].as_str());
    router.use_authority_key_identifier_extension = true;
    router.key_usages = vec![KeyUsagePurpose::DigitalSignature];
    router.extended_key_usages = vec![ExtendedKeyUsagePurpose::ServerAuth];
    (router.not_before, router.not_after) = (from, until);
    let router_key = KeyPair::generate()?;
    let router_cert = router.signed_by(&router_key, &issuer)?;

    let files = [
        (CA_CERT, ca_pem, false),
        (CA_KEY, ca_key_pem, true),
        (ROUTER_CERT, router_cert.pem(), false),
        (ROUTER_KEY, router_key.serialize_pem(), true),
    ];
    let mut written = Vec::new();
    for (name, pem, secret) in files {
        let path = out.join(name);
        write(&path, pem.as_bytes(), secret)
            .with_context(|| format!("cannot write {}", path.display()))?;
        written.push(path);
    }
    Ok(written)
}

fn write(path: &Path, bytes: &[u8], secret: bool) -> std::io::Result<()> {
    use std::io::Write;
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create(true).truncate(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.mode(if secret { 0o600 } else { 0o644 });
    }
    options.open(path)?.write_all(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_authority_and_a_router_certificate_are_written_as_pem() {
        let dir = tempfile::tempdir().unwrap();
        let files = make(dir.path(), &["localhost".into(), "127.0.0.1".into()], 30).unwrap();
        assert_eq!(files.len(), 4);
        for f in &files {
            let text = std::fs::read_to_string(f).unwrap();
            assert!(text.starts_with("-----BEGIN "), "{}", f.display());
        }
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(dir.path().join(ROUTER_KEY))
                .unwrap()
                .permissions()
                .mode();
            assert_eq!(mode & 0o077, 0, "the key is private: {mode:o}");
        }
        assert!(make(dir.path(), &[], 30).is_err());
        assert!(make(dir.path(), &["localhost".into()], 0).is_err());
    }
}
