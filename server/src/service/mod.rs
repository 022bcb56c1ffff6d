//! The gRPC services of the contract, served by tonic: `Scenes`, `Sessions`,
//! `Station.Join`, `Observe` and `Recordings`, with gRPC reflection (v1 and v1alpha)
//! and the standard health service, so that grpcurl, grpcui and clients in other
//! languages work without our code.
//!
//! The same port serves the browser console ([`crate::console`]): HTTP/1.1 is
//! accepted, gRPC-web is translated to gRPC, cross-origin calls are refused
//! unless `cors_origins` allows them, a browser's calls to a server without
//! tokens must name an allowed host (`allowed_hosts`; against DNS rebinding), and
//! only the console's static assets are served without a token.
//!
//! Every service runs the [`auth::Authenticate`] interceptor, and answers a request
//! it cannot read with the contract's codes ([`decode_status`]). The server refuses to
//! listen on a non-loopback address unless it has both TLS and tokens, or is told
//! `insecure`. On shutdown every session closes: open streams end with
//! `UNAVAILABLE` and the reason, mechanics threads stop, then the server returns,
//! within [`shutdown::SHUTDOWN_BOUND`] whatever the clients do.
//!
//! What the server takes on at once is limited ([`capacity`]: sessions,
//! connections, replays); its connections are accepted by its own loop
//! ([`connections`]: counted, closed when idle or when their peer stops reading,
//! severed at shutdown).

pub mod attach;
pub mod auth;
pub mod capacity;
pub mod catalog;
pub mod connections;
pub mod decode_status;
pub mod join_rate;
pub mod limits;
pub mod listen;
pub mod liveness;
pub mod observe;
pub mod read_status;
pub mod recorder_room;
pub mod recorders;
pub mod recordings;
pub mod registry;
pub mod replay;
pub mod scenes;
pub mod sessions;
pub mod shutdown;
pub mod station;
pub mod stream;
pub mod tls_files;

use std::future::Future;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use laparo_proto::v1;
use thiserror::Error;

use crate::engine::scene::read_bounded;
use crate::recording::recorder::with_causes;
use tokio::net::TcpListener;
use tonic::service::Routes;
use tonic::service::interceptor::InterceptedService;
use tonic::transport::{Identity, Server, ServerTlsConfig};

pub use auth::{Caller, Role, TokenListError, Tokens, TokensError};
pub use catalog::{CatalogError, SceneCatalog};
use decode_status::ContractStatus;
pub use liveness::StationTimeout;
pub use registry::Registry;
pub use station::PoseLimits;

/// Largest TLS certificate or key file read, bytes: 1 MiB (a certificate chain is a
/// few kB).
pub const MAX_PEM_BYTES: u64 = 1 << 20;

/// Largest message a client may send, bytes: poses and requests are well under a
/// kilobyte; 64 KiB leaves room and refuses floods. A larger message is answered
/// with `RESOURCE_EXHAUSTED` naming this limit ([`decode_status`]).
pub const MAX_MESSAGE_BYTES: usize = 64 * 1024;
/// Largest message the server sends, bytes: a liver-300k surface frame is ~1 MB.
pub const MAX_SEND_BYTES: usize = 64 * 1024 * 1024;

/// TLS certificate and key, PEM files.
#[derive(Clone, Debug)]
pub struct TlsFiles {
    pub cert: PathBuf,
    pub key: PathBuf,
}

/// How the server runs.
#[derive(Clone, Debug, Default)]
pub struct ServeConfig {
    /// Scene files offered besides the embedded default.
    pub scene_dir: Option<PathBuf>,
    /// Bearer tokens; `None`: every caller is an instructor.
    pub tokens: Option<Tokens>,
    pub tls: Option<TlsFiles>,
    /// Default idle timeout of sessions; `None`: never.
    pub idle_timeout: Option<Duration>,
    pub pose_limits: PoseLimits,
    /// How long a station may send nothing, or take nothing, before it loses its
    /// instruments ([`liveness`]).
    pub station_timeout: StationTimeout,
    /// Listen on a non-loopback address without TLS and tokens anyway.
    pub insecure: bool,
    /// Directory sessions are recorded in (created if missing); `None`: no
    /// recording.
    pub recordings: Option<PathBuf>,
    /// The free space a new recording needs in `recordings`, bytes; `None`:
    /// [`crate::recording::space::MIN_FREE_BYTES`].
    pub recordings_min_free: Option<u64>,
    /// Sessions, connections and replays at once (default: derived from the machine).
    pub capacity: capacity::Capacity,
    /// A connection with no open stream this long is closed; `None`:
    /// [`connections::DEFAULT_IDLE_CONNECTION`].
    pub idle_connection: Option<Duration>,
    /// A connection whose peer takes none of the bytes waiting for it this long is
    /// closed; `None`: [`connections::DEFAULT_WRITE_STALL`].
    pub write_stall: Option<Duration>,
    /// Origins whose pages may call the server (CORS); empty: none but the
    /// server's own (the console it serves).
    pub cors_origins: Vec<String>,
    /// Stations attached through `Station.Attach` at once; `None`:
    /// [`attach::MAX_ATTACHED`].
    pub max_attached: Option<usize>,
    /// Host names a browser's request may name on a server without tokens,
    /// besides IP addresses, `localhost` and the hosts of `cors_origins`
    /// ([`crate::console::host`]: against DNS rebinding).
    pub allowed_hosts: Vec<String>,
}

#[derive(Debug, Error)]
pub enum ServeError {
    #[error("scenes: {0}")]
    Scenes(#[from] CatalogError),
    #[error("reflection: {0}")]
    Reflection(#[from] tonic_reflection::server::Error),
    #[error("TLS: {0}")]
    Tls(String),
    #[error(
        "refusing to listen on {0} without TLS and tokens: give --tls-cert, --tls-key and --tokens, or --insecure"
    )]
    Insecure(SocketAddr),
    #[error("listener: {0}")]
    Io(#[from] std::io::Error),
    #[error("transport: {0}")]
    Transport(#[from] tonic::transport::Error),
    #[error("{0}")]
    Cors(#[from] crate::console::CorsError),
    #[error("{0}")]
    AllowedHost(#[from] crate::console::AllowedHostError),
}

/// Serves the contract on `listener` until `shutdown` resolves, then closes every
/// session and returns.
pub async fn serve(
    config: ServeConfig,
    listener: TcpListener,
    shutdown: impl Future<Output = ()> + Send,
) -> Result<(), ServeError> {
    let addr = listener.local_addr()?;
    let secured = config.tls.is_some() && config.tokens.is_some();
    if !addr.ip().is_loopback() && !secured && !config.insecure {
        return Err(ServeError::Insecure(addr));
    }
    let origins = config
        .cors_origins
        .iter()
        .map(|o| crate::console::parse_origin(o))
        .collect::<Result<Vec<_>, _>>()?;
    let hosts = crate::console::AllowedHosts::new(&config.allowed_hosts, &config.cors_origins)?;
    // With tokens a rebinding page is refused by the interceptor: it has none.
    let hosts = config.tokens.is_none().then_some(hosts);
    let catalog = SceneCatalog::load(config.scene_dir.as_deref())?;
    if let Some(dir) = &config.recordings
        && let Err(what) = crate::recording::space::usable_dir(dir)
    {
        // Unrecorded sessions still run; a recorded one is refused, naming it.
        tracing::warn!(
            dir = %dir.display(),
            "the recordings directory {what}: sessions that record are refused \
             until it is mended"
        );
    }
    let registry = Arc::new(
        Registry::new(catalog, config.idle_timeout, config.recordings.clone())
            .with_capacity(config.capacity)
            .with_min_free(
                config
                    .recordings_min_free
                    .unwrap_or(crate::recording::space::MIN_FREE_BYTES),
            ),
    );
    let auth = auth::Authenticate::new(config.tokens.clone());

    let reflection_v1 = tonic_reflection::server::Builder::configure()
        .register_encoded_file_descriptor_set(laparo_proto::FILE_DESCRIPTOR_SET)
        .register_encoded_file_descriptor_set(tonic_health::pb::FILE_DESCRIPTOR_SET)
        .build_v1()?;
    let reflection_v1alpha = tonic_reflection::server::Builder::configure()
        .register_encoded_file_descriptor_set(laparo_proto::FILE_DESCRIPTOR_SET)
        .register_encoded_file_descriptor_set(tonic_health::pb::FILE_DESCRIPTOR_SET)
        .build_v1alpha()?;
    let (health_reporter, health) = tonic_health::server::health_reporter();

    macro_rules! service {
        ($server:ty, $inner:expr) => {
            ContractStatus(InterceptedService::new(
                <$server>::new($inner)
                    .max_decoding_message_size(MAX_MESSAGE_BYTES)
                    .max_encoding_message_size(MAX_SEND_BYTES),
                auth.clone(),
            ))
        };
    }
    let scenes = service!(
        v1::scenes_server::ScenesServer<scenes::ScenesService>,
        scenes::ScenesService {
            registry: registry.clone()
        }
    );
    let sessions = service!(
        v1::sessions_server::SessionsServer<sessions::SessionsService>,
        sessions::SessionsService {
            registry: registry.clone()
        }
    );
    let station = service!(
        v1::station_server::StationServer<station::StationService>,
        station::StationService {
            registry: registry.clone(),
            limits: config.pose_limits,
            timeout: config.station_timeout,
            attachments: Arc::new(attach::Attachments::with_limit(
                config.max_attached.unwrap_or(attach::MAX_ATTACHED)
            )),
        }
    );
    let observe = service!(
        v1::observe_server::ObserveServer<observe::ObserveService>,
        observe::ObserveService {
            registry: registry.clone(),
            timeout: config.station_timeout,
        }
    );
    let recordings = service!(
        v1::recordings_server::RecordingsServer<recordings::RecordingsService>,
        recordings::RecordingsService {
            registry: registry.clone(),
            lister: Default::default(),
            timeout: config.station_timeout,
        }
    );
    for name in [
        "laparo.v1.Scenes",
        "laparo.v1.Sessions",
        "laparo.v1.Station",
        "laparo.v1.Observe",
        "laparo.v1.Recordings",
    ] {
        health_reporter
            .set_service_status(name, tonic_health::ServingStatus::Serving)
            .await;
    }

    let limits = connections::ConnectionLimits {
        max: config.capacity.connections,
        per_peer: config.capacity.connections_per_peer,
        idle: config
            .idle_connection
            .unwrap_or(connections::DEFAULT_IDLE_CONNECTION),
        write_stall: config
            .write_stall
            .unwrap_or(connections::DEFAULT_WRITE_STALL),
        keepalive_interval: connections::DEFAULT_KEEPALIVE_INTERVAL,
        keepalive_timeout: connections::DEFAULT_KEEPALIVE_TIMEOUT,
    };
    let mut builder = Server::builder()
        .max_concurrent_streams(limits::MAX_STREAMS_PER_CONNECTION)
        .http2_keepalive_interval(Some(limits.keepalive_interval))
        .http2_keepalive_timeout(Some(limits.keepalive_timeout));
    if let Some(tls) = &config.tls {
        let read = |p: &PathBuf| {
            read_bounded(p, None, MAX_PEM_BYTES)
                .map_err(|e| ServeError::Tls(format!("{} {e}", p.display())))
        };
        let (cert, key) = (read(&tls.cert)?, read(&tls.key)?);
        tls_files::check_certificates(&cert).map_err(|why| {
            ServeError::Tls(format!(
                "--tls-cert {} is not a PEM certificate: {why}",
                tls.cert.display()
            ))
        })?;
        tls_files::check_private_key(&key).map_err(|why| {
            ServeError::Tls(format!(
                "--tls-key {} is not a PEM private key: {why}",
                tls.key.display()
            ))
        })?;
        let identity = Identity::from_pem(cert, key);
        builder = builder
            .tls_config(ServerTlsConfig::new().identity(identity))
            .map_err(|e| {
                ServeError::Tls(format!(
                    "{} with {} and {} (are they a certificate and its own key, in PEM?)",
                    with_causes(&e),
                    tls.cert.display(),
                    tls.key.display()
                ))
            })?;
    }
    tracing::info!(
        %addr,
        tls = config.tls.is_some(),
        tokens = config.tokens.is_some(),
        sessions = config.capacity.sessions,
        connections = config.capacity.connections,
        connections_per_peer = config.capacity.connections_per_peer,
        replays = config.capacity.replays,
        "serving laparo.v1"
    );
    let severance = connections::Severance::default();
    let incoming = connections::incoming(listener, limits, Default::default(), severance.clone());
    let mut routes = Routes::builder();
    routes
        .add_service(health)
        .add_service(reflection_v1)
        .add_service(reflection_v1alpha)
        .add_service(scenes)
        .add_service(sessions)
        .add_service(station)
        .add_service(observe)
        .add_service(recordings);
    // The services' calls go through `call_layers`; the console's static assets
    // answer what no service does (outside the translation, which refuses any
    // other HTTP/1.1 request).
    let routes = Routes::from(
        routes
            .routes()
            .into_axum_router()
            .route_layer(call_layers(connections::REQUEST_DEADLINE))
            .fallback(crate::console::asset),
    );
    // HTTP/1.1 too: gRPC-web from a browser.
    builder
        .accept_http1(true)
        .layer(connections::CountStreamsLayer)
        .layer(crate::console::cors_layer(origins))
        // Inside CORS: preflights are CORS's, and a refusal carries its headers.
        .layer(crate::console::HostCheckLayer::new(hosts))
        .add_routes(routes)
        .serve_with_incoming_shutdown(
            incoming,
            shutdown::on_signal(shutdown, registry.clone(), severance),
        )
        .await?;
    Ok(())
}

/// What each of the services' calls passes through, outermost first: gRPC-web
/// translated to gRPC (the browser console's calls; a gRPC call passes as it
/// is), then the request's `deadline` ([`connections::RequestDeadline`]) on the
/// translated body. In this order a gRPC-web call whose request does not arrive
/// in time is answered `DEADLINE_EXCEEDED`, as a gRPC one is: the translation
/// reports any error of the body it decodes as `INTERNAL`.
pub fn call_layers(
    deadline: Duration,
) -> tower_layer::Stack<connections::RequestDeadlineLayer, tonic_web::GrpcWebLayer> {
    tower_layer::Stack::new(
        connections::RequestDeadlineLayer::new(deadline),
        tonic_web::GrpcWebLayer::new(),
    )
}
