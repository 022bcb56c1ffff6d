//! `run_station` against a minimal fake `Station` service on loopback: the token
//! arrives, the open message is first, poses are numbered and echoed back as
//! `pose_sequence`, invalid local models are counted, `Leave` ends the stream, a
//! status ending the stream comes back with its code, and a join that does not
//! grant every instrument claimed is a protocol error. No timing assertions.

use std::time::Duration;

use laparo_client::proto::force::{LocalModel, wire};
use laparo_client::proto::v1::station_server::{Station, StationServer};
use laparo_client::proto::v1::{
    self, Force, InstrumentDescription, InstrumentState, Joined, SceneDescription, ServerMessage,
    StationMessage, SurfaceFrame, SurfaceMesh, Vec3, server_message, station_message,
};
use laparo_client::station::{StationConfig, StationEnd, StationError, run_station};
use nalgebra::{Point3, Vector3};
use tokio::sync::mpsc;
use tokio_stream::wrappers::{ReceiverStream, TcpListenerStream};
use tonic::{Request, Response, Status, Streaming};

struct Fake;

fn scene() -> SceneDescription {
    SceneDescription {
        rest_surface: Some(SurfaceMesh {
            positions: vec![0.0, 0.0, 0.0],
            triangles: vec![],
        }),
        instruments: vec![InstrumentDescription {
            name: "left".into(),
            radius_m: 0.005,
            length_m: 0.3,
            trocar: Some(Vec3 {
                x: 0.0,
                y: 0.0,
                z: 0.2,
            }),
            tip_contact: true,
            shaft_contact: true,
        }],
        ..Default::default()
    }
}

fn state(tick: u64, sequence: u64, valid: bool) -> ServerMessage {
    let model = LocalModel::free(tick, 0.0, Point3::origin(), Vector3::z_axis());
    let mut model = v1::LocalModel::from(&model);
    if !valid {
        model.pose.as_mut().unwrap().tip.as_mut().unwrap().x = f64::NAN;
    }
    ServerMessage {
        kind: Some(server_message::Kind::InstrumentState(InstrumentState {
            tick,
            instrument: "left".into(),
            pose_sequence: Some(sequence),
            local_model: Some(model),
            force: Some(Force {
                force: Some(wire::to_vec3(&Vector3::new(0.0, 0.0, 2.0))),
                ..Default::default()
            }),
            ..Default::default()
        })),
    }
}

#[tonic::async_trait]
impl Station for Fake {
    type JoinStream = ReceiverStream<Result<ServerMessage, Status>>;
    type AttachStream = ReceiverStream<Result<laparo_proto::v1::AttachMessage, Status>>;

    async fn attach(
        &self,
        _: Request<laparo_proto::v1::JoinRequest>,
    ) -> Result<Response<Self::AttachStream>, Status> {
        Err(Status::unimplemented("the client under test uses Join"))
    }

    async fn send_poses(
        &self,
        _: Request<laparo_proto::v1::SendPosesRequest>,
    ) -> Result<Response<laparo_proto::v1::SendPosesResponse>, Status> {
        Err(Status::unimplemented("the client under test uses Join"))
    }

    async fn join(
        &self,
        request: Request<Streaming<StationMessage>>,
    ) -> Result<Response<Self::JoinStream>, Status> {
        let auth = request
            .metadata()
            .get("authorization")
            .and_then(|v| v.to_str().ok());
        if auth != Some("Bearer tok") {
            return Err(Status::unauthenticated("bad token"));
        }
        let mut incoming = request.into_inner();
        let Some(station_message::Kind::Open(open)) =
            incoming.message().await?.and_then(|m| m.kind)
        else {
            return Err(Status::invalid_argument("open must come first"));
        };
        if open.session_id == "missing" {
            return Err(Status::not_found("no session \"missing\""));
        }
        let known: Vec<String> = open
            .instruments
            .iter()
            .filter(|n| *n == "left")
            .cloned()
            .collect();
        // As the contract says, a join is granted whole or refused; the session
        // "partial" breaks it and grants what it knows.
        let granted = if open.session_id == "partial" || known == open.instruments {
            known
        } else {
            return Err(Status::not_found("no instrument \"right\""));
        };
        let (tx, rx) = mpsc::channel(1024);
        tx.send(Ok(ServerMessage {
            kind: Some(server_message::Kind::Joined(Joined {
                station_id: 1,
                session_id: open.session_id.clone(),
                scene: Some(scene()),
                instruments: granted,
                surface_frame_rate_hz: 60.0,
                tick: 0,
                max_pose_rate_hz: 0.0,
            })),
        }))
        .await
        .unwrap();
        let fail = open.session_id == "fails";
        tokio::spawn(async move {
            let mut tick = 0;
            let mut last_sequence = 0;
            while let Ok(Some(message)) = incoming.message().await {
                match message.kind {
                    Some(station_message::Kind::Pose(pose)) => {
                        assert!(pose.sequence > last_sequence, "sequence increases");
                        last_sequence = pose.sequence;
                        assert!(wire::pose(pose.pose.as_ref()).is_ok());
                        tick += 1;
                        let frame = ServerMessage {
                            kind: Some(server_message::Kind::SurfaceFrame(SurfaceFrame {
                                tick,
                                sim_time_s: tick as f64 / 60.0,
                                positions: vec![0.0, 0.0, 0.0],
                            })),
                        };
                        let _ = tx.send(Ok(frame)).await;
                        // Every fifth state carries an invalid local model.
                        let _ = tx.send(Ok(state(tick, pose.sequence, tick % 5 != 0))).await;
                        if fail && tick == 20 {
                            let _ = tx.send(Err(Status::aborted("mechanics failed"))).await;
                            return;
                        }
                    }
                    Some(station_message::Kind::Leave(_)) => return,
                    _ => {}
                }
            }
        });
        Ok(Response::new(ReceiverStream::new(rx)))
    }
}

async fn serve() -> String {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let url = format!("http://{}", listener.local_addr().unwrap());
    tokio::spawn(
        tonic::transport::Server::builder()
            .add_service(StationServer::new(Fake))
            .serve_with_incoming(TcpListenerStream::new(listener)),
    );
    url
}

fn config(url: &str, session: &str, seconds: f64) -> StationConfig {
    let mut c = StationConfig::new(url, session, vec!["left".into()]);
    c.connect.token = Some("tok".into());
    c.duration = Some(Duration::from_secs_f64(seconds));
    c
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn station_streams_poses_feeds_models_and_measures_latency() {
    let url = serve().await;
    let summary = run_station(config(&url, "s1", 1.0)).await.unwrap();
    assert_eq!(summary.end, StationEnd::Duration);
    assert_eq!(summary.instruments, vec!["left".to_owned()]);
    assert!(summary.poses_sent > 0);
    assert!(summary.states > 0 && summary.frames > 0);
    assert!(summary.latency.count > 0, "{summary:?}");
    assert!((summary.max_force_n - 2.0).abs() < 1e-12);
    let left = &summary.per_instrument[0];
    assert!(left.models_applied > 0);
    assert_eq!(left.models_applied + left.models_invalid, summary.states);
    assert!(left.loop_stats.ticks > 0);
    assert!(left.loop_stats.models_received > 0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn statuses_come_back_with_their_code() {
    let url = serve().await;
    let e = run_station(config(&url, "missing", 5.0)).await.unwrap_err();
    assert!(
        matches!(
            &e,
            StationError::Status {
                code: tonic::Code::NotFound,
                ..
            }
        ),
        "{e}"
    );
    let e = run_station(config(&url, "fails", 30.0)).await.unwrap_err();
    assert!(
        matches!(&e, StationError::Status { code: tonic::Code::Aborted, message } if message == "mechanics failed"),
        "{e}"
    );
    let mut no_token = config(&url, "s1", 5.0);
    no_token.connect.token = None;
    let e = run_station(no_token).await.unwrap_err();
    assert!(
        matches!(
            &e,
            StationError::Status {
                code: tonic::Code::Unauthenticated,
                ..
            }
        ),
        "{e}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_join_is_granted_whole_or_the_station_does_not_run() {
    let url = serve().await;
    let both = |session: &str| {
        let mut c = config(&url, session, 5.0);
        c.instruments = vec!["left".into(), "right".into()];
        c
    };
    // Refused whole: the server's status.
    let e = run_station(both("s1")).await.unwrap_err();
    assert!(
        matches!(
            &e,
            StationError::Status {
                code: tonic::Code::NotFound,
                ..
            }
        ),
        "{e}"
    );
    // A server that grants part of the claim breaks the protocol.
    let e = run_station(both("partial")).await.unwrap_err();
    assert!(
        matches!(&e, StationError::Protocol(m) if m.contains("granted")),
        "{e}"
    );
}
