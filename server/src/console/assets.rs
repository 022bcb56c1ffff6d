//! The console's static assets, embedded from `web/dist` at build time (the
//! bundle is committed, so building the server needs no npm; [`super::bundle`]
//! checks that it is not stale).
//!
//! `GET /` is `index.html`; `GET /assets/…` the bundle's files, whose names carry
//! their content hash (cached for a year); anything else is 404. A request that
//! is a gRPC call to a service the server does not have still gets gRPC's
//! `UNIMPLEMENTED`, not a page.

use axum::body::Body;
use axum::http::{HeaderValue, Method, Request, Response, StatusCode, header};
use rust_embed::Embed;

#[derive(Embed)]
#[folder = "../web/dist"]
pub struct Assets;

/// The bundle's stamp ([`super::bundle`]), embedded with it but not served.
pub const STAMP: &str = "bundle-hash.txt";

/// Same-origin only: the bundle loads its own scripts, styles and images, and
/// talks to the origin it came from.
const CONTENT_SECURITY_POLICY: &str = "default-src 'self'; img-src 'self' data: blob:; style-src 'self' 'unsafe-inline'; object-src 'none'; base-uri 'none'; frame-ancestors 'none'";

/// The router's fallback: a static asset, or gRPC's `UNIMPLEMENTED` for a call to
/// an unknown service.
pub async fn asset(request: Request<Body>) -> Response<Body> {
    if let Some(content_type) = super::host::grpc_content_type(request.headers()) {
        return unimplemented(content_type.clone());
    }
    lookup(request.method(), request.uri().path())
}

/// gRPC's `UNIMPLEMENTED` (trailers-only) in the call's own content type: a
/// gRPC-web client reads a status only from an answer in gRPC-web's.
fn unimplemented(content_type: HeaderValue) -> Response<Body> {
    let (mut parts, ()) = tonic::Status::unimplemented("no such service")
        .into_http::<()>()
        .into_parts();
    parts.headers.insert(header::CONTENT_TYPE, content_type);
    Response::from_parts(parts, Body::empty())
}

/// The answer for `method` and `path` (no query).
pub fn lookup(method: &Method, path: &str) -> Response<Body> {
    if method != Method::GET && method != Method::HEAD {
        let mut refused = plain(StatusCode::METHOD_NOT_ALLOWED, "only GET and HEAD here\n");
        refused
            .headers_mut()
            .insert(header::ALLOW, HeaderValue::from_static("GET, HEAD"));
        return refused;
    }
    let name = match path {
        "/" | "/index.html" => "index.html",
        p => p.trim_start_matches('/'),
    };
    // The stamp of the bundle's inputs is for the staleness test, not a page.
    let Some(file) = Assets::get(name).filter(|_| name != STAMP) else {
        return plain(StatusCode::NOT_FOUND, "not found\n");
    };
    let cache = if name.starts_with("assets/") {
        "public, max-age=31536000, immutable"
    } else {
        "no-cache"
    };
    // A HEAD states the length its GET would send (an empty body would say 0).
    let length = HeaderValue::from(file.data.len());
    let body = if method == Method::HEAD {
        Body::empty()
    } else {
        Body::from(file.data.into_owned())
    };
    let mut response = Response::new(body);
    let headers = response.headers_mut();
    headers.insert(header::CONTENT_LENGTH, length);
    headers.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static(content_type(name)),
    );
    headers.insert(header::CACHE_CONTROL, HeaderValue::from_static(cache));
    headers.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static(CONTENT_SECURITY_POLICY),
    );
    headers.insert(
        header::X_CONTENT_TYPE_OPTIONS,
        HeaderValue::from_static("nosniff"),
    );
    response
}

fn plain(status: StatusCode, text: &'static str) -> Response<Body> {
    let mut response = Response::new(Body::from(text));
    *response.status_mut() = status;
    response.headers_mut().insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("text/plain; charset=utf-8"),
    );
    response
}

/// The media type of a bundle file, by its extension.
fn content_type(name: &str) -> &'static str {
    match name.rsplit_once('.').map(|(_, ext)| ext) {
        Some("html") => "text/html; charset=utf-8",
        Some("js" | "mjs") => "text/javascript; charset=utf-8",
        Some("css") => "text/css; charset=utf-8",
        Some("json") => "application/json",
        Some("svg") => "image/svg+xml",
        Some("png") => "image/png",
        Some("ico") => "image/x-icon",
        Some("wasm") => "application/wasm",
        Some("txt" | "map") => "text/plain; charset=utf-8",
        _ => "application/octet-stream",
    }
}

#[cfg(test)]
mod tests;
