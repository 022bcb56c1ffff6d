//! A server killed with SIGKILL in the middle of a recorded session: its file stops
//! short of the summary, holds every chunk closed up to about the last second, and
//! recovers into a valid file that re-simulates exactly.
//!
//! The recorder closes a chunk at least every 500 ms, so what the kill loses is the
//! open chunk plus what waited in the recorder's channel: well under a second at the
//! default scene's rate. The bound asserted is one second, as the recording format
//! promises.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use laparo_proto::v1;
use laparo_server::recording::{Existing, ReadError, Recording, recover, resimulate};
use tokio::sync::mpsc;
use tokio_stream::wrappers::ReceiverStream;

mod common;
use common::process::{Server, connect, create_recorded_session, free_port};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_killed_server_leaves_a_file_readable_to_the_last_second_and_recoverable() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let mut child = Command::new(env!("CARGO_BIN_EXE_laparo-server"))
        .args(["--listen", &format!("127.0.0.1:{port}"), "--recordings"])
        .arg(dir.path())
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Keep the server's log readable in the test's output if something goes wrong.
    let stderr = child.stderr.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            eprintln!("server: {line}");
        }
    });
    let mut server = Server(child);
    let ch = connect(port).await;
    let (session_id, file) = create_recorded_session(ch.clone(), "default", dir.path()).await;

    // A station presses the left instrument into the liver's front face.
    let (tx, out) = mpsc::channel(64);
    tx.send(v1::StationMessage {
        kind: Some(v1::station_message::Kind::Open(v1::JoinRequest {
            session_id: session_id.clone(),
            role: v1::Role::Trainee as i32,
            instruments: vec!["left".into()],
            surface_frame_rate_hz: None,
            client_name: "killed".into(),
        })),
    })
    .await
    .unwrap();
    let mut rx = v1::station_client::StationClient::new(ch)
        .join(ReceiverStream::new(out))
        .await
        .unwrap()
        .into_inner();
    let Some(v1::server_message::Kind::Joined(joined)) = rx.message().await.unwrap().unwrap().kind
    else {
        panic!("expected Joined");
    };
    let scene = joined.scene.unwrap();
    let left = &scene.instruments[0];
    let trocar = left.trocar.unwrap();
    let rest = scene.rest_surface.unwrap().positions;
    // The front-most surface vertex (least y), approached along y.
    let front = rest
        .chunks_exact(3)
        .min_by(|a, b| a[1].total_cmp(&b[1]))
        .map(|p| [p[0] as f64, p[1] as f64, p[2] as f64])
        .unwrap();
    let sender = tokio::spawn(async move {
        for k in 0u64.. {
            let t = k as f64 * 4e-3;
            // From 5 mm in front of the face, in at 1 cm/s to 8 mm deep.
            let tip = [front[0], front[1] - 0.005 + (t * 0.01).min(0.013), front[2]];
            let d = [trocar.x - tip[0], trocar.y - tip[1], trocar.z - tip[2]];
            let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let pose = v1::DevicePose {
                instrument: "left".into(),
                pose: Some(v1::Pose {
                    tip: Some(v1::Vec3 {
                        x: tip[0],
                        y: tip[1],
                        z: tip[2],
                    }),
                    axis: Some(v1::Vec3 {
                        x: d[0] / n,
                        y: d[1] / n,
                        z: d[2] / n,
                    }),
                }),
                device_time_s: t,
                sequence: k + 1,
            };
            let m = v1::StationMessage {
                kind: Some(v1::station_message::Kind::Pose(pose)),
            };
            if tx.send(m).await.is_err() {
                break;
            }
            tokio::time::sleep(Duration::from_millis(4)).await;
        }
    });

    // Run about 2.5 s, then kill while still receiving.
    let mut newest = 0.0f64;
    let mut held = false;
    let until = Instant::now() + Duration::from_millis(2500);
    while Instant::now() < until {
        let Ok(Some(m)) = rx.message().await else {
            panic!("the stream ended before the kill");
        };
        if let Some(v1::server_message::Kind::InstrumentState(s)) = m.kind {
            newest = newest.max(s.sim_time_s);
            held |= s.held_vertex_count > 0;
        }
    }
    server.0.kill().unwrap();
    server.0.wait().unwrap();
    sender.abort();
    assert!(held, "the station never held tissue");
    assert!(newest > 1.5, "only {newest} s simulated before the kill");

    // No summary: the reader says so and names the fix.
    let err = Recording::open(&file).unwrap_err();
    assert!(matches!(err, ReadError::Truncated { .. }), "{err}");
    assert!(err.to_string().contains("recover"), "{err}");

    // Read as it is, through a recovery in memory, and rewritten: the same.
    let partial = Recording::open_unfinished(&file).unwrap();
    assert!(!partial.is_complete());

    let fixed = dir.path().join("recovered.mcap");
    let recovery = recover(&file, &fixed, Existing::Refuse).unwrap();
    assert!(recovery.messages > 0, "{recovery:?}");
    let rec = Recording::open(&fixed).unwrap();
    let surfaces = rec.surfaces().unwrap();
    assert_eq!(partial.surfaces().unwrap(), surfaces);
    let last = surfaces
        .last()
        .expect("some ticks were kept")
        .message
        .sim_time_s;
    eprintln!(
        "killed at {newest:.3} s simulated (newest state seen); recovered up to {last:.3} s: \
         {} chunks, {} messages, {} bytes kept, {} left out",
        recovery.chunks, recovery.messages, recovery.bytes_kept, recovery.bytes_dropped
    );
    assert!(
        last >= newest - 1.0,
        "the recovered file ends at {last} s, the station had seen {newest} s"
    );
    // Every tick from the first on, none missing, and the poses that drove them.
    assert!(
        surfaces
            .iter()
            .enumerate()
            .all(|(i, s)| s.message.tick == i as u64 + 1)
    );
    assert!(!rec.poses().unwrap().is_empty());
    // What was kept is the session as it ran: it re-simulates to the bit.
    let resim = resimulate(&rec, None, |_| {}).unwrap();
    assert_eq!(resim.ticks_compared, surfaces.len() as u64);
    assert!(resim.is_exact(), "{resim:?}");
}
