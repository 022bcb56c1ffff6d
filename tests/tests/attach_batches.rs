//! `Station.SendPoses` batches, as the browser console sends them (the poses
//! sampled at the station's pose rate since its last call): a batch over
//! `MAX_POSES_PER_CALL` is refused with a status that names the limit and
//! queues nothing; a full batch is taken whole, each pose in the order sent —
//! the recording holds every one, in order, and the instrument ends at the last.

use laparo_proto::v1;
use laparo_server::recording::Recording;
use laparo_server::service::attach::MAX_POSES_PER_CALL;
use laparo_tests::recordings::*;
use laparo_tests::server::*;
use tonic::Code;
use tonic::transport::Channel;

/// Tip of pose `k` of the batch: 1.5 cm in front of the liver's front, moving in
/// by 0.1 mm per pose (a slow insertion, sampled).
fn tip(front: [f64; 3], k: u64) -> [f64; 3] {
    [front[0], front[1], front[2] + 0.015 - 1e-4 * k as f64]
}

fn device_pose(tip: [f64; 3], sequence: u64) -> v1::DevicePose {
    let Some(v1::station_message::Kind::Pose(p)) =
        pose("left", tip, [0.0, 0.0, 1.0], sequence).kind
    else {
        unreachable!()
    };
    p
}

async fn send(
    ch: &Channel,
    handle: &str,
    poses: Vec<v1::DevicePose>,
) -> Result<u32, tonic::Status> {
    v1::station_client::StationClient::new(ch.clone())
        .send_poses(v1::SendPosesRequest {
            handle: handle.into(),
            poses,
            leave: false,
        })
        .await
        .map(|r| r.into_inner().queued)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_batch_is_bounded_and_drives_the_instrument_through_its_poses_in_order() {
    let (server, ch, dir) = recording_server("attach-batches").await;
    let mut sessions = v1::sessions_client::SessionsClient::new(ch.clone());
    let info = create_recorded(&mut sessions).await;
    let file = dir.join(info.recording_file.clone().unwrap());
    let mut rx = v1::station_client::StationClient::new(ch.clone())
        .attach(v1::JoinRequest {
            session_id: info.session_id.clone(),
            role: v1::Role::Trainee as i32,
            instruments: vec!["left".into()],
            surface_frame_rate_hz: None,
            client_name: "browser".into(),
        })
        .await
        .unwrap()
        .into_inner();
    let Some(v1::attach_message::Kind::Attached(attached)) =
        rx.message().await.unwrap().and_then(|m| m.kind)
    else {
        panic!("the first message is not Attached");
    };
    let Some(v1::attach_message::Kind::Message(v1::ServerMessage {
        kind: Some(v1::server_message::Kind::Joined(joined)),
    })) = rx.message().await.unwrap().and_then(|m| m.kind)
    else {
        panic!("the second message is not Joined");
    };
    let front = laparo_tests::pressing::front(&joined);
    let handle = attached.handle;

    // One pose over the limit: refused, the limit named, nothing queued.
    let over: Vec<_> = (1..=MAX_POSES_PER_CALL as u64 + 1)
        .map(|k| device_pose(tip(front, k), k))
        .collect();
    let refused = send(&ch, &handle, over).await.unwrap_err();
    assert_eq!(refused.code(), Code::InvalidArgument, "{refused:?}");
    assert!(
        refused.message().contains("MAX_POSES_PER_CALL")
            && refused.message().contains(&MAX_POSES_PER_CALL.to_string()),
        "{}",
        refused.message()
    );

    // A full batch: all queued, and the instrument ends at its last pose.
    let n = MAX_POSES_PER_CALL as u64;
    let batch: Vec<_> = (1..=n).map(|k| device_pose(tip(front, k), k)).collect();
    assert_eq!(send(&ch, &handle, batch).await.unwrap(), n as u32);
    let last = tokio::time::timeout(WAIT, async {
        while let Ok(Some(m)) = rx.message().await {
            if let Some(v1::attach_message::Kind::Message(v1::ServerMessage {
                kind: Some(v1::server_message::Kind::InstrumentState(s)),
            })) = m.kind
                && s.instrument == "left"
                && s.pose_sequence == Some(n)
            {
                return Some(s);
            }
        }
        None
    })
    .await
    .ok()
    .flatten()
    .expect("the instrument never took the batch's last pose");
    let at = last.pose.unwrap().tip.unwrap();
    let want = tip(front, n);
    assert!(
        (at.x - want[0]).abs() < 1e-12
            && (at.y - want[1]).abs() < 1e-12
            && (at.z - want[2]).abs() < 1e-12,
        "{at:?} {want:?}"
    );
    drop(rx);
    sessions
        .close_session(v1::CloseSessionRequest {
            session_id: info.session_id.clone(),
            reason: "test over".into(),
        })
        .await
        .unwrap();

    // Every pose of the batch was taken, in the order sent, and none of the
    // refused call's.
    let recorded = Recording::open(&file).unwrap().poses().unwrap();
    let sequences: Vec<u64> = recorded.iter().map(|p| p.message.sequence).collect();
    assert_eq!(sequences, (1..=n).collect::<Vec<_>>());
    for p in &recorded {
        let t = p.message.pose.as_ref().unwrap().tip.as_ref().unwrap();
        let want = tip(front, p.message.sequence);
        assert!((t.z - want[2]).abs() < 1e-12, "{t:?} {want:?}");
    }
    server.shutdown().await.unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}
