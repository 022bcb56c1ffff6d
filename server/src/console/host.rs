//! The host a browser's request names, checked on a server without tokens: a
//! guard against DNS rebinding.
//!
//! A server without tokens (the default on loopback) serves whoever reaches it.
//! CORS keeps the pages of other origins out, but not a page whose own name comes
//! to point at the server: a page at `http://attacker.example:50051` that the
//! trainee opens can have its name answered with `127.0.0.1` a moment later (DNS
//! rebinding), after which its gRPC-web calls reach this server and are, to the
//! browser, same-origin: no preflight, no CORS. Such a call still names the
//! attacker's host, since a browser sends the host of the page's URL in `Host`
//! (HTTP/1.1) or `:authority` (HTTP/2).
//!
//! So on a server without tokens, a request other than `GET` or `HEAD` that
//! carries `Origin` (a browser's: every gRPC-web `POST` does) is served only if
//! each host it names (port ignored, case and a trailing dot too) is
//! - an IP literal (`127.0.0.1`, `[::1]`): a rebinding needs a name;
//! - `localhost` or a name ending in `.localhost`, which browsers resolve to
//!   loopback themselves, never through DNS;
//! - the host of a `--cors-origin`, or a name given with `--allowed-host` (the
//!   name the server is reached by on a LAN, say).
//!
//! Any other is refused: a gRPC or gRPC-web call with `PERMISSION_DENIED`
//! (trailers-only, in the request's content type, as tonic-web answers a call
//! refused before its handler), anything else with HTTP 403; both name the host
//! and `--allowed-host`, and carry [`REFUSAL_HEADER`]`: host`, by which the
//! console tells this refusal from a token's (no token helps here). A request
//! naming no host, more than one `Host`, or one that is not `host[:port]` (or not
//! ASCII) is refused the same way.
//!
//! Left alone:
//! - requests without `Origin`. Native gRPC clients (tonic, grpcurl, the
//!   `laparo` client) send none: they name the host they were given, not a page's,
//!   so a DNS answer cannot turn them against the server.
//! - `GET` and `HEAD` but in a gRPC content type: the console's assets, which
//!   hold no secret and do nothing (every call of a browser is a `POST`; tonic
//!   serves a call whatever its method, so one sent as `GET` is checked). A
//!   browser sends `Origin` with some of them (the page's module script is
//!   fetched in CORS mode even from its own origin), so checking them left a page
//!   opened by a refused name blank, with nothing to say why; served, the page
//!   loads and shows its first call's refusal.
//! - servers with tokens: a rebinding page has no token, and the authentication
//!   interceptor refuses its calls (`UNAUTHENTICATED`).
//!
//! The layer sits inside the CORS layer: preflights are answered by CORS (a
//! rebinding page sends none, being same-origin), and a refusal to an allowed
//! origin carries the CORS headers its page needs to read the status.

use std::future::Future;
use std::net::{IpAddr, Ipv4Addr, Ipv6Addr};
use std::pin::Pin;
use std::sync::Arc;
use std::task::{Context, Poll};

use http::{HeaderMap, HeaderValue, Method, Request, Response, StatusCode, header};
use tonic::body::Body;
use tonic::{Code, Status};

/// A host a request names, its port dropped.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Host {
    /// An IP literal (IPv6 written in brackets).
    Ip(IpAddr),
    /// A name, lower-cased, without a trailing dot.
    Name(String),
}

impl std::fmt::Display for Host {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Host::Ip(IpAddr::V6(ip)) => write!(f, "[{ip}]"),
            Host::Ip(ip) => write!(f, "{ip}"),
            Host::Name(name) => f.write_str(name),
        }
    }
}

/// Most digits of a port (`65535`).
const PORT_DIGITS: usize = 5;

/// Reads `host[:port]` as `Host` and `:authority` write it: a bracketed IPv6
/// address, an IPv4 address or a name (letters, digits, `-`, `_`, dot-separated
/// labels, one trailing dot allowed), then an optional `:` and up to five digits.
/// `None` for anything else.
pub fn parse_host(text: &str) -> Option<Host> {
    let (host, port) = match text.strip_prefix('[') {
        Some(rest) => {
            let (inside, after) = rest.split_once(']')?;
            let port = match after {
                "" => "",
                p => p.strip_prefix(':')?,
            };
            let ip: Ipv6Addr = inside.parse().ok()?;
            return valid_port(port).then_some(Host::Ip(IpAddr::V6(ip)));
        }
        None => text.split_once(':').unwrap_or((text, "")),
    };
    if !valid_port(port) {
        return None;
    }
    let name = host.strip_suffix('.').unwrap_or(host);
    if let Ok(ip) = name.parse::<Ipv4Addr>() {
        return Some(Host::Ip(IpAddr::V4(ip)));
    }
    let label = |l: &str| {
        (1..=MAX_LABEL).contains(&l.len())
            && l.bytes()
                .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_')
    };
    (name.len() <= MAX_NAME && name.split('.').all(label))
        .then(|| Host::Name(name.to_ascii_lowercase()))
}

/// Longest label of a host name, and longest name, characters (RFC 1035, §2.3.4):
/// no longer name resolves, so none is a host a browser can name.
const MAX_LABEL: usize = 63;
const MAX_NAME: usize = 253;

/// An empty port (`host:` is allowed) or up to five digits.
fn valid_port(port: &str) -> bool {
    port.len() <= PORT_DIGITS && port.bytes().all(|b| b.is_ascii_digit())
}

/// An `--allowed-host` argument that is not a host name.
#[derive(Debug, thiserror::Error)]
#[error(
    "--allowed-host `{0}`: a host name (letters, digits, `-`, `_`, `.`), without scheme or port; IP addresses and localhost need none; a name with other letters is given in the ASCII form browsers send (`xn--…`)"
)]
pub struct AllowedHostError(pub String);

/// Checks a name as `--allowed-host` takes it, and gives it as hosts are
/// compared: lower-cased, without a trailing dot.
pub fn parse_allowed_host(name: &str) -> Result<String, AllowedHostError> {
    match parse_host(name) {
        Some(Host::Name(n)) if !name.contains(':') => Ok(n),
        // An IPv4 address is always allowed: harmless to name.
        Some(Host::Ip(IpAddr::V4(ip))) if !name.contains(':') => Ok(ip.to_string()),
        _ => Err(AllowedHostError(name.to_string())),
    }
}

/// The hosts a browser's request may name on a server without tokens, besides IP
/// literals and `localhost`.
#[derive(Clone, Debug, Default)]
pub struct AllowedHosts {
    /// Lower-cased, without a trailing dot.
    names: Vec<String>,
}

impl AllowedHosts {
    /// The names of `--allowed-host` and the hosts of `--cors-origin`s (as
    /// [`super::parse_origin`] takes them; an origin whose host is an IP literal,
    /// or not `host[:port]`, adds nothing).
    pub fn new(allowed: &[String], cors_origins: &[String]) -> Result<Self, AllowedHostError> {
        let mut names = allowed
            .iter()
            .map(|n| parse_allowed_host(n))
            .collect::<Result<Vec<_>, _>>()?;
        for origin in cors_origins {
            if let Some(Host::Name(n)) = super::cors::origin_authority(origin).and_then(parse_host)
            {
                names.push(n);
            }
        }
        Ok(AllowedHosts { names })
    }

    /// Whether a browser's request may name `host`.
    pub fn allows(&self, host: &Host) -> bool {
        match host {
            Host::Ip(_) => true,
            Host::Name(n) => {
                n == "localhost" || n.ends_with(".localhost") || self.names.contains(n)
            }
        }
    }

    /// Why `request` is refused, if it is: it is a call (not a `GET` or `HEAD`,
    /// or one in a gRPC content type: tonic serves a call whatever its method),
    /// carries `Origin` and names a host not allowed, or none it can be checked by.
    fn refusal<B>(&self, request: &Request<B>) -> Option<Refusal> {
        let reads = matches!(*request.method(), Method::GET | Method::HEAD)
            && grpc_content_type(request.headers()).is_none();
        if reads || !request.headers().contains_key(header::ORIGIN) {
            return None;
        }
        let mut hosts = request.headers().get_all(header::HOST).iter();
        let host_header = hosts.next();
        if hosts.next().is_some() {
            return Some(Refusal::ManyHosts);
        }
        // HTTP/2's `:authority`, or HTTP/1.1's absolute-form target.
        let authority = request.uri().authority().map(|a| a.host().as_bytes());
        if authority.is_none() && host_header.is_none() {
            return Some(Refusal::NoHost);
        }
        authority
            .into_iter()
            .chain(host_header.map(HeaderValue::as_bytes))
            .find_map(|bytes| self.check(bytes).err())
    }

    /// One host as the request writes it.
    fn check(&self, bytes: &[u8]) -> Result<(), Refusal> {
        let text = std::str::from_utf8(bytes)
            .ok()
            .filter(|t| t.is_ascii())
            .ok_or(Refusal::NotAscii)?;
        match parse_host(text) {
            None => Err(Refusal::Malformed(shortened(text))),
            Some(host) if self.allows(&host) => Ok(()),
            Some(host) => Err(Refusal::NotAllowed(host.to_string())),
        }
    }
}

/// Longest part of a malformed host a refusal repeats, characters.
const ECHOED_CHARS: usize = 64;

/// `text`, cut to [`ECHOED_CHARS`] (it is ASCII).
fn shortened(text: &str) -> String {
    if text.len() <= ECHOED_CHARS {
        text.to_string()
    } else {
        format!("{}…", &text[..ECHOED_CHARS])
    }
}

/// Why a browser's request is refused.
#[derive(Debug, PartialEq)]
enum Refusal {
    /// A name that is not allowed.
    NotAllowed(String),
    /// A `Host` or `:authority` that is not `host[:port]`.
    Malformed(String),
    NotAscii,
    NoHost,
    ManyHosts,
}

/// What every refusal but a name not allowed adds.
const WHY: &str = "a browser's request to a server without tokens must name the host it is for (a guard against DNS rebinding; see --allowed-host)";

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Refusal::NotAllowed(name) => write!(
                f,
                "host `{name}` is not allowed for a browser's request to a server without tokens \
                 (a guard against DNS rebinding): open the console by IP address or localhost, \
                 or start the server with --allowed-host {name}"
            ),
            Refusal::Malformed(text) => write!(f, "the host `{text}` is not host[:port]: {WHY}"),
            Refusal::NotAscii => write!(f, "the request's Host is not ASCII: {WHY}"),
            Refusal::NoHost => write!(f, "the request names no host: {WHY}"),
            Refusal::ManyHosts => write!(f, "the request has more than one Host: {WHY}"),
        }
    }
}

/// The header every refusal of this layer carries, with the value `host`: the
/// console reads it to say that the page must be opened by another name, not
/// that a token is missing (`PERMISSION_DENIED` is also a role's refusal on a
/// server with tokens). CORS exposes it, so that a page of a `--cors-origin`
/// reads it too.
pub const REFUSAL_HEADER: &str = "laparo-refusal";

/// The answer to a refused request: for a gRPC or gRPC-web call (its content
/// type `application/grpc…`), `PERMISSION_DENIED` in the headers
/// (trailers-only), in the call's content type; otherwise HTTP 403, the message
/// as text. Both carry [`REFUSAL_HEADER`]`: host`.
fn refused(request: &HeaderMap, message: &str) -> Response<Body> {
    let Some(content_type) = grpc_content_type(request) else {
        let mut response = Response::new(Body::new(format!("{message}\n")));
        *response.status_mut() = StatusCode::FORBIDDEN;
        let headers = response.headers_mut();
        headers.insert(
            header::CONTENT_TYPE,
            HeaderValue::from_static("text/plain; charset=utf-8"),
        );
        headers.insert(REFUSAL_HEADER, HeaderValue::from_static("host"));
        return response;
    };
    let mut response = Response::new(Body::default());
    let headers = response.headers_mut();
    headers.insert(header::CONTENT_TYPE, content_type.clone());
    headers.insert(REFUSAL_HEADER, HeaderValue::from_static("host"));
    // The message is percent-encoded, so it can always be a header value; if it
    // could not, the code alone.
    if Status::permission_denied(message)
        .add_header(headers)
        .is_err()
    {
        headers.insert(
            "grpc-status",
            HeaderValue::from(Code::PermissionDenied as i32),
        );
    }
    response
}

/// The request's content type if it is a gRPC or gRPC-web one
/// (`application/grpc…`).
pub(super) fn grpc_content_type(request: &HeaderMap) -> Option<&HeaderValue> {
    request
        .get(header::CONTENT_TYPE)
        .filter(|v| v.as_bytes().starts_with(b"application/grpc"))
}

/// The layer of [`HostCheck`].
#[derive(Clone, Debug)]
pub struct HostCheckLayer {
    allowed: Option<Arc<AllowedHosts>>,
}

impl HostCheckLayer {
    /// Checks browsers' requests against `allowed`; `None` (a server with
    /// tokens) checks nothing.
    pub fn new(allowed: Option<AllowedHosts>) -> Self {
        HostCheckLayer {
            allowed: allowed.map(Arc::new),
        }
    }
}

impl<S> tower_layer::Layer<S> for HostCheckLayer {
    type Service = HostCheck<S>;

    fn layer(&self, inner: S) -> HostCheck<S> {
        HostCheck {
            inner,
            allowed: self.allowed.clone(),
        }
    }
}

/// Refuses a browser's request that names a host not allowed (see the module);
/// passes every other request to the service it wraps.
#[derive(Clone, Debug)]
pub struct HostCheck<S> {
    inner: S,
    allowed: Option<Arc<AllowedHosts>>,
}

type BoxFuture<T> = Pin<Box<dyn Future<Output = T> + Send>>;

impl<S, ReqBody> tower_service::Service<Request<ReqBody>> for HostCheck<S>
where
    S: tower_service::Service<Request<ReqBody>, Response = Response<Body>>,
    S::Future: Send + 'static,
    S::Error: Send + 'static,
{
    type Response = Response<Body>;
    type Error = S::Error;
    type Future = BoxFuture<Result<Response<Body>, S::Error>>;

    fn poll_ready(&mut self, cx: &mut Context<'_>) -> Poll<Result<(), S::Error>> {
        self.inner.poll_ready(cx)
    }

    fn call(&mut self, request: Request<ReqBody>) -> Self::Future {
        let refusal = self.allowed.as_ref().and_then(|a| a.refusal(&request));
        match refusal {
            None => Box::pin(self.inner.call(request)),
            Some(refusal) => {
                let message = refusal.to_string();
                tracing::debug!(%message, "browser request refused");
                let response = refused(request.headers(), &message);
                Box::pin(std::future::ready(Ok(response)))
            }
        }
    }
}

#[cfg(test)]
mod tests;
