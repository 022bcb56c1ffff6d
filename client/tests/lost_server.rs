//! A server that goes away in the middle of a stream: `laparo observe` ends with
//! status 1 and says the connection was lost and how, in words (it said "the server
//! ended the stream with Unknown: h2 protocol error" before).
//!
//! The server is a minimal `Observe` service on its own runtime and thread; once
//! the client's call arrived and the scene was sent, the runtime is dropped, which
//! closes every connection without a word, as a killed server does. Or it freezes,
//! as a stopped (SIGSTOP) or hung server does: its one worker thread blocks, its
//! connections stay open and nothing answers, not even a keep-alive ping.

mod peers;

use std::net::SocketAddr;
use std::sync::mpsc as std_mpsc;
use std::time::Instant;

use laparo_client::proto::v1::observe_server::{Observe, ObserveServer};
use laparo_client::proto::v1::{ObserveMessage, ObserveRequest, SceneDescription, observe_message};
use tokio::sync::mpsc;
use tokio_stream::wrappers::{ReceiverStream, TcpListenerStream};
use tonic::{Request, Response, Status};

struct Fake {
    arrived: std_mpsc::Sender<()>,
}

#[tonic::async_trait]
impl Observe for Fake {
    type ObserveStream = ReceiverStream<Result<ObserveMessage, Status>>;

    async fn observe(
        &self,
        _: Request<ObserveRequest>,
    ) -> Result<Response<Self::ObserveStream>, Status> {
        let (tx, rx) = mpsc::channel(4);
        let scene = ObserveMessage {
            kind: Some(observe_message::Kind::Scene(SceneDescription::default())),
        };
        tx.send(Ok(scene)).await.expect("the stream is open");
        // The stream stays open, with nothing more to say, until the server goes.
        tokio::spawn(async move {
            let _held = tx;
            std::future::pending::<()>().await;
        });
        let _ = self.arrived.send(());
        Ok(Response::new(ReceiverStream::new(rx)))
    }
}

/// What the fake server does when told.
#[derive(Clone, Copy)]
enum End {
    /// Every socket closed at once.
    Vanish,
    /// Nothing runs any more; every socket stays open.
    Freeze,
}

/// Starts the fake server on its own thread; returns its address, the signal that a
/// call arrived, and the sender that makes it end as `end` says.
fn start(end: End) -> (SocketAddr, std_mpsc::Receiver<()>, std_mpsc::Sender<()>) {
    let (address_tx, address_rx) = std_mpsc::channel();
    let (arrived_tx, arrived_rx) = std_mpsc::channel();
    let (vanish_tx, vanish_rx) = std_mpsc::channel::<()>();
    std::thread::spawn(move || {
        // One worker: blocking it stops every task of the server.
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .enable_all()
            .build()
            .unwrap();
        let listener = runtime
            .block_on(tokio::net::TcpListener::bind("127.0.0.1:0"))
            .unwrap();
        address_tx.send(listener.local_addr().unwrap()).unwrap();
        runtime.spawn(
            tonic::transport::Server::builder()
                .add_service(ObserveServer::new(Fake {
                    arrived: arrived_tx,
                }))
                .serve_with_incoming(TcpListenerStream::new(listener)),
        );
        let _ = vanish_rx.recv();
        match end {
            // Every task dropped, every socket closed: no GOAWAY, no status.
            End::Vanish => runtime.shutdown_background(),
            End::Freeze => {
                runtime.spawn(async { std::thread::sleep(peers::LIMIT) });
                // The runtime (and its sockets) live on, frozen, until the test
                // process ends.
                std::mem::forget(runtime);
            }
        }
    });
    (address_rx.recv().unwrap(), arrived_rx, vanish_tx)
}

#[test]
fn a_server_that_vanishes_mid_stream_is_a_lost_connection_in_words() {
    let (address, arrived, vanish) = start(End::Vanish);
    let server = format!("http://{address}");
    let started = Instant::now();
    let client = peers::start_laparo(&["observe", "--server", &server, "--session", "s1"]);
    let came = arrived.recv_timeout(peers::LIMIT);
    vanish.send(()).unwrap();
    let run = peers::finish(client, started);
    came.unwrap_or_else(|_| panic!("the observe call never arrived: {}", run.stderr));
    run.fails_saying(&[
        "lost the connection to the server",
        "the server closed the connection",
    ]);
    assert!(!run.stderr.contains("h2 protocol error"), "{}", run.stderr);
}

#[test]
fn a_server_that_freezes_mid_stream_is_said_to_have_stopped_answering() {
    let (address, arrived, freeze) = start(End::Freeze);
    let server = format!("http://{address}");
    let started = Instant::now();
    let client = peers::start_laparo(&["observe", "--server", &server, "--session", "s1"]);
    let came = arrived.recv_timeout(peers::LIMIT);
    freeze.send(()).unwrap();
    let run = peers::finish(client, started);
    came.unwrap_or_else(|_| panic!("the observe call never arrived: {}", run.stderr));
    // Ended by the keep-alive (10 s without a frame, then 5 s without a reply to its
    // ping), well within the peers' limit, in words.
    run.fails_saying(&["the server stopped answering"]);
}
