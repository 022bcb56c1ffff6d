//! The CA certificate an `https` URL is checked against.
//!
//! tonic accepts any bytes as a PEM certificate and silently skips what does not
//! parse, so a wrong file only shows in the handshake as "transport error". The
//! file is read and parsed here first, and a file without a certificate is refused
//! with its name.

use std::path::Path;

use tonic::transport::{Certificate, ClientTlsConfig};

use laparo_server::engine::scene::read_bounded;
use laparo_server::service::tls_files::check_certificates;

use super::ConnectError;

/// Largest CA certificate file read, bytes: 1 MiB (a bundle of every public root
/// CA is about 200 kB).
pub const MAX_CA_BYTES: u64 = 1 << 20;

/// A TLS configuration trusting the CA certificates in the PEM file at `path`.
pub fn tls_config(url: &str, path: &Path) -> Result<ClientTlsConfig, ConnectError> {
    let pem = read_bounded(path, None, MAX_CA_BYTES).map_err(|source| ConnectError::ReadCa {
        url: url.to_owned(),
        path: path.to_owned(),
        source,
    })?;
    check_certificates(&pem).map_err(|reason| ConnectError::BadCa {
        path: path.to_owned(),
        reason,
    })?;
    Ok(ClientTlsConfig::new().ca_certificate(Certificate::from_pem(pem)))
}
