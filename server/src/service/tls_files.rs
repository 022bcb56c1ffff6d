//! The PEM files of TLS, checked before tonic reads them.
//!
//! tonic accepts any bytes as PEM and silently skips what does not parse, so a
//! wrong file only shows later as "transport error: peer sent no certificates"
//! (the server's `--tls-cert`) or a failed handshake (a client's CA file). These
//! say what the file lacks, so that the refusal can name it.

use rustls_pki_types::pem::PemObject;
use rustls_pki_types::{CertificateDer, PrivateKeyDer};

/// Checks that `pem` holds at least one certificate and that every certificate
/// block decodes; says what is wrong otherwise.
pub fn check_certificates(pem: &[u8]) -> Result<(), String> {
    let mut certificates = 0;
    for item in CertificateDer::pem_slice_iter(pem) {
        item.map_err(|e| format!("a certificate block does not decode ({e})"))?;
        certificates += 1;
    }
    if certificates == 0 {
        return Err("no `-----BEGIN CERTIFICATE-----` block".into());
    }
    Ok(())
}

/// Checks that `pem` holds a private key (PKCS#8, PKCS#1 or SEC1) that decodes;
/// says what is wrong otherwise.
pub fn check_private_key(pem: &[u8]) -> Result<(), String> {
    match PrivateKeyDer::from_pem_slice(pem) {
        Ok(_) => Ok(()),
        Err(rustls_pki_types::pem::Error::NoItemsFound) => {
            Err("no `-----BEGIN PRIVATE KEY-----` (or RSA, EC) block".into())
        }
        Err(e) => Err(format!("its key block does not decode ({e})")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_without_a_certificate_block_is_not_a_pem_certificate() {
        assert!(check_certificates(b"hello, I am not a certificate\n").is_err());
        assert!(check_certificates(b"").is_err());
        let broken = b"-----BEGIN CERTIFICATE-----\n!!!not base64!!!\n-----END CERTIFICATE-----\n";
        assert!(check_certificates(broken).is_err());
        let fine = b"-----BEGIN CERTIFICATE-----\nAAAA\n-----END CERTIFICATE-----\n";
        assert_eq!(check_certificates(fine), Ok(()));
    }

    #[test]
    fn a_file_without_a_key_block_is_not_a_pem_key() {
        let e = check_private_key(b"").unwrap_err();
        assert!(e.contains("PRIVATE KEY"), "{e}");
        // A certificate is not a key.
        let cert = b"-----BEGIN CERTIFICATE-----\nAAAA\n-----END CERTIFICATE-----\n";
        assert!(check_private_key(cert).is_err());
        let broken = b"-----BEGIN PRIVATE KEY-----\n!!!\n-----END PRIVATE KEY-----\n";
        assert!(check_private_key(broken).is_err());
        let fine = b"-----BEGIN PRIVATE KEY-----\nAAAA\n-----END PRIVATE KEY-----\n";
        assert_eq!(check_private_key(fine), Ok(()));
    }
}
