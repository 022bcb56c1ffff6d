//! The browser console, served on the gRPC port: its static assets (the bundle
//! built from `web/`, embedded in the binary), gRPC-web for the page's calls
//! (`tonic-web`, over HTTP/1.1 or HTTP/2), CORS for the origins the operator
//! allows with `--cors-origin` (none by default: a page of another origin cannot
//! call the server), and, on a server without tokens, a check of the host a
//! browser's request names ([`host`]: against DNS rebinding).
//!
//! Only the static assets are served without a token: every gRPC and gRPC-web call
//! goes to the same services, behind the same authentication interceptor, as a
//! native client's.

pub mod assets;
pub mod bundle;
pub mod cors;
pub mod host;

pub use assets::asset;
pub use cors::{CorsError, cors_layer, parse_origin};
pub use host::{AllowedHostError, AllowedHosts, HostCheckLayer, parse_allowed_host};
