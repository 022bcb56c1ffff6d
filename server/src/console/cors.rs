//! Cross-origin requests: refused unless the origin is one given with
//! `--cors-origin`. The console itself is same-origin (served by the server it
//! calls) and needs none; another origin (a page served elsewhere during
//! development, say) must be allowed by name.
//!
//! gRPC-web calls carry `content-type: application/grpc-web…` and
//! `authorization`, so a browser always asks first (a preflight `OPTIONS`); for
//! an origin not allowed the answer has no `Access-Control-Allow-Origin` and the
//! browser does not send the call.

use std::time::Duration;

use axum::http::{HeaderName, HeaderValue, Method};
use tower_http::cors::{AllowOrigin, CorsLayer};

/// An origin argument that is not `scheme://host[:port]`.
#[derive(Debug, thiserror::Error)]
#[error(
    "--cors-origin `{0}`: an origin is `http://host[:port]` or `https://host[:port]`, without a path"
)]
pub struct CorsError(pub String);

/// What follows an origin's `http://` or `https://`: its `host[:port]`. `None`
/// for another scheme.
pub(super) fn origin_authority(origin: &str) -> Option<&str> {
    origin
        .strip_prefix("http://")
        .or_else(|| origin.strip_prefix("https://"))
}

/// Checks an origin as `--cors-origin` takes it.
pub fn parse_origin(origin: &str) -> Result<HeaderValue, CorsError> {
    let bad = || CorsError(origin.to_string());
    let rest = origin_authority(origin).ok_or_else(bad)?;
    // What a browser can send as `Origin`: a host it can name, and a port of 1 to
    // 65535 if any (an origin that can never match would be taken without a word).
    let valid = super::host::parse_host(rest).is_some()
        && port(rest).is_none_or(|p| p.parse::<u16>().is_ok_and(|n| n > 0));
    if !valid {
        return Err(bad());
    }
    HeaderValue::from_str(origin).map_err(|_| bad())
}

/// The port `host[:port]` writes, if any (after a bracketed IPv6 address's `]`).
fn port(authority: &str) -> Option<&str> {
    let after = authority
        .rfind(']')
        .map_or(authority, |i| &authority[i + 1..]);
    after.split_once(':').map(|(_, p)| p)
}

/// The CORS layer: the allowed origins (none: every cross-origin call is
/// refused), gRPC-web's request headers, and the headers a page must read to see
/// a call's status.
pub fn cors_layer(origins: Vec<HeaderValue>) -> CorsLayer {
    const REQUEST_HEADERS: [&str; 7] = [
        "authorization",
        "content-type",
        "x-grpc-web",
        "x-user-agent",
        "grpc-timeout",
        "connect-protocol-version",
        "connect-timeout-ms",
    ];
    const EXPOSED_HEADERS: [&str; 4] = [
        "grpc-status",
        "grpc-message",
        "grpc-status-details-bin",
        super::host::REFUSAL_HEADER,
    ];
    CorsLayer::new()
        .allow_origin(AllowOrigin::list(origins))
        .allow_methods([Method::GET, Method::POST])
        .allow_headers(REQUEST_HEADERS.map(HeaderName::from_static))
        .expose_headers(EXPOSED_HEADERS.map(HeaderName::from_static))
        .max_age(Duration::from_secs(600))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn origins_are_scheme_host_and_port_only() {
        for good in [
            "http://localhost:5173",
            "https://console.example.org",
            "http://[::1]:8080",
            "http://[::1]",
            "http://127.0.0.1:65535",
        ] {
            assert!(parse_origin(good).is_ok(), "{good}");
        }
        for bad in [
            "",
            "*",
            "localhost:5173",
            "ftp://example.org",
            "http://",
            "http://example.org/",
            "http://example.org/path",
            "http://exa mple.org",
            "http://[[[",
            "http://a:b:c",
            "http://evil.example:99999999",
            "http://example.org:65536",
            "http://example.org:0",
            "http://example.org:",
            "http://[::1]:",
            "http://a..b",
        ] {
            let e = parse_origin(bad).unwrap_err();
            assert!(e.to_string().contains("--cors-origin"), "{bad}: {e}");
        }
    }
}
