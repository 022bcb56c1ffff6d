//! Connecting to a laparo server: a tonic [`Channel`] to a URL, over plain HTTP/2
//! (`http://host:port`) or TLS (`https://host:port`, trusting the CA certificate
//! given), and the bearer-token interceptor that authenticates every call.
//!
//! This build carries no system trust roots, so an `https` URL needs the CA
//! certificate (PEM) that signed the server's certificate; [`connect`] says so rather
//! than failing later in the TLS handshake.
//!
//! # Never waiting for ever
//!
//! [`connect`] makes the connection and its first exchange within one time limit
//! ([`DEFAULT_CONNECT_TIMEOUT`], `--connect-timeout`): TCP, TLS, HTTP/2 and a call to
//! the standard health service asking for `laparo.v1.Station`. A peer that accepts
//! and stays silent, answers in HTTP/1, or serves gRPC without laparo is told apart
//! here, in words ([`failure`]). Once connected, HTTP/2 keep-alive pings
//! ([`KEEPALIVE_INTERVAL`], [`KEEPALIVE_TIMEOUT`]) end any call on a server that died
//! or froze, and unary calls carry [`CALL_TIMEOUT`] ([`unary`]).

use std::error::Error as _;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use tonic::Request;
use tonic::service::interceptor::InterceptedService;
use tonic::transport::{Channel, Endpoint};
use tonic_health::pb::HealthCheckRequest;
use tonic_health::pb::health_client::HealthClient;

mod auth;
pub mod dial;
pub mod failure;
mod tls;

#[cfg(test)]
mod tests;

pub use auth::{BearerAuth, InvalidToken};
pub use failure::{describe_status, error_chain};

use crate::proto::v1::observe_client::ObserveClient;
use crate::proto::v1::recordings_client::RecordingsClient;
use crate::proto::v1::scenes_client::ScenesClient;
use crate::proto::v1::sessions_client::SessionsClient;
use crate::proto::v1::station_client::StationClient;

/// How long [`connect`] waits by default for the connection and the server's first
/// answer (TCP, TLS, HTTP/2 and the health check together). A laparo server answers
/// the health check in milliseconds on a LAN, even while it builds a session; 5 s
/// leaves room for a slow link and TLS while a user at a silent address learns it
/// soon.
pub const DEFAULT_CONNECT_TIMEOUT: Duration = Duration::from_secs(5);

/// How long a connection may stay without receiving anything before an HTTP/2 PING
/// asks whether the server is still there. A live session streams frames many times
/// a second, so a ping is only sent to a server that went quiet.
pub const KEEPALIVE_INTERVAL: Duration = Duration::from_secs(10);

/// How long the answer to a keep-alive PING may take before the connection is
/// declared dead and every call on it ends: a server's HTTP/2 layer answers pings
/// whatever its sessions do, so only a dead, frozen or cut-off server misses this.
pub const KEEPALIVE_TIMEOUT: Duration = Duration::from_secs(5);

/// How long a unary call (create, get or close a session, list recordings) may wait
/// for its answer: creating a session builds its scene, which takes well under a
/// second for the shipped scenes and a few seconds for the largest meshes a scene
/// may name; 30 s says "the server is stuck", not "the server is slow".
pub const CALL_TIMEOUT: Duration = Duration::from_secs(30);

/// The service the health check asks for: a server that does not know it is not a
/// laparo server.
pub const PROBED_SERVICE: &str = "laparo.v1.Station";

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
    /// How long to wait for the connection and the server's first answer.
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

impl ConnectConfig {
    /// These settings with the connect timeout cut to `limit` when one is given: a
    /// run of bounded duration is bounded connecting included.
    pub fn within(&self, limit: Option<Duration>) -> ConnectConfig {
        let mut config = self.clone();
        if let Some(limit) = limit {
            config.connect_timeout = config.connect_timeout.min(limit);
        }
        config
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
    #[error("CA certificate {} for {url} {source}", path.display())]
    ReadCa {
        url: String,
        path: PathBuf,
        source: laparo_server::engine::scene::FileError,
    },
    /// The CA certificate file holds no certificate.
    #[error("{}: not a PEM certificate: {reason}", path.display())]
    BadCa { path: PathBuf, reason: String },
    /// The TLS configuration was refused, or the TLS handshake failed.
    #[error("TLS with {url} failed: {detail}")]
    Tls { url: String, detail: String },
    /// Nothing listens at the address.
    #[error("cannot connect to {url}: connection refused (is the server running, on this port?)")]
    Refused { url: String },
    /// The TCP connection was not made in time.
    #[error(
        "cannot connect to {url}: no answer within {} s (is the address right, the host up, the port open?)",
        after.as_secs_f64()
    )]
    NoConnection { url: String, after: Duration },
    /// The peer accepted the connection and said nothing in time.
    #[error("no answer from {url} within {} s: is it a laparo server?", after.as_secs_f64())]
    NoAnswer { url: String, after: Duration },
    /// The peer accepted the connection and closed it without a word: what a
    /// laparo server does with a connection past its limits, and what a server of
    /// another kind may do.
    #[error(
        "{url} closed the connection without answering: a laparo server does that at its \
         connection limit (--max-connections, or --max-connections-per-peer for connections \
         from this address), so try again later; or it is not a laparo server"
    )]
    Closed { url: String },
    /// The peer speaks something else than gRPC (HTTP/1, TLS where plain HTTP/2 was
    /// expected, or HTTP/2 without gRPC).
    #[error("{url} does not speak gRPC (it answered {answered})")]
    NotGrpc { url: String, answered: String },
    /// A plain server behind an `https` URL.
    #[error("{url} does not speak TLS (it answered {answered}): use an http URL")]
    NotTls { url: String, answered: String },
    /// A gRPC server without the laparo services.
    #[error("{url} speaks gRPC but does not serve {PROBED_SERVICE}: is it a laparo server?")]
    NotLaparo { url: String },
    /// The server could not be reached for another reason.
    #[error("cannot connect to {url}: {detail}")]
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

/// A unary request carrying [`CALL_TIMEOUT`]: the call ends with an error rather
/// than waiting for ever on a stuck server (the server is told the deadline too).
pub fn unary<T>(message: T) -> Request<T> {
    let mut request = Request::new(message);
    request.set_timeout(CALL_TIMEOUT);
    request
}

/// Where [`connect`] failed.
enum Stage {
    /// Making the TCP, TLS and HTTP/2 connection.
    Connect(tonic::transport::Error),
    /// The health check, on a connection made.
    Check(tonic::Status),
}

/// Connects to the server of `config` and returns the connection once the server
/// answered the health check, all within `config.connect_timeout` (the connection
/// is made here, not at the first call, so that a wrong address or a peer that is
/// not a laparo server is reported as such); see the [module documentation](self).
pub async fn connect(config: &ConnectConfig) -> Result<Connection, ConnectError> {
    let url = config.url.clone();
    let auth = BearerAuth::new(config.token.as_deref())
        .map_err(|_| ConnectError::InvalidToken { url: url.clone() })?;
    let endpoint = endpoint(config)?;
    let tls = endpoint.uri().scheme_str() == Some("https");
    let dial = dial::Dial::default();
    let seen = Arc::clone(&dial.seen);
    let attempt = async {
        let channel = endpoint
            .connect_with_connector(dial)
            .await
            .map_err(Stage::Connect)?;
        let answer = HealthClient::new(channel.clone())
            .check(HealthCheckRequest {
                service: PROBED_SERVICE.into(),
            })
            .await;
        match answer {
            Ok(_) => Ok(channel),
            Err(status) => match checked(status) {
                Ok(()) => Ok(channel),
                Err(stage) => Err(stage),
            },
        }
    };
    let failed = match tokio::time::timeout(config.connect_timeout, attempt).await {
        Ok(Ok(channel)) => return Ok(Connection { url, channel, auth }),
        Ok(Err(stage)) => stage,
        Err(_) => {
            let after = config.connect_timeout;
            return Err(match failure::peer_answer(&seen.first_bytes(), tls) {
                Some(answered) if tls => ConnectError::NotTls { url, answered },
                Some(answered) => ConnectError::NotGrpc { url, answered },
                None if seen.connected() => ConnectError::NoAnswer { url, after },
                None => ConnectError::NoConnection { url, after },
            });
        }
    };
    Err(match failed {
        Stage::Check(status) if status.source().is_none() => {
            // A gRPC answer that is not the health service's: `checked` said which.
            if status.code() == tonic::Code::NotFound {
                ConnectError::NotLaparo { url }
            } else {
                ConnectError::NotGrpc {
                    url,
                    answered: format!("HTTP/2 without gRPC: {}", status.message()),
                }
            }
        }
        Stage::Check(status) => transport_failure(url, tls, &seen, &status, false),
        Stage::Connect(e) => transport_failure(url, tls, &seen, &e, true),
    })
}

/// Whether the health check's error status still shows a laparo server: any status
/// the peer sent proves it speaks gRPC and answers (a server without the health
/// service says UNIMPLEMENTED), except NOT_FOUND (the health service does not know
/// laparo) and a status tonic made up from a plain HTTP/2 answer.
fn checked(status: tonic::Status) -> Result<(), Stage> {
    let made_up = status.message().starts_with("grpc-status header missing");
    if status.source().is_some() || made_up || status.code() == tonic::Code::NotFound {
        Err(Stage::Check(status))
    } else {
        Ok(())
    }
}

/// Words for a connection that failed below gRPC; `connecting` when it failed while
/// the connection was being made (for `https`, that is the TLS handshake).
fn transport_failure(
    url: String,
    tls: bool,
    seen: &dial::Seen,
    error: &(dyn std::error::Error + 'static),
    connecting: bool,
) -> ConnectError {
    let first = seen.first_bytes();
    if let Some(answered) = failure::peer_answer(&first, tls) {
        return if tls {
            ConnectError::NotTls { url, answered }
        } else {
            ConnectError::NotGrpc { url, answered }
        };
    }
    let detail = error_chain(error);
    match failure::io_kind(error) {
        Some(std::io::ErrorKind::ConnectionRefused) => ConnectError::Refused { url },
        _ if !seen.connected() => ConnectError::Unreachable { url, detail },
        _ if tls && connecting => match failure::certificate_words(&detail) {
            Some(words) => ConnectError::Tls {
                url,
                detail: format!("{words} ({detail})"),
            },
            None => ConnectError::Tls { url, detail },
        },
        _ if first.is_empty() => ConnectError::Closed { url },
        _ => ConnectError::Unreachable { url, detail },
    }
}

/// The port as written in the endpoint's URL (after any `user@`, and after the `]`
/// of an IPv6 address); `None` when none is written.
fn written_port(endpoint: &Endpoint) -> Option<&str> {
    let authority = endpoint.uri().authority()?.as_str();
    let host_end = authority.rfind([']', '@']).map_or(0, |i| i + 1);
    let colon = host_end + authority[host_end..].rfind(':')?;
    Some(&authority[colon + 1..]).filter(|port| !port.is_empty())
}

/// The endpoint for `config`: URL checked, keep-alive set, TLS configured for
/// `https`. Nothing is connected yet.
fn endpoint(config: &ConnectConfig) -> Result<Endpoint, ConnectError> {
    let url = &config.url;
    let endpoint = Endpoint::from_shared(url.clone()).map_err(|e| ConnectError::InvalidUrl {
        url: url.clone(),
        reason: error_chain(&e),
    })?;
    // The URI parser takes any digits after the host as a port (and then names no
    // port at all); a TCP port is 1 to 65535, and dialling another fails as
    // "connection refused", naming no cause.
    if let Some(port) = written_port(&endpoint)
        && !matches!(port.parse::<u16>(), Ok(1..))
    {
        return Err(ConnectError::InvalidUrl {
            url: url.clone(),
            reason: format!("port {port} is not a TCP port (1 to 65535)"),
        });
    }
    // The connect timeout also bounds reconnecting after a lost connection.
    let endpoint = endpoint
        .connect_timeout(config.connect_timeout)
        .http2_keep_alive_interval(KEEPALIVE_INTERVAL)
        .keep_alive_timeout(KEEPALIVE_TIMEOUT)
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
            let tls = tls::tls_config(url, path)?;
            endpoint.tls_config(tls).map_err(|e| ConnectError::Tls {
                url: url.clone(),
                detail: error_chain(&e),
            })
        }
        _ => Err(ConnectError::UnsupportedScheme { url: url.clone() }),
    }
}
