//! Connecting to a laparo server: a tonic [`Channel`] to a URL, over plain HTTP/2
//! (`http://host:port`) or TLS (`https://host:port`, trusting the CA certificate
//! given), and the bearer-token interceptor that authenticates every call.
//!
//! This build carries no system trust roots, so an `https` URL needs the CA
//! certificate (PEM) that signed the server's certificate; [`connect`] says so rather
//! than failing later in the TLS handshake.

use std::path::{Path, PathBuf};
use std::time::Duration;

use tonic::metadata::{AsciiMetadataValue, MetadataValue};
use tonic::service::Interceptor;
use tonic::service::interceptor::InterceptedService;
use tonic::transport::{Certificate, Channel, ClientTlsConfig, Endpoint};
use tonic::{Request, Status};

use crate::proto::v1::observe_client::ObserveClient;
use crate::proto::v1::recordings_client::RecordingsClient;
use crate::proto::v1::scenes_client::ScenesClient;
use crate::proto::v1::sessions_client::SessionsClient;
use crate::proto::v1::station_client::StationClient;

/// How long [`connect`] waits for the TCP (and TLS) connection by default.
pub const DEFAULT_CONNECT_TIMEOUT: Duration = Duration::from_secs(10);

/// Where the server is and how to authenticate to it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ConnectConfig {
    /// Server URL, `http://host:port` or `https://host:port`.
    pub url: String,
    /// Bearer token sent as `authorization: Bearer <token>` with every call; `None`
    /// sends no `authorization` header.
    pub token: Option<String>,
    /// CA certificate (PEM file) to trust for an `https` URL.
    pub ca_file: Option<PathBuf>,
    /// How long to wait for the connection.
    pub connect_timeout: Duration,
}

impl ConnectConfig {
    /// The server at `url`, no token, no CA certificate, the default timeout.
    pub fn new(url: impl Into<String>) -> Self {
        ConnectConfig {
            url: url.into(),
            token: None,
            ca_file: None,
            connect_timeout: DEFAULT_CONNECT_TIMEOUT,
        }
    }
}

/// Why the client could not connect.
#[derive(Debug, thiserror::Error)]
pub enum ConnectError {
    /// The URL does not parse.
    #[error("server URL {url:?} is not valid: {reason}")]
    InvalidUrl { url: String, reason: String },
    /// The URL is neither `http` nor `https`.
    #[error("server URL {url:?}: scheme must be http or https")]
    UnsupportedScheme { url: String },
    /// An `https` URL without a CA certificate to trust.
    #[error(
        "server URL {url:?} uses TLS: give the CA certificate that signed the server's \
         certificate (--ca FILE); this client carries no system trust roots"
    )]
    MissingCa { url: String },
    /// A CA certificate given for a plain `http` URL.
    #[error("server URL {url:?} is plain http: a CA certificate only applies to https")]
    CaWithoutTls { url: String },
    /// The CA certificate file cannot be read.
    #[error("CA certificate {path:?} for {url:?} cannot be read: {source}")]
    ReadCa {
        url: String,
        path: PathBuf,
        source: std::io::Error,
    },
    /// The TLS configuration was refused.
    #[error("TLS configuration for {url:?} refused: {detail}")]
    Tls { url: String, detail: String },
    /// The server could not be reached.
    #[error("cannot connect to {url:?}: {detail}")]
    Unreachable { url: String, detail: String },
    /// The token cannot be sent in an HTTP header.
    #[error("the bearer token for {url:?} cannot be sent in an HTTP header (visible ASCII only)")]
    InvalidToken { url: String },
}

/// A connection to a server: one HTTP/2 channel and the bearer token, from which the
/// clients of every service are made (they share the channel).
#[derive(Clone, Debug)]
pub struct Connection {
    url: String,
    channel: Channel,
    auth: BearerAuth,
}

/// A channel that adds the bearer token to every call.
pub type AuthChannel = InterceptedService<Channel, BearerAuth>;

impl Connection {
    /// The URL connected to.
    pub fn url(&self) -> &str {
        &self.url
    }

    /// A client of the `Station` service.
    pub fn station(&self) -> StationClient<AuthChannel> {
        StationClient::with_interceptor(self.channel.clone(), self.auth.clone())
    }

    /// A client of the `Observe` service.
    pub fn observe(&self) -> ObserveClient<AuthChannel> {
        ObserveClient::with_interceptor(self.channel.clone(), self.auth.clone())
    }

    /// A client of the `Sessions` service.
    pub fn sessions(&self) -> SessionsClient<AuthChannel> {
        SessionsClient::with_interceptor(self.channel.clone(), self.auth.clone())
    }

    /// A client of the `Scenes` service.
    pub fn scenes(&self) -> ScenesClient<AuthChannel> {
        ScenesClient::with_interceptor(self.channel.clone(), self.auth.clone())
    }

    /// A client of the `Recordings` service.
    pub fn recordings(&self) -> RecordingsClient<AuthChannel> {
        RecordingsClient::with_interceptor(self.channel.clone(), self.auth.clone())
    }
}

/// Connects to the server of `config` and returns the connection once the channel is
/// up (the connection is made here, not at the first call, so that a wrong address
/// is reported as such).
pub async fn connect(config: &ConnectConfig) -> Result<Connection, ConnectError> {
    let url = config.url.clone();
    let auth = BearerAuth::new(config.token.as_deref())
        .map_err(|_| ConnectError::InvalidToken { url: url.clone() })?;
    let endpoint = endpoint(config).await?;
    let channel = endpoint
        .connect()
        .await
        .map_err(|e| ConnectError::Unreachable {
            url: url.clone(),
            detail: error_chain(&e),
        })?;
    Ok(Connection { url, channel, auth })
}

/// The endpoint for `config`: URL checked, timeouts set, TLS configured for `https`.
async fn endpoint(config: &ConnectConfig) -> Result<Endpoint, ConnectError> {
    let url = &config.url;
    let endpoint = Endpoint::from_shared(url.clone()).map_err(|e| ConnectError::InvalidUrl {
        url: url.clone(),
        reason: error_chain(&e),
    })?;
    let endpoint = endpoint
        .connect_timeout(config.connect_timeout)
        .tcp_nodelay(true);
    match endpoint.uri().scheme_str() {
        Some("http") => {
            if config.ca_file.is_some() {
                return Err(ConnectError::CaWithoutTls { url: url.clone() });
            }
            Ok(endpoint)
        }
        Some("https") => {
            let path = config
                .ca_file
                .as_ref()
                .ok_or_else(|| ConnectError::MissingCa { url: url.clone() })?;
            let tls = tls_config(url, path)?;
            endpoint.tls_config(tls).map_err(|e| ConnectError::Tls {
                url: url.clone(),
                detail: error_chain(&e),
            })
        }
        _ => Err(ConnectError::UnsupportedScheme { url: url.clone() }),
    }
}

/// A TLS configuration trusting the CA certificate in the PEM file at `path`.
fn tls_config(url: &str, path: &Path) -> Result<ClientTlsConfig, ConnectError> {
    let pem = std::fs::read(path).map_err(|source| ConnectError::ReadCa {
        url: url.to_owned(),
        path: path.to_owned(),
        source,
    })?;
    Ok(ClientTlsConfig::new().ca_certificate(Certificate::from_pem(pem)))
}

/// An error and its sources, joined with `: ` (tonic's transport errors say little
/// at the top level).
pub fn error_chain(error: &dyn std::error::Error) -> String {
    let mut out = error.to_string();
    let mut source = error.source();
    while let Some(e) = source {
        let s = e.to_string();
        if !out.ends_with(&s) {
            out.push_str(": ");
            out.push_str(&s);
        }
        source = e.source();
    }
    out
}

/// Adds `authorization: Bearer <token>` to every request when a token is given, and
/// leaves requests untouched otherwise.
#[derive(Clone, Debug, Default)]
pub struct BearerAuth {
    header: Option<AsciiMetadataValue>,
}

/// A token that cannot be carried in an HTTP header.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("the bearer token cannot be sent in an HTTP header (visible ASCII only)")]
pub struct InvalidToken;

impl BearerAuth {
    /// An interceptor sending `token`, or nothing for `None`.
    pub fn new(token: Option<&str>) -> Result<Self, InvalidToken> {
        let header = token
            .map(|t| MetadataValue::try_from(format!("Bearer {t}")).map_err(|_| InvalidToken))
            .transpose()?;
        Ok(BearerAuth { header })
    }
}

impl Interceptor for BearerAuth {
    fn call(&mut self, mut request: Request<()>) -> Result<Request<()>, Status> {
        if let Some(value) = &self.header {
            request
                .metadata_mut()
                .insert("authorization", value.clone());
        }
        Ok(request)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bearer_auth_adds_the_header_when_a_token_is_given() {
        let mut auth = BearerAuth::new(Some("s3cret")).unwrap();
        let request = auth.call(Request::new(())).unwrap();
        let value = request.metadata().get("authorization").unwrap();
        assert_eq!(value.to_str().unwrap(), "Bearer s3cret");
    }

    #[test]
    fn bearer_auth_without_token_adds_nothing() {
        let mut auth = BearerAuth::new(None).unwrap();
        let request = auth.call(Request::new(())).unwrap();
        assert!(request.metadata().get("authorization").is_none());
    }

    #[test]
    fn a_token_with_a_newline_is_refused() {
        assert_eq!(BearerAuth::new(Some("a\nb")).unwrap_err(), InvalidToken);
    }

    #[tokio::test]
    async fn urls_are_checked_before_connecting() {
        let bad = |url: &'static str| async move {
            let mut c = ConnectConfig::new(url);
            c.connect_timeout = Duration::from_millis(100);
            connect(&c).await.unwrap_err()
        };
        assert!(matches!(
            bad("ftp://127.0.0.1:1").await,
            ConnectError::UnsupportedScheme { .. }
        ));
        assert!(matches!(
            bad("https://127.0.0.1:1").await,
            ConnectError::MissingCa { .. }
        ));
        assert!(matches!(
            bad("not a url").await,
            ConnectError::InvalidUrl { .. }
        ));
        let mut c = ConnectConfig::new("https://127.0.0.1:1");
        c.ca_file = Some("/nonexistent/ca.pem".into());
        let e = connect(&c).await.unwrap_err();
        assert!(matches!(e, ConnectError::ReadCa { .. }));
        assert!(e.to_string().contains("https://127.0.0.1:1"), "{e}");
    }
}
